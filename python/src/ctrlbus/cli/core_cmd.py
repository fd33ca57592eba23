# SPDX-License-Identifier: MIT
"""`ctrlbus core`: the Core emulator, driving a base over a serial port (or any pyserial URL).

    ctrlbus core --port URL [--baud N] [--json] [--rates NAME=HZ,...] [--timeout-ms N]
                 [--retries N] [--profile reference|sdk2020] [--connect-timeout S]
                 [--interval S] [--duration S]
                 [--dashboard [--http HOST[:PORT]] [--token T] [--push-hz HZ]]

Shows a live status: one screen redrawn in place on a terminal, one line per update otherwise,
or one JSON object per line with --json (fields: docs/core.md). Exit codes: 0 after Ctrl-C,
SIGTERM or --duration; 2 for a port that cannot be opened, a bad option, or a base that does not
answer CONNECT_BASE within --connect-timeout (default 5 s; 0 waits forever); 1 if the Core
itself failed. Once connected, a base that goes silent is reconnected automatically, never an exit.
"""

from __future__ import annotations

import argparse
import contextlib
import json
import os
import sys
import threading
import time
from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Any, TextIO

from ctrlbus.cli.common import (
    add_baud_argument,
    add_dashboard_arguments,
    add_port_argument,
    positive_number,
    stop_on_signals,
)
from ctrlbus.cli.core_status import SCREEN_HOME_CLEAR, json_status, render_screen, status_line
from ctrlbus.constants import Profile
from ctrlbus.core import CoreConfig, CoreRunner, CoreSession, PollRates, byte_time_for_baud
from ctrlbus.errors import ProtocolTimeout, UsageError
from ctrlbus.link import Link
from ctrlbus.ports import open_link

if TYPE_CHECKING:
    from ctrlbus.web.server import DashboardServer

__all__ = [
    "DEFAULT_CONNECT_TIMEOUT_S",
    "DEFAULT_INTERVAL_S",
    "DESCRIPTION",
    "MIN_INTERVAL_S",
    "StatusOutput",
    "config_from_args",
    "register",
    "run",
]

DEFAULT_CONNECT_TIMEOUT_S = 5.0
DEFAULT_INTERVAL_S = 0.5
MIN_INTERVAL_S = 0.01

DESCRIPTION = """\
Run the Core emulator (the bus master) against a base: connect (CONNECT_BASE until answered),
read its configuration, send SYSTEM_UP_OK, then poll it (docs/protocol.md section 11), showing a
live status. With --dashboard it also serves the browser dashboard (docs/dashboard.md).

A base that never answers ends the command after --connect-timeout seconds with exit code 2;
after the first connection a silent base is reconnected automatically. Ctrl-C stops (exit 0),
after telling a connected base SEND_EVENT CORE_DISCONNECT.
"""


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "core",
        help="run the Core emulator against a base (live status, JSON lines or a dashboard)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_port_argument(parser)
    add_baud_argument(parser)
    parser.add_argument("--json", action="store_true", help="one JSON status object per line (docs/core.md)")
    parser.add_argument(
        "--rates",
        default="",
        metavar="NAME=HZ,...",
        help="polling rates, e.g. set_v=50,status=2 (names: " + ", ".join(PollRates.names()) + "; 0 = off)",
    )
    parser.add_argument(
        "--timeout-ms",
        default="200",
        metavar="N",
        help="answer timeout after a request's last byte (default 200)",
    )
    parser.add_argument(
        "--retries",
        default="2",
        metavar="N",
        help="disconnected after 1 + N attempts in a row get nothing back (default 2)",
    )
    parser.add_argument(
        "--profile",
        choices=[profile.value for profile in Profile],
        default=Profile.REFERENCE.value,
        help="requests in standard frames (reference, default) or long frames (sdk2020)",
    )
    parser.add_argument(
        "--connect-timeout",
        default=str(DEFAULT_CONNECT_TIMEOUT_S),
        metavar="S",
        help=f"give up (exit 2) if the base has not answered within S seconds (default "
        f"{DEFAULT_CONNECT_TIMEOUT_S:g}; 0 waits forever)",
    )
    parser.add_argument(
        "--interval",
        default=str(DEFAULT_INTERVAL_S),
        metavar="S",
        help=f"seconds between status updates (default {DEFAULT_INTERVAL_S:g})",
    )
    parser.add_argument(
        "--duration", default="0", metavar="S", help="stop after S seconds (default 0: until Ctrl-C)"
    )
    parser.add_argument("--dashboard", action="store_true", help="also serve the browser dashboard")
    add_dashboard_arguments(parser)
    parser.set_defaults(func=run)


def config_from_args(args: argparse.Namespace) -> CoreConfig:
    """The checked Core settings; UsageError (one line) for a bad value."""
    retries = positive_number("--retries", args.retries, allow_zero=True)
    if retries != int(retries):
        raise UsageError(f"--retries wants a whole number, got {args.retries!r}")
    return CoreConfig(
        rates=PollRates.parse(args.rates),
        request_timeout_s=positive_number("--timeout-ms", args.timeout_ms) / 1000.0,
        retries=int(retries),
        byte_time_s=byte_time_for_baud(args.baud),
        long_frames=args.profile == Profile.SDK2020,
    )


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Run until Ctrl-C / SIGTERM / --duration (or until `stop` is set, for callers in threads)."""
    config = config_from_args(args)
    connect_timeout = positive_number("--connect-timeout", args.connect_timeout, allow_zero=True)
    interval = max(MIN_INTERVAL_S, positive_number("--interval", args.interval))
    duration = positive_number("--duration", args.duration, allow_zero=True)
    dashboard_options = None
    if args.dashboard:
        from ctrlbus.web.options import DashboardOptions

        dashboard_options = DashboardOptions.from_args(args)  # refuse an unsafe address up front

    def reopen() -> Link:
        return open_link(args.port, args.baud)

    link = reopen()  # a bad URL or a refused connection ends here, exit 2
    session = CoreSession(config, port=args.port)
    runner = CoreRunner(session, link, reopen=reopen)
    stop = stop if stop is not None else threading.Event()
    server: DashboardServer | None = None
    output = StatusOutput(sys.stdout, json_lines=args.json, lock=runner.lock)
    started = time.monotonic()
    try:
        with stop_on_signals(stop):
            runner.start()
            if dashboard_options is not None:
                from ctrlbus.web import start_dashboard
                from ctrlbus.web.source import CoreSource

                server = start_dashboard(CoreSource.for_runner(runner), dashboard_options)
                print(f"ctrlbus core: dashboard at {server.display_url}", file=sys.stderr, flush=True)
                output.note = f"dashboard {server.display_url}"
            while True:
                elapsed = time.monotonic() - started
                if not output.show(session):
                    break  # stdout was closed (a pipe reader went away): nothing left to show
                if runner.failure is not None:
                    print(f"ctrlbus core: the Core failed: {runner.failure}", file=sys.stderr, flush=True)
                    return 1
                with runner.lock:
                    connects = session.connects
                if connect_timeout and elapsed > connect_timeout and connects == 0:
                    raise ProtocolTimeout(
                        f"no answer to CONNECT_BASE from {args.port} within {connect_timeout:g} s "
                        "(is the base on this port and powered? --connect-timeout 0 waits forever)"
                    )
                if duration and elapsed >= duration:
                    break
                wait = interval if not duration else min(interval, max(0.0, duration - elapsed))
                if stop.wait(wait):
                    break
    finally:
        if server is not None:
            server.stop()
        runner.stop()
    output.show(session, final=True)
    return 0


class StatusOutput:
    """Writes the status: redrawn screen on a terminal, plain lines, or JSON lines. The text is
    made under `lock` (the lock of the runner that drives the session) and written after."""

    def __init__(
        self,
        stream: TextIO,
        *,
        json_lines: bool,
        lock: AbstractContextManager[Any] | None = None,
    ) -> None:
        self.stream = stream
        self.lock = lock if lock is not None else contextlib.nullcontext()
        self.json_lines = json_lines
        self.screen = not json_lines and _is_terminal(stream)
        self.last_seq = 0
        self.closed = False
        self.note: str | None = None  # a line the screen keeps showing (the dashboard's address)

    def show(self, session: CoreSession, *, final: bool = False) -> bool:
        """Write one update; False once the stream is gone."""
        if self.closed:
            return False
        with self.lock:
            text = self._text(session)
        try:
            self.stream.write(text)
            self.stream.flush()
        except BrokenPipeError:
            self.closed = True
            # Point stdout at /dev/null so the interpreter's final flush does not fail again.
            with contextlib.suppress(OSError):
                devnull = os.open(os.devnull, os.O_WRONLY)
                os.dup2(devnull, self.stream.fileno())
                os.close(devnull)
            return False
        return True

    def _text(self, session: CoreSession) -> str:
        if self.json_lines:
            status = json_status(session, self.last_seq)
            if status["events"]:
                self.last_seq = status["events"][-1]["seq"]
            return json.dumps(status, separators=(",", ":"), allow_nan=False) + "\n"
        if self.screen:
            return SCREEN_HOME_CLEAR + render_screen(session, self.note) + "\n"
        lines = [status_line(session) + "\n"]
        for event in session.events(self.last_seq):
            lines.append(f"{'':11}{event.direction:<4} {event.text}\n")
            self.last_seq = event.seq
        return "".join(lines)


def _is_terminal(stream: TextIO) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):
        return False
