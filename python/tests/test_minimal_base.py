# SPDX-License-Identifier: MIT
"""The minimal base (c/examples/minimal_base), the front door for base authors, passes the checker.

`make c-build` builds it for the host (host_port.c: a pty as its UART); it prints the pty's path
and `ctrlbus check` runs against it there, as a base author would run it.
"""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from support.base_harness import REPO, Process

from ctrlbus.checker import CHECKS

BINARY = REPO / "build" / "c" / "examples" / "minimal_base" / "minimal_base"
# Every check but 21 (profile: skipped without --profile) passes against the minimal base.
CHECKS_PASSING = 22
# The checks that judge answer times (latency, the watchdog's timing, ...): in these real-time runs
# over a pty or an emulator they may warn when the shared host was slow, and only they may.
TIMED = frozenset(check.name for check in CHECKS if check.timed)


def assert_checker_passes(
    port: str,
    report: Path,
    describe: Callable[[], str],
    extra_args: tuple[str, ...] = (),
    warned: frozenset[str] = frozenset(),
) -> dict[str, int]:
    """Run `ctrlbus check` against `port`; every check must pass, none warn but exactly the checks
    named in `warned` (and a check of TIMED on a slow moment of the host). Returns the summary."""
    result = subprocess.run(
        [sys.executable, "-m", "ctrlbus", "check", "--port", port, "--json", str(report), *extra_args],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode == 0, f"{result.stdout}\n{result.stderr}\n{describe()}"
    run = json.loads(report.read_text())
    summary: dict[str, int] = run["summary"]
    warnings = {check["name"] for check in run["checks"] if check["status"] == "warn"}
    late = (warnings & TIMED) - warned
    assert summary["fail"] == 0 and warnings - late == warned, f"{summary}\n{result.stdout}"
    assert summary["pass"] == CHECKS_PASSING - len(warned) - len(late), f"{summary}\n{result.stdout}"
    return summary


def test_minimal_base_passes_the_checker_on_a_pty(tmp_path: Path) -> None:
    if not BINARY.exists():
        pytest.fail(f"{BINARY} is missing: build it with `make c-build`")
    base = Process([str(BINARY)], tmp_path / "minimal_base.log")
    try:
        line = base.read_line()
        assert line.startswith("pty: /dev/"), f"unexpected first line {line!r} from {base.describe()}"
        assert_checker_passes(line.removeprefix("pty: "), tmp_path / "report.json", base.describe)
    finally:
        base.stop()
