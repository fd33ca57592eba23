# SPDX-License-Identifier: MIT
"""ctrlbus: the SLAMWARE Control Bus, byte-exact, in Python."""

__version__ = "0.1.0"
