# SPDX-License-Identifier: MIT
"""`ctrlbus spy`: sit between a Core and a base, forward every byte, show the conversation.

    ctrlbus spy --core ENDPOINT --base ENDPOINT [--capture FILE] [--json] [--fault SPEC]...
                [--duration S] [--color auto|always|never] [--timeout-ms N] [--max-frame N]

ENDPOINT is a pyserial URL, `pty` or `listen:HOST:PORT` (cli.common.open_endpoint), so the spy can
open two real serial ports or offer a side to a program that opens a port itself. One thread per
direction reads and writes at once (nothing waits for decoding); the chunks then go to the main
thread, which records them (--capture) and decodes them (ctrlbus.annotate).

--fault injects faults into the forwarded bytes: a per-direction byte transform (`ByteTransform`);
the spec and the fault model are ctrlbus.faults'.
"""

from __future__ import annotations

import argparse
import json
import os
import queue
import sys
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Protocol

from ctrlbus.annotate import Annotator, direction_label, format_annotation, sender_name
from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.cli.common import (
    ENDPOINT_HELP,
    add_baud_argument,
    add_color_argument,
    add_decoder_arguments,
    decoder_settings,
    endpoint_address,
    open_endpoint,
    positive_number,
    stop_on_signals,
    use_color,
)
from ctrlbus.cli.decode_cmd import DEFAULT_TIMEOUT_MS, summary_json, summary_text
from ctrlbus.errors import CaptureError, CtrlbusError, LinkError, UsageError
from ctrlbus.faults import FaultFilter, FaultSpec, fault_models
from ctrlbus.link import Link

__all__ = [
    "DESCRIPTION",
    "HELD_POLL_S",
    "IDLE_S",
    "READ_TIMEOUT_S",
    "ByteTransform",
    "Chunk",
    "Spy",
    "fault_transforms",
    "register",
    "run",
]

DESCRIPTION = """\
Forward bytes between a Core and a base unchanged and show the decoded conversation live (the
same annotations as `ctrlbus decode`). --core and --base each take a pyserial URL (/dev/ttyUSB0,
socket://HOST:PORT), 'pty' (the spy creates a pseudo-terminal for that side to open) or
'listen:HOST:PORT' (the spy accepts a TCP connection for that side). The addresses of 'pty' and
'listen:' sides are printed first. --capture records both directions, as forwarded, in a pcap file
(docs/capture-format.md). --fault changes the forwarded bytes (a ctrlbus.faults spec; tx = what
the Core sends, rx = what the base sends): see docs/tools.md. Ctrl-C stops.
"""

READ_TIMEOUT_S = 0.05  # how long a forwarding thread waits for bytes before checking for stop
HELD_POLL_S = 0.002  # how often a transform holding bytes back (a delay fault) gets to release them
IDLE_S = 0.2  # with no chunk for this long, report rejections still open and apply timeouts


# --- faults ------------------------------------------------------------------------------------


class ByteTransform(Protocol):
    """What --fault plugs into the forwarding path of one direction: the bytes read at `now`
    (seconds) in, the bytes to forward now out. It may hold bytes back (a delay); it is then called
    with b"" every few milliseconds so that it can release them. Called from that direction's
    thread only. `ctrlbus.faults.FaultFilter` is one."""

    def __call__(self, data: bytes, now: float) -> bytes: ...


def fault_transforms(spec_text: str | None) -> dict[Direction, FaultFilter]:
    """The transforms of a --fault spec (ctrlbus.faults grammar, docs/reliability.md): its `tx`
    faults change what the Core sends (core→base), its `rx` faults what the base sends, as seen
    from the Core's side of the line. Directions without faults get none."""
    if spec_text is None:
        return {}
    spec = FaultSpec.parse(spec_text)
    to_base, to_core = fault_models(spec)
    transforms: dict[Direction, FaultFilter] = {}
    if spec.tx.active:
        transforms[Direction.CORE_TO_BASE] = FaultFilter(to_base)
    if spec.rx.active:
        transforms[Direction.BASE_TO_CORE] = FaultFilter(to_core)
    return transforms


# --- forwarding ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class Chunk:
    """What one forwarding thread read and forwarded: `data` is what it wrote (after the fault)."""

    direction: Direction
    data: bytes
    time: float
    original: bytes


class Spy:
    """Forwards bytes between `core` and `base`, one thread per direction, and queues every chunk
    for whoever records or decodes it (`chunks()`). The forwarding threads do nothing else: read,
    transform if asked, queue, write. Queueing before writing keeps cause before effect: an answer
    is never queued before the request that it answers.

    A link that fails stops both directions; `failure` then says why. With `forward=False` nothing
    is written: both links only listen (a passive tap, `ctrlbus capture --tap`).
    """

    def __init__(
        self,
        core: Link,
        base: Link,
        *,
        transforms: Mapping[Direction, ByteTransform] | None = None,
        clock: Callable[[], float] = time.time,
        forward: bool = True,
    ) -> None:
        self.core = core
        self.base = base
        self._transforms = dict(transforms or {})
        self._clock = clock
        self._forward_bytes = forward
        self._queue: queue.Queue[Chunk] = queue.Queue()
        self.stop_event = threading.Event()
        self.failure: BaseException | None = None
        self._threads = [
            threading.Thread(
                target=self._forward,
                args=(core, base, Direction.CORE_TO_BASE),
                name="spy-core-to-base",
                daemon=True,
            ),
            threading.Thread(
                target=self._forward,
                args=(base, core, Direction.BASE_TO_CORE),
                name="spy-base-to-core",
                daemon=True,
            ),
        ]
        self.forwarded = {direction: 0 for direction in Direction}

    def start(self) -> Spy:
        for thread in self._threads:
            thread.start()
        return self

    def _forward(self, source: Link, target: Link, direction: Direction) -> None:
        transform = self._transforms.get(direction)
        try:
            if transform is None:
                while not self.stop_event.is_set():
                    data = source.read(READ_TIMEOUT_S)
                    if data:
                        # Queued before it is written: the answer it causes cannot be queued first.
                        self._queue.put(Chunk(direction, data, self._clock(), data))
                        if self._forward_bytes:
                            target.write(data)
                        self.forwarded[direction] += len(data)
                return
            while not self.stop_event.is_set():
                # A transform holding bytes back (a delay) gets to release them within HELD_POLL_S.
                holding = getattr(transform, "held_bytes", 0)
                data = source.read(HELD_POLL_S if holding else READ_TIMEOUT_S)
                now = self._clock()
                out = transform(data, now)
                if data or out:
                    self._queue.put(Chunk(direction, out, now, data))
                if out and self._forward_bytes:
                    target.write(out)
                    self.forwarded[direction] += len(out)
        except Exception as exc:  # reported through `failure`, never lost in a thread
            if self.failure is None:
                self.failure = exc
            self.stop_event.set()

    def chunks(self, timeout: float) -> list[Chunk]:
        """The chunks forwarded since the last call, in the order they were read, waiting up to
        `timeout` s for the first."""
        try:
            taken = [self._queue.get(timeout=timeout)]
        except queue.Empty:
            return []
        while True:
            try:
                taken.append(self._queue.get_nowait())
            except queue.Empty:
                return taken

    def stop(self) -> None:
        """Stop forwarding and wait for both threads (the links stay open: their owner closes them)."""
        self.stop_event.set()
        for thread in self._threads:
            if thread.is_alive() and thread is not threading.current_thread():
                thread.join(timeout=2.0)


# --- the command -------------------------------------------------------------------------------


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "spy",
        help="forward bytes between a Core and a base and show the decoded conversation",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument("--core", required=True, metavar="ENDPOINT", help="the Core's side: " + ENDPOINT_HELP)
    parser.add_argument("--base", required=True, metavar="ENDPOINT", help="the base's side: " + ENDPOINT_HELP)
    add_baud_argument(parser)
    parser.add_argument(
        "--capture", metavar="FILE", help="record both directions (as forwarded) in a pcap file"
    )
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    parser.add_argument(
        "--fault",
        metavar="SPEC",
        help="change the forwarded bytes with a fault spec (docs/reliability.md: 'ber=1e-4,burst=0.01', "
        "'tx.drop=0.001', ...); tx = what the Core sends, rx = what the base sends",
    )
    parser.add_argument("--duration", metavar="S", help="stop after S seconds (default: until Ctrl-C)")
    add_color_argument(parser)
    add_decoder_arguments(parser, timeout_ms=DEFAULT_TIMEOUT_MS)
    parser.set_defaults(func=run)


class Printer:
    """Prints annotations as they come: one text line or one JSON object per line.

    When stdout's reader goes away (`| head`), printing stops and the session goes on: a tap or
    a spy writing a capture keeps recording (the file is the product), a spy keeps forwarding.
    `gone_note` is what stderr is told then, once."""

    def __init__(self, *, as_json: bool, color: bool, time_origin: float, gone_note: str = "") -> None:
        self.as_json = as_json
        self.color = color
        self.time_origin = time_origin
        self.gone_note = gone_note
        self.gone = False

    def line(self, text: str) -> None:
        if self.gone:
            return
        try:
            sys.stdout.write(text + "\n")
            sys.stdout.flush()
        except BrokenPipeError:
            self.gone = True
            # Later writes, and the flush at exit, go nowhere instead of failing again.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            os.close(devnull)
            print(f"ctrlbus: stdout was closed; {self.gone_note or 'the output stops'}", file=sys.stderr)

    def record(self, record: dict[str, Any], text: str) -> None:
        self.line(json.dumps(record) if self.as_json else text)


def open_sides(core_spec: str, base_spec: str, baud: int) -> tuple[Link, Link]:
    core = open_endpoint(core_spec, baud)
    try:
        base = open_endpoint(base_spec, baud)
    except BaseException:
        core.close()
        raise
    return core, base


def run(args: argparse.Namespace) -> int:
    timeout, max_frame = decoder_settings(args)
    duration = None if args.duration is None else positive_number("--duration", args.duration)
    transforms = fault_transforms(args.fault)
    annotator = Annotator(timeout=timeout, max_frame=max_frame)
    core, base = open_sides(args.core, args.base, args.baud)
    try:
        spy = Spy(core, base, transforms=transforms)
        printer = Printer(
            as_json=args.json,
            color=use_color(args.color),
            time_origin=time.time(),
            gone_note="still forwarding" + (f" and recording to {args.capture}" if args.capture else ""),
        )
        run_session(spy, annotator, printer, capture_path=args.capture, duration=duration)
        for direction, injected in sorted(transforms.items()):
            counters = injected.model.counters.as_dict()
            text = ", ".join(f"{name} {value}" for name, value in counters.items() if value)
            printer.record(
                {"kind": "faults", "direction": sender_name(direction), "counters": counters},
                f"# faults injected {direction_label(direction)}: {text or 'none'}",
            )
        raise_failure(spy)
    finally:
        core.close()
        base.close()
    return 0


def run_session(
    spy: Spy, annotator: Annotator, printer: Printer, *, capture_path: str | None, duration: float | None
) -> None:
    """Print the addresses of both sides, run `spy` until Ctrl-C, `duration` or a failed link,
    showing (and recording in `capture_path`) every chunk, then report the end. The links stay
    open; `raise_failure` tells whether one failed."""
    capture: CaptureWriter | None = None
    if capture_path is not None:
        try:
            capture = CaptureWriter.create(capture_path)
        except OSError as exc:
            raise UsageError(f"cannot write {capture_path}: {exc.strerror or exc}") from None
    try:
        for side, link in (("core", spy.core), ("base", spy.base)):
            address = endpoint_address(link)
            printer.record({"kind": "endpoint", "side": side, "address": address}, f"{side}: {address}")
        deadline = None if duration is None else time.monotonic() + duration
        with stop_on_signals(spy.stop_event):
            spy.start()
            try:
                watch(spy, annotator, capture, printer, deadline)
            finally:
                spy.stop()
        report_end(spy, annotator, capture, printer)
    finally:
        if capture is not None:
            capture.close()


def raise_failure(spy: Spy) -> None:
    """Raise what stopped `spy`, if a link failed (a CtrlbusError as it is, else a LinkError)."""
    failure = spy.failure
    if failure is None:
        return
    if isinstance(failure, CtrlbusError):
        raise failure
    raise LinkError(f"forwarding failed: {failure}")


def report_end(spy: Spy, annotator: Annotator, capture: CaptureWriter | None, printer: Printer) -> None:
    """After `spy` stopped: show and record what it still holds, what the end of the input
    settles, and each direction's decoder counters."""
    # What arrived between the last look and the stop is still shown and recorded.
    show_chunks(spy.chunks(0.0), annotator, capture, printer)
    for entry in annotator.finish():
        printer.record(
            entry.to_json(), format_annotation(entry, color=printer.color, time_origin=printer.time_origin)
        )
    for direction in annotator.streams:
        stats = annotator.stats(direction)
        printer.record(summary_json(direction, stats), summary_text(direction, stats))


def watch(
    spy: Spy, annotator: Annotator, capture: CaptureWriter | None, printer: Printer, deadline: float | None
) -> None:
    while not spy.stop_event.is_set():
        if deadline is not None and time.monotonic() >= deadline:
            return
        chunks = spy.chunks(IDLE_S)
        if chunks:
            show_chunks(chunks, annotator, capture, printer)
        else:
            for entry in annotator.idle(time.time()):
                printer.record(
                    entry.to_json(),
                    format_annotation(entry, color=printer.color, time_origin=printer.time_origin),
                )


def show_chunks(
    chunks: Sequence[Chunk], annotator: Annotator, capture: CaptureWriter | None, printer: Printer
) -> None:
    for chunk in chunks:
        if capture is not None and chunk.data:
            try:
                capture.write(chunk.direction, chunk.data, chunk.time)
            except OSError as exc:  # a full disk: the message names the file
                raise UsageError(
                    f"cannot write {capture.path or 'the capture'}: {exc.strerror or exc}"
                ) from None
            except CaptureError as exc:
                raise UsageError(f"cannot write the capture: {exc}") from None
        for entry in annotator.feed(chunk.data, chunk.direction, chunk.time):
            printer.record(
                entry.to_json(),
                format_annotation(entry, color=printer.color, time_origin=printer.time_origin),
            )
