# SPDX-License-Identifier: MIT
"""The conformance checker: does a base follow docs/protocol.md, and will it work with a Core?

    link = open_link("/dev/ttyUSB0")
    report = check_base(link, CheckOptions())
    print(render_text(report))

A numbered list of checks (`CHECKS`), each naming the rules of docs/protocol.md it enforces
(section and anchor id), each ending pass, warn, fail or skip with evidence: the exact bytes sent
and received, timed. docs/checker.md lists the checks and their criteria.

Layers: `probe` (the checker's own master over a Link), `framework` (checks, results, the run
loop), `checks_*` (the checks), `report` (text, JSON, JUnit XML).
"""

from __future__ import annotations

import time
from collections.abc import Callable

from ctrlbus.checker.checks_config import CHECKS as _CONFIG_CHECKS
from ctrlbus.checker.checks_requests import CHECKS as _REQUEST_CHECKS
from ctrlbus.checker.checks_timing import CHECKS as _TIMING_CHECKS
from ctrlbus.checker.checks_wire import CHECKS as _WIRE_CHECKS
from ctrlbus.checker.framework import (
    PROFILES,
    Check,
    CheckOptions,
    CheckResult,
    Report,
    Rule,
    Status,
    run_checks,
)
from ctrlbus.checker.probe import Prober
from ctrlbus.checker.report import (
    render_details,
    render_header,
    render_json,
    render_junit,
    render_result_line,
    render_summary,
    render_text,
)
from ctrlbus.errors import UsageError
from ctrlbus.link import Link

__all__ = [
    "CHECKS",
    "PROFILES",
    "Check",
    "CheckOptions",
    "CheckResult",
    "Report",
    "Rule",
    "Status",
    "check_base",
    "parse_selection",
    "render_details",
    "render_header",
    "render_json",
    "render_junit",
    "render_result_line",
    "render_summary",
    "render_text",
]

CHECKS: tuple[Check, ...] = tuple(
    sorted(_REQUEST_CHECKS + _WIRE_CHECKS + _TIMING_CHECKS + _CONFIG_CHECKS, key=lambda check: check.number)
)
assert [check.number for check in CHECKS] == list(range(1, len(CHECKS) + 1)), "check numbers must run 1..N"


def check_base(
    link: Link,
    options: CheckOptions,
    *,
    on_result: Callable[[CheckResult], None] | None = None,
    clock: Callable[[], float] = time.monotonic,
    sleep: Callable[[float], None] = time.sleep,
) -> Report:
    """Run the checks selected by `options` against the base on `link`.

    `clock` and `sleep` are the checker's sense of time: the host's by default; a
    `ctrlbus.vtime.VirtualLink`'s (`clock=link.clock, sleep=link.sleep`) for a base in simulated
    time. ProtocolTimeout if nothing at all answers; LinkError if the link fails before the first
    check.
    """
    prober = Prober(
        link,
        answer_limit_s=options.wait_s,
        clock=clock,
        sleep=sleep,
        interbyte_timeout_s=options.interbyte_timeout_s,
    )
    return run_checks(prober, CHECKS, options, on_result=on_result)


def parse_selection(text: str) -> frozenset[int]:
    """Check numbers from "1,3,5-7" or names ("watchdog,latency"); UsageError for anything else."""
    by_name = {check.name: check.number for check in CHECKS}
    chosen: set[int] = set()
    for token in (part.strip() for part in text.split(",")):
        if not token:
            continue
        if token in by_name:
            chosen.add(by_name[token])
            continue
        low, dash, high = token.partition("-")
        try:
            numbers = range(int(low), int(high) + 1) if dash else range(int(low), int(low) + 1)
        except ValueError:
            raise UsageError(
                f"--only: {token!r} is neither a check number, a range nor a check name"
            ) from None
        if not numbers or numbers.start < 1 or numbers.stop - 1 > len(CHECKS):
            raise UsageError(f"--only: {token!r} is outside the checks 1..{len(CHECKS)}")
        chosen.update(numbers)
    if not chosen:
        raise UsageError("--only: no check selected")
    return frozenset(chosen)
