# SPDX-License-Identifier: MIT
"""What a check is, what it reports, and the loop that runs a list of them against one base.

A check is a function of a `CheckContext`. It talks to the base through the context (which wraps
the `Prober`), records findings (`fail`, `warn`, `note`) and may end early (`abort`, `skip`).
Its status is the worst finding: fail over warn over pass. The runner gives every check a fresh
transcript, which becomes the check's evidence, and skips the remaining checks with a reason
once the link is dead (no valid frame ever came back, or the base stopped answering).
"""

from __future__ import annotations

import contextlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime, timezone
from typing import NoReturn, TypeVar

from ctrlbus.checker.probe import (
    FLUSHING_SYNC,
    HOST_INTERBYTE_TIMEOUT_S,
    Evidence,
    Exchange,
    NoAnswer,
    Prober,
    describe_frame,
)
from ctrlbus.compat import StrEnum
from ctrlbus.constants import Profile
from ctrlbus.errors import LinkError, MessageError, ProtocolTimeout, UsageError
from ctrlbus.frame import Frame
from ctrlbus.messages import (
    AnswerMessage,
    ConnectBase,
    ErrorAnswer,
    RequestMessage,
    Response,
    SetBaseMotor,
    decode_answer,
    request_frame,
)
from ctrlbus.messages import fields as message_fields

__all__ = [
    "DEAD_AFTER_SILENT_REQUESTS",
    "DEFAULT_LATENCY_COUNT",
    "DEFAULT_TIMEOUT_S",
    "PROFILES",
    "SECOND_ANSWER_WAIT_S",
    "Check",
    "CheckAborted",
    "CheckContext",
    "CheckOptions",
    "CheckResult",
    "Finding",
    "Report",
    "Rule",
    "Status",
    "describe_request",
    "error_code_of",
    "run_checks",
]

DEFAULT_TIMEOUT_S = 0.2  # the Core's request timeout, docs/protocol.md §11.6 [core-timeouts]
DEFAULT_LATENCY_COUNT = 100
MIN_ANSWER_LIMIT_S = 1.0  # how long the checker waits for any answer (at least; 5 x the timeout)
SECOND_ANSWER_WAIT_S = 0.05  # after an answer, how long to listen for a second one
DEAD_AFTER_SILENT_REQUESTS = 3  # requests in a row with no byte back: the base stopped answering
PROFILES = ("any", *(profile.value for profile in Profile))  # "any": every variant a master accepts


class Status(StrEnum):
    PASS = "pass"
    WARN = "warn"
    FAIL = "fail"
    SKIP = "skip"


_SEVERITY = {Status.PASS: 0, Status.SKIP: 0, Status.WARN: 1, Status.FAIL: 2}


@dataclass(frozen=True)
class Rule:
    """A rule of docs/protocol.md: its section number and its stable anchor id."""

    section: str  # "§3.2"
    anchor: str  # "frame-checksum"

    def __str__(self) -> str:
        return f"{self.section} [{self.anchor}]"


@dataclass(frozen=True)
class Check:
    """One numbered check. `slow`: it needs real time (seconds), not just round trips. `timed`:
    its verdict depends on how fast the base answers (a heavily loaded host can turn a pass into
    a warning)."""

    number: int
    name: str
    title: str
    rules: tuple[Rule, ...]
    run: Callable[[CheckContext], None]
    slow: bool = False
    timed: bool = False


@dataclass(frozen=True)
class Finding:
    status: Status  # PASS for a plain remark
    text: str


@dataclass(frozen=True)
class CheckOptions:
    """How to run the checks.

    - `timeout_s`: the request timeout answers are judged against (the Core's, §11.6).
    - `answer_limit_s`: how long to wait for any one answer before giving up on it (default
      max(1 s, 5 x timeout)); longer than the timeout so that a slow base is measured, not lost.
    - `profile`: "any" accepts every variant a master must accept; "reference" / "sdk2020" also
      require the answer sizes of that base profile (§6.2).
    - `latency_count`: requests timed by the latency check.
    - `only`: check numbers to run (None: all).
    - `interbyte_timeout_s`: the inter-byte timeout of the checker's own decoder, which reads the
      answers (default 100 ms, a host program's, docs/protocol.md §7.6); longer for a base in an
      emulator, whose answers leave a byte at a time and pause whenever the host is busy.
    """

    timeout_s: float = DEFAULT_TIMEOUT_S
    answer_limit_s: float | None = None
    profile: str = "any"
    latency_count: int = DEFAULT_LATENCY_COUNT
    only: frozenset[int] | None = None
    interbyte_timeout_s: float = HOST_INTERBYTE_TIMEOUT_S

    def __post_init__(self) -> None:
        if not (0 < self.timeout_s <= 60):
            raise UsageError(f"timeout must be more than 0 and at most 60 s, got {self.timeout_s:g} s")
        if self.answer_limit_s is not None and not (0 < self.answer_limit_s <= 600):
            raise UsageError(f"answer limit must be more than 0 and at most 600 s, got {self.answer_limit_s}")
        if self.profile not in PROFILES:
            raise UsageError(f"unknown profile {self.profile!r} (choose {', '.join(PROFILES)})")
        if not (1 <= self.latency_count <= 100_000):
            raise UsageError(f"latency count must be 1..100000, got {self.latency_count}")
        if not (0 < self.interbyte_timeout_s <= 60):
            raise UsageError(
                f"inter-byte timeout must be more than 0 and at most 60 s, got {self.interbyte_timeout_s:g} s"
            )

    @property
    def wait_s(self) -> float:
        if self.answer_limit_s is not None:
            return self.answer_limit_s
        return max(MIN_ANSWER_LIMIT_S, 5 * self.timeout_s)


class CheckAborted(Exception):
    """The check cannot go on; its findings so far say why."""


class CheckSkipped(Exception):
    """The check does not apply (the reason is the message)."""


_Answer = TypeVar("_Answer", bound=AnswerMessage)


class CheckContext:
    """What a check works with: the prober, the options, and its findings."""

    def __init__(self, prober: Prober, options: CheckOptions) -> None:
        self.prober = prober
        self.options = options
        self.findings: list[Finding] = []
        self.summary: str | None = None

    # -- findings -----------------------------------------------------------------------------

    def fail(self, text: str) -> None:
        self.findings.append(Finding(Status.FAIL, text))
        self.prober.note(f"FAIL: {text}")

    def warn(self, text: str) -> None:
        self.findings.append(Finding(Status.WARN, text))
        self.prober.note(f"WARN: {text}")

    def note(self, text: str) -> None:
        self.findings.append(Finding(Status.PASS, text))
        self.prober.note(text)

    def abort(self, text: str) -> NoReturn:
        self.fail(text)
        raise CheckAborted(text)

    def skip(self, reason: str) -> NoReturn:
        raise CheckSkipped(reason)

    @property
    def failed(self) -> bool:
        return any(finding.status is Status.FAIL for finding in self.findings)

    def part(self, run: Callable[[], None]) -> None:
        """Run one independent part of a check: if it aborts or gets no answer, that is recorded
        and the check goes on with its next part (unless the base has stopped answering)."""
        try:
            run()
        except CheckAborted:
            pass
        except NoAnswer as exc:
            self.fail(str(exc))
            if self.prober.silent_streak >= DEAD_AFTER_SILENT_REQUESTS:
                raise CheckAborted(str(exc)) from None

    # -- talking to the base ------------------------------------------------------------------

    @property
    def now(self) -> float:
        return self.prober.now()

    def exchange(self, data: bytes, what: str, *, limit_s: float | None = None) -> Exchange:
        """Send raw bytes and wait for the first frame back (NoAnswer if none: the check fails)."""
        return self.prober.request(data, what, limit_s=limit_s)

    def ask(
        self, request: RequestMessage, *, long: bool = False, what: str | None = None
    ) -> tuple[AnswerMessage, Frame]:
        """Send a well-formed request and read the answer as an answer to it; a frame that does
        not decode as such an answer fails the check."""
        label = what or describe_request(request)
        frame = self.exchange(request_frame(request, long=long), label).frame
        assert frame is not None
        try:
            return decode_answer(request, frame.cmd, frame.payload), frame
        except MessageError as exc:
            self.abort(
                f"{label}: unreadable answer (CMD 0x{frame.cmd:02X}, {len(frame.payload)} bytes): {exc}"
            )

    def expect_ok(
        self,
        request: RequestMessage,
        answer_type: type[_Answer],
        *,
        long: bool = False,
        what: str | None = None,
    ) -> tuple[_Answer, Frame]:
        """`ask`, and fail the check unless the answer is OK."""
        label = what or describe_request(request)
        answer, frame = self.ask(request, long=long, what=label)
        if isinstance(answer, ErrorAnswer):
            self.abort(f"{label} answered ERROR 0x{answer.error_code:04X}, expected OK")
        if not isinstance(answer, answer_type):
            self.abort(f"{label} answered {answer.NAME}, expected OK")
        return answer, frame

    def no_extra_answers(self, quiet_s: float = SECOND_ANSWER_WAIT_S, *, stray_bytes: bool = False) -> None:
        """Fail if a frame came back during this check that answered none of its requests (a
        second answer), after listening `quiet_s` more (§8.4 [base-one-answer]). Bytes outside
        frames count too with `stray_bytes` (check 1 judges them; the others only note them)."""
        self.prober.drain(quiet_s)
        extra = [r for r in self.prober.unsolicited if stray_bytes or isinstance(r.item, Frame)]
        if extra:
            shown = ", ".join(
                describe_frame(r.item) if isinstance(r.item, Frame) else str(r.item) for r in extra[:8]
            )
            what = "answer(s) or stray bytes" if stray_bytes else "answer(s)"
            self.fail(f"{len(extra)} {what} beyond one answer per request: {shown} (§8.4)")

    def stop_wheels(self) -> None:
        """Best effort: command zero wheel speed (used when leaving a check that moved them)."""
        with contextlib.suppress(LinkError):
            self.prober.exchange(request_frame(SetBaseMotor((0, 0, 0, 0))), "SET_BASE_MOTOR 0 0 (stop)")


def describe_request(request: RequestMessage) -> str:
    """A request's name and arguments for transcripts: "SET_BASE_MOTOR [100, -100, 0, 0]"."""
    values = message_fields(request)
    if not values:
        return request.NAME
    shown = ", ".join(
        f"{key}=0x{value:08X}" if key == "error_code" else f"{key}={value}" for key, value in values.items()
    )
    return f"{request.NAME} {shown}"


def error_code_of(frame: Frame) -> int | None:
    """The code of an ERROR answer with a 2-byte payload; None for anything else."""
    if frame.cmd == Response.ERROR and len(frame.payload) == 2:
        return int.from_bytes(frame.payload, "little")
    return None


@dataclass
class CheckResult:
    check: Check
    status: Status
    message: str
    findings: list[Finding] = field(default_factory=list)
    evidence: list[Evidence] = field(default_factory=list)
    duration_s: float = 0.0


@dataclass
class Report:
    port: str
    options: CheckOptions
    started: str
    results: list[CheckResult] = field(default_factory=list)
    preamble: list[Evidence] = field(default_factory=list)
    duration_s: float = 0.0

    @property
    def failed(self) -> bool:
        return any(result.status is Status.FAIL for result in self.results)

    def counts(self) -> dict[Status, int]:
        counts = dict.fromkeys(Status, 0)
        for result in self.results:
            counts[result.status] += 1
        return counts


# A reference base is silent for about 1.9 s after power-on (reference §4): keep asking this long.
HELLO_BOOT_S = 2.5


def _result_of(
    check: Check, context: CheckContext, evidence: list[Evidence], duration_s: float
) -> CheckResult:
    findings = context.findings
    status = max((finding.status for finding in findings), key=_SEVERITY.__getitem__, default=Status.PASS)
    chosen = next((f.text for f in findings if f.status is status and status is not Status.PASS), None)
    message = chosen or context.summary or "ok"
    return CheckResult(check, status, message, list(findings), evidence, duration_s)


def _hello(prober: Prober) -> None:
    """Make sure something answers before any check runs; ProtocolTimeout if nothing does.

    CONNECT_BASE attempts, with the Core's flushing SYNC between them (a reference base may be
    stuck on a partial frame left by whoever used the port before), for at least two attempts and
    HELLO_BOOT_S: a reference base just powered on says nothing for about 1.9 s (reference §4).
    """
    connect = request_frame(ConnectBase())
    began = prober.now()
    attempt = 0
    while attempt < 2 or prober.now() - began < HELLO_BOOT_S:
        attempt += 1
        exchange = prober.exchange(connect, f"CONNECT_BASE (is a base there? attempt {attempt})")
        if exchange.frame is not None or prober.bytes_received:
            prober.drain(0.05)
            return
        prober.send(FLUSHING_SYNC, "flushing SYNC (512 bytes), §11.1")
        prober.wait(0.1)
        if prober.bytes_received:  # a booting base answered the last frame it heard: the SYNC
            prober.drain(0.05)
            return
    limit_ms = prober.answer_limit_s * 1000
    raise ProtocolTimeout(
        f"no answer from {prober.link.name}: not one byte came back to CONNECT_BASE "
        f"({attempt} attempts, {limit_ms:.0f} ms each, over {prober.now() - began:.1f} s); "
        "is the base running on this port, at this baud rate?"
    )


def run_checks(
    prober: Prober,
    checks: Sequence[Check],
    options: CheckOptions,
    *,
    on_result: Callable[[CheckResult], None] | None = None,
) -> Report:
    """Run `checks` (those in options.only, if given) in order against the base behind `prober`.

    ProtocolTimeout if the base never answers at all; LinkError if the link fails before any
    check ran. Once the link is dead, the remaining checks are skipped with the reason.
    """
    started = prober.now()
    report = Report(
        port=prober.link.name,
        options=options,
        started=datetime.now(timezone.utc).isoformat(timespec="seconds"),
    )
    prober.start_transcript()
    _hello(prober)
    report.preamble = prober.transcript
    dead: str | None = None
    for check in checks:
        if options.only is not None and check.number not in options.only:
            continue
        if dead is not None:
            result = CheckResult(check, Status.SKIP, f"not run: {dead}")
        else:
            result, dead = _run_one(check, prober, options)
        report.results.append(result)
        if on_result is not None:
            on_result(result)
    report.duration_s = prober.now() - started
    return report


def _run_one(check: Check, prober: Prober, options: CheckOptions) -> tuple[CheckResult, str | None]:
    prober.start_transcript()
    context = CheckContext(prober, options)
    began = prober.now()
    dead: str | None = None
    skipped: str | None = None
    try:
        check.run(context)
    except CheckAborted:
        pass
    except CheckSkipped as exc:
        skipped = str(exc)
    except NoAnswer as exc:
        context.fail(str(exc))
    except LinkError as exc:
        context.fail(f"the link failed: {exc}")
        dead = f"the link failed during check {check.number} ({exc})"
    duration = prober.now() - began
    evidence = prober.transcript
    if skipped is not None:
        result = CheckResult(check, Status.SKIP, skipped, list(context.findings), evidence, duration)
    else:
        result = _result_of(check, context, evidence, duration)
    if dead is None and prober.frames_received == 0:
        dead = f"no valid frame ever came back (up to check {check.number})"
    if dead is None and prober.silent_streak >= DEAD_AFTER_SILENT_REQUESTS:
        dead = f"the base stopped answering during check {check.number} ({check.name})"
    return result, dead
