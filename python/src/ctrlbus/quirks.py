# SPDX-License-Identifier: MIT
"""A model of the reference base firmware's receiver, for the simulated base's quirks mode.

docs/simulator.md ("Reference quirks") is the manual. The reference (base_ref v4, firmware 0.90)
receives bytes in an interrupt and acts on them in a busy main loop; what a Core sees of that is
reproduced here, sans-IO (bytes and time in, the items the main loop acts on out):

- no inter-byte timeout: a frame in progress waits for its last byte for ever;
- a byte outside a frame that is not 0x10 or 0x50 raises the "not synchronised" bit (0x10), a
  long LEN that does not fit the 512-byte receive buffer raises "too long" (0x20) and resets the
  receiver, a checksum mismatch raises "checksum" (0x40) together with "a frame was ready" (0x80);
- each main-loop pass reports every raised bit at once as one ERROR code (0x0010, 0x0030, 0x00C0,
  0x00D0, ...) and clears them; the main loop is busy while it sends an answer, so a burst of
  garbage gives several reports;
- a frame that completes while an error is raised and not yet reported, or while a report is being
  sent, is dropped: the next report carries 0x80 (and 0x10) instead, e.g. 0x0090, and the
  request is never answered;
- one 512-byte buffer holds the CMD and payload of the last frame, and the handlers read their
  fields at fixed places in it: lengths are never checked (a short request is completed with the
  previous frame's bytes, a long one is cut), and LEN = 0 (`10 00 10`) re-runs whatever the
  previous frame left there;
- for `boot_s` after power-on the main loop does not run (the reference beeps); frames received
  meanwhile overwrite each other and only the last complete one is acted on when the loop starts.

This is a model built from what was observed (reference §2-§4), not the vendor's code: the exact
number of 0x0010 reports for a given burst depends on timing the model only approximates.
"""

from __future__ import annotations

from collections.abc import Callable

from ctrlbus.compat import StrEnum
from ctrlbus.constants import Profile
from ctrlbus.errors import MessageError, MessageFormatError, UsageError
from ctrlbus.frame import FLAG_LONG, FLAG_STANDARD, Frame, checksum
from ctrlbus.messages import Cmd, decode_request

__all__ = [
    "BOOT_SILENCE_S",
    "CHECKSUM_BIT",
    "FRAME_READY_BIT",
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
BOOT_SILENCE_S = 1.9  # power-on beeps before the main loop runs (reference §4)
STARTUP_BATTERY_S = 3.0  # 0 % and a low-battery error until the first battery reading
DEFAULT_BYTE_TIME_S = 10 / 115200
MAX_FIXED_REQUEST = 24  # longer than any control-bus request with a fixed layout (SET_BASE_MOTOR: 17)


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


Served = Callable[[Frame | int], bytes]


class ReferenceReceiver:
    """The reference's interrupt-driven receiver and the main loop that reports on it.

    `feed(data, now, serve)`: `data` arrived, its last byte at `now`, the bytes `byte_time_s`
    apart. `serve(item)` is called for each thing the main loop acts on, in order: a Frame to
    execute, or an int ERROR code to report; it returns the answer bytes, whose length keeps the
    loop busy. `feed` returns every answer byte produced. Call it with b"" to let time pass.
    """

    def __init__(self, *, byte_time_s: float = DEFAULT_BYTE_TIME_S, boot_s: float = BOOT_SILENCE_S) -> None:
        self.byte_time_s = byte_time_s
        self.boot_s = boot_s
        self._loop_from: float | None = None  # when the main loop starts (power-on + boot_s)
        self._booted = False
        self._buf = bytearray()
        self._bits = 0
        self._work_since = 0.0  # when the pending bits or frame appeared
        self._ready: Frame | None = None
        self._body = bytearray(REFERENCE_RX_BUFFER)  # CMD and payload of the last frame
        self._body_len = 0
        self._busy_until = 0.0  # the main loop is sending until then
        self._reporting = False  # what it sends is an error report
        self._last_time = 0.0
        self.dropped_frames = 0  # frames that completed behind a pending report
        self.reports = 0

    def power_on(self, now: float) -> None:
        """Start (or restart, after a reboot) at `now`: buffers cleared, boot silence again."""
        self._loop_from = now + self.boot_s
        self._booted = False
        self._buf.clear()
        self._bits = 0
        self._ready = None
        self._busy_until = self._last_time = now

    def feed(self, data: bytes, now: float, serve: Served) -> bytes:
        if self._loop_from is None:
            self.power_on(now)
        out = bytearray()
        count = len(data)
        for index, byte in enumerate(data):
            at = max(now - (count - 1 - index) * self.byte_time_s, self._last_time)
            self._run_loop(at, serve, out, before=True)
            self._receive_byte(byte, at)
            self._last_time = at
        self._last_time = max(self._last_time, now)
        self._run_loop(now, serve, out, before=False)
        return bytes(out)

    # -- the interrupt ---------------------------------------------------------------------------

    def _raise(self, bits: int, at: float) -> None:
        if not self._bits:
            self._work_since = at
        self._bits |= bits

    def _booting(self, at: float) -> bool:
        return self._loop_from is not None and at < self._loop_from

    def _receive_byte(self, byte: int, at: float) -> None:
        buf = self._buf
        if not buf:
            if byte in (FLAG_STANDARD, FLAG_LONG):
                buf.append(byte)
            else:
                self._raise(NOT_SYNCED_BIT, at)
            return
        buf.append(byte)
        header = 2 if buf[0] == FLAG_STANDARD else 3
        if len(buf) < header:
            return
        length = buf[1] if header == 2 else buf[1] | buf[2] << 8
        if header == 3 and len(buf) == 3 and length + 3 > REFERENCE_RX_BUFFER:
            buf.clear()
            self._raise(TOO_LONG_BIT, at)
            return
        if len(buf) < header + length + 1:
            return  # no timeout: a partial frame waits for ever
        raw = bytes(buf)
        buf.clear()
        if checksum(raw[:-1]) != raw[-1]:
            self._raise(CHECKSUM_BIT | FRAME_READY_BIT, at)
            return
        if length:
            self._body[:length] = raw[header:-1]
            self._body_len = length
        # LEN = 0 writes nothing: the previous frame's command and payload run again.
        frame = self._read_request(header == 3)
        if self._booting(at):
            self._ready = frame  # the loop is not running yet: only the last one survives
            return
        if self._bits & _ERROR_BITS or (at < self._busy_until and self._reporting):
            self.dropped_frames += 1
            self._ready = None
            self._raise(NOT_SYNCED_BIT | FRAME_READY_BIT, at)
            return
        self._ready = frame
        if not self._bits:
            self._work_since = at
        self._bits |= FRAME_READY_BIT

    # -- the main loop ---------------------------------------------------------------------------

    def _run_loop(self, until: float, serve: Served, out: bytearray, *, before: bool) -> None:
        """Run the main-loop passes that happen before `until` (or at it, if not `before`)."""
        loop_from = self._loop_from if self._loop_from is not None else 0.0
        if until < loop_from:
            return
        if not self._booted:
            self._booted = True
            self._bits = FRAME_READY_BIT if self._ready is not None else 0
            self._work_since = loop_from
        while self._bits:
            start = max(self._busy_until, self._work_since, loop_from)
            if start > until or (before and start == until):
                return
            bits, frame = self._bits, self._ready
            self._bits = 0
            self._ready = None
            if bits & _ERROR_BITS:
                self.reports += 1
                answer = serve(bits)
                self._reporting = True
            elif frame is not None:
                answer = serve(frame)
                self._reporting = False
            else:
                continue
            out += answer
            self._busy_until = start + len(answer) * self.byte_time_s

    def _read_request(self, long: bool) -> Frame:
        """The request as the reference's handlers see it: the CMD byte, then as many payload
        bytes as the request's layout has, taken from the buffer whatever the frame's length."""
        body = bytes(self._body)
        sent = max(0, self._body_len - 1)
        cmd = body[0]
        if cmd == Cmd.CTRL_BUS:
            for size in (sent, *range(1, MAX_FIXED_REQUEST)):
                try:
                    decode_request(cmd, body[1 : 1 + size])
                except MessageFormatError:
                    continue  # not this request's length
                except MessageError:
                    break  # unsupported: refused whatever its length
                return Frame(cmd, body[1 : 1 + size], long=long)
        return Frame(cmd, body[1 : 1 + sent], long=long)
