# SPDX-License-Identifier: MIT
"""A model of the reference base firmware's receiver, for the garbage-burst recovery comparison.

It behaves as control-bus.md §4 describes the reference: it hunts for 0x10 or 0x50, reads the
length, then collects exactly that many bytes plus the checksum, whatever they are. There is no
backtracking and no timeout: a false flag in noise followed by a bogus length swallows the real
frames behind it, and when its checksum then fails those bytes are gone. A long frame whose LEN
does not fit the 512-byte receive buffer (LEN > 509) resets the receiver right after the length
bytes (the reference answers ERROR 0x0020 there). A LEN = 0 frame carries no command: its
checksum byte is read and nothing is delivered.

The model yields whole frames as bytes; it is not part of ctrlbus and must not be used as a decoder.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field

FLAG_STANDARD = 0x10
FLAG_LONG = 0x50
RX_BUFFER = 512
LONG_LEN_LIMIT = RX_BUFFER - 3  # long LEN above this gets ERROR 0x0020 and a receiver reset

_FLAGS = re.compile(b"[\x10\x50]")


@dataclass
class ReferenceModelCounters:
    frames: int = 0
    checksum_errors: int = 0
    oversize: int = 0
    empty_frames: int = 0
    bytes_discarded: int = 0


@dataclass
class ReferenceModelDecoder:
    """Feed bytes, get the frames the reference firmware would execute (as their raw bytes)."""

    counters: ReferenceModelCounters = field(default_factory=ReferenceModelCounters)
    offsets: list[int] = field(default_factory=list)  # stream offset of every frame delivered
    _pending: bytearray = field(default_factory=bytearray)
    _pending_offset: int = 0  # stream offset of the first pending byte

    def feed(self, data: bytes) -> list[bytes]:
        buf = self._pending + data
        base = self._pending_offset
        frames: list[bytes] = []
        pos = 0
        end = len(buf)
        while pos < end:
            match = _FLAGS.search(buf, pos)
            if match is None:
                self.counters.bytes_discarded += end - pos
                pos = end
                break
            self.counters.bytes_discarded += match.start() - pos
            pos = match.start()
            header = 2 if buf[pos] == FLAG_STANDARD else 3
            if pos + header > end:
                break  # wait for the length byte(s)
            length = buf[pos + 1] if header == 2 else buf[pos + 1] | buf[pos + 2] << 8
            if header == 3 and length > LONG_LEN_LIMIT:
                self.counters.oversize += 1
                self.counters.bytes_discarded += header
                pos += header
                continue
            size = header + length + 1
            if pos + size > end:
                break  # a partial frame waits for ever: no timeout
            candidate = bytes(buf[pos : pos + size])
            pos += size
            checksum = 0
            for byte in candidate[:-1]:
                checksum ^= byte
            if checksum != candidate[-1]:
                self.counters.checksum_errors += 1
                self.counters.bytes_discarded += size
            elif length == 0:
                self.counters.empty_frames += 1
                self.counters.bytes_discarded += size
            else:
                self.counters.frames += 1
                frames.append(candidate)
                self.offsets.append(base + pos - size)
        self._pending = bytearray(buf[pos:])
        self._pending_offset = base + pos
        return frames
