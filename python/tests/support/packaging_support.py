# SPDX-License-Identifier: MIT
"""What the packaging tests share (test_c_consumers.py, test_manifests.py, test_release.py): the
checkout, the version read from its one home (the CTRLBUS_VERSION_* macros of ctrlbus.h, read here
independently of the build scripts that also read it), and running tools with clear failures.

Not a test module itself.
"""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[3]
HEADER = REPO / "c" / "include" / "ctrlbus" / "ctrlbus.h"


def header_version() -> str:
    text = HEADER.read_text()
    parts = [
        re.search(rf"^#define CTRLBUS_VERSION_{p} +(\d+)", text, re.M) for p in ("MAJOR", "MINOR", "PATCH")
    ]
    assert all(parts), f"no CTRLBUS_VERSION_* macros in {HEADER}"
    return ".".join(m.group(1) for m in parts if m)


def tool(name: str) -> str:
    """The path of a program make test installs; the test fails (never skips) without it."""
    path = shutil.which(name)
    assert path, f"{name} is not installed (scripts/setup.sh installs it)"
    return path


def run(
    *args: str | Path, cwd: Path | None = None, env: dict[str, str] | None = None, timeout: float = 300
) -> str:
    """Runs a program at low priority; its stdout and stderr, or a failure that shows them."""
    result = subprocess.run(
        ["nice", *map(str, args)], cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout
    )
    assert result.returncode == 0, f"{' '.join(map(str, args))} failed:\n{result.stdout}\n{result.stderr}"
    return result.stdout + result.stderr
