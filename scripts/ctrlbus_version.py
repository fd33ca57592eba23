# SPDX-License-Identifier: MIT
"""The ctrlbus version, read from its one home: the CTRLBUS_VERSION_* macros of
c/include/ctrlbus/ctrlbus.h. `python scripts/ctrlbus_version.py` prints it (the Makefile's release
names use it)."""

import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
HEADER = REPO / "c" / "include" / "ctrlbus" / "ctrlbus.h"


def ctrlbus_version(header: Path = HEADER) -> str:
    text = header.read_text()
    parts = []
    for part in ("MAJOR", "MINOR", "PATCH"):
        match = re.search(rf"^#define CTRLBUS_VERSION_{part} +(\d+)", text, re.M)
        if not match:
            raise SystemExit(f"{header}: no CTRLBUS_VERSION_{part}")
        parts.append(match.group(1))
    return ".".join(parts)


if __name__ == "__main__":
    print(ctrlbus_version())
