# SPDX-License-Identifier: MIT
"""Checks of the mandatory requests: answered, with a valid length and plausible values.

Each check asks well-formed requests (built with ctrlbus.messages) and reads each answer as the
answer to that request, so a wrong length or an impossible value (a sensor count above 8, a
message without NUL) fails as the codec refuses it; plausibility beyond the codec (battery at most
100 %, angles 0..360°, defined bits) is checked here.
"""

from __future__ import annotations

from ctrlbus import binconf
from ctrlbus.checker.framework import Check, CheckContext, Rule, error_code_of
from ctrlbus.checker.probe import describe_frame
from ctrlbus.constants import (
    MOTION_DEFINED_BITS,
    POWER_DEFINED_BITS,
    PROFILE_ANSWER_SIZES,
    Profile,
    parse_profile,
)
from ctrlbus.errors import BinaryConfigError
from ctrlbus.frame import Frame, encode
from ctrlbus.messages import (
    Cmd,
    ConnectBase,
    ConnectBaseAnswer,
    EmptyAnswer,
    ErrorAnswer,
    ErrorCode,
    Event,
    ExternalCommand,
    GetBaseBumperData,
    GetBaseBumperDataAnswer,
    GetBaseConf,
    GetBaseConfAdv,
    GetBaseConfAdvAnswer,
    GetBaseConfAnswer,
    GetBaseMotorData,
    GetBaseMotorDataAnswer,
    GetBaseSensorData,
    GetBaseSensorDataAnswer,
    GetBaseStatus,
    GetBaseStatusAnswer,
    GetChargerData,
    GetChargerDataAnswer,
    HealthGetError,
    HealthGetErrorAnswer,
    HealthGetHealth,
    HealthGetHealthAnswer,
    OkAnswer,
    PollBaseAnsCmd,
    PollBaseCmd,
    PollBaseCmdAnswer,
    Position,
    Request,
    Response,
    SendEvent,
    SetBaseMotor,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
)

__all__ = ["CHECKS", "read_health"]

MAX_ANGLE_Q8 = 360 * 256
PLAUSIBLE_RADIUS_MM = 2000.0
PLAUSIBLE_OFFSET_MM = 5000.0  # a sensor or bumper more than 5 m from the robot's centre
PLAUSIBLE_DISTANCE_MM = 100_000.0  # a distance reading beyond 100 m
MAX_PROBES = 8
POLL_ROUNDS = 20  # POLL_BASE_ANS_CMD rounds before calling a pending command stuck
MAX_HEALTH_ENTRIES_READ = 64
HEALTH_LEVELS = {1: "warning", 2: "error", 4: "fatal"}
TIMESTAMP_TOLERANCE_MS = 250
UNKNOWN_EVENT = 0x7E
UNKNOWN_HEALTH_SUB = 0x7F


# --- 1 link ----------------------------------------------------------------------------------


def check_link(ctx: CheckContext) -> None:
    """Plain requests, each answered by exactly one well-formed frame and nothing else."""
    prober = ctx.prober
    requests = [
        (encode(Cmd.CTRL_BUS, bytes((Request.CONNECT_BASE, 1))), "CONNECT_BASE", False),
        (encode(Cmd.CTRL_BUS, bytes((Request.GET_BASE_STATUS,))), "GET_BASE_STATUS", False),
        (encode(Cmd.CTRL_BUS, bytes((Request.GET_BASE_CONF,))), "GET_BASE_CONF (264-byte answer)", False),
        (encode(Cmd.SYNC, b""), "SYNC", True),
    ]
    good = 0
    for data, what, is_sync in requests:
        exchange = prober.exchange(data, what)
        frame = exchange.frame
        seen = ", ".join(str(event) for event in exchange.before)
        if frame is None:
            limit_ms = prober.answer_limit_s * 1000
            if seen:
                ctx.fail(f"{what}: no valid frame came back; the answer stream had: {seen}")
            elif exchange.bytes_heard:
                ctx.fail(
                    f"{what}: no valid frame came back within {limit_ms:.0f} ms, only "
                    f"{exchange.bytes_heard} bytes that are no frame (wrong baud rate?)"
                )
            else:
                ctx.fail(f"{what}: no answer within {limit_ms:.0f} ms")
            continue
        if seen:
            ctx.fail(f"{what}: bytes that are no frame came before the answer: {seen} (§3.1, §3.2)")
            continue
        kind = describe_frame(frame)
        if frame.cmd == Response.INVALID:
            ctx.warn(f"{what} answered INVALID: defined but never sent by the reference or ctrlbus (§4.4)")
        elif is_sync and frame.raw != data:
            ctx.fail(f"{what} answered {kind}, not its own copy")
        elif not is_sync and frame.cmd not in (Response.OK, Response.ERROR):
            ctx.fail(f"{what} answered {kind}: a control-bus request is answered OK or ERROR (§4.4)")
        elif frame.cmd == Response.ERROR and len(frame.payload) != 2:
            ctx.fail(f"{what} answered ERROR with {len(frame.payload)} payload bytes (must be 2, §4.4)")
        else:
            good += 1
    ctx.no_extra_answers(stray_bytes=True)
    ctx.summary = f"{good} of {len(requests)} requests answered by exactly one well-formed frame"


# --- 2 connect -------------------------------------------------------------------------------


def check_connect(ctx: CheckContext) -> None:
    answer, frame = ctx.expect_ok(ConnectBase(), ConnectBaseAnswer)
    form = "2018 reference form" if answer.firmware_version_suffix is None else "2020 SDK form"
    if not answer.model:
        ctx.warn("CONNECT_BASE model is empty: the Core shows it to identify the base")
    suffix = "" if not answer.firmware_version_suffix else answer.firmware_version_suffix
    ctx.summary = (
        f"{len(frame.payload)} bytes ({form}): model {answer.model!r}, firmware "
        f"{answer.firmware_version_text}{suffix}, hardware 0x{answer.hardware_version:04X}"
    )


# --- 3 configuration -------------------------------------------------------------------------


def _check_position(ctx: CheckContext, label: str, position: Position) -> None:
    angle = position.angle_deg_q8
    if angle > MAX_ANGLE_Q8:
        if angle >= 1 << 31:
            shown = (angle - (1 << 32)) / 256
            ctx.fail(
                f"{label}: angle {shown:g}° is negative; angles are 0..360° anticlockwise (315, not -45)"
            )
        else:
            ctx.fail(f"{label}: angle {angle / 256:g}° is above 360°")
    for axis in ("x_mm", "y_mm", "z_mm"):
        value = getattr(position, axis)
        if abs(value) > PLAUSIBLE_OFFSET_MM:
            ctx.warn(f"{label}: {axis[0]} = {value:g} mm is implausibly far from the robot's centre")


def check_configuration(ctx: CheckContext) -> None:
    def base_conf() -> None:
        conf, _ = ctx.expect_ok(GetBaseConf(), GetBaseConfAnswer)
        if conf.base_type not in (0, 1):
            ctx.warn(f"base_type {conf.base_type} is neither 0 (round) nor 1 (square)")
        if conf.motor_type != 0:
            ctx.warn(f"motor_type {conf.motor_type} is not 0 (two-wheel differential)")
        if not 0 < conf.base_radius_mm <= PLAUSIBLE_RADIUS_MM:
            ctx.warn(f"base radius {conf.base_radius_mm:g} mm is implausible")
        for group, count, positions in (
            ("sensor", conf.sensor_num, conf.sensors),
            ("bumper", conf.bumper_num, conf.bumpers),
        ):
            for slot, position in enumerate(positions):
                if slot < count:
                    _check_position(ctx, f"{group} {slot}", position)
                elif position != Position():
                    ctx.warn(f"{group} slot {slot} is unused ({group}_num {count}) but not zero (§5.2)")
        ctx.summary = (
            f"radius {conf.base_radius_mm:g} mm, {conf.sensor_num} distance sensors, "
            f"{conf.bumper_num} bumpers"
        )

    def binary_conf() -> None:
        answer, _ = ctx.ask(GetBaseConfAdv())
        if isinstance(answer, ErrorAnswer):
            if answer.error_code == ErrorCode.UNSUPPORTED:
                ctx.note("GET_BASE_CONF_ADV: ERROR 0x8000, no binary configuration (the Core uses 0x20)")
            else:
                ctx.fail(
                    f"GET_BASE_CONF_ADV answered ERROR 0x{answer.error_code:04X}: a base without a "
                    "binary configuration answers 0x8000, so that the Core falls back (§5.3)"
                )
        elif isinstance(answer, GetBaseConfAdvAnswer):
            try:
                tree = binconf.decode(answer.blob)
            except BinaryConfigError as exc:
                ctx.warn(f"GET_BASE_CONF_ADV blob ({len(answer.blob)} bytes) does not decode (§12): {exc}")
            else:
                ctx.note(f"GET_BASE_CONF_ADV: {len(answer.blob)}-byte blob, {len(tree)} top-level keys")
        else:
            ctx.fail(f"GET_BASE_CONF_ADV answered {answer.NAME}")

    ctx.part(base_conf)
    ctx.part(binary_conf)


# --- 4 telemetry -----------------------------------------------------------------------------


def check_telemetry(ctx: CheckContext) -> None:
    readings: list[str] = []

    def status() -> None:
        answer, _ = ctx.expect_ok(GetBaseStatus(), GetBaseStatusAnswer)
        if answer.battery_percent > 100:
            ctx.fail(f"GET_BASE_STATUS battery_percent {answer.battery_percent} is above 100 (§5.4)")
        if answer.power_status & ~POWER_DEFINED_BITS:
            ctx.warn(f"GET_BASE_STATUS power_status 0x{answer.power_status:02X} has undefined bits set")
        readings.append(f"battery {answer.battery_percent} %, power 0x{answer.power_status:02X}")

    def motor() -> None:
        answer, _ = ctx.expect_ok(GetBaseMotorData(), GetBaseMotorDataAnswer)
        if answer.status & ~MOTION_DEFINED_BITS:
            ctx.warn(f"GET_BASE_MOTOR_DATA status 0x{answer.status:02X} has undefined bits set")
        readings.append(f"wheels {answer.left_distance_mm} / {answer.right_distance_mm} mm")

    def sensors() -> None:
        answer, _ = ctx.expect_ok(GetBaseSensorData(), GetBaseSensorDataAnswer)
        far = [(i, d) for i, d in enumerate(answer.distances_mm) if d > PLAUSIBLE_DISTANCE_MM]
        if far:
            shown = ", ".join(f"channel {i}: {d:g} mm" for i, d in far)
            ctx.warn(f"GET_BASE_SENSOR_DATA distances beyond {PLAUSIBLE_DISTANCE_MM / 1000:g} m: {shown}")
        readings.append("16 distances")

    def bumpers() -> None:
        answer, _ = ctx.expect_ok(GetBaseBumperData(), GetBaseBumperDataAnswer)
        if answer.payload_size < 4:
            ctx.note(f"GET_BASE_BUMPER_DATA answered {answer.payload_size} bytes (allowed; the Core pads)")
        readings.append(f"bumpers 0x{answer.bitmap:0{2 * answer.payload_size}X}")

    def charger() -> None:
        answer, _ = ctx.expect_ok(GetChargerData(), GetChargerDataAnswer)
        if answer.beacon_count > MAX_PROBES or answer.probe_count > MAX_PROBES:
            ctx.warn(
                f"GET_CHARGER_DATA counts {answer.beacon_count} beacons / {answer.probe_count} probes "
                f"(more than {MAX_PROBES} is implausible; the reference has 3 and 3)"
            )
        elif any(probe >> answer.beacon_count for probe in answer.probes):
            ctx.warn(
                f"GET_CHARGER_DATA probe bits {list(answer.probes)} name beacons beyond "
                f"beacon_count {answer.beacon_count}"
            )
        readings.append(f"charger {answer.beacon_count} beacons, probes {list(answer.probes)}")

    for part in (status, motor, sensors, bumpers, charger):
        ctx.part(part)
    ctx.summary = "; ".join(readings)


# --- 5 motion commands -----------------------------------------------------------------------


def check_motion_commands(ctx: CheckContext) -> None:
    def wheels() -> None:
        ctx.expect_ok(SetBaseMotor((0, 0, 0, 0)), EmptyAnswer)

    def velocity() -> None:
        first, _ = ctx.expect_ok(SetVAndGetDeadreckon(0, 0, 0), SetVAndGetDeadreckonAnswer)
        first_at = ctx.now
        ctx.prober.wait(0.05)
        second, _ = ctx.expect_ok(SetVAndGetDeadreckon(0, 0, 0), SetVAndGetDeadreckonAnswer)
        second_at = ctx.now
        form = "13 bytes, reference form" if first.timestamp_ms is None else "17 bytes, 2020 SDK form"
        ctx.note(f"SET_V_AND_GET_DEADRECKON answered {form}")
        for answer in (first, second):
            if answer.status & ~MOTION_DEFINED_BITS:
                ctx.warn(f"deadreckon status 0x{answer.status:02X} has undefined bits set")
        if first.timestamp_ms is not None and second.timestamp_ms is not None:
            step_ms = (second.timestamp_ms - first.timestamp_ms) & 0xFFFF_FFFF
            host_ms = (second_at - first_at) * 1000
            if abs(step_ms - host_ms) > TIMESTAMP_TOLERANCE_MS:
                ctx.warn(
                    f"deadreckon timestamp_ms moved {step_ms} ms while {host_ms:.0f} ms passed "
                    "(it counts milliseconds since power-up, §5.11)"
                )
        if (first.timestamp_ms is None) != (second.timestamp_ms is None):
            ctx.warn("SET_V_AND_GET_DEADRECKON switched between its 13- and 17-byte forms")

    def events() -> None:
        ctx.expect_ok(SendEvent(Event.SYSTEM_UP_OK), EmptyAnswer)
        ctx.expect_ok(
            SendEvent(UNKNOWN_EVENT), EmptyAnswer, what=f"SEND_EVENT 0x{UNKNOWN_EVENT:02X} (no such event)"
        )

    for part in (wheels, velocity, events):
        ctx.part(part)
    ctx.summary = "SET_BASE_MOTOR, SET_V_AND_GET_DEADRECKON and SEND_EVENT (known and unknown) answered"


# --- 6 POLL / ANS ----------------------------------------------------------------------------


def _poll(ctx: CheckContext) -> PollBaseCmdAnswer:
    answer, _ = ctx.expect_ok(PollBaseCmd(), PollBaseCmdAnswer)
    return answer


def _poll_text(answer: PollBaseCmdAnswer) -> str:
    if answer.command is not None:
        return f"command 0x{answer.command:02X} pending"
    return "nothing pending (empty)" if answer.payload_size == 0 else "nothing pending (FF form)"


def check_poll(ctx: CheckContext) -> None:
    first = _poll(ctx)
    ctx.note(f"POLL_BASE_CMD: {_poll_text(first)}")
    if first.command is None:
        ctx.expect_ok(PollBaseAnsCmd(), EmptyAnswer, what="POLL_BASE_ANS_CMD with nothing pending")
        after = _poll(ctx)
        if after.command is not None:
            ctx.warn(f"a command (0x{after.command:02X}) became pending right after POLL_BASE_ANS_CMD")
        ctx.summary = (
            f"{_poll_text(first)}; ANS with nothing pending answered OK (no pending command to test)"
        )
        return
    command = first.command
    if command not in tuple(ExternalCommand):
        ctx.warn(f"pending command 0x{command:02X} is not an external command code (§5.12)")
    again = _poll(ctx)
    if again.command != command:
        ctx.fail(
            f"the pending command changed from 0x{command:02X} to {_poll_text(again)} without "
            "POLL_BASE_ANS_CMD: it must stay pending until acknowledged (§5.12 [poll-rules])"
        )
        return
    taken = 0
    current = again
    while current.command is not None and taken < POLL_ROUNDS:
        ctx.expect_ok(PollBaseAnsCmd(), EmptyAnswer)
        taken += 1
        current = _poll(ctx)
    if current.command is not None:
        ctx.fail(
            f"still {_poll_text(current)} after {POLL_ROUNDS} POLL_BASE_ANS_CMD: the acknowledgement "
            "does not clear the pending command (§5.13)"
        )
        return
    ctx.summary = f"command 0x{command:02X} stayed pending until acknowledged; {taken} ANS cleared the queue"


# --- 7 HEALTH --------------------------------------------------------------------------------


def read_health(ctx: CheckContext) -> tuple[HealthGetHealthAnswer, list[HealthGetErrorAnswer]]:
    """GET_HEALTH, then GET_ERROR for every index it announces (a refused index fails)."""
    health, _ = ctx.expect_ok(HealthGetHealth(), HealthGetHealthAnswer)
    entries: list[HealthGetErrorAnswer] = []
    for index in range(min(health.error_count, MAX_HEALTH_ENTRIES_READ)):
        answer, _ = ctx.ask(HealthGetError(index))
        if isinstance(answer, ErrorAnswer):
            ctx.abort(
                f"HEALTH_GET_ERROR index {index} answered ERROR 0x{answer.error_code:04X}, but "
                f"error_count is {health.error_count}"
            )
        if not isinstance(answer, HealthGetErrorAnswer):
            ctx.abort(f"HEALTH_GET_ERROR index {index} answered {answer.NAME}")
        entries.append(answer)
    return health, entries


def _expect_error_code(ctx: CheckContext, data: bytes, what: str, expected: int, why: str) -> None:
    frame = ctx.exchange(data, what).frame
    assert frame is not None
    code = error_code_of(frame)
    if code == expected:
        return
    got = describe_frame(frame) if code is None else f"ERROR 0x{code:04X}"
    ctx.fail(f"{what} answered {got}, expected ERROR 0x{expected:04X} ({why})")


def check_health(ctx: CheckContext) -> None:
    health, entries = read_health(ctx)
    expected_flags = 0
    codes: list[int] = []
    for index, entry in enumerate(entries):
        level = entry.error_code >> 24
        expected_flags |= level & 0x07
        if level not in HEALTH_LEVELS:
            ctx.warn(f"error {index} code 0x{entry.error_code:08X} has level {level}, not 1, 2 or 4 (§10.1)")
        if entry.error_code in codes:
            ctx.warn(f"error code 0x{entry.error_code:08X} is listed twice (§10.4)")
        codes.append(entry.error_code)
        ctx.note(f"error {index}: 0x{entry.error_code:08X} {entry.message!r}")
    if health.flags != expected_flags:
        ctx.fail(
            f"HEALTH_GET_HEALTH flags 0x{health.flags:02X} do not match the levels of its "
            f"{health.error_count} errors (expected 0x{expected_flags:02X}, §5.15)"
        )
    count = health.error_count
    prefix = bytes((Request.HEALTH_MGMT,))
    ctx.part(
        lambda: _expect_error_code(
            ctx,
            encode(Cmd.CTRL_BUS, prefix + bytes((0x02, min(count, 0xFF)))),
            f"HEALTH_GET_ERROR index {count} (one past the last)",
            ErrorCode.OPERATION,
            "index out of range, §5.15 [health-errors]",
        )
    )
    unknown = 0x04FF_FE00
    while unknown in codes:
        unknown += 1
    ctx.part(
        lambda: _expect_error_code(
            ctx,
            encode(Cmd.CTRL_BUS, prefix + bytes((0x03,)) + unknown.to_bytes(4, "little")),
            f"HEALTH_CLR_ERROR 0x{unknown:08X} (not registered)",
            ErrorCode.OPERATION,
            "no such error, §5.15 [health-errors]",
        )
    )
    ctx.part(
        lambda: _expect_error_code(
            ctx,
            encode(Cmd.CTRL_BUS, prefix + bytes((UNKNOWN_HEALTH_SUB,))),
            f"HEALTH_MGMT sub-command 0x{UNKNOWN_HEALTH_SUB:02X} (unknown)",
            ErrorCode.OPERATION,
            "the reference's code for an unknown HEALTH sub-command is 0x8002, not 0x8000",
        )
    )
    ctx.summary = f"flags 0x{health.flags:02X}, {count} errors, all readable; the three refusals are 0x8002"


# --- 21 profile ------------------------------------------------------------------------------

COMMON_SIZES = {
    "GET_BASE_STATUS": 2,
    "GET_BASE_SENSOR_DATA": 64,
    "GET_BASE_BUMPER_DATA": 4,
    "HEALTH_GET_HEALTH": 2,
    "HEALTH_GET_ERROR": 36,
}


def check_profile(ctx: CheckContext) -> None:
    profile = ctx.options.profile
    if profile == "any":
        ctx.skip("no --profile given: every variant a master must accept is accepted")
    sizes = {**COMMON_SIZES, **PROFILE_ANSWER_SIZES[parse_profile(profile)]}
    checked: list[str] = []

    def frame_type(name: str, frame: Frame) -> None:
        if frame.long:
            return
        text = f"{name} answered in a standard frame; the {profile} profile answers in long frames"
        if profile == Profile.SDK2020:
            ctx.fail(text + " (the 2020 SDK only reads frames starting 0x50)")
        else:
            ctx.warn(text + " (allowed as an option, §3.4)")

    def size(name: str, frame: Frame, detail: str = "") -> None:
        wanted = sizes[name]
        if len(frame.payload) != wanted:
            ctx.fail(
                f"{name} answered {len(frame.payload)} bytes{detail}; the {profile} profile sends {wanted}"
            )
        frame_type(name, frame)
        checked.append(name)

    for request in (ConnectBase(), GetBaseStatus(), GetBaseSensorData(), GetBaseBumperData()):
        _, frame = ctx.expect_ok(request, OkAnswer)
        size(request.NAME, frame)
    _, frame = ctx.expect_ok(SetVAndGetDeadreckon(0, 0, 0), OkAnswer)
    size("SET_V_AND_GET_DEADRECKON", frame)
    health, frame = ctx.expect_ok(HealthGetHealth(), HealthGetHealthAnswer)
    size("HEALTH_GET_HEALTH", frame)
    if health.error_count:
        _, frame = ctx.expect_ok(HealthGetError(0), OkAnswer)
        size("HEALTH_GET_ERROR", frame)
    poll, frame = ctx.expect_ok(PollBaseCmd(), PollBaseCmdAnswer)
    if poll.command is None:
        size("POLL_BASE_CMD", frame, " with nothing pending")
    else:
        ctx.note("a command is pending, so POLL_BASE_CMD's nothing-pending form was not seen")
    bad = bytearray(encode(Cmd.CTRL_BUS, bytes((Request.GET_BASE_STATUS,))))
    bad[-1] ^= 0xFF
    error = ctx.exchange(bytes(bad), "GET_BASE_STATUS with a wrong checksum").frame
    assert error is not None
    code = error_code_of(error)
    if code == ErrorCode.REFERENCE_CHECKSUM:
        ctx.warn(
            "checksum mismatch answered 0x00C0 (the reference's quirk, an option); both profiles send 0x0040"
        )
    elif code != ErrorCode.CHECKSUM:
        ctx.fail(f"checksum mismatch answered {describe_frame(error)}; both profiles send ERROR 0x0040")
    frame_type("ERROR", error)
    ctx.summary = f"answer sizes and frame types of the {profile} profile: {', '.join(checked)}"


CHECKS = (
    Check(
        1,
        "link",
        "answers are well-formed frames, one per request",
        (
            Rule("§3.1", "frame-layout"),
            Rule("§3.2", "frame-checksum"),
            Rule("§4.4", "top-responses"),
            Rule("§8.4", "base-one-answer"),
        ),
        check_link,
    ),
    Check(2, "connect", "CONNECT_BASE answered (28 or 39 bytes)", (Rule("§5.1", "connect"),), check_connect),
    Check(
        3,
        "configuration",
        "GET_BASE_CONF plausible; GET_BASE_CONF_ADV a blob or ERROR 0x8000",
        (Rule("§5.2", "base-conf"), Rule("§5.2", "base-conf-counts"), Rule("§5.3", "base-conf-adv")),
        check_configuration,
    ),
    Check(
        4,
        "telemetry",
        "status, motor, sensor, bumper and charger data: valid lengths, plausible values",
        (
            Rule("§5.4", "status"),
            Rule("§5.5", "motor-data"),
            Rule("§5.6", "sensor-data"),
            Rule("§5.7", "bumper-data"),
            Rule("§5.8", "charger-data"),
        ),
        check_telemetry,
    ),
    Check(
        5,
        "motion-commands",
        "SET_BASE_MOTOR, SET_V_AND_GET_DEADRECKON (13 or 17 bytes) and SEND_EVENT answered",
        (
            Rule("§5.10", "set-motor"),
            Rule("§5.11", "set-v"),
            Rule("§5.11", "deadreckon"),
            Rule("§5.14", "send-event"),
        ),
        check_motion_commands,
    ),
    Check(
        6,
        "poll",
        "POLL_BASE_CMD forms; a pending command stays until POLL_BASE_ANS_CMD clears it",
        (Rule("§5.12", "poll"), Rule("§5.12", "poll-rules"), Rule("§5.13", "poll-ans")),
        check_poll,
    ),
    Check(
        7,
        "health",
        "HEALTH_MGMT: flags match the errors, every error readable, refusals are 0x8002",
        (
            Rule("§5.15", "health"),
            Rule("§5.15", "health-errors"),
            Rule("§10.1", "health-code-layout"),
            Rule("§10.4", "health-list"),
            Rule("§1.5", "text-fields"),
        ),
        check_health,
    ),
    Check(
        21,
        "profile",
        "answer sizes and frame types of the chosen base profile (--profile)",
        (Rule("§6.2", "profiles"),),
        check_profile,
    ),
)
