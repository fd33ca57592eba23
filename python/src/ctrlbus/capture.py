# SPDX-License-Identifier: MIT
"""Capture files: what went over the wire, both directions, with the time of every chunk.

The format (docs/capture-format.md) is a classic libpcap file that Wireshark and tcpdump open:

- link type 147 (DLT_USER0; tools/wireshark/ctrlbus.lua dissects it);
- written with microsecond timestamps, little-endian; read in either byte order and in microsecond
  or nanosecond resolution;
- each record is one chunk of bytes as it was read from one side: a direction byte
  (0 = Core to base, master to slave; 1 = base to Core) followed by the bytes. A chunk is not a frame:
  a frame may span several records and one record may hold several frames.

The writer flushes after every record by default, so a live capture can be read while it grows;
the reader then stops at a final record that is not complete yet, reports its size in
`truncated_tail`, and continues from it if iterated again once more bytes have arrived.
"""

from __future__ import annotations

import contextlib
import struct
import threading
from collections.abc import Iterator
from dataclasses import dataclass
from enum import IntEnum
from pathlib import Path
from types import TracebackType
from typing import BinaryIO

from ctrlbus.errors import CaptureError

__all__ = [
    "LINKTYPE_USER0",
    "MAGIC_MICROSECONDS",
    "MAGIC_NANOSECONDS",
    "MAX_CHUNK",
    "SNAPLEN",
    "CaptureReader",
    "CaptureRecord",
    "CaptureWriter",
    "Direction",
    "looks_like_capture",
    "read_capture",
]

LINKTYPE_USER0 = 147
SNAPLEN = 65535
# Data bytes per record: the direction byte takes one of the snapshot length.
MAX_CHUNK = SNAPLEN - 1

MAGIC_MICROSECONDS = 0xA1B2C3D4
MAGIC_NANOSECONDS = 0xA1B23C4D
_PCAPNG_MAGIC = b"\x0a\x0d\x0d\x0a"
_GLOBAL_HEADER = struct.Struct("<IHHiIII")
_RECORD_HEADER = struct.Struct("<IIII")
# A record claiming more than this is damage, not data (the largest pcap snapshot length in use).
_MAX_RECORD = 0x40000
_READ_SIZE = 1 << 16


class Direction(IntEnum):
    """Who sent a chunk; the value is the direction byte in the file."""

    CORE_TO_BASE = 0  # master to slave: requests
    BASE_TO_CORE = 1  # slave to master: answers


@dataclass(frozen=True)
class CaptureRecord:
    """One chunk: when it was read (nanoseconds since the writer's time origin), from whom, what."""

    time_ns: int
    direction: Direction
    data: bytes
    offset: int  # where the record starts in the file, for messages

    @property
    def time(self) -> float:
        """Seconds since the writer's time origin (the Unix epoch for live captures)."""
        return self.time_ns / 1e9


def looks_like_capture(head: bytes) -> bool:
    """Whether bytes starting a file are a pcap header (either byte order or resolution)."""
    if len(head) < 4:
        return False
    return any(
        struct.unpack(order + "I", head[:4])[0] in (MAGIC_MICROSECONDS, MAGIC_NANOSECONDS) for order in "<>"
    )


# ---------------------------------------------------------------------------------------------
# Writing


class CaptureWriter:
    """Appends chunks to a capture. Thread-safe, so the two directions may write from two threads.

    `time` is in seconds: pass `time.time()` for a live capture (Wireshark shows wall-clock time),
    or a virtual clock's seconds for a simulated one. Timestamps are stored to the microsecond.
    """

    def __init__(self, stream: BinaryIO, *, flush: bool = True, owns_stream: bool = False) -> None:
        self._stream = stream
        self._flush = flush
        self._owns_stream = owns_stream
        self._lock = threading.Lock()
        self._closed = False
        self._failed = False  # a write failed (a full disk): what is buffered cannot be written
        # The file's name, for messages about it (None for a stream that is not a named file).
        self.path: str | None = str(stream.name) if isinstance(getattr(stream, "name", None), str) else None
        stream.write(_GLOBAL_HEADER.pack(MAGIC_MICROSECONDS, 2, 4, 0, 0, SNAPLEN, LINKTYPE_USER0))
        if flush:
            stream.flush()

    @classmethod
    def create(cls, path: str | Path, *, flush: bool = True) -> CaptureWriter:
        """A writer on a new file at `path` (an existing file is replaced)."""
        return cls(open(path, "wb"), flush=flush, owns_stream=True)

    def write(self, direction: Direction | int, data: bytes, time: float) -> None:
        """Record one chunk. An empty chunk records nothing; one longer than MAX_CHUNK becomes
        several records with the same time (chunk boundaries carry no meaning)."""
        try:
            side = Direction(direction)
        except ValueError:
            raise CaptureError(
                f"direction must be 0 (core→base) or 1 (base→core), not {direction!r}"
            ) from None
        if not 0.0 <= time < 2.0**32:
            raise CaptureError(f"capture time must be 0 <= seconds < 2**32, not {time!r}")
        seconds, microseconds = divmod(round(time * 1_000_000), 1_000_000)
        seconds = min(seconds, 2**32 - 1)
        with self._lock:
            if self._closed:
                raise CaptureError("the capture is closed")
            try:
                for start in range(0, len(data), MAX_CHUNK):
                    piece = bytes(data[start : start + MAX_CHUNK])
                    size = len(piece) + 1
                    self._stream.write(_RECORD_HEADER.pack(seconds, microseconds, size, size))
                    self._stream.write(bytes([side]) + piece)
                if self._flush and data:
                    self._stream.flush()
            except OSError:
                self._failed = True
                raise

    def flush(self) -> None:
        with self._lock:
            self._stream.flush()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            if self._failed:
                # The write's error was raised; flushing the same bytes again would only raise it
                # once more (from close, hiding the first report).
                if self._owns_stream:
                    with contextlib.suppress(OSError):
                        self._stream.close()
                return
            self._stream.flush()
            if self._owns_stream:
                self._stream.close()

    def __enter__(self) -> CaptureWriter:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


# ---------------------------------------------------------------------------------------------
# Reading


class CaptureReader:
    """Reads the records of a capture from a binary stream.

    The header is checked at once (CaptureError: not pcap, pcapng, wrong link type, damaged).
    Iterating yields CaptureRecords; a damaged record raises CaptureError naming its offset. An
    incomplete final record (a live capture still being written, or a file cut short) ends the
    iteration and its size is left in `truncated_tail`; with `strict=True` it raises CaptureError
    instead. Iterating again later continues where the last complete record ended.
    """

    def __init__(
        self, stream: BinaryIO, *, strict: bool = False, name: str = "capture", owns_stream: bool = False
    ) -> None:
        self._stream = stream
        self._strict = strict
        self._owns_stream = owns_stream
        self.name = name
        self._buffer = bytearray()
        self._pos = 0  # next unread byte in _buffer
        self._base_offset = 0  # file offset of _buffer[0]
        if not self._fill(_GLOBAL_HEADER.size):
            head = bytes(self._buffer)
            if looks_like_capture(head) or not head:
                raise CaptureError(f"{name}: too short for a pcap header ({len(head)} of 24 bytes)")
            raise CaptureError(f"{name}: not a pcap capture file")
        self._parse_global_header(bytes(self._buffer[: _GLOBAL_HEADER.size]))
        self._pos = _GLOBAL_HEADER.size

    @classmethod
    def open(cls, path: str | Path, *, strict: bool = False) -> CaptureReader:
        stream = open(path, "rb")  # noqa: SIM115 - the reader closes it
        try:
            return cls(stream, strict=strict, name=str(path), owns_stream=True)
        except BaseException:
            stream.close()
            raise

    def _parse_global_header(self, header: bytes) -> None:
        if header[:4] == _PCAPNG_MAGIC:
            raise CaptureError(
                f"{self.name}: pcapng is not supported; save it as pcap (editcap -F pcap in.pcapng out.pcap)"
            )
        for order in "<>":
            magic = struct.unpack(order + "I", header[:4])[0]
            if magic in (MAGIC_MICROSECONDS, MAGIC_NANOSECONDS):
                self.byte_order = order
                self.nanoseconds = magic == MAGIC_NANOSECONDS
                break
        else:
            raise CaptureError(f"{self.name}: not a pcap capture file (magic {header[:4].hex(' ')})")
        _, major, minor, _, _, snaplen, network = struct.unpack(order + _GLOBAL_HEADER.format[1:], header)
        if major != 2:
            raise CaptureError(f"{self.name}: pcap version {major}.{minor} is not supported (2.4 is)")
        link_type = network & 0x03FFFFFF  # the upper bits may carry FCS information
        if link_type != LINKTYPE_USER0:
            raise CaptureError(
                f"{self.name}: link type {link_type} is not a ctrlbus capture (DLT_USER0 = {LINKTYPE_USER0})"
            )
        self.snaplen = snaplen
        self._record_header = struct.Struct(order + _RECORD_HEADER.format[1:])

    def _fill(self, count: int) -> bool:
        """Read until `count` unread bytes are buffered; False if the stream ends first."""
        while len(self._buffer) - self._pos < count:
            chunk = self._stream.read(max(_READ_SIZE, count))
            if not chunk:
                return False
            if self._pos >= _READ_SIZE:
                del self._buffer[: self._pos]
                self._base_offset += self._pos
                self._pos = 0
            self._buffer += chunk
        return True

    @property
    def truncated_tail(self) -> int:
        """Bytes of an incomplete final record seen by the last iteration (0 if none)."""
        return len(self._buffer) - self._pos

    def __iter__(self) -> Iterator[CaptureRecord]:
        return self.records()

    def records(self) -> Iterator[CaptureRecord]:
        header_size = self._record_header.size
        while True:
            offset = self._base_offset + self._pos
            if not self._fill(header_size):
                break
            seconds, fraction, included, original = self._record_header.unpack_from(self._buffer, self._pos)
            self._check_record(offset, included, original)
            if not self._fill(header_size + included):
                break
            start = self._pos + header_size
            direction = self._buffer[start]
            if direction not in (0, 1):
                raise CaptureError(
                    f"{self.name}: record at offset {offset}: direction byte {direction} is neither "
                    "0 (core→base) nor 1 (base→core)"
                )
            data = bytes(self._buffer[start + 1 : start + included])
            self._pos = start + included
            time_ns = seconds * 1_000_000_000 + fraction * (1 if self.nanoseconds else 1000)
            yield CaptureRecord(time_ns, Direction(direction), data, offset)
        if self.truncated_tail and self._strict:
            raise CaptureError(
                f"{self.name}: the final record at offset {self._base_offset + self._pos} is cut short "
                f"({self.truncated_tail} bytes)"
            )

    def _check_record(self, offset: int, included: int, original: int) -> None:
        where = f"{self.name}: record at offset {offset}"
        if included == 0:
            raise CaptureError(f"{where} is empty (it needs at least the direction byte)")
        if included > _MAX_RECORD or (self.snaplen and included > max(self.snaplen, SNAPLEN)):
            raise CaptureError(
                f"{where} claims {included} bytes, more than the file's snapshot length allows"
            )
        if original != included:
            raise CaptureError(
                f"{where} holds {included} of the chunk's {original} bytes; a capture cut by a snapshot "
                "length has lost bytes"
            )

    def close(self) -> None:
        if self._owns_stream:
            self._stream.close()

    def __enter__(self) -> CaptureReader:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()


def read_capture(path: str | Path, *, strict: bool = True) -> list[CaptureRecord]:
    """Every record of a capture file (a truncated final record is an error unless strict=False)."""
    with CaptureReader.open(path, strict=strict) as reader:
        return list(reader)
