# SPDX-License-Identifier: MIT
"""Bytes to an annotated conversation: the engine behind `ctrlbus decode`, `ctrlbus spy` and
anything else that shows people what went over a Control Bus link.

One `StreamDecoder` per stream (a direction, or one stream of unknown direction) turns bytes into
frames and decoder events (docs/protocol.md §7). The annotator then

- names every frame: frame type, CMD, request (or answer) name, every field decoded, with units
  (`format_fields`: "vx 0.200 m/s");
- pairs each answer with the request waiting in the other direction (one outstanding request,
  docs/protocol.md [core-one-outstanding]), so that an OK payload can be read at all;
- accounts for every byte that is not part of a frame: each decoder event becomes a `Rejection`
  covering the bytes from its offset to the next frame or event of its stream (so garbage runs have
  counts), checksum failures carry the expected and found checksum, and bytes discarded silently
  (inside an earlier failure's span, §7 D4) get a rejection of their own.

Pairing follows the Wireshark dissector (docs/capture-format.md "Pairing rule"), by order, timing
and size together: the requests still waiting are the last few request frames seen (at most
`PAIR_DEPTH`, none older than `PAIR_WINDOW_S` when times are known); an answer goes to the newest
of them that it fits (an OK whose size that request's answer can have, a SYNC/ECHO copy of it, or
any ERROR or INVALID), and that request and every older one stop waiting, since a base answers in
order. A line on which noise took an answer away leaves an older request waiting behind a newer
one, and its late answer still finds it. An OK that fits none of them is "unpaired" (never a
format error of the base). ERROR 0x0010, 0x0020, 0x0040, 0x00C0 and the other codes below 0x0100
answer bytes on the line rather than a request: no `to`, and the requests keep waiting.

Which frames are requests: with a known direction, everything the Core sends (core→base) is a
request and everything the base sends is an answer. In one stream of unknown direction, a frame
whose CMD is a response code (OK 0x02, ERROR 0x03, INVALID 0xFF) is an answer and the others are
requests, except SYNC and ECHO, which are both: such a frame is read as the answer when it is an
exact copy of the outstanding request and as a request otherwise, and flagged as ambiguous.

The annotator never reads a clock: times are passed in (seconds, any origin), as for the decoder.
A rejection is reported once the next frame or event of its stream shows where it ends; `idle()`
and `finish()` report what is still open (and `finish` flushes a partial frame at the end of the
input as the inter-byte timeout would, so that frames behind a false start are not lost).
"""

from __future__ import annotations

import enum
import json
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any

from ctrlbus import binconf, protocol_tables
from ctrlbus.capture import Direction
from ctrlbus.compat import StrEnum
from ctrlbus.constants import LINE_FAULT_LIMIT
from ctrlbus.constants import MOTION_BIT_NAMES as _MOTION_BITS
from ctrlbus.constants import POWER_BIT_NAMES as _POWER_BITS
from ctrlbus.errors import BinaryConfigError, MessageError, UnsupportedMessageError, UsageError
from ctrlbus.frame import MAX_FRAME, DecoderEvent, DecoderStats, EventKind, Frame, StreamDecoder
from ctrlbus.messages import (
    OK_ANSWER_CLASSES,
    AnswerMessage,
    BaseSubcommand,
    Cmd,
    ConnectBaseAnswer,
    ErrorAnswer,
    ErrorCode,
    Event,
    ExternalCommand,
    GetBaseConfAdvAnswer,
    HealthGetErrorAnswer,
    HealthGetHealthAnswer,
    HealthSub,
    Message,
    Request,
    RequestMessage,
    Response,
    decode_answer,
    decode_request,
    fields,
    from_q8,
    from_q16,
    hex_text,
)

__all__ = [
    "SENDERS",
    "Annotation",
    "Annotator",
    "FrameNote",
    "Rejection",
    "Role",
    "direction_label",
    "format_annotation",
    "format_fields",
    "parse_sender",
    "sender_name",
    "si_values",
]

# The two directions by who sends: what the CLI's --direction and the JSON "direction" key say.
SENDERS: Mapping[str, Direction] = {"core": Direction.CORE_TO_BASE, "base": Direction.BASE_TO_CORE}

MIN_TEXT_RUN = 4  # printable ASCII shown beside a payload's hex from this many characters on
_ANSWER_CMDS = frozenset({Response.OK, Response.ERROR, Response.INVALID})
_COPY_CMDS = frozenset({Cmd.SYNC, Cmd.ECHO})  # the same CMD in a request and in its answer

PREVIEW_BYTES = 64  # rejected bytes kept for display (the count is always exact)
# A stream whose bytes have not been accounted for after this many bytes (one endless garbage run)
# reports what it has, so that memory stays bounded in a live spy.
_OPEN_LIMIT = MAX_FRAME + (1 << 16)
# Used for the end-of-input flush when the caller switched the inter-byte timeout off.
_FLUSH_TIMEOUT_S = 1.0
# How many requests may wait for an answer at once, and for how long: a Core has one outstanding,
# but on a noisy line an answer may come after the Core has moved on to the next request (or to a
# flushing SYNC). Seconds of capture time; a base answers within milliseconds.
PAIR_DEPTH = 4
PAIR_WINDOW_S = 1.0
# OK payload sizes each request's answer may have, from the protocol description (the same table
# as the Wireshark dissector's and the sigrok decoder's pairing): a tuple of sizes, "any", or
# "counted" (a fixed head, then as many bytes as the head's last byte says).
OK_SIZES = protocol_tables.OK_SIZES


NO_REQUEST_TEXT = "no request outstanding: an OK payload can only be read knowing its request"


def ok_size_fits(name: str | None, payload: bytes) -> bool:
    """Whether an OK answer of `payload` can answer the request `name` by its size (True for a
    request of unknown kind, or one without an OK answer layout: nothing tells)."""
    sizes = OK_SIZES.get(name or "")
    if sizes is None:
        return True
    if sizes == "any":
        return True  # a blob of any size (the codec takes even an empty one)
    if sizes == "counted":
        head = protocol_tables.OK_COUNTED_HEAD[name or ""]
        return len(payload) >= head and len(payload) == head + payload[head - 1]
    return len(payload) in sizes


def parse_sender(text: str) -> Direction:
    """'core' (bytes the Core sends: core→base) or 'base' (base→core); UsageError otherwise."""
    try:
        return SENDERS[text]
    except KeyError:
        raise UsageError(f"direction must be 'core' or 'base', got {text!r}") from None


def direction_label(direction: Direction) -> str:
    """How the text output names a direction: 'core→base' or 'base→core'."""
    return "core→base" if direction is Direction.CORE_TO_BASE else "base→core"


def sender_name(direction: Direction | None) -> str | None:
    """Inverse of parse_sender; None for a stream of unknown direction."""
    if direction is None:
        return None
    return "core" if direction is Direction.CORE_TO_BASE else "base"


class Role(StrEnum):
    REQUEST = "request"
    ANSWER = "answer"


# --- annotations -------------------------------------------------------------------------------


@dataclass(frozen=True)
class FrameNote:
    """A frame and what it means.

    `name` is the contract's message name: a request name (`GET_BASE_STATUS`, `SYNC`, ...) or an
    answer name (`OK`, `ERROR`, `INVALID`, `SYNC`, `ECHO`); None for an unknown CMD or request
    code. `to` is the request an answer answers (None if none was outstanding, or for a line-fault
    ERROR) and `request_offset` / `request_time` where that request was. `message` is the decoded
    message, None when it could not be decoded; then `error` says why ("format", "unsupported" or
    "unpaired": an OK with no request to read it by) and `error_message` how.
    """

    seq: int
    direction: Direction | None
    offset: int
    time: float | None
    frame: Frame
    role: Role
    name: str | None
    message: Message | None = None
    to: str | None = None
    request_offset: int | None = None
    request_time: float | None = None
    error: str | None = None
    error_message: str | None = None
    ambiguous: bool = False
    notes: tuple[str, ...] = ()
    guess: str | None = None  # a lone OK read as the answer to this request, guessed by its size

    @property
    def size(self) -> int:
        return self.frame.size

    @property
    def cmd_name(self) -> str:
        names: type[enum.IntEnum] = Cmd if self.role is Role.REQUEST else Response
        try:
            return names(self.frame.cmd).name
        except ValueError:
            return f"0x{self.frame.cmd:02X}"

    @property
    def request_code(self) -> int | None:
        """The control-bus request byte of a CTRL_BUS request (None otherwise)."""
        if self.role is Role.REQUEST and self.frame.cmd == Cmd.CTRL_BUS and self.frame.payload:
            return self.frame.payload[0]
        return None

    def to_json(self) -> dict[str, Any]:
        values = fields(self.message) if self.message is not None else None
        converted = si_values(values) if values is not None else None
        if converted is not None and isinstance(self.message, GetBaseConfAdvAnswer):
            tree, problem = _configuration(self.message.blob)
            converted["config"] = tree
            if problem is not None:
                converted["config_error"] = problem
        return {
            "kind": "frame",
            "direction": sender_name(self.direction),
            "offset": self.offset,
            "size": self.size,
            "time": self.time,
            "long": self.frame.long,
            "cmd": self.frame.cmd,
            "cmd_name": self.cmd_name,
            "hex": hex_text(self.frame.raw),
            "role": str(self.role),
            "ambiguous": self.ambiguous,
            "name": self.name,
            "request_code": self.request_code,
            "to": self.to,
            "request_offset": self.request_offset,
            "fields": values,
            "values": converted,
            "error": self.error,
            "error_message": self.error_message,
            "notes": list(self.notes),
            "guess": self.guess,
        }


class RejectReason(StrEnum):
    """Why bytes were not a frame: the decoder's events, plus two of our own."""

    GARBAGE = "garbage"
    CHECKSUM_ERROR = "checksum_error"
    OVERSIZE = "oversize"
    TIMEOUT = "timeout"
    EMPTY_FRAME = "empty_frame"
    SILENT = "silent"  # discarded without an event: inside an earlier failure's span (§7 D4)
    INCOMPLETE = "incomplete"  # the input ended inside a frame candidate


@dataclass(frozen=True)
class Rejection:
    """`count` bytes from `offset` that are not part of any frame, and why.

    For CHECKSUM_ERROR, the checksum the candidate's bytes give (`expected_checksum`) and the one it
    carried (`found_checksum`); for OVERSIZE, the frame size its length announced. `preview` holds
    the first bytes (at most PREVIEW_BYTES).
    """

    seq: int
    direction: Direction | None
    offset: int
    time: float | None
    reason: RejectReason
    count: int
    preview: bytes
    expected_checksum: int | None = None
    found_checksum: int | None = None
    declared_size: int | None = None

    @property
    def size(self) -> int:
        return self.count

    def describe(self) -> str:
        count = f"{self.count} byte{'s' if self.count != 1 else ''}"
        reason = self.reason
        if reason is RejectReason.GARBAGE:
            return f"garbage: {count} discarded"
        if reason is RejectReason.CHECKSUM_ERROR:
            return (
                f"checksum error: checksum 0x{self.found_checksum or 0:02X}, expected "
                f"0x{self.expected_checksum or 0:02X}; {count} discarded"
            )
        if reason is RejectReason.OVERSIZE:
            return f"oversize: a frame of {self.declared_size} bytes announced; {count} discarded"
        if reason is RejectReason.TIMEOUT:
            return f"timeout: a frame stopped arriving (inter-byte timeout); {count} discarded"
        if reason is RejectReason.EMPTY_FRAME:
            return f"empty frame (LEN = 0, no CMD): {count}"
        if reason is RejectReason.SILENT:
            return f"{count} discarded silently (inside an earlier failure's span)"
        return f"incomplete: the input ends inside a frame; {count} left over"

    def to_json(self) -> dict[str, Any]:
        return {
            "kind": "rejected",
            "direction": sender_name(self.direction),
            "offset": self.offset,
            "size": self.count,
            "time": self.time,
            "reason": str(self.reason),
            "bytes": hex_text(self.preview),
            "expected_checksum": self.expected_checksum,
            "found_checksum": self.found_checksum,
            "declared_size": self.declared_size,
        }


Annotation = FrameNote | Rejection


# --- the engine --------------------------------------------------------------------------------


@dataclass
class _Outstanding:
    name: str | None
    frame: Frame
    direction: Direction | None
    time: float | None


@dataclass
class _Stream:
    decoder: StreamDecoder
    fed: int = 0  # bytes fed so far: the stream offset of the next byte
    accounted: int = 0  # bytes before this offset are reported (as frames or rejections)
    tail: bytearray = field(default_factory=bytearray)  # bytes from `accounted` to `fed`
    open_event: DecoderEvent | None = None  # the rejection starting at `accounted`, end not known
    open_reason: RejectReason = RejectReason.GARBAGE
    open_time: float | None = None
    open_seq: int = 0
    last_time: float | None = None
    stats_at_end: DecoderStats | None = None  # counters before the end-of-input flush

    @property
    def decided(self) -> int:
        """Offset up to which the decoder has decided every byte (the rest is a partial frame)."""
        return self.fed - self.decoder.buffered


class Annotator:
    """Turns the bytes of one or two streams into `Annotation`s, in stream order.

    `feed(data, direction, time)` takes bytes of one stream: `direction` is who sent them, or None
    for a stream of unknown direction. `timeout` is the inter-byte timeout in seconds (0 = off);
    it is applied only when times are given. `max_frame` as for StreamDecoder.
    """

    def __init__(self, *, timeout: float = 0.0, max_frame: int = MAX_FRAME) -> None:
        if not timeout >= 0:
            raise UsageError(f"timeout must be 0 (off) or positive, got {timeout}")
        self._timeout = timeout
        self._max_frame = max_frame
        StreamDecoder(max_frame=max_frame)  # check max_frame now rather than at the first feed
        self._streams: dict[Direction | None, _Stream] = {}
        self._waiting: list[_Outstanding] = []  # requests that may still be answered, oldest first
        self._answers_seen = False  # "no answer yet" only means something once answers are seen
        self._seq = 0

    def stats(self, direction: Direction | None = None) -> DecoderStats:
        """The decoder counters of a stream (before the end-of-input flush, if finished)."""
        stream = self._streams.get(direction)
        if stream is None:
            return DecoderStats()
        return stream.stats_at_end or stream.decoder.stats

    @property
    def streams(self) -> tuple[Direction | None, ...]:
        """The streams seen so far: the one of unknown direction, then core→base, base→core."""
        return tuple(sorted(self._streams, key=lambda direction: -1 if direction is None else direction))

    def feed(
        self, data: bytes, direction: Direction | None = None, time: float | None = None
    ) -> list[Annotation]:
        """Take the next bytes of a stream (read at `time`); return what is now known, in order."""
        stream = self._stream(direction)
        out: list[Annotation] = []
        items = stream.decoder.feed_items(data, self._decoder_time(time))
        stream.tail += data
        stream.fed += len(data)
        if time is not None:
            stream.last_time = time
        self._take(stream, direction, items, time, out)
        if stream.decided - stream.accounted > _OPEN_LIMIT:
            self._close_open(stream, direction, out)
        return out

    def idle(self, time: float) -> list[Annotation]:
        """Nothing arrived until `time`: apply the inter-byte timeout and report the rejections
        still open (their end is where the decoder stands now)."""
        out: list[Annotation] = []
        for direction, stream in self._streams.items():
            items = stream.decoder.feed_items(b"", self._decoder_time(time))
            self._take(stream, direction, items, time, out)
            self._close_open(stream, direction, out)
        return out

    def finish(self) -> list[Annotation]:
        """End of input: flush partial frames as an inter-byte timeout would (reported as
        `incomplete`, with any frames found behind them) and report everything still open."""
        out: list[Annotation] = []
        for direction, stream in self._streams.items():
            if stream.stats_at_end is None:
                stream.stats_at_end = stream.decoder.stats
            if stream.decoder.buffered:
                last = stream.last_time if stream.last_time is not None else 0.0
                limit = stream.decoder.timeout
                items = stream.decoder.feed_items(b"", last)
                items += stream.decoder.feed_items(b"", last + 2 * limit + 1.0)
                self._take(stream, direction, items, stream.last_time, out, end_of_input=True)
            self._close_open(stream, direction, out)
        return out

    @property
    def open_seq(self) -> int | None:
        """Sequence number of the earliest rejection whose end is not known yet, or None.

        Annotations with a higher number may already have been returned (from another stream);
        a reader printing in sequence order holds them back until it is reported."""
        pending = [stream.open_seq for stream in self._streams.values() if stream.open_event is not None]
        return min(pending, default=None)

    def report_open(self) -> list[Annotation]:
        """Report every rejection still open as it stands now (bytes of it still to come are
        then reported as a new rejection): what a streaming reader does to bound what it holds."""
        out: list[Annotation] = []
        for direction, stream in self._streams.items():
            self._close_open(stream, direction, out)
        return out

    # -- streams and rejections ---------------------------------------------------------------

    def _stream(self, direction: Direction | None) -> _Stream:
        stream = self._streams.get(direction)
        if stream is None:
            timeout = self._timeout if self._timeout > 0 else _FLUSH_TIMEOUT_S
            stream = _Stream(StreamDecoder(max_frame=self._max_frame, timeout=timeout))
            self._streams[direction] = stream
        return stream

    def _decoder_time(self, time: float | None) -> float | None:
        # Without a timeout the decoder gets no times at all, so D5 never fires (until finish()).
        return time if self._timeout > 0 else None

    def _next_seq(self) -> int:
        self._seq += 1
        return self._seq

    def _take(
        self,
        stream: _Stream,
        direction: Direction | None,
        items: Iterable[Frame | DecoderEvent],
        time: float | None,
        out: list[Annotation],
        *,
        end_of_input: bool = False,
    ) -> None:
        for item in items:
            self._close_open(stream, direction, out, upto=item.offset)
            if isinstance(item, Frame):
                out.append(self._frame(item, direction, time))
                self._account(stream, item.offset + item.size)
            else:
                stream.open_event = item
                # A timeout raised by the end-of-input flush is the end of the input, not a pause.
                flushed = end_of_input and item.kind is EventKind.TIMEOUT
                stream.open_reason = RejectReason.INCOMPLETE if flushed else RejectReason(str(item.kind))
                stream.open_time = time
                stream.open_seq = self._next_seq()

    def _close_open(
        self, stream: _Stream, direction: Direction | None, out: list[Annotation], upto: int | None = None
    ) -> None:
        """Report the bytes from `accounted` up to `upto` (default: all decided bytes)."""
        end = stream.decided if upto is None else upto
        if end <= stream.accounted:
            return
        event = stream.open_event
        count = end - stream.accounted
        preview = bytes(stream.tail[: min(count, PREVIEW_BYTES)])
        if event is None:
            out.append(
                Rejection(
                    self._next_seq(),
                    direction,
                    stream.accounted,
                    stream.last_time,
                    RejectReason.SILENT,
                    count,
                    preview,
                )
            )
        else:
            out.append(
                Rejection(
                    stream.open_seq,
                    direction,
                    event.offset,
                    stream.open_time,
                    stream.open_reason,
                    count,
                    preview,
                    event.expected_checksum,
                    event.found_checksum,
                    event.declared_size,
                )
            )
            stream.open_event = None
        self._account(stream, end)

    @staticmethod
    def _account(stream: _Stream, end: int) -> None:
        del stream.tail[: end - stream.accounted]
        stream.accounted = end

    # -- frames -------------------------------------------------------------------------------

    def _frame(self, frame: Frame, direction: Direction | None, time: float | None) -> FrameNote:
        seq = self._next_seq()
        if direction is Direction.CORE_TO_BASE:
            return self._request(seq, frame, direction, time)
        if direction is Direction.BASE_TO_CORE:
            return self._answer(seq, frame, direction, time)
        # One stream, direction unknown: decide by CMD.
        if frame.cmd in _ANSWER_CMDS:
            return self._answer(seq, frame, None, time)
        if frame.cmd in _COPY_CMDS:
            pending = self._waiting[-1] if self._waiting else None
            if pending is not None and pending.frame == frame:  # Frame equality includes the type
                note = "ambiguous without a direction: a copy of the request before it, read as its answer"
                return self._answer(seq, frame, None, time, ambiguous=note)
            note = "ambiguous without a direction: SYNC/ECHO read as a request"
            return self._request(seq, frame, None, time, ambiguous=note)
        return self._request(seq, frame, None, time)

    def _expire_waiting(self, time: float | None) -> None:
        """Requests sent more than PAIR_WINDOW_S before `time` are no longer answered."""
        if time is not None:
            self._waiting = [
                item for item in self._waiting if item.time is None or time - item.time <= PAIR_WINDOW_S
            ]

    def _pair(self, frame: Frame) -> _Outstanding | None:
        """The request answer `frame` answers: the newest waiting one it fits (None: none)."""
        line_fault = (
            frame.cmd == Response.ERROR
            and len(frame.payload) == 2
            and int.from_bytes(frame.payload, "little") < LINE_FAULT_LIMIT
        )
        if line_fault:
            return self._waiting[-1] if self._waiting else None
        for request in reversed(self._waiting):
            if _fits(request, frame):
                return request
        return None

    def _request(
        self, seq: int, frame: Frame, direction: Direction | None, time: float | None, ambiguous: str = ""
    ) -> FrameNote:
        notes: list[str] = [ambiguous] if ambiguous else []
        previous = self._waiting[-1] if self._waiting else None
        if previous is not None and self._answers_seen:
            notes.append(
                f"the {previous.name or 'request'} at offset {previous.frame.offset} has no answer yet"
            )
        name = request_name(frame)
        message: RequestMessage | None = None
        error = error_message = None
        try:
            message = decode_request(frame.cmd, frame.payload)
        except MessageError as exc:
            error, error_message = _error_kind(exc), str(exc)
        self._waiting.append(_Outstanding(name, frame, direction, time))
        del self._waiting[:-PAIR_DEPTH]
        return FrameNote(
            seq,
            direction,
            frame.offset,
            time,
            frame,
            Role.REQUEST,
            name,
            message,
            error=error,
            error_message=error_message,
            ambiguous=bool(ambiguous),
            notes=tuple(notes),
        )

    def _answer(
        self, seq: int, frame: Frame, direction: Direction | None, time: float | None, ambiguous: str = ""
    ) -> FrameNote:
        notes: list[str] = [ambiguous] if ambiguous else []
        self._expire_waiting(time)
        pending = self._pair(frame)
        waiting = list(self._waiting)
        self._answers_seen = True
        line_fault = (
            frame.cmd == Response.ERROR
            and len(frame.payload) == 2
            and int.from_bytes(frame.payload, "little") < LINE_FAULT_LIMIT
        )
        to = request_offset = request_time = None
        if line_fault:
            if pending is not None:
                notes.append(f"answers bytes on the line; {pending.name or 'the request'} is still waiting")
            else:
                notes.append("answers bytes on the line, not a request")
        elif pending is not None:
            to, request_offset, request_time = pending.name, pending.frame.offset, pending.time
            del self._waiting[: self._waiting.index(pending) + 1]  # a base answers in order
            if pending is not waiting[-1]:
                newer = ", ".join(item.name or "a request" for item in waiting[waiting.index(pending) + 1 :])
                notes.append(f"a late answer: it fits {pending.name or 'the request'}, not the newer {newer}")
            if frame.cmd in _COPY_CMDS and pending.frame != frame:
                notes.append("not a copy of the request")
        name = _answer_name(frame.cmd)
        message: AnswerMessage | None = None
        error = error_message = guess = None
        try:
            if frame.cmd == Response.OK and to is None:
                error = "unpaired"
                if line_fault or not waiting:
                    error_message = (
                        "no request outstanding: an OK payload can only be read knowing its request"
                    )
                elif pending is None:
                    error_message = "fits no outstanding request: " + "; ".join(
                        f"{item.name} (offset {item.frame.offset}) is not answered by {len(frame.payload)} "
                        "OK payload bytes"
                        for item in reversed(waiting)
                    )
                    waiting_names = ", ".join(item.name or "a request of unknown kind" for item in waiting)
                    notes.append(f"unpaired: it fits none of the waiting requests ({waiting_names})")
                else:
                    error_message = "answers a request of unknown kind: the OK payload cannot be read"
                guess = guess_request(frame.payload)
                if guess is not None:
                    message = decode_answer(guess, frame.cmd, frame.payload)
                    notes.append(
                        f"a guess: read as the answer to {guess}, the only request whose OK answer "
                        f"can be these {len(frame.payload)} bytes"
                    )
            else:
                # Answers that do not depend on the request decode the same for any request name.
                message = decode_answer(to or "SYNC", frame.cmd, frame.payload)
        except MessageError as exc:
            error, error_message = _error_kind(exc), str(exc)
        if pending is None and not line_fault and error != "unpaired":
            notes.append("no request outstanding" if not waiting else "fits no outstanding request")
        return FrameNote(
            seq,
            direction,
            frame.offset,
            time,
            frame,
            Role.ANSWER,
            name,
            message,
            to=to,
            request_offset=request_offset,
            request_time=request_time,
            error=error,
            error_message=error_message,
            ambiguous=bool(ambiguous),
            notes=tuple(notes),
            guess=guess,
        )


def _fits(request: _Outstanding, frame: Frame) -> bool:
    """Whether answer `frame` can be the answer to `request` (order and timing aside)."""
    if frame.cmd in _COPY_CMDS:
        return request.frame.cmd == frame.cmd  # (a SYNC or ECHO that is no copy is flagged as such)
    if frame.cmd == Response.OK:
        return request.frame.cmd not in _COPY_CMDS and ok_size_fits(request.name, frame.payload)
    return True  # ERROR and INVALID answer any request


def guess_request(payload: bytes) -> str | None:
    """The request whose OK answer alone can be `payload` (each answer layout is tried; a
    GET_BASE_CONF_ADV blob must decode as a configuration tree), or None when none or several
    can: CONNECT_BASE for 28 or 39 bytes, GET_BASE_CONF for 264, GET_BASE_SENSOR_DATA for 64, ...;
    2 bytes (status, health, poll) and empty answers stay unread."""
    found: list[str] = []
    for name in OK_ANSWER_CLASSES:
        try:
            if name == "GET_BASE_CONF_ADV":
                binconf.decode(payload)
            else:
                decode_answer(name, Response.OK, payload)
        except (MessageError, BinaryConfigError):
            continue
        found.append(name)
        if len(found) > 1:
            return None
    return found[0] if found else None


def printable_runs(data: bytes, minimum: int = MIN_TEXT_RUN) -> list[str]:
    """The runs of at least `minimum` printable ASCII characters in `data`, in order."""
    runs: list[str] = []
    current = bytearray()
    for byte in (*data, 0):
        if 0x20 <= byte < 0x7F:
            current.append(byte)
            continue
        if len(current) >= minimum:
            runs.append(current.decode("ascii"))
        current.clear()
    return runs


def _error_kind(exc: MessageError) -> str:
    return "unsupported" if isinstance(exc, UnsupportedMessageError) else "format"


def _answer_name(cmd: int) -> str | None:
    try:
        return Response(cmd).name
    except ValueError:
        return None


def request_name(frame: Frame) -> str | None:
    """The contract name a request frame's CMD, request code and sub-command give (even when its
    payload is malformed), or None if they are unknown."""
    if frame.cmd != Cmd.CTRL_BUS:
        try:
            return Cmd(frame.cmd).name
        except ValueError:
            return None
    payload = frame.payload
    if not payload:
        return None
    if payload[0] == Request.HEALTH_MGMT:
        if len(payload) < 2:
            return None
        try:
            return f"HEALTH_{HealthSub(payload[1]).name}"
        except ValueError:
            return None
    try:
        return Request(payload[0]).name
    except ValueError:
        return None


# --- fields, units and text --------------------------------------------------------------------

# Unit suffixes of the contract's field names (after _q8 / _q16), longest first.
_UNITS: tuple[tuple[str, str], ...] = (
    ("_mm_s", "mm/s"),
    ("_radps", "rad/s"),
    ("_mps", "m/s"),
    ("_percent", "%"),
    ("_deg", "deg"),
    ("_mm", "mm"),
    ("_ms", "ms"),
)
_FIXED = (("_q16", 16), ("_q8", 8))


def _split_name(name: str) -> tuple[str, str, int]:
    """'vx_mps_q16' -> ('vx', 'm/s', 16): display name, unit, fraction bits."""
    bits = 0
    for suffix, frac in _FIXED:
        if name.endswith(suffix):
            name, bits = name[: -len(suffix)], frac
            break
    for suffix, unit in _UNITS:
        if name.endswith(suffix):
            return name[: -len(suffix)], unit, bits
    return name, "", bits


def _unfix(value: Any, bits: int) -> Any:
    if isinstance(value, list):
        return [_unfix(item, bits) for item in value]
    if bits == 16:
        return from_q16(value)
    return from_q8(value)


def si_values(values: Mapping[str, Any]) -> dict[str, Any]:
    """The contract's field form with fixed-point fields converted: {'vx_mps_q16': 13107} ->
    {'vx_mps': 0.19999...}; other fields unchanged (nested positions converted too)."""
    out: dict[str, Any] = {}
    for key, value in values.items():
        if isinstance(value, list) and value and isinstance(value[0], Mapping):
            out[key] = [si_values(item) for item in value]
            continue
        for suffix, bits in _FIXED:
            if key.endswith(suffix) and value is not None:
                out[key[: -len(suffix)]] = _unfix(value, bits)
                break
        else:
            out[key] = value
    return out


def _enum_text(names: type[enum.IntEnum], value: int, width: int = 2) -> str:
    try:
        return f"0x{value:0{width}X} {names(value).name}"
    except ValueError:
        return f"0x{value:0{width}X}"


def _bits_text(value: int, bits: Mapping[int, str], none: str) -> str:
    set_bits = [text for bit, text in bits.items() if value & bit]
    return f"0x{value:02X} ({', '.join(set_bits) if set_bits else none})"


# Bit meanings and code names from the protocol description (protocol/ctrlbus.json).
_HEALTH_BITS = protocol_tables.HEALTH_FLAGS_BITS
_HEALTH_LEVELS = protocol_tables.HEALTH_LEVELS
_HEALTH_COMPONENTS = protocol_tables.HEALTH_COMPONENTS
_ERROR_MEANINGS = {
    ErrorCode.NOT_SYNCED: "channel not synchronised",
    ErrorCode.TOO_LONG: "request too long",
    ErrorCode.CHECKSUM: "checksum mismatch",
    ErrorCode.REFERENCE_CHECKSUM: "checksum mismatch, reference form",
    ErrorCode.UNSUPPORTED: "not supported",
    ErrorCode.FORMAT: "format error",
    ErrorCode.OPERATION: "operation failed",
}
_BASE_TYPES = protocol_tables.BASE_TYPES
_MOTOR_TYPES = protocol_tables.MOTOR_TYPES


def _health_code_text(code: int) -> str:
    level = _HEALTH_LEVELS.get(code >> 24, f"level {code >> 24}")
    component = _HEALTH_COMPONENTS.get((code >> 16) & 0xFF, f"component {(code >> 16) & 0xFF}")
    return f"0x{code:08X} ({level}, {component}, type 0x{(code >> 8) & 0xFF:02X}, index {code & 0xFF})"


def _value_text(message: Message, key: str, value: Any) -> str:
    """One field's value as a person reads it."""
    if value is None:
        return "none"
    if isinstance(message, ErrorAnswer) and key == "error_code":
        meaning = _ERROR_MEANINGS.get(value, "unknown code")
        return f"0x{value:04X} ({meaning})"
    if key == "error_code":
        return _health_code_text(value)
    if isinstance(message, HealthGetHealthAnswer) and key == "flags":
        return _bits_text(value, _HEALTH_BITS, "all well")
    if isinstance(message, ConnectBaseAnswer):
        if key == "firmware_version":
            return f"0x{value:04X} ({value >> 8}.{value & 0xFF})"
        if key == "serial":
            return "".join(f"{word:08X}" for word in value)
    if isinstance(value, str) and (
        isinstance(message, HealthGetErrorAnswer) or key in ("model", "firmware_version_suffix")
    ):
        return repr(value)
    names: dict[str, type[enum.IntEnum]] = {
        "event": Event,
        "command": ExternalCommand,
        "subcommand": BaseSubcommand,
    }
    if key in names and isinstance(value, int):
        return _enum_text(names[key], value)
    if key == "power_status":
        return _bits_text(value, _POWER_BITS, "on battery")
    if key == "status":
        return _bits_text(value, _MOTION_BITS, "ok")
    if key == "bitmap":
        return f"0x{value:08X}"
    if key == "base_type":
        return f"{value} ({_BASE_TYPES.get(value, 'unknown')})"
    if key == "motor_type":
        return f"{value} ({_MOTOR_TYPES.get(value, 'unknown')})"
    if key in ("filler", "data", "blob"):
        size = len(value.replace(" ", "")) // 2
        shown = value if size <= 16 else value[: 16 * 3 - 1] + " ..."
        runs = printable_runs(bytes.fromhex(value))
        text = ("  text " + " ".join(json.dumps(run) for run in runs)) if runs else ""
        return f"{size} bytes" + (f": {shown}" if size else "") + text
    return str(value)


def _number_text(key: str, value: Any) -> str:
    name, unit, bits = _split_name(key)
    if isinstance(value, list):
        if bits:
            text = ", ".join(f"{v:.3f}" for v in _unfix(value, bits))
        else:
            text = ", ".join(str(v) for v in value)
        body = f"[{text}]"
    elif bits:
        body = f"{_unfix(value, bits):.3f}"
    else:
        body = str(value)
    return f"{name} {body}" + (f" {unit}" if unit else "")


def _position_text(position: Mapping[str, Any]) -> str:
    return "(" + ", ".join(_number_text(key, value) for key, value in position.items()) + ")"


def _configuration(blob: bytes) -> tuple[Any, str | None]:
    """The JSON tree of a binary configuration (docs/binary-config.md), or (None, why not)."""
    try:
        return binconf.decode(blob), None
    except BinaryConfigError as exc:
        return None, str(exc)


def format_fields(message: Message) -> str:
    """Every field of a message, with units: 'vx 0.200 m/s, vy 0.000 m/s, omega 0.500 rad/s'."""
    values = fields(message)
    parts: list[str] = []
    for key, value in values.items():
        if key in ("sensors", "bumpers"):
            count = values.get("sensor_num" if key == "sensors" else "bumper_num", 0)
            used = [_position_text(item) for item in value[:count]]
            unused = value[count:]
            if any(any(item.values()) for item in unused):
                used += [_position_text(item) for item in unused]
            parts.append(f"{key} [{', '.join(used)}]")
            continue
        short, unit, bits = _split_name(key)
        if value is None:
            parts.append(f"{short if bits or unit else key} none")
        elif (bits or unit) and isinstance(value, int | list):
            parts.append(_number_text(key, value))
        else:
            parts.append(f"{key} {_value_text(message, key, value)}")
    if isinstance(message, GetBaseConfAdvAnswer):
        tree, problem = _configuration(message.blob)
        parts.append(f"config {json.dumps(tree)}" if problem is None else f"not a configuration: {problem}")
    return ", ".join(parts)


class _Style:
    """ANSI colours, or nothing."""

    def __init__(self, color: bool) -> None:
        self.color = color

    def _wrap(self, code: str, text: str) -> str:
        return f"\x1b[{code}m{text}\x1b[0m" if self.color and text else text

    def dim(self, text: str) -> str:
        return self._wrap("2", text)

    def name(self, text: str) -> str:
        return self._wrap("1;36", text)

    def good(self, text: str) -> str:
        return self._wrap("1;32", text)

    def bad(self, text: str) -> str:
        return self._wrap("1;31", text)

    def note(self, text: str) -> str:
        return self._wrap("33", text)


def format_annotation(entry: Annotation, *, color: bool = False, time_origin: float | None = None) -> str:
    """One line for a person: [time] [direction] @offset, then the frame or the rejection."""
    style = _Style(color)
    head: list[str] = []
    if entry.time is not None and time_origin is not None:
        head.append(f"{entry.time - time_origin:10.6f}")
    if entry.direction is not None:
        head.append(direction_label(entry.direction))
    head.append(style.dim(f"@{entry.offset:<6d}"))
    if isinstance(entry, Rejection):
        text = style.bad("rejected") + " " + entry.describe()
        if entry.preview:
            more = " ..." if entry.count > len(entry.preview[:16]) else ""
            text += style.dim(f"  [{hex_text(entry.preview[:16])}{more}]")
        return " ".join(head) + " " + text
    frame = entry.frame
    kind = "long" if frame.long else "std "
    parts = [kind]
    if entry.role is Role.REQUEST:
        parts.append(f"{entry.cmd_name}")
        if frame.cmd == Cmd.CTRL_BUS:
            parts.append(style.name(entry.name or "?"))
        else:
            parts[-1] = style.name(entry.cmd_name)
    else:
        label = entry.name or entry.cmd_name
        painted = style.bad(label) if label in ("ERROR", "INVALID") else style.good(label)
        parts.append(painted)
        if entry.request_offset is not None:
            parts.append(f"to {style.name(entry.to or '?')}{style.dim(f' @{entry.request_offset}')}")
    text = " ".join(parts)
    if entry.message is not None:
        described = format_fields(entry.message)
        if described:
            text += ": " + described
    elif entry.error is not None:
        text += " " + style.bad(f"[{entry.error}] {entry.error_message}")
        if frame.payload:
            text += style.dim(
                f"  payload {hex_text(frame.payload[:32])}{' ...' if len(frame.payload) > 32 else ''}"
            )
            runs = printable_runs(frame.payload)
            if runs:
                text += style.dim("  text " + " ".join(json.dumps(run) for run in runs))
    for note in entry.notes:
        text += "  " + style.note(f"({note})")
    return " ".join(head) + " " + text
