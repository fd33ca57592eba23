# SPDX-License-Identifier: MIT
"""`ctrlbus capture`: record what one port receives, or what two tapped lines carry, in a pcap.

    ctrlbus capture --port ENDPOINT -o FILE [--direction core|base] [--duration S] [--baud N]
    ctrlbus capture --tap core=ENDPOINT --tap base=ENDPOINT -o FILE [--json] [--color ...]
                    [--duration S] [--baud N] [--timeout-ms N] [--max-frame N]

Each read becomes one record (docs/capture-format.md) with the time it was read and the direction
given: `core` when the port hears what a Core sends (core→base), `base` when it hears a base.

--tap is the passive two-line tap: two ports whose RX pins listen to the Core's TX line and the
base's TX line. Nothing is written to either. It is a spy that does not forward (cli.spy_cmd.Spy
with forward=False): the same reading threads, live annotations and end report; only the order
differs. A spy sees cause before effect because it forwards; a tap's two ports are independent, so
`Tap` holds what it reads for MERGE_WINDOW_S and hands it on in conversation order (ctrlbus.tap).
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable
from typing import Any, Protocol

from ctrlbus.annotate import Annotator, direction_label, parse_sender
from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.cli.common import (
    ENDPOINT_HELP,
    add_baud_argument,
    add_color_argument,
    add_decoder_arguments,
    add_direction_argument,
    decoder_settings,
    endpoint_address,
    open_endpoint,
    positive_number,
    stop_on_signals,
    use_color,
)
from ctrlbus.cli.decode_cmd import DEFAULT_TIMEOUT_MS
from ctrlbus.cli.spy_cmd import Chunk, Printer, Spy, open_sides, raise_failure, run_session
from ctrlbus.errors import UsageError
from ctrlbus.frame import MAX_FRAME
from ctrlbus.link import Link
from ctrlbus.tap import DEFAULT_SKEW_S, TapMerger

__all__ = [
    "DESCRIPTION",
    "READ_TIMEOUT_S",
    "ChunkSink",
    "record",
    "register",
    "run",
]

DESCRIPTION = """\
Record the bytes one port receives in a pcap capture (docs/capture-format.md), one record per
read with its time. --direction says who sent them: core (default: the port hears the Core's
requests) or base (it hears a base's answers). --port takes a pyserial URL, 'pty' or
'listen:HOST:PORT'; for 'pty' and 'listen:' the address is printed first. Runs until --duration
has passed or Ctrl-C; every record is written at once, so the file is complete whenever it stops.

Both directions without cutting the wire (a passive tap): --tap core=ENDPOINT --tap base=ENDPOINT,
two ports whose RX pins listen to the Core's TX line and to the base's TX line (GND shared). Both
are recorded in one capture, merged by time, and the conversation is shown live as `ctrlbus spy`
shows it (--json, --color, --timeout-ms, --max-frame as there). Nothing is ever written to a
tapped port. To sit in the line instead, use `ctrlbus spy --capture`.
"""

READ_TIMEOUT_S = 0.05
# How long a tap holds what it read before handing it on: at least the merge's skew
# (ctrlbus.tap), short enough to look live.
MERGE_WINDOW_S = 0.1
TAP_SIDES = ("core", "base")


class ChunkSink(Protocol):
    """Where `record` puts chunks: a CaptureWriter, or anything with its write()."""

    def write(self, direction: Direction, data: bytes, time: float) -> None: ...


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "capture",
        help="record what a port receives in a pcap capture",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--port", metavar="ENDPOINT", help="the one port to record: " + ENDPOINT_HELP)
    source.add_argument(
        "--tap",
        action="append",
        metavar="SIDE=ENDPOINT",
        help="passive tap, given twice: core=ENDPOINT (hears the Core's TX) and base=ENDPOINT "
        "(hears the base's TX)",
    )
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="the pcap file to write")
    add_direction_argument(
        parser,
        default="core",
        help_text="--port: who sent the bytes the port receives (default core: core→base)",
    )
    parser.add_argument("--duration", metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    add_baud_argument(parser)
    parser.add_argument("--json", action="store_true", help="--tap: one JSON object per line")
    add_color_argument(parser)
    add_decoder_arguments(parser, timeout_ms=DEFAULT_TIMEOUT_MS)
    parser.set_defaults(func=run)


def record(
    link: Link,
    writer: ChunkSink,
    direction: Direction,
    *,
    stop: threading.Event,
    deadline: float | None = None,
) -> tuple[int, int]:
    """Write every chunk `link` delivers until `stop` is set or the monotonic `deadline` passes;
    return (records, bytes)."""
    records = size = 0
    while not stop.is_set():
        wait = READ_TIMEOUT_S
        if deadline is not None:
            wait = min(wait, deadline - time.monotonic())
            if wait <= 0:
                break
        data = link.read(wait)
        if data:
            try:
                writer.write(direction, data, time.time())
            except OSError as exc:  # a full disk: the message names the file
                where = getattr(writer, "path", None) or "the capture"
                raise UsageError(f"cannot write {where}: {exc.strerror or exc}") from None
            records += 1
            size += len(data)
    return records, size


def run(args: argparse.Namespace) -> int:
    duration = None if args.duration is None else positive_number("--duration", args.duration)
    if args.tap is not None:
        return run_tap(args, duration)
    direction = parse_sender(args.direction)
    link = open_endpoint(args.port, args.baud)
    try:
        try:
            writer = CaptureWriter.create(args.output)
        except OSError as exc:
            raise UsageError(f"cannot write {args.output}: {exc.strerror or exc}") from None
        with writer:
            print(endpoint_address(link), flush=True)
            stop = threading.Event()
            deadline = None if duration is None else time.monotonic() + duration
            with stop_on_signals(stop):
                records, size = record(link, writer, direction, stop=stop, deadline=deadline)
    finally:
        link.close()
    print(
        f"ctrlbus capture: {size} bytes in {records} records ({direction_label(direction)}) "
        f"written to {args.output}",
        file=sys.stderr,
    )
    return 0


# --- the passive tap ---------------------------------------------------------------------------


class Tap(Spy):
    """Reads two tapped lines and writes nothing. `chunks()` hands on what was read in
    conversation order (ctrlbus.tap.TapMerger): each piece is held until `merge_window` s after it
    was read (all of them once stopped), so that bytes the other line's thread read a moment
    earlier, or the answer a request is waiting for, can still go before it."""

    def __init__(
        self,
        core: Link,
        base: Link,
        *,
        merge_window: float = MERGE_WINDOW_S,
        clock: Callable[[], float] = time.time,
        max_frame: int = MAX_FRAME,
    ) -> None:
        super().__init__(core, base, clock=clock, forward=False)
        self._merge_window = merge_window
        self._merger = TapMerger(skew=min(DEFAULT_SKEW_S, merge_window), max_frame=max_frame)

    def chunks(self, timeout: float) -> list[Chunk]:
        """The pieces whose hold time is over, in conversation order, waiting up to `timeout` s for
        one. It never returns nothing while holding pieces (the window is shorter than any
        caller's timeout), so an empty answer means the lines were quiet."""
        deadline = time.monotonic() + timeout
        merger = self._merger
        while True:
            stopped = self.stop_event.is_set()
            for chunk in super().chunks(0.0):
                merger.add(chunk.direction, chunk.data, chunk.time)
            cutoff = self._clock() - self._merge_window
            ready = merger.release(None if stopped else cutoff)
            if ready or stopped:
                return [Chunk(piece.direction, piece.data, piece.time, piece.data) for piece in ready]
            oldest = merger.oldest
            if oldest is not None:
                wait = min(oldest - cutoff, self._merge_window)
            else:
                wait = deadline - time.monotonic()
                if wait <= 0:
                    return []
            for chunk in super().chunks(max(wait, 0.001)):
                merger.add(chunk.direction, chunk.data, chunk.time)


def tap_endpoints(specs: list[str]) -> dict[str, str]:
    """{'core': ENDPOINT, 'base': ENDPOINT} from the --tap values; UsageError unless each side
    is given exactly once."""
    sides: dict[str, str] = {}
    for spec in specs:
        side, equals, endpoint = spec.partition("=")
        if not equals or side not in TAP_SIDES:
            raise UsageError(f"--tap wants core=ENDPOINT or base=ENDPOINT, got {spec!r}")
        if side in sides:
            raise UsageError(f"--tap {side}= given twice")
        sides[side] = endpoint
    missing = [side for side in TAP_SIDES if side not in sides]
    if missing:
        raise UsageError(f"--tap needs both lines: {missing[0]}=ENDPOINT is missing")
    return sides


def run_tap(args: argparse.Namespace, duration: float | None) -> int:
    endpoints = tap_endpoints(args.tap)
    timeout, max_frame = decoder_settings(args)
    annotator = Annotator(timeout=timeout, max_frame=max_frame)
    core, base = open_sides(endpoints["core"], endpoints["base"], args.baud)
    try:
        tap = Tap(core, base, max_frame=max_frame)
        printer = Printer(
            as_json=args.json,
            color=use_color(args.color),
            time_origin=time.time(),
            gone_note=f"still recording to {args.output}",
        )
        run_session(tap, annotator, printer, capture_path=args.output, duration=duration)
        raise_failure(tap)
    finally:
        core.close()
        base.close()
    return 0
