# SPDX-License-Identifier: MIT
"""ctrlbus: the SLAMWARE Control Bus, byte-exact, in Python."""

from importlib.metadata import PackageNotFoundError, version

# The installed package's version, which is the C library's (python/setup.py reads it from
# c/include/ctrlbus/ctrlbus.h): there is no second copy to keep in step.
try:
    __version__ = version("ctrlbus")
except PackageNotFoundError:  # imported from a source tree that was never installed
    __version__ = "0+unknown"
