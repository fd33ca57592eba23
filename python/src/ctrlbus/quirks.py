# SPDX-License-Identifier: MIT
"""A model of the reference base firmware's receiver, for the simulated base's quirks mode.

docs/simulator.md ("Reference quirks") is the manual and docs/protocol.md §8.5 [ref-receiver] states the
mechanism. The reference (base_ref v4) parses bytes in its receive interrupt and acts on them in a
main loop; the two share one 512-byte buffer and one state word, and they race. This module
reproduces that machinery sans-IO (bytes and time in, the answers the main loop sends out), so
that what a Core sees follows from it rather than from a table of cases:

- the receiver: a frame starts at 0x10 or 0x50 (any other byte there raises "not synchronised",
  0x10); the header, CMD and payload are stored in the buffer from its first byte on, a checksum
  mismatch raises 0x40, a completed frame raises "ready" (0x80) even when its checksum failed;
  a long LEN that does not fit the buffer raises "too long" (0x20) at the CMD byte and drops that
  byte; no inter-byte timeout; a frame completing while "ready" is still raised simply replaces it
  (the interrupt's guard against that tests a bit that is never set);
- the main loop: each pass looks at the state word once; any error bit sends ERROR with the whole
  low byte (0x0010, 0x0020, 0x0090, 0x00C0, ...), otherwise "ready" runs the request in the
  buffer (SYNC and ECHO are echoed from the buffer); sending first clears the whole state word,
  including the receiver's position in a frame being received: the next byte of that frame is
  thrown away and the rest of it counts as stray bytes;
- the transmitter: an answer waits until the previous answer's last byte has left the DMA (two
  byte times before the line is free); the loop is blocked meanwhile, bytes keep arriving;
- the schedule (as on the refbase harness, whose timing the figures here were calibrated on): a
  pass takes 20 µs, then the loop sleeps until the next byte in or out, or 1 ms; a byte due
  during a pass is handled at its end;
- power-on: for its first 100 ms the firmware has no receiver (bytes are lost); then the receiver
  works, but until `boot_s` the main loop does not run (the reference beeps).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable

from ctrlbus.compat import StrEnum
from ctrlbus.constants import Profile
from ctrlbus.errors import MessageError, MessageFormatError, UsageError
from ctrlbus.frame import FLAG_LONG, FLAG_STANDARD, MAX_LONG_PAYLOAD, MAX_STANDARD_PAYLOAD, Frame
from ctrlbus.messages import Cmd, decode_request

__all__ = [
    "BOOT_SILENCE_S",
    "CHECKSUM_BIT",
    "DEAF_S",
    "FRAME_READY_BIT",
    "IDLE_WAKE_S",
    "MAIN_LOOP_PASS_S",
    "NOT_SYNCED_BIT",
    "REFERENCE_RX_BUFFER",
    "STARTUP_BATTERY_S",
    "TOO_LONG_BIT",
    "Quirks",
    "ReferenceReceiver",
    "parse_quirks",
]

NOT_SYNCED_BIT = 0x10
TOO_LONG_BIT = 0x20
CHECKSUM_BIT = 0x40
FRAME_READY_BIT = 0x80
_ERROR_BITS = NOT_SYNCED_BIT | TOO_LONG_BIT | CHECKSUM_BIT
REFERENCE_RX_BUFFER = 512
# Set-up (0.12 ms, after the 100 ms supply wait) and 1.8 s of beeps, then the main loop runs.
BOOT_SILENCE_S = 1.90012
STARTUP_BATTERY_S = 3.0  # 0 % and a low-battery error until the first battery reading
MAIN_LOOP_PASS_S = 20e-6  # one pass of the main loop (refbase --pass-us)
IDLE_WAKE_S = 1e-3  # an idle loop looks again this long after a pass (refbase --idle-us)
DEAF_S = 100.12e-3  # after power-on it waits for its supply, then sets up its board, then the UART
DEFAULT_BYTE_TIME_S = 10 / 115200
MAX_FIXED_REQUEST = 24  # longer than any control-bus request with a fixed layout (SET_BASE_MOTOR: 17)
_DMA_TAIL_BYTES = 2  # the DMA is done when the last byte enters the data register: 2 bytes early
_TIE_S = 1e-9  # a byte due when the loop wakes (or its wait ends) is received first

# The receiver's position in a frame (kept in the high half of the shared state word).
_IDLE = 0  # also what the main loop's clear leaves, even in the middle of a frame
_WANT_LEN = 1
_WANT_LEN_HIGH = 2
_WANT_CMD = 3
_WANT_BODY = 4


class Quirks(StrEnum):
    """How faithfully a simulated base imitates the reference firmware's receiver."""

    NONE = "none"  # the documented ctrlbus behaviour (docs/protocol.md §7-§8)
    REFERENCE = Profile.REFERENCE.value  # base_ref v4 as observed (this module), named as its profile


def parse_quirks(value: Quirks | str) -> Quirks:
    """A Quirks from itself or its name; UsageError naming the choices otherwise."""
    if isinstance(value, Quirks):
        return value
    try:
        return Quirks(str(value).strip().lower())
    except ValueError:
        choices = ", ".join(item.value for item in Quirks)
        raise UsageError(f"unknown quirks mode {value!r} (choose one of {choices})") from None


# What the main loop acts on: a request to execute (Frame), an ERROR code to report (int), or
# the verbatim bytes of a SYNC/ECHO echo (bytes). The callback returns the answer's bytes.
Served = Callable[[Frame | int | bytes], bytes]


class ReferenceReceiver:
    """The reference's receive interrupt, main loop and transmitter, on a virtual clock.

    `feed(data, now, serve)`: `data` arrived, its last byte at `now`, the bytes `byte_time_s`
    apart (never earlier than bytes already fed). Every main-loop pass due by `now` runs;
    `serve(item)` is called for each thing a pass acts on, in order, and returns the answer
    bytes, whose length keeps the transmitter busy. `feed` returns the answer bytes produced.
    Call it with b"" to let time pass.
    """

    def __init__(
        self,
        *,
        byte_time_s: float = DEFAULT_BYTE_TIME_S,
        boot_s: float = BOOT_SILENCE_S,
        pass_s: float = MAIN_LOOP_PASS_S,
        idle_s: float = IDLE_WAKE_S,
    ) -> None:
        self.byte_time_s = byte_time_s
        self.boot_s = boot_s
        self.pass_s = pass_s
        self.idle_s = idle_s
        self._started = False
        self.dropped_frames = 0  # frames received whole or in part that the main loop never ran
        self.reports = 0  # ERROR reports of receive errors sent
        self._reset(0.0)

    def _reset(self, now: float) -> None:
        # The receiver (interrupt side): the shared buffer and state word.
        self._buffer = bytearray(REFERENCE_RX_BUFFER)
        self._pos = 0
        self._position = _IDLE
        self._bits = 0
        self._sum = 0
        # The line and the main loop.
        self._pending: deque[tuple[float, int]] = deque()  # bytes on their way in: (due, byte)
        self._line_in_free = float("-inf")  # when the last byte fed has fully arrived
        self._clock = now  # everything before this has been simulated
        self._deaf_until = now + DEAF_S  # bytes before then are lost, even halfway through a frame
        self._loop_from = now + self.boot_s
        self._next_pass_from = self._loop_from  # the loop may wake from then on...
        self._serviced = now  # ...and has seen every event up to then
        self._dma_done = now
        self._line_out_free = now
        self._sending: deque[tuple[float, int]] = deque()  # answers on the line: (start, size)

    def power_on(self, now: float) -> None:
        """Start (or restart, after a reboot) at `now`: buffers cleared, boot silence again."""
        self._started = True
        self._reset(now)

    def feed(self, data: bytes, now: float, serve: Served) -> bytes:
        if not self._started:
            self.power_on(now)
        count = len(data)
        for index, byte in enumerate(data):
            arrived = now - (count - 1 - index) * self.byte_time_s
            due = max(arrived, self._line_in_free + self.byte_time_s, self._clock)
            self._pending.append((due, byte))
            self._line_in_free = due
        out = bytearray()
        while True:
            wake = self._next_wake(now)
            if wake > now + _TIE_S:
                break
            self._receive_until(wake)
            self._pass(wake, serve, out)
        self._receive_until(now)
        self._clock = max(self._clock, now)
        return bytes(out)

    # -- the receive interrupt -------------------------------------------------------------------

    def _receive_until(self, until: float) -> None:
        while self._pending and self._pending[0][0] <= until + _TIE_S:
            due, byte = self._pending.popleft()
            self._clock = max(self._clock, due)
            if due > self._deaf_until + _TIE_S:
                self._receive(byte)

    def _frame_length(self) -> int:
        buf = self._buffer
        return buf[1] | buf[2] << 8 if buf[0] == FLAG_LONG else buf[1]

    def _store(self, byte: int, position: int) -> None:
        self._sum ^= byte
        self._buffer[self._pos] = byte
        self._pos += 1
        self._position = position

    def _receive(self, byte: int) -> None:
        if self._pos == 0:
            if byte in (FLAG_STANDARD, FLAG_LONG):
                self._sum = 0
                self._store(byte, _WANT_LEN)
            else:
                self._bits |= NOT_SYNCED_BIT
            return
        position = self._position
        if position == _WANT_LEN:
            self._store(byte, _WANT_LEN_HIGH if self._buffer[0] == FLAG_LONG else _WANT_CMD)
            return
        if position == _WANT_LEN_HIGH:
            self._store(byte, _WANT_CMD)
            return
        if position == _IDLE:
            # The main loop cleared the state in the middle of this frame: the byte is lost and
            # the receiver waits for a new flag, so the frame's remaining bytes are stray.
            self._pos = 0
            self.dropped_frames += 1
            return
        length = self._frame_length()
        if position == _WANT_CMD and length + self._pos > REFERENCE_RX_BUFFER:
            self._bits |= TOO_LONG_BIT
            self._pos = 0
            return
        header = 3 if self._buffer[0] == FLAG_LONG else 2
        if self._pos == length + header:  # this is the checksum byte
            if byte != self._sum:
                self._bits |= CHECKSUM_BIT
            if self._bits & FRAME_READY_BIT:
                self.dropped_frames += 1  # the one not yet run is replaced
            self._bits |= FRAME_READY_BIT
            self._pos = 0
            return
        self._store(byte, _WANT_BODY)

    # -- the main loop ---------------------------------------------------------------------------

    def _next_wake(self, horizon: float) -> float:
        """When the main loop next looks at the state word (`horizon`: how far time goes now)."""
        start = self._next_pass_from
        if start <= self._loop_from:
            return self._loop_from
        event = self._pending[0][0] if self._pending else float("inf")
        sent = self._next_byte_out(self._serviced)
        if sent is not None:
            event = min(event, sent)
        idle_wake = start + self.idle_s
        limit = min(event, horizon)
        if not self._bits and limit > idle_wake:
            # Idle passes with nothing raised do nothing but keep the loop's phase: skip to the
            # last of them before the next event (or the horizon) instead of running each.
            period = self.idle_s + self.pass_s
            idle_wake += int((limit - idle_wake) / period) * period
        return max(min(idle_wake, event), start)

    def _next_byte_out(self, after: float) -> float | None:
        """When the next answer byte after `after` leaves (the harness wakes the loop then)."""
        sending = self._sending
        while sending:
            start, size = sending[0]
            if start + size * self.byte_time_s > after + _TIE_S:
                index = max(0, int((after - start) / self.byte_time_s + _TIE_S))
                while start + (index + 1) * self.byte_time_s <= after + _TIE_S:
                    index += 1
                return start + (index + 1) * self.byte_time_s
            sending.popleft()
        return None

    def _pass(self, now: float, serve: Served, out: bytearray) -> None:
        self._clock = max(self._clock, now)
        bits = self._bits
        header = 3 if self._buffer[0] == FLAG_LONG else 2
        echo_size = 0
        answer = b""
        if bits & _ERROR_BITS:
            if bits & FRAME_READY_BIT:
                self.dropped_frames += 1
            self.reports += 1
            answer = serve(bits & 0xFFFF)
        elif bits & FRAME_READY_BIT:
            if self._buffer[header] in (Cmd.SYNC, Cmd.ECHO):
                echo_size = self._frame_length() + header
                saved_sum = self._sum
            else:
                answer = serve(self._request(header))  # the handler reads the buffer now
        else:
            self._serviced = now
            self._next_pass_from = now + self.pass_s
            return
        # Sending clears the whole state word first, then waits for the transmitter.
        self._bits = 0
        self._position = _IDLE
        resume = max(now, self._dma_done)
        self._receive_until(resume)
        if echo_size:
            # SYNC/ECHO goes back from the buffer as it is once the transmitter is free (bytes
            # received meanwhile are in it), with the checksum the receiver had at the poll.
            answer = serve(bytes(self._buffer[:echo_size]) + bytes([saved_sum]))
        if answer:
            self._transmit(answer, resume, out)
        self._serviced = resume
        self._next_pass_from = resume + self.pass_s

    def _transmit(self, answer: bytes, ready: float, out: bytearray) -> None:
        start = max(ready, self._line_out_free)
        size = len(answer)
        self._sending.append((start, size))
        self._line_out_free = start + size * self.byte_time_s
        self._dma_done = max(ready, start + max(size - _DMA_TAIL_BYTES, 0) * self.byte_time_s)
        out += answer

    def _request(self, header: int) -> Frame:
        """The request as the reference's handlers see it: the CMD byte, then as many payload
        bytes as the request's layout has, read at fixed places whatever the frame's LEN."""
        long = self._buffer[0] == FLAG_LONG
        body = bytes(self._buffer[header:])
        cmd = body[0]
        sent = (self._frame_length() - 1) & 0xFFFF  # LEN = 0 reads as 65,535 payload bytes
        limit = min(MAX_LONG_PAYLOAD if long else MAX_STANDARD_PAYLOAD, len(body) - 1)
        if cmd == Cmd.CTRL_BUS:
            for size in (sent, *range(1, MAX_FIXED_REQUEST)):
                if size > limit:
                    continue
                try:
                    decode_request(cmd, body[1 : 1 + size])
                except MessageFormatError:
                    continue  # not this request's length
                except MessageError:
                    break  # unsupported: refused whatever its length
                return Frame(cmd, body[1 : 1 + size], long=long)
        return Frame(cmd, body[1 : 1 + min(sent, limit)], long=long)
