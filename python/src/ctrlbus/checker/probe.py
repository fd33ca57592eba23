# SPDX-License-Identifier: MIT
"""The conformance checker's own master: exact bytes out, frames in, everything timed and logged.

The checker does not use the Core emulator: it must send bytes a Core never sends (bad
checksums, bogus lengths, garbage) and see every byte that comes back. `Prober` writes bytes to a
`Link`, reads the answers through a host-side `StreamDecoder` (100 ms inter-byte timeout,
docs/protocol.md §7.6) and keeps a transcript of what went each way, with times, that becomes a
check's evidence.

Every wait is bounded: `answer_limit_s` caps the wait for any one answer, so a silent or slow
base costs seconds, not forever.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field

from ctrlbus.errors import CtrlbusError, LinkError
from ctrlbus.frame import DecoderEvent, Frame, StreamDecoder, encode
from ctrlbus.link import Link
from ctrlbus.messages import Cmd, Response

__all__ = [
    "FLUSHING_SYNC",
    "HOST_INTERBYTE_TIMEOUT_S",
    "Evidence",
    "Exchange",
    "NoAnswer",
    "Prober",
    "Received",
    "describe_frame",
]

HOST_INTERBYTE_TIMEOUT_S = 0.1  # docs/protocol.md §7.6: programs reading a port on a host
# The Core's flushing SYNC (§11.1): a long SYNC of exactly 512 bytes that completes any candidate
# a reference base (no inter-byte timeout) may be stuck on.
FLUSHING_SYNC = encode(Cmd.SYNC, bytes(507), long=True)
READ_SLICE_S = 0.02  # longest single read, so arrivals are time-stamped closely
SPURIOUS_READ_PAUSE_S = 0.01
# An answer stream that delivered bytes but no frame, then went quiet this long, has no frame
# coming: a request stops waiting then (a base with garbled answers costs seconds, not minutes).
STRAY_QUIET_S = 0.3
WRITE_CHUNK = 1024  # big requests go out in pieces (see Prober.send)
COALESCE_S = 0.01  # received pieces closer than this make one transcript line


class NoAnswer(CtrlbusError):
    """A request got no complete frame back within the answer limit."""


@dataclass(frozen=True)
class Evidence:
    """One line of a transcript: bytes sent (`sent`), bytes received (`received`) or a remark
    (`note`), at `t_s` seconds since the transcript started."""

    t_s: float
    direction: str
    data: bytes = b""
    note: str = ""


@dataclass(frozen=True)
class Received:
    """A frame or decoder event taken from the answer stream, and when its last byte arrived."""

    item: Frame | DecoderEvent
    time: float


@dataclass
class Exchange:
    """One request and what came back: `frame` is the first complete frame after the request
    (None if none came), `latency_s` the time from the request's last byte to that frame's last
    byte; `before` holds decoder events seen before it."""

    request: bytes
    what: str
    sent_at: float
    frame: Frame | None = None
    latency_s: float | None = None
    before: list[DecoderEvent] = field(default_factory=list)
    bytes_heard: int = 0  # bytes received between the request and the frame (or the give-up)


def describe_frame(frame: Frame) -> str:
    """A short reading of an answer frame for transcripts: "OK 2 bytes", "ERROR 0x8000"."""
    if frame.cmd == Response.ERROR and len(frame.payload) == 2:
        return f"ERROR 0x{int.from_bytes(frame.payload, 'little'):04X}"
    names: dict[int, str] = {
        Response.SYNC: "SYNC",
        Response.ECHO: "ECHO",
        Response.OK: "OK",
        Response.ERROR: "ERROR",
    }
    name = names.get(frame.cmd, "INVALID" if frame.cmd == Response.INVALID else f"CMD 0x{frame.cmd:02X}")
    kind = "long" if frame.long else "standard"
    size = len(frame.payload)
    return f"{name} {size} byte{'' if size == 1 else 's'} ({kind})"


class Prober:
    """Send bytes to a base and read its answers, with bounded waits and a transcript.

    `clock` and `sleep` are injectable (`ctrlbus.vtime.VirtualLink` gives both: the checker then
    runs in simulated time, untouched by the host's load); by default they are real time,
    because the checker judges real timing (latency, the motor watchdog).
    """

    def __init__(
        self,
        link: Link,
        *,
        answer_limit_s: float,
        clock: Callable[[], float] = time.monotonic,
        sleep: Callable[[float], None] = time.sleep,
        interbyte_timeout_s: float = HOST_INTERBYTE_TIMEOUT_S,
    ) -> None:
        self.link = link
        self.answer_limit_s = answer_limit_s
        self._clock = clock
        self._sleep = sleep
        self._decoder = StreamDecoder(timeout=interbyte_timeout_s)
        self._queue: deque[Received] = deque()
        self.transcript: list[Evidence] = []
        self.unsolicited: list[Received] = []  # what drain() took since the transcript started
        self.recording = True  # False: bytes are not logged (long series of timed requests)
        self._origin = clock()
        # Requests in a row that got no byte at all back: the runner calls the link dead at 3.
        self.silent_streak = 0
        self.bytes_received = 0
        self.frames_received = 0
        self._last_rx = self._origin

    # -- time and transcript ------------------------------------------------------------------

    def now(self) -> float:
        return self._clock()

    def start_transcript(self) -> None:
        self.transcript = []
        self.unsolicited = []
        self._origin = self._clock()

    def note(self, text: str) -> None:
        self.transcript.append(Evidence(self._clock() - self._origin, "note", note=text))

    # -- raw input and output -----------------------------------------------------------------

    def send(self, data: bytes, what: str) -> float:
        """Write `data`; returns the time right after the write (its last byte handed over).

        A big request goes out in pieces, with whatever has come back read in between: a base
        (or an echoing port) that answers while we write must never find the way back full.
        """
        if self.recording:
            self.transcript.append(Evidence(self._clock() - self._origin, "sent", data, what))
        for start in range(0, len(data), WRITE_CHUNK):
            if start:
                self._pump(0.0)
            self.link.write(data[start : start + WRITE_CHUNK])
        return self._clock()

    def _read(self, timeout: float) -> bytes:
        try:
            return self.link.read(timeout)
        except LinkError:
            # pyserial reading a pty slave may once report readiness without data (a kernel
            # race when the other side writes); a port that is really gone fails again.
            self._sleep(SPURIOUS_READ_PAUSE_S)
            return self.link.read(0.0)

    def _pump(self, timeout: float) -> bool:
        """Read once (waiting up to `timeout`); queue what the bytes complete. True if bytes came."""
        data = self._read(max(0.0, min(timeout, READ_SLICE_S)))
        now = self._clock()
        items = self._decoder.feed_items(data, now)  # with no bytes: applies the inter-byte timeout
        if data:
            self.bytes_received += len(data)
            self._last_rx = now
        notes = []
        for item in items:
            self._queue.append(Received(item, now))
            if isinstance(item, Frame):
                self.frames_received += 1
                notes.append(describe_frame(item))
            else:
                notes.append(f"decoder: {item.kind}")
        if not self.recording:
            pass
        elif data:
            self._log_received(now, data, notes)
        elif notes:
            self.transcript.append(Evidence(now - self._origin, "note", note="; ".join(notes)))
        return bool(data)

    def _log_received(self, now: float, data: bytes, notes: list[str]) -> None:
        """Log received bytes; pieces that follow each other closely make one line (some ports
        deliver an answer a byte at a time), stamped with the time of its last piece."""
        last = self.transcript[-1] if self.transcript else None
        if last is not None and last.direction == "received" and now - self._origin - last.t_s <= COALESCE_S:
            notes = [last.note, *notes] if last.note else notes
            data = last.data + data
            self.transcript.pop()
        self.transcript.append(Evidence(now - self._origin, "received", data, "; ".join(notes)))

    def next_item(self, deadline: float) -> Received | None:
        """The next frame or decoder event, waiting until `deadline` at most."""
        while not self._queue:
            remaining = deadline - self._clock()
            if remaining <= 0:
                # One last non-blocking look, so a deadline already past still sees what is there.
                self._pump(0.0)
                break
            self._pump(remaining)
        return self._queue.popleft() if self._queue else None

    def collect(self, duration_s: float) -> list[Received]:
        """Everything that arrives within `duration_s` from now (frames and events)."""
        deadline = self._clock() + duration_s
        items: list[Received] = []
        while True:
            item = self.next_item(deadline)
            if item is None:
                return items
            items.append(item)

    def drain(self, quiet_s: float = 0.0) -> list[Received]:
        """Take what is already queued or arriving, until nothing came for `quiet_s` (or, from a
        base that never stops sending, until the answer limit has passed on top).

        Anything taken here answers no request of ours (a late answer, an extra answer, stray
        bytes) and is logged as unsolicited.
        """
        items: list[Received] = []
        give_up = self._clock() + quiet_s + self.answer_limit_s  # a base that never stops talking
        while self._clock() < give_up:
            while self._queue:
                items.append(self._queue.popleft())
            if quiet_s > 0:
                got = self.collect(quiet_s)
                if not got:
                    break
                items.extend(got)
            elif not self._pump(0.0) and not self._queue:
                break
        self.unsolicited.extend(items)
        if items:
            described = ", ".join(
                describe_frame(r.item) if isinstance(r.item, Frame) else str(r.item.kind) for r in items
            )
            self.note(f"unsolicited: {described}")
        return items

    def wait(self, seconds: float) -> list[Received]:
        """Let `seconds` pass while reading (so whatever arrives is logged with its time)."""
        return self.collect(seconds)

    # -- requests -----------------------------------------------------------------------------

    def exchange(self, request: bytes, what: str, *, limit_s: float | None = None) -> Exchange:
        """Drain, send `request`, and wait for the first complete frame (up to `limit_s`,
        default the answer limit). Events before it are kept in `before`; the exchange's frame
        is None if none came (see `request` for the raising form)."""
        self.drain()
        received_before = self.bytes_received
        sent_at = self.send(request, what)
        exchange = Exchange(request, what, sent_at)
        deadline = sent_at + (self.answer_limit_s if limit_s is None else limit_s)
        while True:
            # Bytes came, but no frame: once they have stopped for a while, no frame is coming.
            heard = self.bytes_received > received_before
            until = min(deadline, self._last_rx + STRAY_QUIET_S) if heard else deadline
            got = self.next_item(until)
            if got is None:
                now = self._clock()
                if now >= deadline or (heard and now >= self._last_rx + STRAY_QUIET_S):
                    break
                continue
            if isinstance(got.item, Frame):
                exchange.frame = got.item
                exchange.latency_s = max(0.0, got.time - sent_at)
                break
            exchange.before.append(got.item)
        exchange.bytes_heard = self.bytes_received - received_before
        if self.bytes_received == received_before:
            self.silent_streak += 1
        else:
            self.silent_streak = 0
        return exchange

    def request(self, request: bytes, what: str, *, limit_s: float | None = None) -> Exchange:
        """Like `exchange`, but raise NoAnswer if no frame came back."""
        exchange = self.exchange(request, what, limit_s=limit_s)
        if exchange.frame is None:
            limit = self.answer_limit_s if limit_s is None else limit_s
            heard = "nothing at all" if self.silent_streak else "bytes, but no valid frame"
            raise NoAnswer(f"no answer to {what} within {limit * 1000:.0f} ms ({heard} came back)")
        return exchange
