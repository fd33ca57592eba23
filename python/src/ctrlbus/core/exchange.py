# SPDX-License-Identifier: MIT
"""The Core's request in flight: its attempts, deadline, retries and the flushing SYNC.

The Core has one request outstanding at a time (docs/protocol.md §11.6). `Exchange` holds it,
sends it again after a failed attempt, matches the frames that arrive to it, and keeps the
counts of failed and silent attempts in a row from which the session decides that the base is
gone. After a silent attempt it puts a flushing SYNC before the next request and holds that
request until the flush is over. What a failure means for the connection (a disconnect, the
next CONNECT_BASE, the stop) is the session's to decide: the exchange says what happened.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from ctrlbus.constants import LINE_FAULT_LIMIT
from ctrlbus.core.config import CoreConfig
from ctrlbus.core.events import describe_request
from ctrlbus.core.journal import Journal
from ctrlbus.core.stats import LinkStats
from ctrlbus.errors import MessageError
from ctrlbus.frame import Frame
from ctrlbus.messages import (
    AnswerMessage,
    Cmd,
    ErrorAnswer,
    ErrorCode,
    GetBaseConfAdv,
    InvalidAnswer,
    RequestMessage,
    Response,
    Sync,
    decode_answer,
    request_frame,
)

__all__ = [
    "CONFIG_READS",
    "FLUSH_FILLER",
    "TRACKED_PURPOSES",
    "Exchange",
    "Outstanding",
    "Purpose",
    "Reply",
    "Verdict",
]

# §11.1: the flushing SYNC is a long frame of exactly 512 bytes: 4 header bytes, 507 filler, checksum.
FLUSH_FILLER = bytes(507)


class Purpose(enum.Enum):
    """Why the Core sends a request: what its answer (or its failure) leads to."""

    CONNECT = "connect"
    FLUSH = "flush"
    CONFIG_ADV = "config_adv"
    CONFIG = "config"
    SYSTEM_UP = "system_up"
    POLL = "poll"
    CONFIG_LATER = "config_later"  # a configuration read asked again while polling (§11.2)
    NOTICE = "notice"  # CORE_DISCONNECT after a lost connection: one attempt, best effort
    STOP = "stop"  # CORE_DISCONNECT when stopped on purpose


# Requests whose fate is accounted (answered, superseded, abandoned at a disconnect, or lost).
TRACKED_PURPOSES = frozenset(
    {Purpose.CONFIG_ADV, Purpose.CONFIG, Purpose.CONFIG_LATER, Purpose.SYSTEM_UP, Purpose.POLL}
)
# Configuration reads: their answers are the largest (0x21 up to 507 bytes, 0x20 264), so on a
# noisy line they arrive damaged far more often than the rest. A failed attempt in which the base
# was heard counts toward no disconnect limit; each read has its own attempt limit, after which
# the Core falls back or goes on, and asks again while polling (§11.2 [core-config-retry]).
CONFIG_READS = frozenset({Purpose.CONFIG_ADV, Purpose.CONFIG, Purpose.CONFIG_LATER})


@dataclass
class Outstanding:
    """A request in flight and its attempts so far."""

    message: RequestMessage
    frame: bytes
    purpose: Purpose
    max_attempts: int
    attempts: int = 0
    sent_at: float = 0.0
    deadline: float = 0.0
    resend: bool = False  # a failed attempt: send again at the next poll()
    transport_error: str | None = None  # a line-fault ERROR seen; the real answer may still follow
    heard: bool = False  # bytes arrived during this attempt (the base is there)
    damaged: bool = False  # the decoder rejected a frame during this attempt (a damaged answer)
    schedule_name: str | None = None


@dataclass(frozen=True)
class Reply:
    """What a frame settled: the request's `answer`, or (None) why the attempt `failed`."""

    request: Outstanding
    answer: AnswerMessage | None
    failed: str = ""


class Verdict(enum.Enum):
    """What a failed attempt comes to."""

    RESENDING = "resending"  # it goes again at the next poll()
    SUPERSEDED = "superseded"  # a periodic request whose next period is due: that one goes instead
    DISCONNECTED = "disconnected"  # too many failed attempts in a row: the base is gone
    GIVEN_UP = "given_up"  # a request with its own attempt limit has used them all


class Exchange:
    """One request in flight at a time, with its attempts (sans-IO: times are given)."""

    def __init__(self, config: CoreConfig, stats: LinkStats, journal: Journal) -> None:
        self._config = config
        self._stats = stats
        self._log = journal.log
        self._outstanding: Outstanding | None = None
        # §11.6 [core-flush]: after a silent attempt, a flushing SYNC goes before the next request,
        # and the request waits (held) until the flush is over.
        self._flush_pending = False
        self._held: Outstanding | None = None
        self._silent_streak = 0  # silent attempts in a row, whatever the request (any frame resets it)
        self._failed_streak = 0  # failed attempts in a row, whatever the request (an answer resets it)
        self._last_error_logged: dict[str, int] = {}

    @property
    def outstanding(self) -> Outstanding | None:
        """The request in flight (None: nothing is)."""
        return self._outstanding

    # ============================================================================== sending

    def due_time(self, now: float) -> float | None:
        """When the request in flight next needs poll(): `now` to resend, else its deadline;
        None when nothing is in flight."""
        outstanding = self._outstanding
        if outstanding is None:
            return None
        return now if outstanding.resend else outstanding.deadline

    def resume(self, now: float, *, may_flush: bool) -> bytes | None:
        """The frame the exchange itself wants sent now: a pending flush (if `may_flush`, while a
        base is connected) or a resend. None if it has none; it may still be waiting for an answer
        (`outstanding`), in which case nothing new may be started."""
        outstanding = self._outstanding
        if self._flush_pending and (outstanding is None or outstanding.resend) and may_flush:
            # A reference base has no inter-byte timeout: a false frame start in noise may be
            # swallowing every request; 512 bytes complete whatever it waits for (§11.6).
            self._flush_pending = False
            self._held = outstanding
            return self._send(self.prepare_flush(), now)
        if outstanding is not None and outstanding.resend:
            return self._send(outstanding, now)
        return None

    def start(
        self,
        message: RequestMessage,
        purpose: Purpose,
        now: float,
        *,
        attempts: int | None = None,
        schedule_name: str | None = None,
        quiet: bool = False,
    ) -> bytes:
        """Make `message` the request in flight and send its first attempt: its frame. It is
        logged unless it is a periodic one (`schedule_name`) or `quiet`."""
        outstanding = self.prepare(message, purpose, attempts=attempts, schedule_name=schedule_name)
        if schedule_name is None and not quiet:
            self._log("core", describe_request(message))
        return self._send(outstanding, now)

    def prepare(
        self,
        message: RequestMessage,
        purpose: Purpose,
        *,
        attempts: int | None = None,
        schedule_name: str | None = None,
    ) -> Outstanding:
        """Make `message` the request in flight, to be sent by the next poll()."""
        long = True if self._config.long_frames or isinstance(message, Sync) else None
        outstanding = Outstanding(
            message=message,
            frame=request_frame(message, long=long),
            purpose=purpose,
            max_attempts=attempts if attempts is not None else 1 + self._config.retries,
            schedule_name=schedule_name,
            resend=True,
        )
        self._outstanding = outstanding
        if purpose in TRACKED_PURPOSES:
            self._stats.tracked_requests += 1
        return outstanding

    def prepare_flush(self) -> Outstanding:
        """Make the flushing SYNC the request in flight (one attempt, never logged)."""
        return self.prepare(Sync(FLUSH_FILLER), Purpose.FLUSH, attempts=1)

    def _send(self, outstanding: Outstanding, now: float) -> bytes:
        if outstanding.attempts:
            self._stats.retries += 1
        outstanding.attempts += 1
        outstanding.resend = False
        outstanding.transport_error = None
        outstanding.heard = outstanding.damaged = False
        outstanding.sent_at = now
        wire_time = len(outstanding.frame) * self._config.byte_time_s
        outstanding.deadline = now + wire_time + self._config.request_timeout_s
        self._stats.count_request(now)
        return outstanding.frame

    # ================================================================= endings of an attempt

    def expired(self, now: float) -> Outstanding | None:
        """The request in flight if its attempt's deadline has passed at `now` (it stays in
        flight: the caller ends the flush, fails the attempt, or drops it)."""
        outstanding = self._outstanding
        if outstanding is None or outstanding.resend or now <= outstanding.deadline:
            return None
        return outstanding

    def drop(self) -> None:
        """Nothing is in flight any more (the request needs no answer now)."""
        self._outstanding = None

    def end_flush(self, *, resume_held: bool) -> None:
        """The flushing SYNC's window is over: the held request goes on if `resume_held`."""
        self._outstanding = None
        if resume_held:
            self._outstanding, self._held = self._held, None

    def fail(self, outstanding: Outstanding, reason: str, *, silent: bool, period_due: bool) -> Verdict:
        """An attempt failed: `silent` (a timeout) or answered by a line fault, INVALID or a
        malformed answer (§11.6 [core-resend]). A request that matters is resent until answered; a
        periodic one whose next period has come (`period_due`) is superseded by it instead; the
        base counts as disconnected after `1 + retries` silent attempts in a row, or
        `line_fault_attempts` failed attempts in a row without an answer. CONNECT_BASE,
        CORE_DISCONNECT and the flush have their own attempt limits (§11.1, §11.7), and so have
        the configuration reads (CONFIG_READS), whose failed attempts count toward a disconnect
        only when silent (§11.2 [core-config-retry])."""
        config = self._config
        if silent:
            self._silent_streak += 1
            self._flush_pending = config.flush_sync
        if outstanding.purpose in CONFIG_READS and not silent:
            # The base was heard (a damaged answer, a line fault): no step towards a disconnect.
            return self._retry_or_give_up(outstanding, reason)
        if outstanding.purpose in TRACKED_PURPOSES and outstanding.purpose not in CONFIG_READS:
            self._failed_streak += 1
            too_silent = self._silent_streak >= 1 + config.retries
            too_faulty = self._failed_streak >= config.line_fault_attempts
            if not too_silent and not too_faulty:
                if period_due:
                    self._outstanding = None
                    self._stats.superseded += 1  # its next period is due: the fresh one goes instead
                    return Verdict.SUPERSEDED
                outstanding.resend = True
                self._log("core", f"{reason} (attempt {outstanding.attempts}): sending again")
                return Verdict.RESENDING
            self._outstanding = None
            self._stats.disconnects += 1
            self._stats.abandoned_at_disconnect += 1
            what = (
                f"{self._silent_streak} attempts in a row unanswered"
                if too_silent
                else (f"{self._failed_streak} attempts in a row failed (line faults, no answer)")
            )
            self._log("core", f"{reason}: {what}, base disconnected")
            return Verdict.DISCONNECTED
        if outstanding.purpose in CONFIG_READS:
            self._failed_streak += 1  # silent: the base may be gone
            if self._silent_streak >= 1 + config.retries or self._failed_streak >= config.line_fault_attempts:
                self._outstanding = None
                self._stats.disconnects += 1
                self._stats.abandoned_at_disconnect += 1
                self._log(
                    "core", f"{reason}: {self._silent_streak} attempts in a row unanswered, base disconnected"
                )
                return Verdict.DISCONNECTED
        return self._retry_or_give_up(outstanding, reason)

    def _retry_or_give_up(self, outstanding: Outstanding, reason: str) -> Verdict:
        """Send again while the request has attempts left, else give it up."""
        if outstanding.attempts < outstanding.max_attempts:
            outstanding.resend = True
            attempt = f"attempt {outstanding.attempts}/{outstanding.max_attempts}"
            self._log("core", f"{reason} ({attempt}): sending again")
            return Verdict.RESENDING
        self._outstanding = None
        return Verdict.GIVEN_UP

    def abandon(self) -> None:
        """The connection ends with a request in flight (the link failed, or the Core stops)."""
        for outstanding in (self._outstanding, self._held):
            if outstanding is not None and outstanding.purpose in TRACKED_PURPOSES:
                self._stats.abandoned_at_disconnect += 1
        self._outstanding = self._held = None
        self._flush_pending = False

    def forget_streaks(self) -> None:
        """A new connection starts with no failed attempts behind it."""
        self._silent_streak = self._failed_streak = 0

    # =============================================================================== frames

    def on_bytes(self, now: float, *, rejected: bool) -> None:
        """Bytes arrived at `now`; `rejected`: the decoder threw a frame away among them. For a
        configuration read a rejected frame is most likely its damaged answer (the base answers
        once): the attempt then ends after the grace instead of the full timeout."""
        outstanding = self._outstanding
        if outstanding is None or outstanding.resend:
            return
        outstanding.heard = True
        if rejected and outstanding.purpose in CONFIG_READS:
            outstanding.damaged = True
            outstanding.deadline = min(outstanding.deadline, now + self._config.transport_error_grace_s)

    def on_frame(self, frame: Frame, now: float, *, connecting: bool) -> Reply | None:
        """A frame from the base at `now` (`connecting`: in the CONNECT_BASE loop). Returns what
        it settled for the request in flight, or None if it settled nothing yet (a stray frame,
        the base's word on a flush, a line fault or NOT_SYNCED after which the answer may come)."""
        outstanding = self._outstanding
        stats = self._stats
        if outstanding is None or outstanding.resend:
            stats.stray_answers += 1
            return None
        if outstanding.purpose is Purpose.FLUSH:
            stats.flushed_frames += 1
            self._silent_streak = 0  # the base is there: it says something about the flush
            if not connecting:
                if frame.cmd == Response.SYNC and frame.raw == outstanding.frame:
                    self.end_flush(resume_held=True)  # the base copied the flush back: nothing more is coming
                else:
                    # The base answers in stream order: what it says about the flush (or the
                    # frame the flush completed) comes now, the rest follows within the grace.
                    grace = now + self._config.transport_error_grace_s
                    outstanding.deadline = min(outstanding.deadline, grace)
            return None
        request = outstanding.message
        if request.CMD == Cmd.CTRL_BUS and frame.cmd in (Response.SYNC, Response.ECHO):
            stats.stray_answers += 1  # a copy of an earlier SYNC or ECHO, not this answer
            return None
        self._silent_streak = 0  # whatever it is, the base is there
        try:
            answer = decode_answer(request, frame.cmd, frame.payload)
        except MessageError as exc:
            stats.malformed_answers += 1
            stats.count_answer(now - outstanding.sent_at)
            self._log("base", f"malformed answer to {request.NAME}: {exc}")
            return Reply(outstanding, None, f"malformed answer to {request.NAME}")
        if isinstance(answer, ErrorAnswer):
            code = answer.error_code
            if code == ErrorCode.UNSUPPORTED and isinstance(request, GetBaseConfAdv):
                stats.unsupported_conf_adv += 1  # the base has no blob: an expected fallback
            else:
                stats.errors_by_code[code] += 1
            if code < LINE_FAULT_LIMIT:
                stats.count_line_fault(code)
            if code == ErrorCode.NOT_SYNCED:
                stats.not_synced_reports += 1  # about stray bytes; the answer may follow
                return None
            if code < LINE_FAULT_LIMIT:
                # A line fault (§11.6 [line-faults]): the request, or a false frame start in noise
                # just before it, did not arrive intact. The base answers in stream order, so an
                # intact request's answer would follow at once: wait a moment for it, then send
                # again (resending at once would put every later answer one step out of order).
                self._log_error(request, code)
                outstanding.transport_error = f"ERROR 0x{code:04X} to {request.NAME}"
                grace = now + self._config.transport_error_grace_s
                outstanding.deadline = min(outstanding.deadline, grace)
                return None
            stats.count_answer(now - outstanding.sent_at)
        elif isinstance(answer, InvalidAnswer):
            stats.invalid_answers += 1
            stats.count_answer(now - outstanding.sent_at)
            self._log("base", f"INVALID to {request.NAME}")
            return Reply(outstanding, None, f"INVALID to {request.NAME}")
        else:
            stats.count_answer(now - outstanding.sent_at)
        self._outstanding = None
        if outstanding.purpose in TRACKED_PURPOSES:
            stats.answered_requests += 1
            self._failed_streak = 0
        if isinstance(answer, ErrorAnswer):
            self._log_error(request, answer.error_code)
        else:
            self._last_error_logged.pop(request.NAME, None)
        return Reply(outstanding, answer)

    def _log_error(self, request: RequestMessage, code: int) -> None:
        """Log an ERROR answer, but not the same one to the same request over and over."""
        if self._last_error_logged.get(request.NAME) != code:
            self._last_error_logged[request.NAME] = code
            self._log("base", f"ERROR 0x{code:04X} to {request.NAME}")
