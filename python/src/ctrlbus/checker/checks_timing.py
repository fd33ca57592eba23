# SPDX-License-Identifier: MIT
"""Checks that need real time: motion that must not happen (a frame that failed its checksum),
motion that must stop (the motor watchdog), and answer latency.

Motion is observed through GET_BASE_MOTOR_DATA's wheel travel totals (both wheels, absolute
changes, so bases whose encoders have no direction work too) and, where the base answers it,
through SET_V_AND_GET_DEADRECKON's turn. The robot is commanded to spin in place, the motion
that needs the least room (check 18: SET_BASE_MOTOR, left back and right forward at SPIN_MM_S;
the watchdog check: SET_V_AND_GET_DEADRECKON at SPIN_OMEGA_RADPS, as a Core drives), and is
always commanded to stop when the check ends.
"""

from __future__ import annotations

import math

from ctrlbus.checker.checks_requests import read_health
from ctrlbus.checker.checks_wire import bad_checksum, ctrl
from ctrlbus.checker.framework import Check, CheckAborted, CheckContext, Rule
from ctrlbus.checker.probe import describe_frame
from ctrlbus.constants import WATCHDOG_TRIPPED_CODE as WATCHDOG_CODE
from ctrlbus.errors import MessageError
from ctrlbus.frame import encode
from ctrlbus.messages import (
    Cmd,
    EmptyAnswer,
    ErrorAnswer,
    GetBaseMotorData,
    GetBaseMotorDataAnswer,
    HealthClrError,
    Request,
    Response,
    SetBaseMotor,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    decode_answer,
    request_frame,
    to_q16,
)

__all__ = [
    "CHECKS",
    "LATENCY_WARN_S",
    "SPIN_MM_S",
    "WATCHDOG_LIMIT_S",
    "WATCHDOG_TOLERANCE_S",
]

SPIN_MM_S = 100  # wheel speed of the test motion (left -100, right +100: turning in place)
SPIN_OMEGA_RADPS = 0.5  # the same idea through SET_V_AND_GET_DEADRECKON
SETTLE_STOP_S = 0.3  # time for wheels to come to rest after a stop command
OBSERVE_S = 0.3  # how long motion is given to show
STILL_TRAVEL_MM = 4.0  # wheel travel (both wheels together) below which nothing moved
STILL_TURN_DEG = 1.0
WATCHDOG_LIMIT_S = 1.0  # §9.1: the wheels stop after 1000 ms without a CTRL_BUS frame
WATCHDOG_TOLERANCE_S = 0.25  # measurement, scheduling and the wheels' own deceleration
WATCHDOG_LOOK_S = 1.5  # when, after the last CTRL_BUS frame, the checker looks again
CALIBRATE_S = 0.25  # spacing of the two readings that measure the spin rate
KEEPALIVE_S = 0.2  # SYNC / ECHO spacing while silent on CTRL_BUS
MIN_RATE_FRACTION = 0.2  # share of the commanded or measured motion below which nothing moves
MIN_SPIN_TRAVEL_MM_S = 10.0  # wheel travel (both wheels) below which the SET_V spin cannot be timed
LATENCY_WARN_S = 0.050  # p99 above this: warning (the reference answers in 1-5 ms, §8.4)
LATENCY_LATE_LIMIT = 5  # answers later than the request timeout before the sampling stops
LATENCY_LOGGED = 4  # exchanges of the latency series kept in the transcript


def spin_request() -> bytes:
    return request_frame(SetBaseMotor((-SPIN_MM_S, SPIN_MM_S, 0, 0)))


def _travel(before: GetBaseMotorDataAnswer, after: GetBaseMotorDataAnswer) -> float:
    return float(
        abs(after.left_distance_mm - before.left_distance_mm)
        + abs(after.right_distance_mm - before.right_distance_mm)
    )


def _motor(ctx: CheckContext, what: str = "GET_BASE_MOTOR_DATA") -> tuple[GetBaseMotorDataAnswer, float]:
    """Wheel totals and the time the request went out."""
    prober = ctx.prober
    exchange = ctx.exchange(request_frame(GetBaseMotorData()), what)
    frame = exchange.frame
    assert frame is not None
    try:
        answer = decode_answer("GET_BASE_MOTOR_DATA", frame.cmd, frame.payload)
    except MessageError as exc:
        ctx.abort(f"{what}: unreadable answer, motion cannot be observed: {exc}")
    if not isinstance(answer, GetBaseMotorDataAnswer):
        ctx.abort(f"{what} answered {describe_frame(frame)}: motion cannot be observed")
    prober.note(f"wheel totals {answer.left_distance_mm} / {answer.right_distance_mm} mm")
    return answer, exchange.sent_at


def _set_v_turn(ctx: CheckContext, omega_radps: float = 0.0, what: str = "") -> tuple[float | None, float]:
    """SET_V_AND_GET_DEADRECKON turning in place at omega_radps: the turn since the previous one
    (None if the base does not answer it readably; check 5 judges that), and when it was sent."""
    request = SetVAndGetDeadreckon(0, 0, to_q16(omega_radps))
    exchange = ctx.prober.exchange(
        request_frame(request), what or f"SET_V_AND_GET_DEADRECKON omega {omega_radps:g}"
    )
    frame = exchange.frame
    if frame is None:
        return None, exchange.sent_at
    try:
        answer = decode_answer("SET_V_AND_GET_DEADRECKON", frame.cmd, frame.payload)
    except MessageError:
        return None, exchange.sent_at
    turn = answer.dtheta_deg if isinstance(answer, SetVAndGetDeadreckonAnswer) else None
    return turn, exchange.sent_at


def _turn_deg(ctx: CheckContext) -> float | None:
    """SET_V_AND_GET_DEADRECKON with zero velocity: the turn since the previous one."""
    return _set_v_turn(ctx, 0.0, "SET_V_AND_GET_DEADRECKON 0")[0]


def _stop(ctx: CheckContext) -> None:
    ctx.expect_ok(SetBaseMotor((0, 0, 0, 0)), EmptyAnswer, what="SET_BASE_MOTOR 0 0 (stop)")


# --- 18 a bad checksum is not executed -------------------------------------------------------


def check_not_executed(ctx: CheckContext) -> None:
    prober = ctx.prober
    try:
        _stop(ctx)
        prober.wait(SETTLE_STOP_S)
        start, _ = _motor(ctx)
        _turn_deg(ctx)  # starts a deadreckon interval
        velocity = SetVAndGetDeadreckon(0, 0, to_q16(SPIN_OMEGA_RADPS))
        for frame, what in (
            (
                bad_checksum(spin_request()),
                f"SET_BASE_MOTOR {-SPIN_MM_S} {SPIN_MM_S} with its checksum inverted",
            ),
            (
                bad_checksum(request_frame(velocity)),
                f"SET_V omega {SPIN_OMEGA_RADPS} rad/s, checksum inverted",
            ),
        ):
            answer = prober.exchange(frame, what).frame
            if answer is not None and answer.cmd == Response.OK:
                ctx.fail(f"{what}: answered OK, so it was executed (§8.1 [base-no-exec])")
        prober.wait(OBSERVE_S)
        end, _ = _motor(ctx)
        turn = _turn_deg(ctx)
        travel = _travel(start, end)
        if travel > STILL_TRAVEL_MM or (turn is not None and abs(turn) > STILL_TURN_DEG):
            turned = "" if turn is None else f", turned {turn:.1f}°"
            ctx.fail(
                f"the wheels moved after motion commands that failed their checksum: {travel:.0f} mm of "
                f"wheel travel{turned} in {OBSERVE_S:g} s (§8.1 [base-no-exec])"
            )
            return
        # The same command with a valid checksum must move the wheels, or nothing was shown.
        ctx.expect_ok(SetBaseMotor((-SPIN_MM_S, SPIN_MM_S, 0, 0)), EmptyAnswer)
        prober.wait(OBSERVE_S)
        moved, _ = _motor(ctx)
        control = _travel(end, moved)
        if control <= STILL_TRAVEL_MM:
            ctx.warn(
                "the same SET_BASE_MOTOR with a valid checksum did not move the wheels either "
                f"({control:.0f} mm), so 'not executed' could not be shown (is the base blocked, or "
                "are its wheel totals not reported?)"
            )
            return
        ctx.summary = (
            f"no wheel travel after the corrupted commands; the valid one gave {control:.0f} mm "
            f"in {OBSERVE_S:g} s"
        )
    finally:
        ctx.stop_wheels()


# --- 19 motor watchdog -----------------------------------------------------------------------


def _keep_talking_without_ctrl_bus(ctx: CheckContext, until: float) -> None:
    """SYNC and ECHO (which must not feed the watchdog) until `until`."""
    prober = ctx.prober
    turn = 0
    while True:
        remaining = until - prober.now()
        if remaining <= 0:
            return
        prober.wait(min(KEEPALIVE_S, remaining))
        if until - prober.now() <= 0:
            return
        if turn % 2 == 0:
            data, what = encode(Cmd.SYNC, b"\x55\xaa"), "SYNC (must not feed the watchdog)"
        else:
            data, what = encode(Cmd.ECHO, b"\x01\x02"), "ECHO (must not feed the watchdog)"
        # Each copy is waited for (up to the answer limit), also past `until`: a slow base's late
        # copy would otherwise be taken for the answer to the measuring request that follows.
        prober.exchange(data, what)
        turn += 1


def _watchdog_in_health(ctx: CheckContext) -> None:
    try:
        _, entries = read_health(ctx)
    except CheckAborted:
        return
    if any(entry.error_code == WATCHDOG_CODE for entry in entries):
        ctx.note("the trip is visible: HEALTH lists 0x01038000 'motor watchdog tripped'")
        answer, _ = ctx.ask(HealthClrError(WATCHDOG_CODE))
        if isinstance(answer, ErrorAnswer):
            ctx.warn(f"HEALTH_CLR_ERROR 0x01038000 answered ERROR 0x{answer.error_code:04X}, expected OK")
    else:
        ctx.warn(
            "the watchdog stopped silently, as the reference does; a ctrlbus base registers the warning "
            "0x01038000 so the Core can see its commands lapsed (§9.1 [watchdog-visible])"
        )


def check_watchdog(ctx: CheckContext) -> None:
    """The robot turns in place on SET_V_AND_GET_DEADRECKON, then hears only SYNC and ECHO: the
    wheel totals (GET_BASE_MOTOR_DATA) and the deadreckon turn (the next SET_V_AND_GET_DEADRECKON)
    must both show it stopped within the watchdog time of the last CTRL_BUS frame."""
    prober = ctx.prober
    spin = f"SET_V_AND_GET_DEADRECKON omega {SPIN_OMEGA_RADPS:g} rad/s"
    try:
        _stop(ctx)
        prober.wait(SETTLE_STOP_S)
        _set_v_turn(ctx, SPIN_OMEGA_RADPS, f"{spin} (start turning)")
        prober.wait(CALIBRATE_S)  # up to speed
        first, first_at = _motor(ctx, "GET_BASE_MOTOR_DATA (measuring the spin)")
        _, interval_start = _set_v_turn(ctx, SPIN_OMEGA_RADPS, f"{spin} (a deadreckon interval starts)")
        prober.wait(CALIBRATE_S)
        second, second_at = _motor(ctx, "GET_BASE_MOTOR_DATA (measuring the spin)")
        turned, last_ctrl_bus = _set_v_turn(
            ctx, SPIN_OMEGA_RADPS, f"{spin} (the last CTRL_BUS frame for a while)"
        )
        rate = _travel(first, second) / max(1e-3, second_at - first_at)  # both wheels, mm/s
        if rate < MIN_SPIN_TRAVEL_MM_S:
            ctx.warn(
                f"the wheels hardly moved on {spin} ({rate:.0f} mm/s of travel), so the watchdog "
                "cannot be observed"
            )
            return
        interval_s = max(1e-3, last_ctrl_bus - interval_start)
        turn_rate = None if turned is None or abs(turned) < STILL_TURN_DEG else turned / interval_s
        prober.note(f"spinning: {rate:.0f} mm/s of wheel travel (both wheels); now only SYNC and ECHO")
        _keep_talking_without_ctrl_bus(ctx, last_ctrl_bus + WATCHDOG_LOOK_S)
        third, third_at = _motor(
            ctx, f"GET_BASE_MOTOR_DATA ({WATCHDOG_LOOK_S:g} s after the last CTRL_BUS frame)"
        )
        prober.wait(CALIBRATE_S)
        fourth, fourth_at = _motor(ctx, "GET_BASE_MOTOR_DATA (still moving?)")
        after, _ = _set_v_turn(
            ctx, 0.0, "SET_V_AND_GET_DEADRECKON 0 (the turn since the last CTRL_BUS frame)"
        )
        # The wheel travel from the second reading on, less the little before the last frame.
        ran_s = _travel(second, third) / rate - (last_ctrl_bus - second_at)
        still_mm_s = _travel(third, fourth) / max(1e-3, fourth_at - third_at)
        limit = WATCHDOG_LIMIT_S + WATCHDOG_TOLERANCE_S
        if still_mm_s > MIN_RATE_FRACTION * rate:
            ctx.fail(
                f"the wheels were still turning {third_at - last_ctrl_bus:.1f} s after the last CTRL_BUS "
                f"frame ({still_mm_s:.0f} mm/s): no motor watchdog, or SYNC/ECHO feed it (§9.1)"
            )
            return
        if ran_s > limit:
            ctx.fail(
                f"the wheels ran about {ran_s:.2f} s after the last CTRL_BUS frame; the watchdog must "
                f"stop them after {WATCHDOG_LIMIT_S:g} s (+{WATCHDOG_TOLERANCE_S:g} s tolerance, §9.1)"
            )
            return
        summary = f"the wheels stopped about {max(0.0, ran_s):.2f} s after the last CTRL_BUS frame"
        if turn_rate is None or after is None:
            ctx.note(
                "the deadreckon turn did not show the spin, so the stop was seen in the wheel totals only"
            )
        else:
            turned_s = after / turn_rate
            if turned_s > limit:
                ctx.fail(
                    f"the deadreckon kept turning about {turned_s:.2f} s after the last CTRL_BUS frame "
                    f"({after:.1f}° at {turn_rate:.1f}°/s) although the wheel totals stopped after "
                    f"{ran_s:.2f} s: the Core would see the robot still moving (§9.1)"
                )
                return
            summary += f" (deadreckon: {max(0.0, turned_s):.2f} s)"
        ctx.summary = summary
        if ran_s < WATCHDOG_LIMIT_S / 2:
            ctx.note(f"a short watchdog ({ran_s:.2f} s); the default is {WATCHDOG_LIMIT_S:g} s")
        _watchdog_in_health(ctx)
    finally:
        ctx.stop_wheels()


# --- 20 latency ------------------------------------------------------------------------------


def percentile(values: list[float], fraction: float) -> float:
    """Nearest-rank percentile of a non-empty list."""
    ordered = sorted(values)
    rank = max(1, math.ceil(fraction * len(ordered)))
    return ordered[rank - 1]


def check_latency(ctx: CheckContext) -> None:
    timeout_s = ctx.options.timeout_s
    prober = ctx.prober
    requests = (
        (ctrl(bytes((Request.GET_BASE_STATUS,))), "GET_BASE_STATUS"),
        (request_frame(SetVAndGetDeadreckon(0, 0, 0)), "SET_V_AND_GET_DEADRECKON 0"),
    )
    latencies: list[float] = []
    late = 0
    try:
        for index in range(ctx.options.latency_count):
            prober.recording = index < LATENCY_LOGGED
            data, what = requests[index % len(requests)]
            exchange = ctx.exchange(data, what)
            assert exchange.frame is not None and exchange.latency_s is not None
            if exchange.frame.cmd not in (Response.OK, Response.ERROR):
                ctx.abort(f"{what} answered {describe_frame(exchange.frame)}, neither OK nor ERROR (§4.4)")
            latencies.append(exchange.latency_s)
            if exchange.latency_s > timeout_s:
                late += 1
                if late >= LATENCY_LATE_LIMIT:
                    ctx.note(f"stopped after {late} answers slower than {timeout_s * 1000:.0f} ms")
                    break
    finally:
        prober.recording = True
    p50 = percentile(latencies, 0.50)
    p99 = percentile(latencies, 0.99)
    text = (
        f"{len(latencies)} requests: p50 {p50 * 1000:.1f} ms, p99 {p99 * 1000:.1f} ms, "
        f"max {max(latencies) * 1000:.1f} ms"
    )
    ctx.note(text)
    if p99 > timeout_s:
        ctx.fail(f"{text}: p99 above the Core's {timeout_s * 1000:.0f} ms request timeout (§11.6)")
    elif p99 > LATENCY_WARN_S:
        ctx.warn(f"{text}: p99 above {LATENCY_WARN_S * 1000:.0f} ms (the reference answers in 1-5 ms)")
    ctx.summary = text


CHECKS = (
    Check(
        18,
        "not-executed",
        "motion commands that fail their checksum are not executed (observed on the wheels)",
        (Rule("§8.1", "base-no-exec"),),
        check_not_executed,
        slow=True,
    ),
    Check(
        19,
        "watchdog",
        "the wheels stop within 1 s (+tolerance) of the last CTRL_BUS frame; SYNC/ECHO do not feed it",
        (Rule("§9.1", "watchdog"), Rule("§9.1", "watchdog-visible")),
        check_watchdog,
        slow=True,
        timed=True,
    ),
    Check(
        20,
        "latency",
        "answer latency p50/p99 (warning above 50 ms, failure above the request timeout)",
        (Rule("§11.6", "core-timeouts"), Rule("§8.4", "base-one-answer")),
        check_latency,
        timed=True,
    ),
)
