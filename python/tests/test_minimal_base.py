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
from support.checker_runs import expected_verdicts, untimed_verdicts

from ctrlbus.checker import CHECKS

BINARY = REPO / "build" / "c" / "examples" / "minimal_base" / "minimal_base"


def assert_checker_passes(
    port: str,
    report: Path,
    describe: Callable[[], str],
    extra_args: tuple[str, ...] = (),
    warned: frozenset[str] = frozenset(),
) -> dict[str, int]:
    """Run `ctrlbus check` against `port`: every check but 21 (profile, skipped without
    --profile) must pass, but those named in `warned` warn; the timed checks are not judged in
    this real-time run (support/checker_runs.py). Returns the summary."""
    result = subprocess.run(
        [sys.executable, "-m", "ctrlbus", "check", "--port", port, "--json", str(report), *extra_args],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert result.returncode in (0, 1), f"{result.stdout}\n{result.stderr}\n{describe()}"  # 1: judged below
    run = json.loads(report.read_text())
    checks = run["checks"]
    assert len(checks) == len(CHECKS), result.stdout
    expected = expected_verdicts(checks, warned=warned, skipped=frozenset({"profile"}))
    assert untimed_verdicts(checks) == expected, f"{run['summary']}\n{result.stdout}\n{describe()}"
    summary: dict[str, int] = run["summary"]
    return summary


def test_minimal_base_passes_the_checker_on_a_pty(tmp_path: Path) -> None:
    if not BINARY.exists():
        pytest.fail(f"{BINARY} is missing: build it with `make c-build`")
    base = Process([str(BINARY)], tmp_path / "minimal_base.log")
    try:
        line = base.read_line()
        assert line.startswith("pty: /dev/"), f"unexpected first line {line!r} from {base.describe()}"
        # The minimal base writes its answers a byte at a time, as on an MCU: a busy host can
        # pause it mid-answer for longer than the checker decoder's 100 ms (232 ms seen under
        # stress-ng), so the emulators' margin.
        margin = ("--interbyte-timeout-ms", "500")
        assert_checker_passes(line.removeprefix("pty: "), tmp_path / "report.json", base.describe, margin)
    finally:
        base.stop()
