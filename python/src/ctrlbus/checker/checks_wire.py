# SPDX-License-Identifier: MIT
"""Checks of the wire rules: frame types, SYNC and ECHO, and what a base answers to faults
(bad checksums, unknown commands, unsupported arguments, wrong lengths, oversize frames,
garbage). Every request here is built byte by byte with ctrlbus.frame.encode, because most of
them are ones a correct master never sends.
"""

from __future__ import annotations

from collections.abc import Callable
from functools import cache, partial

from ctrlbus.base import Base, BaseConfig, BaseStack
from ctrlbus.checker.framework import SECOND_ANSWER_WAIT_S, Check, CheckContext, Rule, error_code_of
from ctrlbus.checker.probe import FLUSHING_SYNC, describe_frame
from ctrlbus.constants import LINE_FAULT_BIT_NAMES, LINE_FAULT_LIMIT
from ctrlbus.core.config import CoreConfig
from ctrlbus.frame import MIN_MAX_FRAME, Frame, StreamDecoder, encode
from ctrlbus.messages import Cmd, ErrorCode, Request, Response

__all__ = [
    "CHECKS",
    "FALSE_FLAG_GARBAGE",
    "GARBAGE_LENGTHS",
    "LONG_GARBAGE",
    "OVERSIZE_PROBE",
    "PLAIN_GARBAGE",
    "STATUS_REQUEST",
    "bad_checksum",
    "ctrl",
]

SMALL_FRAME = 64  # a base refusing a SYNC/ECHO longer than this as oversize has a small buffer
# Garbage without any byte that could start a frame, then a request: one ERROR 0x0010 and the answer.
PLAIN_GARBAGE = bytes.fromhex("AA 55 AA 55 00 FF 13 37")
# Garbage with no 0x10 or 0x50 in it; check 17 sends each length of it in front of a request.
LONG_GARBAGE = PLAIN_GARBAGE + bytes.fromhex("A5 5A 01 02 03 04 FE EF")
GARBAGE_LENGTHS = range(1, len(LONG_GARBAGE) + 1)
# Garbage with false frame starts: 10 FF (a standard frame of 258 bytes that never completes),
# 50 40 1F (a long frame of 8004 bytes: oversize) and 10 03 F8 (a short frame whose checksum
# fails and whose span covers the real request's flag). A §7 decoder recovers the request after
# its inter-byte timeout; the reference, without one, waits for 258 bytes.
FALSE_FLAG_GARBAGE = bytes.fromhex("00 13 37 10 FF 55 AA 50 40 1F C3 10 03 F8 A5 5A")
# A SYNC bigger than the reference's 512-byte receive buffer and ctrlbus's default 1024-byte one.
OVERSIZE_PROBE = encode(Cmd.SYNC, bytes(4096), long=True)
LARGEST_SYNC = encode(Cmd.SYNC, bytes(65534), long=True)  # 65539 bytes: the largest frame there is


def ctrl(payload: bytes, *, long: bool = False) -> bytes:
    """A CTRL_BUS frame with this payload (request code first)."""
    return encode(Cmd.CTRL_BUS, payload, long=long)


def bad_checksum(frame: bytes) -> bytes:
    """The same frame with its checksum byte inverted."""
    return frame[:-1] + bytes((frame[-1] ^ 0xFF,))


# A genuine reference behaviour that a real Core tolerates is a warning that names it (issue 11).
REFERENCE_RESENDS = "the reference firmware does this; a Core resends"


def line_fault_bits(code: int) -> str:
    """'0x0010 not synchronised + 0x0080 a frame was ready' for a line-fault code (below 0x0100)."""
    return (
        " + ".join(f"0x{bit:04X} {name}" for bit, name in LINE_FAULT_BIT_NAMES.items() if code & bit)
        or "no bit"
    )


def is_line_fault(code: int | None, bit: int = 0xF0) -> bool:
    """An ERROR code below 0x0100 (the receiver's state, §11.6 [line-faults]) with `bit` set."""
    return code is not None and code < LINE_FAULT_LIMIT and bool(code & bit)


def _got(frame: Frame) -> str:
    code = error_code_of(frame)
    return describe_frame(frame) if code is None else f"ERROR 0x{code:04X}"


STATUS_REQUEST = ctrl(bytes((Request.GET_BASE_STATUS,)))


# How often a probe answered by a line fault is sent again, as a Core does (§11.6).
LINE_FAULT_RESENDS = 3


def _answer_as_core(ctx: CheckContext, data: bytes, what: str) -> tuple[Frame | None, list[int]]:
    """Sends `data` and takes its answer as a Core does: an ERROR below 0x0100 is a line fault
    (§11.6 [line-faults]), after which the real answer may still come within the Core's grace;
    if it does not, the request is sent again, up to LINE_FAULT_RESENDS times. Returns the last
    answer (None: none came) and the line-fault codes met on the way."""
    faults: list[int] = []
    frame = ctx.prober.exchange(data, what).frame
    code = None if frame is None else error_code_of(frame)
    while code is not None and is_line_fault(code) and len(faults) < LINE_FAULT_RESENDS:
        faults.append(code)
        grace_s = CoreConfig.transport_error_grace_s
        _, frame, _ = _until(ctx, ctx.now, grace_s, lambda got: not is_line_fault(error_code_of(got)))
        if frame is None:
            frame = ctx.prober.exchange(data, f"{what}, sent again as a Core does").frame
        code = None if frame is None else error_code_of(frame)
    return frame, faults


def _faults_text(faults: list[int]) -> str:
    return ", ".join(f"ERROR 0x{code:04X} ({line_fault_bits(code)})" for code in faults)


def _still_answers(ctx: CheckContext, after: str) -> None:
    """A plain GET_BASE_STATUS must still be answered OK, as a Core would see it: a line fault
    first is what the reference does on a busy line (a warning), no OK at all fails."""
    what = f"GET_BASE_STATUS (still answering after {after}?)"
    frame, faults = _answer_as_core(ctx, STATUS_REQUEST, what)
    if frame is None:
        ctx.fail(f"after {after}, a valid GET_BASE_STATUS was not answered")
    elif frame.cmd != Response.OK:
        ctx.fail(f"after {after}, a valid GET_BASE_STATUS was answered {_got(frame)}")
    elif faults:
        ctx.warn(
            f"after {after}, a valid GET_BASE_STATUS was answered {_faults_text(faults)} before OK "
            f"when sent again: {REFERENCE_RESENDS} (§11.6 [line-faults])"
        )


def _extra_answers(ctx: CheckContext) -> list[Frame]:
    return [item.item for item in ctx.prober.collect(SECOND_ANSWER_WAIT_S) if isinstance(item.item, Frame)]


# --- 8 frame flags ---------------------------------------------------------------------------


def check_frame_flags(ctx: CheckContext) -> None:
    cases = [
        (bytes((Request.CONNECT_BASE, 1)), "CONNECT_BASE", True),
        (bytes((Request.GET_BASE_STATUS,)), "GET_BASE_STATUS", False),
        (bytes((Request.GET_BASE_CONF,)), "GET_BASE_CONF", True),
        (bytes((0x7F,)), "request 0x7F (unknown)", True),
    ]

    def compare(payload: bytes, what: str, same_payload: bool) -> None:
        standard = ctx.exchange(ctrl(payload), f"{what} as a standard frame (0x10)").frame
        long = ctx.exchange(ctrl(payload, long=True), f"{what} as a long frame (0x50)").frame
        assert standard is not None and long is not None
        for frame, kind in ((standard, "standard"), (long, "long")):
            if frame.cmd not in (Response.OK, Response.ERROR):
                ctx.abort(f"{what} as a {kind} frame answered {_got(frame)}, neither OK nor ERROR (§4.4)")
        differs = standard.cmd != long.cmd or len(standard.payload) != len(long.payload)
        if same_payload and standard.payload != long.payload:
            differs = True
        if differs:
            ctx.fail(
                f"{what} answered differently by frame type: standard -> {_got(standard)}, "
                f"long -> {_got(long)} (both must be accepted, §3.4)"
            )

    for payload, what, same in cases:
        compare(payload, what, same)  # an unanswered frame type ends the check: it will not change
        if ctx.failed:
            return
    ctx.summary = f"{len(cases)} requests answered alike as standard (0x10) and long (0x50) frames"


# --- 9 SYNC and 10 ECHO ----------------------------------------------------------------------


def _difference(sent: bytes, frame: Frame) -> str:
    raw = frame.raw
    if raw[0] != sent[0]:
        return f"flag 0x{raw[0]:02X} instead of 0x{sent[0]:02X}"
    if frame.cmd != sent[2 if sent[0] == 0x10 else 3]:
        return f"answered {_got(frame)}"
    if len(raw) != len(sent):
        return f"{len(raw)} bytes instead of {len(sent)}"
    first = next(i for i, (a, b) in enumerate(zip(raw, sent, strict=True)) if a != b)
    return f"byte {first} is 0x{raw[first]:02X} instead of 0x{sent[first]:02X}"


# Sent after a SYNC or ECHO that the base refused as oversize: its copy ends the answers to the
# rest of the refused frame.
END_OF_REFUSED = encode(Cmd.ECHO, b"end")  # 7 bytes: fits every buffer that passes the 12-byte copy

Answers = tuple[tuple[int, bytes], ...]  # (CMD, payload) of each answer, in order


@cache
def section_7_answers_to_refused(data: bytes) -> frozenset[Answers]:
    """What a base answers to `data` when its max_frame is smaller than the frame, for each
    max_frame from the least to one byte less than the frame, with either checksum-error code: the
    refusal (0x0020), then the answers to what its decoder finds in the rest of the frame (§7 D4:
    an oversize candidate's span is its length bytes only, so a flag byte further in starts a
    candidate of its own). Modelled with ctrlbus.base, whose requests all answer 0x8000."""
    outcomes = set()
    for max_frame in range(MIN_MAX_FRAME, len(data)):
        for reference_code in (False, True):
            config = BaseConfig(max_frame=max_frame, reference_checksum_code=reference_code)
            answer_bytes = BaseStack(Base(), config).receive(data, 0.0)
            outcomes.add(
                tuple((frame.cmd, frame.payload) for frame in StreamDecoder(timeout=0).feed(answer_bytes))
            )
    return frozenset(outcomes)


def _rest_of_refused(ctx: CheckContext, data: bytes, refusal: Frame, what: str) -> None:
    """After `data` was refused as oversize: the answers to the rest of it, up to the copy of
    END_OF_REFUSED, must be those of a §7 base, or none (a base that skips the refused frame)."""
    prober = ctx.prober
    prober.send(END_OF_REFUSED, "ECHO (its copy ends the answers to the rest of the refused frame)")
    answers: list[tuple[int, bytes]] = [(refusal.cmd, refusal.payload)]
    deadline = prober.now() + prober.answer_limit_s
    while (got := prober.next_item(deadline)) is not None:
        if not isinstance(got.item, Frame):
            continue
        if got.item.raw == END_OF_REFUSED:
            break
        answers.append((got.item.cmd, got.item.payload))
    else:
        ctx.fail(f"after {what}: no copy of the ECHO sent after it ({len(answers) - 1} answer(s) before)")
        return
    if len(answers) == 1:
        return
    if tuple(answers) in section_7_answers_to_refused(data):
        ctx.note(
            f"{what}: {len(answers) - 1} more answer(s) to frame starts inside the refused frame, "
            "as a §7 decoder finds them (§7 D4)"
        )
        return
    shown = ", ".join(f"CMD 0x{cmd:02X} {payload.hex(' ')}" for cmd, payload in answers[1:])
    ctx.fail(
        f"{what}: after refusing it, answered {shown} to the rest of the frame, which is neither "
        "nothing nor what a §7 decoder finds there (§7 D4, §8.4)"
    )


def _verbatim(ctx: CheckContext, data: bytes, what: str) -> None:
    frame = ctx.exchange(data, what).frame
    assert frame is not None
    if frame.raw == data:
        return
    if error_code_of(frame) == ErrorCode.TOO_LONG and len(data) > SMALL_FRAME:
        ctx.warn(
            f"{what}: refused as oversize (0x0020); the base's receive buffer is smaller than this "
            f"{len(data)}-byte frame (the reference's holds 512 bytes, and the Core's flushing SYNC is 512)"
        )
        _rest_of_refused(ctx, data, frame, what)
        return
    ctx.fail(f"{what}: not answered by its verbatim copy ({_difference(data, frame)}, §4.2)")


def _copy_cases(cmd: int, name: str) -> list[tuple[bytes, str]]:
    looks_like_frames = bytes.fromhex("10 50 00 FF 10 02 F8 30")
    pattern = bytes(range(256))
    return [
        (encode(cmd, b""), f"{name} without data, standard"),
        (encode(cmd, looks_like_frames), f"{name} with 8 bytes that look like frame starts"),
        (encode(cmd, pattern[:254]), f"{name} with 254 bytes (the largest standard frame)"),
        (encode(cmd, b"", long=True), f"{name} without data, long"),
        (encode(cmd, pattern + pattern[:44], long=True), f"{name} with 300 bytes, long"),
        (encode(cmd, bytes(507), long=True), f"{name} of 512 bytes, long (the size of the flushing SYNC)"),
    ]


def check_sync(ctx: CheckContext) -> None:
    cases = _copy_cases(Cmd.SYNC, "SYNC")
    for data, what in cases:
        ctx.part(partial(_verbatim, ctx, data, what))
    ctx.no_extra_answers()
    ctx.summary = f"{len(cases)} SYNC frames (0 to 507 filler bytes, both frame types) copied verbatim"


def check_echo(ctx: CheckContext) -> None:
    cases = _copy_cases(Cmd.ECHO, "ECHO")
    cases.append((bytes.fromhex("50 03 00 01 AA 55 AD"), "ECHO of AA 55, long (the reference's example)"))
    for data, what in cases:
        ctx.part(partial(_verbatim, ctx, data, what))
    ctx.no_extra_answers()
    ctx.summary = f"{len(cases)} ECHO frames (0 to 507 data bytes, both frame types) copied verbatim"


# --- 11 checksum error -----------------------------------------------------------------------


def check_checksum_error(ctx: CheckContext) -> None:
    codes: list[str] = []
    for long in (False, True):
        what = f"GET_BASE_STATUS ({'long' if long else 'standard'}) with its checksum inverted"
        frame = ctx.exchange(bad_checksum(ctrl(bytes((Request.GET_BASE_STATUS,)), long=long)), what).frame
        assert frame is not None
        code = error_code_of(frame)
        if code == ErrorCode.CHECKSUM:
            codes.append("0x0040")
        elif is_line_fault(code, ErrorCode.CHECKSUM) and code is not None:
            codes.append(f"0x{code:04X}")
            ctx.warn(
                f"{what}: answered 0x{code:04X} ({line_fault_bits(code)}), not 0x0040: {REFERENCE_RESENDS}; "
                "ctrlbus bases send 0x0040 (§4.5, §11.6 [line-faults])"
            )
        elif frame.cmd == Response.OK:
            ctx.fail(f"{what}: answered OK, so the frame was executed (§8.1 [base-no-exec])")
        else:
            ctx.fail(f"{what}: answered {_got(frame)}, expected ERROR 0x0040 (§8.1)")
    _still_answers(ctx, "the checksum errors")
    ctx.no_extra_answers()
    ctx.summary = f"checksum mismatches answered {' and '.join(codes)}; the next request answered"


# --- 12, 13, 14: unknown and unsupported -----------------------------------------------------


def _expect_unsupported(
    ctx: CheckContext, data: bytes, what: str, *, ok_is: str = "fail", other_is: str = "fail", why: str
) -> None:
    """ERROR 0x8000 expected; an OK or another answer is recorded as `ok_is` / `other_is`."""
    frame = ctx.exchange(data, what).frame
    assert frame is not None
    code = error_code_of(frame)
    if code == ErrorCode.UNSUPPORTED:
        return
    text = f"{what}: answered {_got(frame)}, expected ERROR 0x8000 ({why})"
    level = ok_is if frame.cmd == Response.OK else other_is
    (ctx.fail if level == "fail" else ctx.warn)(text)


def check_unknown_cmd(ctx: CheckContext) -> None:
    cmds = (0x02, 0x0F, 0x42, 0xF7, 0xFF)
    for cmd in cmds:
        ctx.part(
            partial(
                _expect_unsupported,
                ctx,
                encode(cmd, b""),
                f"CMD 0x{cmd:02X}",
                why="an unsupported CMD, §4.1 [top-requests]",
            )
        )
    ctx.no_extra_answers()
    ctx.summary = f"CMD {', '.join(f'0x{c:02X}' for c in cmds)} answered ERROR 0x8000"


def check_unknown_request(ctx: CheckContext) -> None:
    codes = (0x00, 0x11, 0x36, 0x7F, 0xFF)
    for code in codes:
        ctx.part(
            partial(
                _expect_unsupported,
                ctx,
                ctrl(bytes((code,))),
                f"control-bus request 0x{code:02X}",
                why="an unknown request code, §5.16 [ctrl-unknown]",
            )
        )
    ctx.no_extra_answers()
    ctx.summary = f"request codes {', '.join(f'0x{c:02X}' for c in codes)} answered ERROR 0x8000"


def check_unsupported_argument(ctx: CheckContext) -> None:
    cases: list[tuple[bytes, str, str, str, str]] = [
        (
            ctrl(bytes((Request.CONNECT_BASE, 0))),
            "CONNECT_BASE protocol version 0",
            "fail",
            "fail",
            "only version 1 exists, §5.1 [connect-version]",
        ),
        (
            ctrl(bytes((Request.CONNECT_BASE, 2))),
            "CONNECT_BASE protocol version 2",
            "fail",
            "fail",
            "only version 1 exists, §5.1 [connect-version]",
        ),
        (
            ctrl(bytes((Request.GET_CHARGER_DATA, 1))),
            "GET_CHARGER_DATA data type 1",
            "fail",
            "fail",
            "only data type 0 exists, §5.8",
        ),
        (
            ctrl(bytes((Request.GET_AUXILIARY_ANCHOR,))),
            "GET_AUXILIARY_ANCHOR",
            "warn",
            "fail",
            "no answer layout is defined, §5.9 [aux-anchor]",
        ),
        (
            encode(Cmd.BASE_CMD, bytes((0x7E,))),
            "BASE_CMD sub-command 0x7E",
            "warn",
            "warn",
            "only 0x01 and 0x02 exist, §4.3 [base-cmd]",
        ),
    ]
    for data, what, ok_is, other_is, why in cases:
        ctx.part(partial(_expect_unsupported, ctx, data, what, ok_is=ok_is, other_is=other_is, why=why))
    ctx.summary = f"{len(cases)} unsupported argument values answered ERROR 0x8000"


# --- 15 wrong lengths ------------------------------------------------------------------------


def check_length(ctx: CheckContext) -> None:
    # (request, description, stale): with `stale`, the missing byte is the one that decides how
    # the request is answered (request code, sub-command, protocol version), so the reference
    # (which never checks lengths) reads a stale byte from its buffer in its place and may answer
    # anything: any answer is then a warning, not a failure.
    cases = [
        (ctrl(bytes((Request.GET_BASE_STATUS, 0))), "GET_BASE_STATUS with 1 extra byte", False),
        (ctrl(bytes((Request.SET_BASE_MOTOR,)) + bytes(8)), "SET_BASE_MOTOR with 8 of its 16 bytes", False),
        (
            ctrl(bytes((Request.SET_V_AND_GET_DEADRECKON,)) + bytes(4)),
            "SET_V_AND_GET_DEADRECKON, 4 of 12",
            False,
        ),
        (ctrl(bytes((Request.CONNECT_BASE,))), "CONNECT_BASE without its version byte", True),
        (ctrl(bytes((Request.SEND_EVENT,))), "SEND_EVENT without its event byte", False),
        (ctrl(bytes((Request.HEALTH_MGMT, 0x01, 0x00))), "HEALTH_GET_HEALTH with 1 extra byte", False),
        (ctrl(bytes((Request.HEALTH_MGMT,))), "HEALTH_MGMT without a sub-command", True),
        (ctrl(b""), "CTRL_BUS without a request code", True),
    ]
    refused = 0
    try:
        for data, what, stale in cases:
            frame = ctx.exchange(data, what).frame
            assert frame is not None
            code = error_code_of(frame)
            if code == ErrorCode.FORMAT:
                refused += 1
            elif frame.cmd == Response.OK:
                ctx.warn(
                    f"{what}: executed (answered OK) like the reference, which never checks lengths; "
                    "a ctrlbus base answers 0x8001 (§8.2 [length-check])"
                )
            elif stale:
                ctx.warn(
                    f"{what}: answered {_got(frame)}; a ctrlbus base answers 0x8001 (§8.2 "
                    "[base-validate]); the reference reads a stale byte in its place"
                )
            else:
                ctx.fail(f"{what}: answered {_got(frame)}, expected ERROR 0x8001 (§8.2)")
        # LEN = 0 right after a valid GET_BASE_STATUS: the reference runs that request again.
        previous = ctx.exchange(STATUS_REQUEST, "GET_BASE_STATUS (the frame before LEN = 0)").frame
        empty = bytes.fromhex("10 00 10")
        what = "a LEN = 0 frame (10 00 10, no CMD)"
        frame = ctx.prober.exchange(empty, what).frame
        if frame is None:
            ctx.warn(f"{what}: not answered; a ctrlbus base answers 0x8001 (§3.3 [frame-empty])")
        elif error_code_of(frame) == ErrorCode.FORMAT:
            refused += 1
        elif (
            previous is not None
            and frame.cmd == previous.cmd == Response.OK
            and len(frame.payload) == len(previous.payload)
        ):
            ctx.warn(
                f"{what}: ran the previous request (GET_BASE_STATUS) again: the reference firmware does "
                "this (its CMD and payload stay in its buffer); a Core never sends LEN = 0, noise can; "
                "a ctrlbus base answers 0x8001 (§3.3 [frame-empty])"
            )
        else:
            ctx.fail(
                f"{what}: answered {_got(frame)}, expected ERROR 0x8001 or a re-run of the previous "
                "request (§3.3 [frame-empty])"
            )
    finally:
        ctx.stop_wheels()  # in case a short SET_BASE_MOTOR was executed with whatever was buffered
    ctx.summary = f"{refused} of {len(cases) + 1} malformed requests answered ERROR 0x8001"


# --- 16 oversize -----------------------------------------------------------------------------


def _oversize_attempt(ctx: CheckContext, data: bytes) -> str:
    """Send `data`; "refused", "copied" or "other" (recorded as a failure)."""
    what = f"SYNC of {len(data)} bytes"
    exchange = ctx.prober.exchange(data, what)
    frame = exchange.frame
    extra = _extra_answers(ctx)
    if frame is None:
        ctx.fail(f"{what}: no answer at all; a frame larger than the receive buffer is answered ERROR 0x0020")
        return "other"
    code = error_code_of(frame)
    if code != ErrorCode.TOO_LONG and is_line_fault(code, ErrorCode.TOO_LONG) and code is not None:
        ctx.warn(
            f"{what}: answered 0x{code:04X} ({line_fault_bits(code)}), not 0x0020: {REFERENCE_RESENDS} "
            "(§4.5, §11.6 [line-faults])"
        )
        code = ErrorCode.TOO_LONG
    if code == ErrorCode.TOO_LONG:
        garbage = sum(1 for f in extra if error_code_of(f) == ErrorCode.NOT_SYNCED)
        if garbage:
            ctx.note(f"then {garbage} x ERROR 0x0010 for the rest of the frame, as the reference does")
        return "refused"
    if frame.raw == data:
        return "copied"
    ctx.fail(f"{what}: answered {_got(frame)}, expected ERROR 0x0020 (§3.5, §8.1)")
    return "other"


def check_oversize(ctx: CheckContext) -> None:
    outcome = _oversize_attempt(ctx, OVERSIZE_PROBE)
    if outcome == "refused":
        ctx.summary = f"a {len(OVERSIZE_PROBE)}-byte SYNC was refused with ERROR 0x0020"
    elif outcome == "copied":
        ctx.note(f"the base took a {len(OVERSIZE_PROBE)}-byte frame; trying the largest frame there is")
        outcome = _oversize_attempt(ctx, LARGEST_SYNC)
        if outcome == "refused":
            ctx.summary = f"a {len(LARGEST_SYNC)}-byte SYNC was refused with ERROR 0x0020"
        elif outcome == "copied":
            ctx.summary = "the base's buffer holds the largest frame (65539 bytes): nothing is oversize"
    ctx.prober.drain(SECOND_ANSWER_WAIT_S)
    _still_answers(ctx, "the oversize frame")


# --- 17 garbage ------------------------------------------------------------------------------


def _until(
    ctx: CheckContext, sent_at: float, limit_s: float, wanted: Callable[[Frame], bool]
) -> tuple[list[Frame], Frame | None, float | None]:
    """Frames until one that is `wanted` (or the limit): (frames before it, it, its latency)."""
    before: list[Frame] = []
    while True:
        got = ctx.prober.next_item(sent_at + limit_s)
        if got is None:
            return before, None, None
        if isinstance(got.item, Frame):
            if wanted(got.item):
                return before, got.item, got.time - sent_at
            before.append(got.item)


def _is_ok(frame: Frame) -> bool:
    return frame.cmd == Response.OK


def _lengths_text(lengths: list[int]) -> str:
    """'1-2, 7' for [1, 2, 7]."""
    runs: list[list[int]] = []
    for length in lengths:
        if runs and runs[-1][-1] == length - 1:
            runs[-1].append(length)
        else:
            runs.append([length])
    return ", ".join(f"{run[0]}-{run[-1]}" if len(run) > 1 else str(run[0]) for run in runs)


def check_garbage(ctx: CheckContext) -> None:
    timeout_s = ctx.options.timeout_s
    wait_s = ctx.options.wait_s
    prober = ctx.prober

    # A: plain garbage of every length from 1 to 16, each followed by a request in the same burst.
    # Whether the reference answers, drops with ERROR 0x0090 or drops silently depends on the
    # length (the race between its receive interrupt and its main loop, protocol.md §8.5).
    reports = 0
    answered: list[int] = []
    marked: list[int] = []  # dropped, and an ERROR with 0x0080 said so
    marking_codes: set[int] = set()
    silent: list[int] = []  # dropped, only garbage reports came back
    for length in GARBAGE_LENGTHS:
        prober.drain()
        garbage = LONG_GARBAGE[:length]
        sent_at = prober.send(
            garbage + STATUS_REQUEST,
            f"{length} garbage byte{'s' if length > 1 else ''}, then GET_BASE_STATUS",
        )
        before, answer, _ = _until(ctx, sent_at, wait_s, _is_ok)
        bytes_text = f"{length} garbage byte{'s' if length > 1 else ''}"
        wrong = [frame for frame in before if not is_line_fault(error_code_of(frame))]
        if wrong:
            ctx.fail(f"GET_BASE_STATUS right after {bytes_text} was answered {_got(wrong[0])}")
            return
        codes = [error_code_of(frame) for frame in before]
        reports += sum(1 for code in codes if is_line_fault(code, ErrorCode.NOT_SYNCED))
        if answer is not None:
            answered.append(length)
            continue
        again, _ = _answer_as_core(ctx, STATUS_REQUEST, "GET_BASE_STATUS again, as a Core resends")
        if again is None or again.cmd != Response.OK:
            got = "nothing" if again is None else _got(again)
            ctx.fail(
                f"GET_BASE_STATUS right after {bytes_text} was not answered within {wait_s * 1000:.0f} ms, "
                f"and when sent again it was answered {got}"
            )
            return
        marks = {code for code in codes if code is not None and is_line_fault(code, 0x80)}
        marking_codes |= marks
        (marked if marks else silent).append(length)
    if marked or silent:
        how = []
        if marked:
            shown = ", ".join(f"0x{code:04X}" for code in sorted(marking_codes))
            how.append(f"after {_lengths_text(marked)} garbage bytes reported dropped (ERROR {shown})")
        if silent:
            how.append(
                f"after {_lengths_text(silent)} garbage bytes dropped without a word (only ERROR 0x0010 "
                "came back: the Core finds out at its request timeout)"
            )
        at_once = f"; answered at once after {_lengths_text(answered)} garbage bytes" if answered else ""
        ctx.warn(
            f"GET_BASE_STATUS right behind garbage was dropped {'; '.join(how)}, and answered when sent "
            f"again: {REFERENCE_RESENDS} (§11.6 [line-faults]){at_once}"
        )
    elif reports == 0:
        ctx.warn("the garbage was not reported with ERROR 0x0010 (§8.1 [base-events])")
    elif reports > len(GARBAGE_LENGTHS):
        ctx.note(
            f"{reports} x ERROR 0x0010 for {len(GARBAGE_LENGTHS)} garbage gaps (the reference sends several)"
        )

    # B: false frame starts with bogus lengths, then the request.
    prober.drain(0.05)
    sent_at = prober.send(
        FALSE_FLAG_GARBAGE + STATUS_REQUEST, "garbage with false frame starts, then GET_BASE_STATUS"
    )
    before, answer, latency = _until(ctx, sent_at, wait_s, _is_ok)
    if answer is not None and latency is not None:
        if latency <= timeout_s:
            ctx.summary = (
                f"recovered from false frame starts: the request was answered after {latency * 1000:.0f} ms; "
                "plain garbage answered ERROR 0x0010"
            )
        else:
            ctx.warn(
                f"the request after the false frame starts was answered after {latency * 1000:.0f} ms, "
                f"beyond the Core's {timeout_s * 1000:.0f} ms request timeout (§11.6): "
                "the base's inter-byte timeout is long"
            )
        return
    prober.note(
        "no answer: the base is probably stuck on the false 10 FF start (258 bytes announced), as the "
        "reference base is (no inter-byte timeout); sending the Core's flushing SYNC (§11.1)"
    )
    prober.send(FLUSHING_SYNC, "flushing SYNC (512 bytes)")
    prober.collect(0.2)
    frame = prober.exchange(STATUS_REQUEST, "GET_BASE_STATUS after the flushing SYNC").frame
    if frame is not None and frame.cmd == Response.OK:
        ctx.warn(
            "recovered only after the Core's flushing SYNC: the reference firmware does this (no "
            "inter-byte timeout); a Core flushes and resends (§11.6 [core-flush]); a §7 decoder "
            "drops a stale partial frame after its inter-byte timeout and finds the request behind it"
        )
    else:
        got = "nothing" if frame is None else _got(frame)
        ctx.fail(f"did not recover from false frame starts, even after a flushing SYNC (then answered {got})")


CHECKS = (
    Check(
        8,
        "frame-flags",
        "requests accepted as standard (0x10) and long (0x50) frames alike",
        (Rule("§3.4", "frame-type-sent"), Rule("§6.1", "accept-all")),
        check_frame_flags,
    ),
    Check(
        9,
        "sync",
        "SYNC answered verbatim (with and without filler, both frame types)",
        (Rule("§4.2", "sync-echo"),),
        check_sync,
    ),
    Check(10, "echo", "ECHO answered verbatim (both frame types)", (Rule("§4.2", "sync-echo"),), check_echo),
    Check(
        11,
        "checksum-error",
        "a checksum mismatch answered ERROR 0x0040 (0x00C0: warning)",
        (Rule("§3.2", "frame-checksum"), Rule("§8.1", "base-events"), Rule("§4.5", "error-codes")),
        check_checksum_error,
    ),
    Check(
        12,
        "unknown-cmd",
        "an unknown CMD answered ERROR 0x8000",
        (Rule("§4.1", "top-requests"),),
        check_unknown_cmd,
    ),
    Check(
        13,
        "unknown-request",
        "an unknown control-bus request answered ERROR 0x8000",
        (Rule("§5.16", "ctrl-unknown"),),
        check_unknown_request,
    ),
    Check(
        14,
        "unsupported-argument",
        "unsupported argument values (CONNECT version, charger type, 0x35, BASE_CMD) answered 0x8000",
        (
            Rule("§5.1", "connect-version"),
            Rule("§5.8", "charger-data"),
            Rule("§5.9", "aux-anchor"),
            Rule("§4.3", "base-cmd"),
        ),
        check_unsupported_argument,
    ),
    Check(
        15,
        "length",
        "wrong payload lengths answered ERROR 0x8001 (executing them: warning)",
        (Rule("§8.2", "length-check"), Rule("§8.2", "base-validate"), Rule("§3.3", "frame-empty")),
        check_length,
    ),
    Check(
        16,
        "oversize",
        "a frame larger than the receive buffer answered ERROR 0x0020",
        (Rule("§3.5", "frame-limits"), Rule("§8.1", "base-events")),
        check_oversize,
    ),
    Check(
        17,
        "garbage",
        "garbage answered ERROR 0x0010; a request behind false frame starts still answered",
        (
            Rule("§7.2", "dec-rules"),
            Rule("§7.2", "dec-backtrack"),
            Rule("§7.2", "dec-timeout"),
            Rule("§8.1", "base-events"),
            Rule("§11.6", "line-faults"),
        ),
        check_garbage,
        timed=True,
    ),
)
