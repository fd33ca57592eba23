# SPDX-License-Identifier: MIT
"""`ctrlbus capture`: record what one port receives in a pcap capture.

    ctrlbus capture --port ENDPOINT -o FILE [--direction core|base] [--duration S] [--baud N]

Each read becomes one record (docs/capture-format.md) with the time it was read and the direction
given: `core` when the port hears what a Core sends (core→base), `base` when it hears a base.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from typing import Any, Protocol

from ctrlbus.annotate import direction_label, parse_sender
from ctrlbus.capture import CaptureWriter, Direction
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
from ctrlbus.link import Link

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
To record both directions, use `ctrlbus spy --capture`.
"""

READ_TIMEOUT_S = 0.05


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
    parser.add_argument("--port", required=True, metavar="ENDPOINT", help=ENDPOINT_HELP)
    parser.add_argument("-o", "--output", required=True, metavar="FILE", help="the pcap file to write")
    add_direction_argument(
        parser, default="core", help_text="who sent the bytes the port receives (default core: core→base)"
    )
    parser.add_argument("--duration", metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    add_baud_argument(parser)
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
            writer.write(direction, data, time.time())
            records += 1
            size += len(data)
    return records, size


def run(args: argparse.Namespace) -> int:
    direction = parse_sender(args.direction)
    duration = None if args.duration is None else positive_number("--duration", args.duration)
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
