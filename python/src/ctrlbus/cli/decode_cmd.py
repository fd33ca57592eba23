# SPDX-License-Identifier: MIT
"""`ctrlbus decode`: show what a byte stream or a capture says, frame by frame.

    ctrlbus decode [FILE|-] [--json] [--direction core|base] [--color auto|always|never]
                   [--format auto|capture|hex|binary] [--timeout-ms N] [--max-frame N]

The input is recognised by its content: a capture (pcap, docs/capture-format.md), hex text, or raw
bytes. Every frame is printed with its offset (and, for a capture, its time and direction), its
type, command and request names and every field with units; answers are paired with their
requests; every byte that is not part of a frame is reported with the reason (docs/tools.md).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from ctrlbus.annotate import (
    Annotation,
    Annotator,
    direction_label,
    format_annotation,
    parse_sender,
    sender_name,
)
from ctrlbus.capture import CaptureReader, Direction, looks_like_capture
from ctrlbus.cli.common import (
    add_color_argument,
    add_decoder_arguments,
    add_direction_argument,
    decoder_settings,
    parse_hex_text,
    read_input_bytes,
    use_color,
)
from ctrlbus.errors import UsageError
from ctrlbus.frame import DecoderStats

__all__ = [
    "DEFAULT_TIMEOUT_MS",
    "DESCRIPTION",
    "Decoded",
    "decode_bytes",
    "detect_format",
    "print_entries",
    "register",
    "run",
    "summary_json",
    "summary_text",
]

DESCRIPTION = """\
Decode Control Bus bytes into an annotated conversation. FILE ('-' or nothing: stdin) is a capture
(pcap from `ctrlbus capture` / `ctrlbus spy --capture`), hex text ('10 02 F8 30 DA', '0x10,0x02',
one or many lines; '#' starts a comment) or raw bytes. Each frame: offset (time and direction for a
capture), standard/long, command, request or answer name, fields with units; answers are paired
with the request they answer. Rejected bytes are shown with the reason: garbage, checksum errors
(expected vs found), oversize, empty frames, inter-byte timeouts (captures), the end of the input
inside a frame. Without a direction, frames are read as requests unless their CMD is OK, ERROR or
INVALID; SYNC and ECHO are flagged as ambiguous. --json prints one JSON object per line (keys in
docs/tools.md).
"""

# The CLI reads host-side captures: the host default of docs/protocol.md §7.6.
DEFAULT_TIMEOUT_MS = 100
_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
_TEXT_CONTROLS = frozenset("\t\n\r\f\v")


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "decode",
        help="decode a capture, hex text or raw bytes into an annotated conversation",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    parser.add_argument(
        "file", nargs="?", default="-", metavar="FILE", help="input file, '-' for stdin (default)"
    )
    parser.add_argument("--json", action="store_true", help="one JSON object per line")
    add_direction_argument(
        parser,
        default=None,
        help_text="capture: show only what this side sent; hex or raw bytes: who sent them "
        "(core = requests, base = answers; default: decide by CMD)",
    )
    add_color_argument(parser)
    parser.add_argument(
        "--format",
        choices=("auto", "capture", "hex", "binary"),
        default="auto",
        help="how to read the input (default auto: recognise a capture, then hex text, else raw bytes)",
    )
    add_decoder_arguments(parser, timeout_ms=DEFAULT_TIMEOUT_MS)
    parser.set_defaults(func=run)


def detect_format(data: bytes) -> str:
    """'capture', 'hex' (text: must then be hex) or 'binary'."""
    head = data[:4]
    if looks_like_capture(head) or head == _PCAPNG_MAGIC:
        return "capture"
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        return "binary"
    if all(char.isprintable() or char in _TEXT_CONTROLS for char in text):
        return "hex"
    return "binary"


def _read(path: str) -> bytes:
    try:
        return read_input_bytes(path)
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None


def _hex_bytes(data: bytes, path: str) -> bytes:
    try:
        text = data.decode("utf-8")
    except UnicodeDecodeError:
        raise UsageError(f"{path} is not text, so not hex text (try --format binary)") from None
    try:
        return parse_hex_text(text)
    except UsageError as exc:
        raise UsageError(
            f"{path}: {exc} (neither a capture nor hex text; --format binary reads raw bytes)"
        ) from None


@dataclass
class Decoded:
    """What decode_bytes found: the annotations in stream order, the annotator (for its counters
    and streams), warnings, and the time of the first chunk of a capture (None otherwise)."""

    entries: list[Annotation]
    annotator: Annotator
    warnings: list[str] = field(default_factory=list)
    time_origin: float | None = None


def decode_bytes(
    data: bytes,
    *,
    name: str = "input",
    input_format: str = "auto",
    direction: Direction | None = None,
    timeout: float = DEFAULT_TIMEOUT_MS / 1000.0,
    max_frame: int = 65539,
) -> Decoded:
    """Annotate the whole input.

    For a capture, `direction` does not change the decoding (both sides are needed to pair
    answers); the caller filters. For hex or raw bytes, it says who sent them.
    """
    kind = detect_format(data) if input_format == "auto" else input_format
    warnings: list[str] = []
    entries: list[Annotation] = []
    origin: float | None = None
    if kind == "capture":
        annotator = Annotator(timeout=timeout, max_frame=max_frame)
        reader = CaptureReader(io.BytesIO(data), name=name)
        for record in reader:
            if origin is None:
                origin = record.time
            entries += annotator.feed(record.data, record.direction, record.time)
        if reader.truncated_tail:
            warnings.append(f"{name}: the last record is cut short ({reader.truncated_tail} bytes); ignored")
    else:
        stream = _hex_bytes(data, name) if kind == "hex" else data
        annotator = Annotator(timeout=0.0, max_frame=max_frame)  # no times, so no timeout
        entries += annotator.feed(stream, direction)
    entries += annotator.finish()
    entries.sort(key=lambda entry: entry.seq)
    return Decoded(entries, annotator, warnings, origin)


def summary_text(direction: Direction | None, stats: DecoderStats) -> str:
    where = f"{direction_label(direction)}: " if direction is not None else ""
    return (
        f"# {where}{stats.frames} frames, {stats.bytes_discarded} bytes discarded, "
        f"{stats.checksum_errors} checksum errors, {stats.oversize} oversize, {stats.timeouts} timeouts, "
        f"{stats.empty_frames} empty frames, {stats.resyncs} resyncs"
    )


def summary_json(direction: Direction | None, stats: DecoderStats) -> dict[str, Any]:
    return {
        "kind": "summary",
        "direction": sender_name(direction),
        "counters": {
            "frames": stats.frames,
            "bytes_discarded": stats.bytes_discarded,
            "checksum_errors": stats.checksum_errors,
            "oversize": stats.oversize,
            "timeouts": stats.timeouts,
            "empty_frames": stats.empty_frames,
            "resyncs": stats.resyncs,
        },
    }


def print_entries(
    entries: Iterable[Annotation], *, as_json: bool, color: bool, time_origin: float | None
) -> None:
    out = sys.stdout
    for entry in entries:
        if as_json:
            out.write(json.dumps(entry.to_json()) + "\n")
        else:
            out.write(format_annotation(entry, color=color, time_origin=time_origin) + "\n")


def run(args: argparse.Namespace) -> int:
    timeout, max_frame = decoder_settings(args)
    sender = parse_sender(args.direction) if args.direction is not None else None
    data = _read(args.file)
    name = "stdin" if args.file == "-" else args.file
    decoded = decode_bytes(
        data, name=name, input_format=args.format, direction=sender, timeout=timeout, max_frame=max_frame
    )
    for warning in decoded.warnings:
        print(f"ctrlbus decode: warning: {warning}", file=sys.stderr)
    entries, annotator = decoded.entries, decoded.annotator
    streams = annotator.streams
    if sender is not None:
        entries = [entry for entry in entries if entry.direction is sender]
        streams = tuple(stream for stream in streams if stream is sender)
    try:
        print_entries(
            entries,
            as_json=args.json,
            color=use_color(args.color),
            time_origin=decoded.time_origin,
        )
        for direction in streams:
            stats = annotator.stats(direction)
            line = json.dumps(summary_json(direction, stats)) if args.json else summary_text(direction, stats)
            sys.stdout.write(line + "\n")
        sys.stdout.flush()
    except BrokenPipeError:
        # The reader went away (decode ... | head): not an error of ours.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
    return 0
