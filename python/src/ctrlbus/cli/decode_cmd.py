# SPDX-License-Identifier: MIT
"""`ctrlbus decode`: show what a byte stream or a capture says, frame by frame.

    ctrlbus decode [FILE|-] [--json] [--direction core|base] [--color auto|always|never]
                   [--format auto|capture|hex|binary] [--strict] [--timeout-ms N] [--max-frame N]

The input is recognised by its content: a capture (pcap, docs/capture-format.md), hex text, or raw
bytes. Every frame is printed with its offset (and, for a capture, its time and direction), its
type, command and request names and every field with units; answers are paired with their
requests; every byte that is not part of a frame is reported with the reason (docs/tools.md).
"""

from __future__ import annotations

import argparse
import codecs
import heapq
import io
import json
import os
import re
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import Any, BinaryIO

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
    _NOT_SEPARATOR,
    BOM,
    add_color_argument,
    add_decoder_arguments,
    add_direction_argument,
    decoder_settings,
    hex_token_bytes,
    hex_token_problem,
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
# Memory bound (docs/tools.md): the input is read in pieces of this size, and at most this many
# annotations (standing for at most this many input bytes) wait for a rejection of the other
# direction to end before it is reported as it stands (so one side's garbage followed by silence
# cannot make the other side's output pile up).
_READ_SIZE = 1 << 16
_WAITING_LIMIT = 1024
_WAITING_BYTES_LIMIT = 1 << 18
_TRAILING_TOKEN = re.compile(_NOT_SEPARATOR.pattern + r"\Z")
_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"


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
    parser.add_argument(
        "--strict",
        action="store_true",
        help="exit 2 when the input is damaged (a capture cut inside its last record, as a full "
        "disk leaves it); without it that is a warning and the exit code is 0",
    )
    add_decoder_arguments(parser, timeout_ms=DEFAULT_TIMEOUT_MS)
    parser.set_defaults(func=run)


def detect_format(data: bytes, *, complete: bool = True) -> str:
    """'capture', 'hex' (text: must then be hex) or 'binary'. With `complete=False`, `data` is
    only the head of the input: a character cut at its end does not make it binary."""
    head = data[:4]
    if looks_like_capture(head) or head == _PCAPNG_MAGIC:
        return "capture"
    try:
        text = codecs.getincrementaldecoder("utf-8")().decode(data, final=complete)
    except UnicodeDecodeError:
        return "binary"
    # A byte order mark opening the text and Unicode spaces (a no-break space pasted from a web
    # page) are text too, as --format hex reads them.
    if all(char.isprintable() or char.isspace() for char in text.removeprefix(BOM)):
        return "hex"
    return "binary"


class _HexText:
    """Hex text read piece by piece (the rules of parse_hex_text: tokens between whitespace, commas
    and colons, '#' comments to the end of the line, each token one or an even number of digits,
    a byte order mark at the start ignored). Holds at most one piece and one token whatever the
    input's size."""

    def __init__(self, name: str) -> None:
        self._name = name
        self._text = codecs.getincrementaldecoder("utf-8")()
        self._rest = ""  # text not parsed yet: an unfinished token or line
        self._in_comment = False  # the rest of the current line is a comment
        self._line = 1
        self._column = 1  # column of _rest's first character
        self._started = False  # the first character was seen (a byte order mark may open the text)

    def feed(self, data: bytes, *, final: bool = False) -> bytes:
        try:
            text = self._rest + self._text.decode(data, final=final)
        except UnicodeDecodeError:
            raise UsageError(f"{self._name} is not text, so not hex text (try --format binary)") from None
        if not self._started and text:
            self._started = True
            text = text.removeprefix(BOM)
        out = bytearray()
        position = 0
        while position < len(text):
            newline = text.find("\n", position)
            if self._in_comment:
                if newline < 0:
                    position = len(text)
                    break
                self._in_comment = False
                self._newline()
                position = newline + 1
                continue
            stop = len(text) if newline < 0 else newline
            hash_mark = text.find("#", position, stop)
            end = stop if hash_mark < 0 else hash_mark
            part = text[position:end]
            if end == len(text) and not final:
                # The piece may end inside a token: keep it for the next piece.
                trailing = _TRAILING_TOKEN.search(part)
                cut = trailing.start() if trailing is not None else len(part)
                self._parse(part[:cut], out)
                self._column += cut
                self._rest = part[cut:]
                return bytes(out)
            self._parse(part, out)
            if hash_mark >= 0:
                self._in_comment = True
                position = hash_mark
                continue
            if newline >= 0:
                self._newline()
            position = stop + 1
        self._rest = ""
        return bytes(out)

    def _newline(self) -> None:
        self._line += 1
        self._column = 1

    def _parse(self, part: str, out: bytearray) -> None:
        for token in _NOT_SEPARATOR.finditer(part):
            spelled = hex_token_bytes(token.group())
            if spelled is None:
                where = f"line {self._line} column {self._column + token.start()}"
                raise UsageError(
                    f"{self._name}: {hex_token_problem(token.group())} at {where} "
                    "(neither a capture nor hex text; --format binary reads raw bytes)"
                )
            out += spelled


class DecodeStream:
    """Decodes an input while reading it, in bounded memory (docs/tools.md).

    Iterating yields the annotations in stream order (sequence numbers), as soon as they are
    known. For a capture, `direction` does not change the decoding (both sides are needed to pair
    answers); the caller filters. For hex or raw bytes, it says who sent them. `warnings` and
    `time_origin` (the time of a capture's first record) are complete once iteration ends.
    """

    def __init__(
        self,
        source: BinaryIO,
        *,
        name: str = "input",
        input_format: str = "auto",
        direction: Direction | None = None,
        timeout: float = DEFAULT_TIMEOUT_MS / 1000.0,
        max_frame: int = 65539,
        before_read: Callable[[], None] | None = None,
    ) -> None:
        # read1: what is there now (a live pipe), not a wait for a whole piece.
        self._read_some: Callable[[int], bytes] = getattr(source, "read1", source.read)
        self._before_read = before_read
        self._name = name
        self._direction = direction
        self._head = self._read()
        while self._head and len(self._head) < 4:  # enough for the magic of a capture
            more = self._read()
            if not more:
                break
            self._head += more
        self.kind = detect_format(self._head, complete=False) if input_format == "auto" else input_format
        # A capture has times, so the inter-byte timeout applies; hex and raw bytes have none.
        self.annotator = Annotator(timeout=timeout if self.kind == "capture" else 0.0, max_frame=max_frame)
        self.warnings: list[str] = []
        self.time_origin: float | None = None
        self._waiting: list[tuple[int, Annotation]] = []  # a heap by sequence number
        self._waiting_bytes = 0  # the input bytes those annotations stand for

    def _read(self) -> bytes:
        if self._before_read is not None:
            self._before_read()
        try:
            return self._read_some(_READ_SIZE)
        except OSError as exc:
            raise UsageError(f"cannot read {self._name}: {exc.strerror or exc}") from None

    def _pieces(self) -> Iterator[bytes]:
        """The input in pieces of at most _READ_SIZE bytes, the head first."""
        piece, self._head = self._head, b""
        while piece:
            yield piece
            piece = self._read()

    def __iter__(self) -> Iterator[Annotation]:
        annotator = self.annotator
        if self.kind == "capture":
            reader = CaptureReader(io.BufferedReader(_Chained(self._pieces())), name=self._name)
            for record in reader:
                if self.time_origin is None:
                    self.time_origin = record.time
                yield from self._in_order(annotator.feed(record.data, record.direction, record.time))
            if reader.truncated_tail:
                self.warnings.append(
                    f"{self._name}: the last record is cut short ({reader.truncated_tail} bytes); ignored"
                )
        else:
            hex_text = _HexText(self._name) if self.kind == "hex" else None
            for piece in self._pieces():
                data = piece if hex_text is None else hex_text.feed(piece)
                yield from self._in_order(annotator.feed(data, self._direction))
            if hex_text is not None:
                yield from self._in_order(annotator.feed(hex_text.feed(b"", final=True), self._direction))
        yield from self._in_order(annotator.finish(), final=True)

    def _in_order(self, produced: list[Annotation], *, final: bool = False) -> Iterator[Annotation]:
        """Annotations whose turn has come: those before the earliest rejection still open (one
        stream's rejection stays open while the other stream goes on)."""
        for entry in produced:
            heapq.heappush(self._waiting, (entry.seq, entry))
            self._waiting_bytes += entry.size
        if len(self._waiting) > _WAITING_LIMIT or self._waiting_bytes > _WAITING_BYTES_LIMIT:
            for entry in self.annotator.report_open():
                heapq.heappush(self._waiting, (entry.seq, entry))
        limit = None if final else self.annotator.open_seq
        while self._waiting and (limit is None or self._waiting[0][0] < limit):
            entry = heapq.heappop(self._waiting)[1]
            self._waiting_bytes -= entry.size
            yield entry


class _Chained(io.RawIOBase):
    """A read-only binary stream over an iterator of pieces (for CaptureReader)."""

    def __init__(self, pieces: Iterator[bytes]) -> None:
        self._pieces = pieces
        self._piece = b""

    def readable(self) -> bool:
        return True

    def readinto(self, buffer: Any) -> int:
        if not self._piece:
            self._piece = next(self._pieces, b"")
        size = min(len(buffer), len(self._piece))
        buffer[:size] = self._piece[:size]
        self._piece = self._piece[size:]
        return size


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
    """Annotate a whole input held in memory (DecodeStream reads one as it comes)."""
    stream = DecodeStream(
        io.BytesIO(data),
        name=name,
        input_format=input_format,
        direction=direction,
        timeout=timeout,
        max_frame=max_frame,
    )
    entries = list(stream)
    return Decoded(entries, stream.annotator, stream.warnings, stream.time_origin)


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


def _open_input(path: str) -> BinaryIO:
    if path == "-":
        return sys.stdin.buffer
    try:
        return open(path, "rb")  # closed by run()
    except OSError as exc:
        raise UsageError(f"cannot read {path}: {exc.strerror or exc}") from None


def run(args: argparse.Namespace) -> int:
    timeout, max_frame = decoder_settings(args)
    sender = parse_sender(args.direction) if args.direction is not None else None
    name = "stdin" if args.file == "-" else args.file
    source = _open_input(args.file)
    try:
        decoded = DecodeStream(
            source,
            name=name,
            input_format=args.format,
            direction=sender,
            timeout=timeout,
            max_frame=max_frame,
            before_read=sys.stdout.flush,  # what is known is shown before waiting for more input
        )
        _print_decoded(decoded, sender, as_json=args.json, color=use_color(args.color))
    finally:
        if source is not sys.stdin.buffer:
            source.close()
    for warning in decoded.warnings:
        print(f"ctrlbus decode: {'error' if args.strict else 'warning'}: {warning}", file=sys.stderr)
    return 2 if args.strict and decoded.warnings else 0


def _print_decoded(decoded: DecodeStream, sender: Direction | None, *, as_json: bool, color: bool) -> None:
    """Print each annotation as it comes (flushed, so a live pipe shows it), then the summaries."""
    out = sys.stdout
    try:
        for entry in decoded:
            if sender is not None and entry.direction is not sender:
                continue
            if as_json:
                out.write(json.dumps(entry.to_json()) + "\n")
            else:
                out.write(format_annotation(entry, color=color, time_origin=decoded.time_origin) + "\n")
        annotator = decoded.annotator
        streams = annotator.streams
        if sender is not None:
            streams = tuple(stream for stream in streams if stream is sender)
        for direction in streams:
            stats = annotator.stats(direction)
            line = json.dumps(summary_json(direction, stats)) if as_json else summary_text(direction, stats)
            out.write(line + "\n")
        out.flush()
    except BrokenPipeError:
        # The reader went away (decode ... | head): not an error of ours.
        os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
