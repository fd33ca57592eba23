# SPDX-License-Identifier: MIT
"""`ctrlbus replay`: play one side of a capture into a port, with the original timing.

    ctrlbus replay FILE --port ENDPOINT [--direction core|base] [--speed X] [--max-gap S]
                   [--capture OUT] [--linger S] [--baud N]

The chunks of the chosen side are written at their recorded times relative to the first of them,
divided by --speed (0: no waiting at all); no pause is longer than --max-gap (a capture's clock
can jump by years). Whatever comes back is read all along (so the other side never blocks on a
full buffer) and, with --capture, recorded together with what was played.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from collections.abc import Callable, Iterable, Sequence
from typing import Any

from ctrlbus.annotate import direction_label, parse_sender
from ctrlbus.capture import CaptureReader, CaptureRecord, CaptureWriter, Direction
from ctrlbus.cli.capture_cmd import ChunkSink, record
from ctrlbus.cli.common import (
    ENDPOINT_HELP,
    add_baud_argument,
    add_direction_argument,
    endpoint_address,
    open_endpoint,
    positive_number,
    stop_on_signals,
)
from ctrlbus.errors import UsageError
from ctrlbus.link import Link, TcpServerLink

__all__ = [
    "DEFAULT_MAX_GAP_S",
    "DESCRIPTION",
    "cap_gaps",
    "play",
    "register",
    "replay_schedule",
    "run",
]

DESCRIPTION = """\
Play one side of a capture into a port: the chunks that side sent (--direction core, the default:
the Core's requests; base: the base's answers), each at its recorded time relative to the first one,
divided by --speed (2 = twice as fast; 0 = as fast as possible); a pause longer than --max-gap
seconds (default 60: a capture's times may jump, by a clock step or a damaged file) is shortened to
it, with a warning. --port takes a pyserial URL, 'pty'
or 'listen:HOST:PORT' (playing starts once a client has connected). Bytes coming back are read and
discarded, or recorded with --capture OUT together with what was played; after the last chunk the
replay waits --linger seconds (default 0.5) for the last answers.
"""


# The longest pause a replay makes by default: a capture whose times jump from 100 s to 2**32 s
# would otherwise sleep for 136 years.
DEFAULT_MAX_GAP_S = 60.0


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "replay",
        help="play one side of a capture into a port with its original timing",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("file", metavar="FILE", help="the capture (pcap) to play")
    parser.add_argument("--port", required=True, metavar="ENDPOINT", help=ENDPOINT_HELP)
    add_direction_argument(parser, default="core", help_text="which side to play (default core: core→base)")
    parser.add_argument(
        "--speed", default="1", metavar="X", help="timing divided by X (default 1; 0: no waiting)"
    )
    parser.add_argument(
        "--max-gap",
        default=str(DEFAULT_MAX_GAP_S),
        metavar="S",
        help=f"no pause between chunks longer than S seconds (default {DEFAULT_MAX_GAP_S:g}); longer "
        "ones are shortened to S, with a warning",
    )
    parser.add_argument("--capture", metavar="OUT", help="record what was played and what came back")
    parser.add_argument(
        "--linger", default="0.5", metavar="S", help="after the last chunk, keep reading S seconds"
    )
    add_baud_argument(parser)
    parser.set_defaults(func=run)


def replay_schedule(
    records: Iterable[CaptureRecord], direction: Direction, speed: float
) -> list[tuple[float, bytes]]:
    """(seconds after the start, bytes) for each chunk `direction` sent; times relative to that
    side's first chunk, divided by `speed` (0: all at once). A record older than the one before it
    (a clock step in the capture) is played right after it."""
    schedule: list[tuple[float, bytes]] = []
    first: int | None = None
    latest = 0.0
    for item in records:
        if item.direction is not direction or not item.data:
            continue
        if first is None:
            first = item.time_ns
        at = 0.0 if speed == 0 else (item.time_ns - first) / 1e9 / speed
        latest = max(latest, at)
        schedule.append((latest, item.data))
    return schedule


def cap_gaps(
    schedule: Sequence[tuple[float, bytes]], max_gap: float
) -> tuple[list[tuple[float, bytes]], list[float]]:
    """`schedule` with every pause between chunks longer than `max_gap` seconds shortened to it;
    and the lengths of the pauses shortened."""
    capped: list[tuple[float, bytes]] = []
    shortened: list[float] = []
    previous = shift = 0.0
    for at, data in schedule:
        gap = at - previous
        previous = at
        if gap > max_gap:
            shortened.append(gap)
            shift += gap - max_gap
        capped.append((at - shift, data))
    return capped, shortened


def play(
    link: Link,
    schedule: Sequence[tuple[float, bytes]],
    *,
    stop: threading.Event,
    on_write: Callable[[bytes], None] | None = None,
) -> int:
    """Write each chunk at its time (from now), after passing it to `on_write`; return the bytes
    written. Stops early on `stop`."""
    start = time.monotonic()
    written = 0
    for at, data in schedule:
        wait = start + at - time.monotonic()
        if wait > 0 and stop.wait(wait):
            break
        if stop.is_set():
            break
        if on_write is not None:
            on_write(data)  # recorded before it is sent: its answer cannot be recorded first
        link.write(data)
        written += len(data)
    return written


def _read_records(path: str) -> list[CaptureRecord]:
    try:
        reader = CaptureReader.open(path)
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None
    with reader:
        records = list(reader)
        if reader.truncated_tail:
            print(
                f"ctrlbus replay: warning: {path}: the last record is cut short "
                f"({reader.truncated_tail} bytes); not played",
                file=sys.stderr,
            )
    return records


def _wait_for_client(link: Link, stop: threading.Event) -> None:
    """A listening endpoint drops what is written while nobody is connected: wait for someone."""
    if not isinstance(link, TcpServerLink):
        return
    while not link.connected and not stop.is_set():
        link.read(0.05)  # accepts a pending connection; nothing can have been sent yet


def run(args: argparse.Namespace) -> int:
    direction = parse_sender(args.direction)
    speed = positive_number("--speed", args.speed, allow_zero=True)
    linger = positive_number("--linger", args.linger, allow_zero=True)
    max_gap = positive_number("--max-gap", args.max_gap, allow_zero=True)
    schedule, shortened = cap_gaps(replay_schedule(_read_records(args.file), direction, speed), max_gap)
    if shortened:
        print(
            f"ctrlbus replay: warning: {args.file}: {len(shortened)} pause(s) longer than --max-gap "
            f"{max_gap:g} s (the longest {max(shortened):.6g} s) shortened to {max_gap:g} s",
            file=sys.stderr,
        )
    link = open_endpoint(args.port, args.baud)
    writer: CaptureWriter | None = None
    try:
        if args.capture is not None:
            try:
                writer = CaptureWriter.create(args.capture)
            except OSError as exc:
                raise UsageError(f"cannot write {args.capture}: {exc.strerror or exc}") from None
        print(endpoint_address(link), flush=True)
        stop = threading.Event()
        with stop_on_signals(stop):
            _wait_for_client(link, stop)
            done_reading = threading.Event()
            other = Direction.BASE_TO_CORE if direction is Direction.CORE_TO_BASE else Direction.CORE_TO_BASE
            sink: ChunkSink = writer if writer is not None else _Discard()
            reader = threading.Thread(
                target=_drain, args=(link, sink, other, done_reading, stop), name="replay-reader", daemon=True
            )
            reader.start()
            try:
                on_write: Callable[[bytes], None] | None = None
                if writer is not None:
                    chosen = writer

                    def record_played(data: bytes) -> None:
                        chosen.write(direction, data, time.time())

                    on_write = record_played
                written = play(link, schedule, stop=stop, on_write=on_write)
                if linger:
                    stop.wait(linger)
            finally:
                done_reading.set()
                reader.join(timeout=2.0)
    finally:
        if writer is not None:
            writer.close()
        link.close()
    print(
        f"ctrlbus replay: {written} bytes in {len(schedule)} chunks ({direction_label(direction)}) played",
        file=sys.stderr,
    )
    return 0


class _Discard:
    """A CaptureWriter stand-in that keeps nothing (the replay still drains the port)."""

    def write(self, direction: Direction, data: bytes, time: float) -> None:
        return None


def _drain(
    link: Link, sink: ChunkSink, direction: Direction, done: threading.Event, stop: threading.Event
) -> None:
    try:
        record(link, sink, direction, stop=done)
    except Exception:  # the port went away: nothing more to read, and playing reports its own errors
        stop.set()
