# SPDX-License-Identifier: MIT
"""The package's version is the C library's: one number, in the CTRLBUS_VERSION_* macros of
c/include/ctrlbus/ctrlbus.h. Building from the checkout reads it there; building a wheel from the
sdist (which has no c/ next to it) reads it back from the sdist's PKG-INFO. Everything else is in
pyproject.toml."""

import re
from pathlib import Path

from setuptools import setup

HERE = Path(__file__).resolve().parent
HEADER = HERE.parent / "c" / "include" / "ctrlbus" / "ctrlbus.h"


def version() -> str:
    if HEADER.exists():
        text = HEADER.read_text()
        names = ("MAJOR", "MINOR", "PATCH")
        parts = [re.search(rf"^#define CTRLBUS_VERSION_{name} +(\d+)", text, re.M) for name in names]
        if not all(parts):
            raise SystemExit(f"setup.py: no CTRLBUS_VERSION_MAJOR/MINOR/PATCH in {HEADER}")
        return ".".join(m.group(1) for m in parts if m)
    match = re.search(r"^Version: (\S+)$", (HERE / "PKG-INFO").read_text(), re.M)
    if not match:
        raise SystemExit("setup.py: neither c/include/ctrlbus/ctrlbus.h nor a PKG-INFO with a Version")
    return match.group(1)


setup(version=version())
