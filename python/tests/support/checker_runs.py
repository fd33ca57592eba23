# SPDX-License-Identifier: MIT
"""What a real-time run of `ctrlbus check` must show (over a pty, TCP or an emulated UART).

The checks that judge answer times (TIMED: the garbage recovery's latency, the motor watchdog's
timing, the latency statistics) measure the host's clock, so on a busy host they may warn or even
fail without the base being wrong: a stalled process stretches what they time. Their verdicts are
tested exactly in simulated time (test_checker.py, test_checker_time.py); a real-time run is a
smoke run, and holds every other check to its verdict.
"""

from __future__ import annotations

from typing import Any

from ctrlbus.checker import CHECKS

TIMED = frozenset(check.name for check in CHECKS if check.timed)


def untimed_verdicts(checks: list[dict[str, Any]]) -> dict[str, str]:
    """name -> status of every check of a JSON report (`checks`) but the TIMED ones."""
    return {check["name"]: check["status"] for check in checks if check["name"] not in TIMED}


def expected_verdicts(
    checks: list[dict[str, Any]],
    *,
    warned: frozenset[str] = frozenset(),
    skipped: frozenset[str] = frozenset(),
) -> dict[str, str]:
    """What untimed_verdicts(checks) must be: a pass for every check, a warning for those in
    `warned`, a skip for those in `skipped`."""
    return {
        name: "warn" if name in warned else "skip" if name in skipped else "pass"
        for name in untimed_verdicts(checks)
    }
