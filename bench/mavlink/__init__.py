# SPDX-License-Identifier: MIT
"""The MAVLink v2 peer of the benchmarks: our own small dialect, generated with pymavlink at bench time."""
