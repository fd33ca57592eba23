# SPDX-License-Identifier: MIT
"""`ctrlbus check`: the conformance checker, run against a base on a port.

    ctrlbus check --port URL [--baud N] [--json FILE] [--junit FILE] [--only N,M]
                  [--timeout-ms N] [--profile any|reference|sdk2020] [--latency-count N] [-v]
    ctrlbus check --list

Prints a line per check as it finishes, then the details of failures and warnings and the totals.
Exit 0 when nothing failed (warnings allowed), 1 when a check failed, 2 for a bad command line, a
port that cannot be opened, or a base that never answers.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import Any

from ctrlbus.checker import (
    CHECKS,
    PROFILES,
    CheckOptions,
    check_base,
    parse_selection,
    render_details,
    render_header,
    render_json,
    render_junit,
    render_result_line,
    render_summary,
)
from ctrlbus.checker.framework import DEFAULT_LATENCY_COUNT, DEFAULT_TIMEOUT_S
from ctrlbus.cli.common import add_baud_argument, add_port_argument, write_output
from ctrlbus.cli.completion_cmd import offer_values
from ctrlbus.errors import UsageError
from ctrlbus.ports import open_link

__all__ = [
    "DESCRIPTION",
    "list_checks",
    "options_from_args",
    "register",
    "run",
]

DESCRIPTION = """\
Check a base against docs/protocol.md: a numbered list of checks, each naming the rules it
enforces, each ending PASS, WARN, FAIL or SKIP with evidence (the bytes sent and received, timed).
Checks 18 and 19 spin the robot in place (left wheel back, right forward, 100 mm/s) for about
a second: give it room or lift it. docs/checker.md describes every check.

exit status: 0 nothing failed (warnings allowed), 1 a check failed, 2 bad arguments, a port that
cannot be opened, or a base that never answers.
"""


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "check",
        help="conformance checker: does a base follow the protocol?",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_port_argument(parser, required=False)
    add_baud_argument(parser)
    parser.add_argument("--json", metavar="FILE", help="write the whole run as JSON ('-' for stdout)")
    parser.add_argument("--junit", metavar="FILE", help="write JUnit XML (one test case per check) for CI")
    only = parser.add_argument(
        "--only", metavar="N,M", help="run only these checks: numbers, ranges (5-7) or names (see --list)"
    )
    offer_values(only, [check.name for check in CHECKS] + [str(check.number) for check in CHECKS])
    parser.add_argument(
        "--timeout-ms",
        default=str(round(DEFAULT_TIMEOUT_S * 1000)),
        metavar="N",
        help=f"the request timeout answers are judged against (default {DEFAULT_TIMEOUT_S * 1000:.0f}, "
        "the Core's); the checker waits up to 5 times longer (at least 1 s) before giving up on an answer",
    )
    parser.add_argument(
        "--profile",
        default="any",
        choices=PROFILES,
        help="any (default): accept every variant a master must accept; reference / sdk2020: also "
        "require that base profile's answer sizes (check 21)",
    )
    parser.add_argument(
        "--latency-count",
        default=str(DEFAULT_LATENCY_COUNT),
        metavar="N",
        help=f"requests timed by the latency check (default {DEFAULT_LATENCY_COUNT})",
    )
    parser.add_argument("--list", action="store_true", help="list the checks and exit")
    parser.add_argument(
        "-v", "--verbose", action="store_true", help="show the evidence of every check, not only failures"
    )
    parser.set_defaults(func=run)


def _positive_number(option: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{option} wants a number, got {text!r}") from None
    if not value > 0 or value == float("inf"):
        raise UsageError(f"{option} wants a number > 0, got {text!r}")
    return value


def _integer(option: str, text: str) -> int:
    try:
        return int(text)
    except ValueError:
        raise UsageError(f"{option} wants an integer, got {text!r}") from None


def _check_output_path(option: str, path: str | None) -> None:
    if path is None or path == "-":
        return
    target = Path(path)
    if target.is_dir():
        raise UsageError(f"{option} {path}: is a directory")
    if not target.parent.is_dir():
        raise UsageError(f"{option} {path}: directory {target.parent} does not exist")


def list_checks() -> str:
    lines = []
    for check in CHECKS:
        rules = ", ".join(str(rule) for rule in check.rules)
        lines.append(f"{check.number:3d} {check.name:20} {check.title}")
        lines.append(f"{'':25}{rules}")
    return "\n".join(lines) + "\n"


def options_from_args(args: argparse.Namespace) -> CheckOptions:
    """The checked options; UsageError (one line) for a bad value."""
    return CheckOptions(
        timeout_s=_positive_number("--timeout-ms", args.timeout_ms) / 1000.0,
        profile=args.profile,
        latency_count=_integer("--latency-count", args.latency_count),
        only=None if args.only is None else parse_selection(args.only),
    )


def run(args: argparse.Namespace) -> int:
    if args.list:
        write_output(None, list_checks())
        return 0
    if not args.port:
        raise UsageError("--port URL is required (or --list to see the checks)")
    options = options_from_args(args)
    _check_output_path("--json", args.json)
    _check_output_path("--junit", args.junit)
    to_stdout = args.json == "-" or args.junit == "-"

    def say(text: str) -> None:
        if not to_stdout:
            print(text, flush=True)

    link = open_link(args.port, args.baud)
    try:
        say(render_header(link.name, options))
        say("")
        report = check_base(link, options, on_result=lambda result: say(render_result_line(result)))
    finally:
        link.close()
    for line in render_details(report, verbose=args.verbose):
        say(line)
    say("")
    say(render_summary(report))
    if args.json is not None:
        write_output(args.json, render_json(report))
    if args.junit is not None:
        write_output(args.junit, render_junit(report))
    return 1 if report.failed else 0
