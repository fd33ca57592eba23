# SPDX-License-Identifier: MIT
"""Virtual time: run a Core session against an in-process base in simulated time.

One loop owns both ends: a `CoreSession` and a sans-IO base (anything with
`receive(data, now) -> bytes` and `tick(now) -> bytes`, such as `ctrlbus.base.BaseStack` or the
simulated base). It moves the bytes between them over two modelled serial lines and advances a
simulated clock from one event to the next (a byte arriving, a base tick, a Core deadline), so a
60-second session runs in a fraction of that, and the same inputs always give the same run.

The model:

- each direction is a UART line: a byte takes `byte_time_s` (default 115200 baud 8N1, 86.8 µs;
  0 = instant); writes queue behind each other, and the bytes of one write reach the other end
  together when its last byte has arrived (or in pieces of `chunk_bytes`, each when its last byte
  has arrived);
- the base answers `base_latency_s` after the bytes that caused the answer reached it (its main
  loop), and its `tick` runs every `tick_period_s`;
- `to_base` and `to_core` (optional) see every write before it goes onto its line and return the
  bytes to send instead: the place for a fault injector. They are called as `filter(data, now)`,
  and also with `b""` at every base tick so that a filter can release bytes it held back.

The session holds no lock. A test that reads or commands it from another thread while the loop
runs gives the loop a `lock` (taken around each call into the session) and takes it too.

`VirtualLink` is the same model seen from a master that does its own I/O (the conformance
checker): a `Link` to the base whose `read(timeout)` runs the simulated clock forward instead of
waiting, with `clock()` and `sleep()` to give that master for its own sense of time. Nothing then
depends on how busy the host is: a slow moment of the host is no time at all on the line.
"""

from __future__ import annotations

import contextlib
import math
from collections import deque
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any, Protocol

from ctrlbus.core.session import CoreSession
from ctrlbus.errors import LinkError, UsageError

__all__ = [
    "DEFAULT_BASE_LATENCY_S",
    "DEFAULT_BYTE_TIME_S",
    "DEFAULT_TICK_PERIOD_S",
    "ByteFilter",
    "SansIoBase",
    "SerialLine",
    "VirtualBus",
    "VirtualLink",
]

DEFAULT_BYTE_TIME_S = 10 / 115200  # one 8N1 character at 115200 baud
DEFAULT_BASE_LATENCY_S = 0.001  # the reference answers 1-5 ms after the request
DEFAULT_TICK_PERIOD_S = 0.005
# When the Core's next deadline is exactly now (an answer due "within" it), look again just after.
_EPSILON_S = 1e-6

ByteFilter = Callable[[bytes, float], bytes]


class SansIoBase(Protocol):
    """What the harness needs from a base."""

    def receive(self, data: bytes, now: float) -> bytes: ...

    def tick(self, now: float) -> bytes: ...


class SerialLine:
    """One direction of a UART: bytes queue, and arrive `byte_time_s` apart."""

    def __init__(self, byte_time_s: float, chunk_bytes: int = 0) -> None:
        self.byte_time_s = byte_time_s
        self.chunk_bytes = chunk_bytes
        self.free_at = 0.0  # when the last queued byte will have arrived
        self.bytes_sent = 0
        self._in_flight: deque[tuple[float, bytes]] = deque()  # (arrival time, bytes), in order

    def send(self, data: bytes, now: float) -> None:
        if not data:
            return
        self.bytes_sent += len(data)
        start = max(now, self.free_at)
        size = self.chunk_bytes or len(data)
        for offset in range(0, len(data), size):
            piece = data[offset : offset + size]
            start += len(piece) * self.byte_time_s
            self._in_flight.append((start, piece))
        self.free_at = start

    def next_arrival(self) -> float | None:
        return self._in_flight[0][0] if self._in_flight else None

    def take(self, now: float) -> bytes:
        """Everything that has arrived by `now`."""
        pieces = []
        while self._in_flight and self._in_flight[0][0] <= now:
            pieces.append(self._in_flight.popleft()[1])
        return b"".join(pieces)

    @property
    def idle(self) -> bool:
        return not self._in_flight


def _check_line_options(byte_time_s: float, base_latency_s: float, tick_period_s: float) -> None:
    for name, value in (("byte_time_s", byte_time_s), ("base_latency_s", base_latency_s)):
        if not (math.isfinite(value) and value >= 0):
            raise UsageError(f"{name} must be a finite number >= 0, got {value!r}")
    if not (math.isfinite(tick_period_s) and tick_period_s > 0):
        raise UsageError(f"tick_period_s must be a positive number, got {tick_period_s!r}")


class VirtualBus:
    """A Core session and a base wired together in simulated time, starting at `start_s`."""

    def __init__(
        self,
        core: CoreSession,
        base: SansIoBase,
        *,
        byte_time_s: float = DEFAULT_BYTE_TIME_S,
        base_latency_s: float = DEFAULT_BASE_LATENCY_S,
        tick_period_s: float = DEFAULT_TICK_PERIOD_S,
        chunk_bytes: int = 0,
        to_base: ByteFilter | None = None,
        to_core: ByteFilter | None = None,
        start_s: float = 0.0,
        lock: AbstractContextManager[Any] | None = None,
    ) -> None:
        _check_line_options(byte_time_s, base_latency_s, tick_period_s)
        if chunk_bytes < 0:
            raise UsageError(f"chunk_bytes must be >= 0, got {chunk_bytes}")
        self.core = core
        self.base = base
        self.lock = lock if lock is not None else contextlib.nullcontext()
        self.base_latency_s = base_latency_s
        self.tick_period_s = tick_period_s
        self.to_base_line = SerialLine(byte_time_s, chunk_bytes)
        self.to_core_line = SerialLine(byte_time_s, chunk_bytes)
        self._to_base = to_base
        self._to_core = to_core
        self.now = start_s
        self._start_s = start_s
        self._ticks = 0
        self.base_ticks = 0
        self.core_requests = 0

    @property
    def elapsed_s(self) -> float:
        return self.now - self._start_s

    def run_for(self, duration_s: float) -> None:
        """Advance simulated time by `duration_s` seconds."""
        if not (math.isfinite(duration_s) and duration_s >= 0):
            raise UsageError(f"duration must be a finite number of seconds >= 0, got {duration_s!r}")
        self._run_to(self.now + duration_s)

    def run_until(
        self, condition: Callable[[], bool], timeout_s: float, check_period_s: float = 0.05
    ) -> bool:
        """Run until `condition()` holds (checked every `check_period_s` of simulated time) or
        `timeout_s` has passed; returns whether it held."""
        end = self.now + timeout_s
        while not condition():
            if self.now >= end:
                return False
            self._run_to(min(end, self.now + check_period_s))
        return True

    # -- the event loop -----------------------------------------------------------------------

    def _next_tick(self) -> float:
        return self._start_s + (self._ticks + 1) * self.tick_period_s

    def _run_to(self, end: float) -> None:
        while True:
            self._poll_core()
            with self.lock:
                wake = self.core.next_poll_time()
            if wake is not None and wake <= self.now:
                wake = self.now + _EPSILON_S
            candidates = [self._next_tick()]
            for value in (self.to_base_line.next_arrival(), self.to_core_line.next_arrival(), wake):
                if value is not None:
                    candidates.append(value)
            moment = max(self.now, min(candidates))
            if moment > end:
                self.now = end
                return
            self.now = moment
            self._deliver()

    def _poll_core(self) -> None:
        with self.lock:
            frame = self.core.poll(self.now)
        if frame is not None:
            self.core_requests += 1
            self._send_to_base(frame, self.now)

    def _deliver(self) -> None:
        now = self.now
        data = self.to_base_line.take(now)
        if data:
            self._send_to_core(self.base.receive(data, now), now + self.base_latency_s)
        data = self.to_core_line.take(now)
        if data:
            with self.lock:
                self.core.receive(data, now)
        if now >= self._next_tick():
            self._ticks += 1
            self.base_ticks += 1
            self._send_to_core(self.base.tick(now), now + self.base_latency_s)
            if self._to_base is not None:
                self._send_to_base(b"", now)

    def _send_to_base(self, data: bytes, when: float) -> None:
        if self._to_base is not None:
            data = self._to_base(data, when)
        self.to_base_line.send(data, when)

    def _send_to_core(self, data: bytes, when: float) -> None:
        if self._to_core is not None:
            data = self._to_core(data, when)
        self.to_core_line.send(data, when)


class VirtualLink:
    """The master's end of a UART to an in-process sans-IO base, in simulated time from `start_s`.

    `write` puts bytes on the line to the base; `read(timeout)` advances the clock from event to
    event (a byte arriving at the base, its answer arriving back, a base tick) until answer bytes
    arrive or `timeout` has passed, and returns them. The base answers `base_latency_s` after the
    bytes that caused the answer reached it and ticks every `tick_period_s`, as on VirtualBus.
    Give the master `clock` and `sleep` (for example `check_base(link, options, clock=link.clock,
    sleep=link.sleep)`): a master that read the host's clock would mix the two times.
    Not thread-safe: one master drives it.
    """

    def __init__(
        self,
        base: SansIoBase,
        *,
        byte_time_s: float = DEFAULT_BYTE_TIME_S,
        base_latency_s: float = DEFAULT_BASE_LATENCY_S,
        tick_period_s: float = DEFAULT_TICK_PERIOD_S,
        start_s: float = 0.0,
        name: str = "virtual link",
    ) -> None:
        _check_line_options(byte_time_s, base_latency_s, tick_period_s)
        self.base = base
        self.base_latency_s = base_latency_s
        self.tick_period_s = tick_period_s
        self.to_base_line = SerialLine(byte_time_s)
        self.to_master_line = SerialLine(byte_time_s)
        self.now = start_s
        self._start_s = start_s
        self._ticks = 0
        self._name = name
        self._closed = False

    @property
    def name(self) -> str:
        return self._name

    def clock(self) -> float:
        """The simulated time, s."""
        return self.now

    def sleep(self, seconds: float) -> None:
        """Let `seconds` of simulated time pass (the base runs; what it sends waits to be read)."""
        self._run_to(self.now + max(0.0, seconds), stop_at_answer=False)

    def write(self, data: bytes) -> None:
        if self._closed:
            raise LinkError(f"{self._name} is closed")
        self.to_base_line.send(bytes(data), self.now)

    def read(self, timeout: float) -> bytes:
        if self._closed:
            raise LinkError(f"{self._name} is closed")
        arrived = self.to_master_line.take(self.now)
        if arrived:
            return arrived
        self._run_to(self.now + max(0.0, timeout), stop_at_answer=True)
        return self.to_master_line.take(self.now)

    def close(self) -> None:
        self._closed = True

    def _next_tick(self) -> float:
        return self._start_s + (self._ticks + 1) * self.tick_period_s

    def _run_to(self, end: float, *, stop_at_answer: bool) -> None:
        """Advance to `end`, or (stop_at_answer) to the moment answer bytes have arrived."""
        while True:
            answer_at = self.to_master_line.next_arrival()
            if stop_at_answer and answer_at is not None and answer_at <= self.now:
                return
            candidates = [self._next_tick()]
            base_at = self.to_base_line.next_arrival()
            if base_at is not None:
                candidates.append(base_at)
            if stop_at_answer and answer_at is not None:
                candidates.append(answer_at)
            moment = max(self.now, min(candidates))
            if moment > end:
                self.now = end
                return
            self.now = moment
            data = self.to_base_line.take(moment)
            if data:
                self.to_master_line.send(self.base.receive(data, moment), moment + self.base_latency_s)
            if moment >= self._next_tick():
                self._ticks += 1
                self.to_master_line.send(self.base.tick(moment), moment + self.base_latency_s)
