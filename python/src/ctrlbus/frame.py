# SPDX-License-Identifier: MIT
"""Frame layer: encode frames and decode a byte stream into frames.

A frame is ``FLAG LEN CMD PAYLOAD CHECKSUM`` (standard, FLAG 0x10, one length byte) or
``FLAG LEN_LO LEN_HI CMD PAYLOAD CHECKSUM`` (long, FLAG 0x50). LEN counts CMD plus payload; the
checksum is the XOR of every byte from FLAG through the last payload byte.

`StreamDecoder` implements the normative decoder of docs/protocol.md §7 (rules D1-D6, the same
as "The stream decoder, precisely" in vectors/README.md): hunting, candidates, backtracking with
silent spans, one garbage event per gap, the inter-byte timeout and the empty LEN = 0 frame. The
module never reads a clock: time is passed in by the caller.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

from ctrlbus.compat import StrEnum
from ctrlbus.errors import FrameError, UsageError

__all__ = [
    "FLAG_LONG",
    "FLAG_STANDARD",
    "MAX_FRAME",
    "MAX_LONG_PAYLOAD",
    "MAX_STANDARD_PAYLOAD",
    "DecoderEvent",
    "DecoderStats",
    "EventKind",
    "Frame",
    "StreamDecoder",
    "checksum",
    "encode",
]

FLAG_STANDARD = 0x10
FLAG_LONG = 0x50
MAX_STANDARD_PAYLOAD = 254  # LEN is one byte and counts the CMD byte too
MAX_LONG_PAYLOAD = 65534  # LEN is 16 bits and counts the CMD byte too
MAX_FRAME = 3 + 65535 + 1  # largest long frame: header, LEN bytes, checksum
MIN_MAX_FRAME = 5  # a decoder must at least hold the smallest long frame with a CMD byte


# --- checksum ----------------------------------------------------------------------------------

# _XOR_WITH[c] maps every byte value v to v ^ c, so that bytes.translate XORs a constant into a
# whole byte string at C speed.
_XOR_WITH: tuple[bytes, ...] = tuple(bytes(v ^ c for v in range(256)) for c in range(256))

# Prefix XORs are computed in blocks: large enough that the per-block Python overhead vanishes,
# small enough that the big-integer shifts stay in cache (measured optimum 4-16 KiB).
_PREFIX_BLOCK = 8192
_PREFIX_BLOCK_MASK = (1 << (8 * _PREFIX_BLOCK)) - 1


def _prefix_xor(data: bytes, start: int = 0) -> bytes:
    """Return out with out[k] = start ^ data[0] ^ ... ^ data[k] (same length as data).

    No per-byte Python loop: inside a block, the bytes are read as one little-endian integer x,
    and ``x ^= x << 8; x ^= x << 16; ...`` (log2(block) steps) leaves in byte k the XOR of bytes
    0..k. Blocks are chained by XOR-ing the previous block's last value into the next one with
    bytes.translate.
    """
    parts: list[bytes] = []
    carry = start
    size = len(data)
    for begin in range(0, size, _PREFIX_BLOCK):
        block = data[begin : begin + _PREFIX_BLOCK]
        count = len(block)
        value = int.from_bytes(block, "little")
        shift = 8
        bits = 8 * count
        while shift < bits:
            value ^= value << shift
            shift <<= 1
        mask = _PREFIX_BLOCK_MASK if count == _PREFIX_BLOCK else (1 << bits) - 1
        prefix = (value & mask).to_bytes(count, "little")
        if carry:
            prefix = prefix.translate(_XOR_WITH[carry])
        carry = prefix[-1]
        parts.append(prefix)
    return b"".join(parts)


def checksum(data: bytes | bytearray | memoryview) -> int:
    """The frame checksum of `data`: the XOR of all its bytes (0 for no bytes)."""
    value = int.from_bytes(data, "little")
    # Fold the integer onto itself: after `value ^= value >> width` the low `width` bits hold the
    # XOR of the two halves, as long as the value had at most 2 * width bits.
    width = 8
    while width * 2 < value.bit_length():
        width *= 2
    while width >= 8:
        value ^= value >> width
        width >>= 1
    return value & 0xFF


# --- encoding ----------------------------------------------------------------------------------


def encode(cmd: int, payload: bytes, *, long: bool | None = None) -> bytes:
    """Encode one frame.

    Standard (0x10) when the payload fits in one (at most 254 bytes) and `long` is not True;
    long (0x50) when it does not fit or `long` is True. `long=False` with a payload over 254
    bytes, a payload over 65534 bytes or a CMD outside 0..255 raises FrameError.
    """
    if not 0 <= cmd <= 0xFF:
        raise FrameError(f"CMD must be 0..255, got {cmd}")
    size = len(payload)
    if long is None:
        long = size > MAX_STANDARD_PAYLOAD
    if long:
        if size > MAX_LONG_PAYLOAD:
            raise FrameError(
                f"payload of {size} bytes does not fit a long frame (at most {MAX_LONG_PAYLOAD})"
            )
        length = size + 1
        body = bytes((FLAG_LONG, length & 0xFF, length >> 8, cmd)) + payload
    else:
        if size > MAX_STANDARD_PAYLOAD:
            raise FrameError(
                f"payload of {size} bytes does not fit a standard frame (at most {MAX_STANDARD_PAYLOAD})"
            )
        body = bytes((FLAG_STANDARD, size + 1, cmd)) + payload
    return body + bytes((checksum(body),))


# --- decoded values ----------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Frame:
    """One valid frame. Equality and hashing look at (cmd, payload, long) only.

    `offset` is the stream offset of the flag byte (0 for a frame not taken from a stream).
    `raw` is the whole frame as it was on the wire; a valid frame is fully determined by
    (cmd, payload, long), so it is rebuilt on demand rather than stored.
    """

    cmd: int
    payload: bytes
    long: bool = False
    offset: int = field(default=0, compare=False)

    def __post_init__(self) -> None:
        if not isinstance(self.payload, bytes):
            raise FrameError(f"payload must be bytes, got {type(self.payload).__name__}")
        limit = MAX_LONG_PAYLOAD if self.long else MAX_STANDARD_PAYLOAD
        if not 0 <= self.cmd <= 0xFF or len(self.payload) > limit:
            raise FrameError(
                f"not a valid {'long' if self.long else 'standard'} frame: CMD {self.cmd}, "
                f"{len(self.payload)} payload bytes"
            )

    @property
    def raw(self) -> bytes:
        """The frame's bytes, flag through checksum."""
        return encode(self.cmd, self.payload, long=self.long)

    @property
    def size(self) -> int:
        """Length of the frame on the wire."""
        return len(self.payload) + (5 if self.long else 4)


class _FrameBuilder:
    """Same slot layout as Frame, without the frozen guard.

    Building a frozen dataclass goes through object.__setattr__ once per field, which made frame
    construction the decoder's largest cost. The decoder fills one of these with plain slot
    stores and then switches its class to Frame (allowed because the slot layouts are identical),
    which yields a genuine, immutable Frame at well under half the price.
    """

    __slots__ = ("cmd", "long", "offset", "payload")

    cmd: int
    payload: bytes
    long: bool
    offset: int


# __class__ assignment needs the same slot names (CPython lays slots out in sorted order).
assert sorted(Frame.__slots__) == sorted(_FrameBuilder.__slots__), (
    "Frame fields changed: update _FrameBuilder"
)


class EventKind(StrEnum):
    """What the decoder rejected (names shared with the C library and the vectors)."""

    GARBAGE = "garbage"
    CHECKSUM_ERROR = "checksum_error"
    OVERSIZE = "oversize"
    TIMEOUT = "timeout"
    EMPTY_FRAME = "empty_frame"


@dataclass(frozen=True, slots=True)
class DecoderEvent:
    """A rejection the layer above may answer (a base answers garbage, checksum_error, oversize
    and empty_frame with ERROR frames).

    `offset` is the stream offset of the first reported garbage byte, or of the flag byte of the
    failed candidate / empty frame. For checksum_error, `expected_checksum` is the XOR of the
    candidate's bytes and `found_checksum` its last byte; for oversize, `declared_size` is the
    whole frame size its length field announced.
    """

    kind: EventKind
    offset: int
    expected_checksum: int | None = None
    found_checksum: int | None = None
    declared_size: int | None = None

    def __str__(self) -> str:
        text = f"{self.kind} at offset {self.offset}"
        if self.kind is EventKind.CHECKSUM_ERROR:
            text += f": checksum 0x{self.found_checksum:02X}, expected 0x{self.expected_checksum:02X}"
        elif self.kind is EventKind.OVERSIZE:
            text += f": frame of {self.declared_size} bytes announced"
        return text


@dataclass(frozen=True, slots=True)
class DecoderStats:
    """The decoder's counters (names shared with the C library and the vectors)."""

    frames: int = 0
    bytes_discarded: int = 0
    checksum_errors: int = 0
    oversize: int = 0
    timeouts: int = 0
    empty_frames: int = 0
    resyncs: int = 0


# --- decoding ----------------------------------------------------------------------------------


class StreamDecoder:
    """Incremental frame decoder: docs/protocol.md §7, rules D1-D6.

    Feed it bytes in chunks of any size; it returns the frames completed by each chunk, counts
    what it rejects (`stats`) and reports rejections as `DecoderEvent`s: to `on_event`, and in
    stream order among the frames from `feed_items`. Events are never queued.

    Time: `now` is the caller's time, in the same unit as `timeout` (seconds by convention). When
    `now` is None the timeout is not evaluated, and bytes fed without a time leave the time of the
    last byte unknown; the timeout then counts from the next call that gives a time.
    ``feed(b"", now)`` applies the timeout without new bytes. ``timeout=0`` switches it off.

    Cost (D6): the happy path does a constant amount of Python work per frame; checksums come
    from a prefix-XOR table built once per fed byte without a per-byte Python loop (see
    _prefix_xor), garbage is skipped with bytes.find, and an incomplete candidate is only appended
    to until its last byte arrives. Backtracking never revisits a byte as a candidate start, so
    there are at most n candidates for n input bytes and each costs O(1) Python work with the
    table. What can repeat is copying at C speed: a candidate left incomplete after a rescan keeps
    up to `max_frame` buffered bytes, copied again whenever a later candidate completes. Worst
    case for n input bytes: O(n) Python steps plus O(n * max_frame / 3) copied bytes, reached by
    back-to-back bogus long headers (``50 FF FF ...``) fed one byte per call; with 4 KiB feeds or
    a base's max_frame of 512 the copies stay small. Memory: one buffer of at most `max_frame`
    bytes between calls, plus the bytes of the current call.
    """

    __slots__ = (
        "_bytes_discarded",
        "_checksum_errors",
        "_collect",
        "_empty_frames",
        "_frames",
        "_last_time",
        "_max_frame",
        "_need",
        "_offset",
        "_on_event",
        "_oversize",
        "_pending",
        "_pending_prefix",
        "_quiet",
        "_resyncs",
        "_silent_end",
        "_timeout",
        "_timeouts",
    )

    def __init__(
        self,
        *,
        max_frame: int = MAX_FRAME,
        timeout: float = 0.010,
        on_event: Callable[[DecoderEvent], None] | None = None,
    ) -> None:
        if not MIN_MAX_FRAME <= max_frame <= MAX_FRAME:
            raise UsageError(f"max_frame must be {MIN_MAX_FRAME}..{MAX_FRAME} bytes, got {max_frame}")
        if not timeout >= 0:  # also rejects NaN
            raise UsageError(f"timeout must be 0 (off) or positive, got {timeout}")
        self._max_frame = max_frame
        self._timeout = timeout
        self._on_event = on_event
        self._collect: list[Frame | DecoderEvent] | None = None
        self.reset()

    def reset(self) -> None:
        """Forget buffered bytes, time, event state and counters: as good as new."""
        # Bytes of the candidate in progress (empty while hunting); _offset is the stream offset
        # of its first byte, or of the next byte when it is empty.
        self._pending = bytearray()
        # Prefix XOR of the first len(...) - 1 pending bytes, with a leading 0; None if unknown.
        self._pending_prefix: bytes | None = None
        # Pending must hold this many bytes before anything can be decided.
        self._need = 1
        self._offset = 0
        # Bytes before this stream offset lie in the span of a failed candidate: silent.
        self._silent_end = 0
        # An event was raised since the last yielded frame (garbage is then not reported).
        self._quiet = False
        self._last_time: float | None = None
        self._frames = 0
        self._bytes_discarded = 0
        self._checksum_errors = 0
        self._oversize = 0
        self._timeouts = 0
        self._empty_frames = 0
        self._resyncs = 0

    @property
    def max_frame(self) -> int:
        return self._max_frame

    @property
    def timeout(self) -> float:
        return self._timeout

    @property
    def buffered(self) -> int:
        """Bytes of the candidate in progress (0 while hunting)."""
        return len(self._pending)

    @property
    def timeout_due(self) -> float | None:
        """The time after which the inter-byte timeout drops the candidate in progress, so a
        caller with nothing else to do knows when to call feed(b"", now); None if there is no
        candidate, no timeout, or no time known yet."""
        if not self._pending or not self._timeout or self._last_time is None:
            return None
        return self._last_time + self._timeout

    @property
    def stats(self) -> DecoderStats:
        """A snapshot of the counters."""
        return DecoderStats(
            frames=self._frames,
            bytes_discarded=self._bytes_discarded,
            checksum_errors=self._checksum_errors,
            oversize=self._oversize,
            timeouts=self._timeouts,
            empty_frames=self._empty_frames,
            resyncs=self._resyncs,
        )

    def feed(self, data: bytes | bytearray | memoryview, now: float | None = None) -> list[Frame]:
        """Take the next bytes of the stream; return the frames they complete, in order.

        Events are counted and passed to `on_event`, not returned.
        """
        frames: list[Frame] = []
        self._run(data, now, frames)  # type: ignore[arg-type]  # only frames go in: _collect is None
        return frames

    def feed_items(
        self, data: bytes | bytearray | memoryview, now: float | None = None
    ) -> list[Frame | DecoderEvent]:
        """Like `feed`, but return frames and events together in stream order."""
        items: list[Frame | DecoderEvent] = []
        self._collect = items
        try:
            self._run(data, now, items)
        finally:
            self._collect = None
        return items

    # The rest is the machinery behind feed().

    def _run(
        self, data: bytes | bytearray | memoryview, now: float | None, out: list[Frame | DecoderEvent]
    ) -> None:
        if now is not None and self._pending and self._timeout:
            if self._last_time is None:
                self._last_time = now
            elif now - self._last_time > self._timeout:
                self._expire(out)
        if not data:
            return
        self._last_time = now
        pending = self._pending
        if len(pending) + len(data) < self._need:
            pending += data  # the candidate is still incomplete: nothing to decide yet
            return
        if pending:
            pending += data
            work = bytes(pending)
        else:
            work = data if isinstance(data, bytes) else bytes(data)
        self._scan(work, self._pending_prefix, False, out)

    def _expire(self, out: list[Frame | DecoderEvent]) -> None:
        """The inter-byte timeout struck with a candidate in progress (D5)."""
        self._scan(bytes(self._pending), self._pending_prefix, True, out)

    def _scan(
        self, work: bytes, head_prefix: bytes | None, flush: bool, out: list[Frame | DecoderEvent]
    ) -> None:
        """Scan `work` (pending bytes plus new ones, starting at stream offset self._offset).

        `head_prefix` is the cached prefix XOR of the first bytes of `work`, if any. With `flush`,
        incomplete candidates fail as timeouts instead of waiting (D5), so nothing stays pending.
        """
        size = len(work)
        base = self._offset
        max_frame = self._max_frame
        append = out.append
        builder = _FrameBuilder
        frame_class = Frame
        prefix = self._prefix(work, head_prefix)  # prefix[k] = XOR of work[:k]
        quiet = self._quiet
        frames = 0
        next_standard = next_long = -1  # cached positions of the next flag bytes (bytes.find)
        index = 0
        need = 1
        while index < size:
            try:
                # Reading past the end of `work` raises IndexError, which ends this loop at no
                # cost on the happy path: either everything is scanned or a header is incomplete.
                while True:
                    flag = work[index]
                    if flag == 0x10:
                        header_end = index + 2
                        length = work[index + 1]
                    elif flag == 0x50:
                        header_end = index + 3
                        length = work[index + 1] | (work[index + 2] << 8)
                    else:
                        # D1 hunting: skip to the next flag byte in one step.
                        if next_standard < index:
                            next_standard = work.find(0x10, index)
                            if next_standard < 0:
                                next_standard = size
                        if next_long < index:
                            next_long = work.find(0x50, index)
                            if next_long < 0:
                                next_long = size
                        stop = next_standard if next_standard < next_long else next_long
                        self._bytes_discarded += stop - index
                        if not quiet:
                            first = max(base + index, self._silent_end)
                            if first < base + stop:
                                quiet = True
                                self._event(EventKind.GARBAGE, first)
                        index = stop
                        continue
                    # D2: a candidate whose size is now known.
                    end = header_end + length + 1
                    if end > size or end - index > max_frame or not length:
                        if end - index > max_frame:
                            declared = end - index
                            if self._fail(
                                EventKind.OVERSIZE, base + index, base + header_end, declared_size=declared
                            ):
                                quiet = True
                            index += 1
                            continue
                        if end > size:
                            if not flush:
                                need = end - index
                                break  # wait for the rest of the candidate
                            if self._fail(EventKind.TIMEOUT, base + index, base + size):
                                quiet = True
                            index += 1
                            continue
                        if prefix[end] == prefix[index]:
                            # LEN = 0 with a right checksum: a frame with no CMD byte.
                            self._empty_frames += 1
                            self._bytes_discarded += end - index
                            if base + index >= self._silent_end:
                                quiet = True
                                self._event(EventKind.EMPTY_FRAME, base + index)
                            index = end
                            continue
                    # D3: complete; the XOR over the whole frame, checksum included, is 0 when valid.
                    if prefix[end] == prefix[index]:
                        frame = builder()
                        frame.cmd = work[header_end]
                        frame.payload = work[header_end + 1 : end - 1]
                        frame.long = flag == 0x50
                        frame.offset = base + index
                        frame.__class__ = frame_class  # type: ignore[assignment]  # see _FrameBuilder
                        append(frame)  # type: ignore[arg-type]
                        frames += 1
                        quiet = False
                        index = end
                    else:
                        expected = prefix[end - 1] ^ prefix[index]
                        if self._fail(
                            EventKind.CHECKSUM_ERROR,
                            base + index,
                            base + end,
                            expected=expected,
                            found=work[end - 1],
                        ):
                            quiet = True
                        index += 1
            except IndexError:
                if index >= size:
                    break
                header_size = 2 if work[index] == 0x10 else 3
                if index + header_size <= size:
                    raise  # not the end of the input: a bug, do not hide it
                if not flush:
                    need = header_size
                    break
                if self._fail(EventKind.TIMEOUT, base + index, base + size):
                    quiet = True
                index += 1
                continue
            break  # the inner loop stopped to wait for more bytes
        self._quiet = quiet
        self._frames += frames
        if index < size:
            self._pending = bytearray(work[index:])
            self._pending_prefix = prefix[index:].translate(_XOR_WITH[prefix[index]])
            self._need = need
        else:
            self._pending = bytearray()
            self._pending_prefix = None
            self._need = 1
        self._offset = base + index

    @staticmethod
    def _prefix(work: bytes, head_prefix: bytes | None) -> bytes:
        """Prefix XOR of `work` with a leading 0, reusing the cached prefix of its first bytes."""
        if head_prefix is None:
            return b"\0" + _prefix_xor(work)
        known = len(head_prefix) - 1
        return head_prefix + _prefix_xor(work[known:], head_prefix[-1])

    def _fail(
        self,
        kind: EventKind,
        flag_offset: int,
        span_end: int,
        *,
        expected: int | None = None,
        found: int | None = None,
        declared_size: int | None = None,
    ) -> bool:
        """A candidate failed (D4): count it, drop its flag byte, report it unless silent.

        `span_end` is the stream offset just past its span (checksum: its declared end; oversize:
        its length bytes; timeout: everything received). The silent region is kept as one end
        offset: scanning only moves forward, and every span starts right after a flag that lies
        behind the scan position, so "inside some span" equals "before the furthest span end".
        Returns whether an event was raised.
        """
        if kind is EventKind.CHECKSUM_ERROR:
            self._checksum_errors += 1
        elif kind is EventKind.OVERSIZE:
            self._oversize += 1
        else:
            self._timeouts += 1
        self._resyncs += 1
        self._bytes_discarded += 1
        raised = flag_offset >= self._silent_end
        if raised:
            self._event(kind, flag_offset, expected, found, declared_size)
        if span_end > self._silent_end:
            self._silent_end = span_end
        return raised

    def _event(
        self,
        kind: EventKind,
        offset: int,
        expected: int | None = None,
        found: int | None = None,
        declared_size: int | None = None,
    ) -> None:
        if self._collect is None and self._on_event is None:
            return
        event = DecoderEvent(kind, offset, expected, found, declared_size)
        if self._collect is not None:
            self._collect.append(event)
        if self._on_event is not None:
            self._on_event(event)
