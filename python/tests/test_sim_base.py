# SPDX-License-Identifier: MIT
"""The simulated base (ctrlbus.sim.base): the World served through the base framework.

Most tests run in virtual time (the test owns the clock and passes it to the stack); one runs the
real-time runner over an in-process link pair.
"""

from __future__ import annotations

import math
import struct
import time
from typing import Any

import pytest

from ctrlbus import binconf
from ctrlbus.base import BaseConfig, BaseRunner, BaseStack, Profile
from ctrlbus.frame import Frame, StreamDecoder, encode
from ctrlbus.kinematics import DeadreckonDelta, Pose, integrate_pose
from ctrlbus.link import link_pair
from ctrlbus.messages import (
    ConnectBaseAnswer,
    GetBaseConfAnswer,
    GetBaseSensorDataAnswer,
    SetVAndGetDeadreckonAnswer,
    decode_answer,
)
from ctrlbus.sim import World
from ctrlbus.sim.base import (
    LOW_BATTERY_ERROR_CODE,
    LOW_BATTERY_WARNING_CODE,
    SimulatedBase,
)

CTRL_BUS, OK, ERROR = 0xF8, 0x02, 0x03
SYNC = bytes.fromhex("10 01 00 11")


def set_velocity(vx_mps: float, omega_radps: float) -> bytes:
    return bytes((0x41,)) + struct.pack("<3i", round(vx_mps * 65536), 0, round(omega_radps * 65536))


def set_motor(left: int, right: int) -> bytes:
    return bytes((0x40,)) + struct.pack("<4i", left, right, 0, 0)


class Rig:
    """A simulated base in virtual time: the test moves the clock."""

    def __init__(self, sim: SimulatedBase | None = None, config: BaseConfig | None = None) -> None:
        self.sim = sim if sim is not None else SimulatedBase()
        self.stack = BaseStack(self.sim, config)
        self.now = 0.0
        self.stack.tick(self.now)

    @property
    def world(self) -> World:
        return self.sim.world

    def frames(self, data: bytes) -> list[Frame]:
        return StreamDecoder().feed(self.stack.receive(data, self.now))

    def ask(self, payload: bytes, cmd: int = CTRL_BUS) -> Frame:
        (answer,) = self.frames(encode(cmd, payload))
        return answer

    def ok(self, payload: bytes, size: int | None = None) -> bytes:
        answer = self.ask(payload)
        assert answer.cmd == OK, f"{payload.hex(' ')} -> {answer}"
        if size is not None:
            assert len(answer.payload) == size
        return answer.payload

    def wait(self, seconds: float, step: float = 0.01) -> None:
        end = self.now + seconds
        while self.now < end - 1e-9:
            self.now = min(end, self.now + step)
            assert self.stack.tick(self.now) == b""


def test_connect_reports_the_description_model() -> None:
    rig = Rig()
    answer = decode_answer("CONNECT_BASE", OK, rig.ok(b"\x10\x01", 28))
    assert isinstance(answer, ConnectBaseAnswer)
    assert answer.model == "ctrlbus sim" == rig.world.base.model
    assert answer.firmware_version == 0x0001  # ctrlbus 0.1


def test_base_config_comes_from_the_description() -> None:
    rig = Rig()
    conf = decode_answer("GET_BASE_CONF", OK, rig.ok(b"\x20", 264))
    assert isinstance(conf, GetBaseConfAnswer)
    base = rig.world.base
    assert (conf.base_type, conf.base_radius_mm, conf.motor_type) == (0, base.radius_mm, 0)
    assert conf.sensor_num == len(base.distance_sensors) == 6
    assert [p.angle_deg for p in conf.sensors[:6]] == [0, 45, 315, 90, 270, 180]
    assert [(p.x_mm, p.y_mm, p.z_mm) for p in conf.sensors[:2]] == [(165, 0, 120), (113, 113, 120)]
    assert conf.bumper_num == 2
    assert [p.angle_deg for p in conf.bumpers[:2]] == [45, 315]
    left = conf.bumpers[0]
    assert math.hypot(left.x_mm, left.y_mm) == pytest.approx(base.radius_mm, abs=0.01)


def test_status_sensors_motor_and_charger_data_come_from_the_world() -> None:
    rig = Rig()
    assert rig.ok(b"\x30") == bytes((80, 0))  # the default robot starts at 80 %, off the dock
    sensors = decode_answer("GET_BASE_SENSOR_DATA", OK, rig.ok(b"\x32", 64))
    assert isinstance(sensors, GetBaseSensorDataAnswer)
    readings = rig.world.distance_readings_mm()
    assert sensors.distances_mm[: len(readings)] == pytest.approx(readings, abs=1e-4)
    assert sensors.distances_mm[len(readings) :] == (0.0,) * (16 - len(readings))
    assert rig.ok(b"\x31") == struct.pack("<iiB", 0, 0, 0)
    dock = rig.world.room.dock
    assert dock is not None
    assert rig.ok(b"\x34\x00") == bytes((len(dock.beacons), 3, *rig.world.beacon_bits()))


def test_bumpers_and_cliffs_are_active_low_bits() -> None:
    rig = Rig()
    assert rig.ok(b"\x33", 4) == b"\xff" * 4
    # Against the bottom wall, facing +x: the wall is on the right, the right bumper (bit 1) closes.
    rig.world.place_robot(Pose(3000, rig.world.base.radius_mm + 0.5, 0))
    assert rig.world.bumpers_pressed == (False, True)
    assert struct.unpack("<I", rig.ok(b"\x33"))[0] == 0xFFFF_FFFD
    # The two front cliff sensors over the stairs: cliff bits start after the bumpers (2 and 3).
    rig.world.place_robot(Pose(4700, 500, 0))
    assert rig.world.cliffs_triggered == (True, True, False, False)
    assert struct.unpack("<I", rig.ok(b"\x33"))[0] == 0xFFFF_FFF3


def test_deadreckon_deltas_integrate_to_the_odometry_pose() -> None:
    rig = Rig()
    start = rig.world.odometry_pose
    first = decode_answer("SET_V_AND_GET_DEADRECKON", OK, rig.ok(set_velocity(0.3, 0.4), 13))
    assert isinstance(first, SetVAndGetDeadreckonAnswer)
    assert (first.dx_mm_q16, first.dy_mm_q16, first.dtheta_deg_q16) == (0, 0, 0)
    pose = start
    for step in range(120):  # 6 s at 20 Hz, a curve, then a turn on the spot
        rig.wait(0.05)
        command = set_velocity(0.3, 0.4) if step < 80 else set_velocity(0.0, -1.0)
        answer = decode_answer("SET_V_AND_GET_DEADRECKON", OK, rig.ok(command, 13))
        assert isinstance(answer, SetVAndGetDeadreckonAnswer)
        assert answer.status == rig.world.motion_status
        pose = integrate_pose(pose, DeadreckonDelta(answer.dx_mm, answer.dy_mm, answer.dtheta_deg))
    odometry = rig.world.odometry_pose
    assert math.hypot(odometry.x_mm - start.x_mm, odometry.y_mm - start.y_mm) > 500  # it really moved
    # The base measures each delta from what it has already reported, so rounding never adds up.
    assert pose.x_mm == pytest.approx(odometry.x_mm, abs=1e-3)
    assert pose.y_mm == pytest.approx(odometry.y_mm, abs=1e-3)
    assert pose.theta_deg == pytest.approx(odometry.theta_deg, abs=1e-4)
    # Wheel slip: the odometry the base reports drifts from the truth, as on a real robot.
    assert odometry != rig.world.true_pose


def test_a_turn_of_more_than_half_a_turn_is_reported_whole() -> None:
    # Issue 17: 270 degrees left between two requests read -90 (a right turn) before.
    rig = Rig()
    rig.ok(set_velocity(0.0, 0.0))
    turn_before = rig.world.odometry_turn_deg
    rig.ok(set_velocity(0.0, 3.0))
    while rig.world.odometry_turn_deg - turn_before < 270.0:
        rig.wait(0.01)
        rig.ok(bytes((0x30,)))  # status requests feed the watchdog without reading the deltas
    answer = decode_answer("SET_V_AND_GET_DEADRECKON", OK, rig.ok(set_velocity(0.0, 0.0), 13))
    assert isinstance(answer, SetVAndGetDeadreckonAnswer)
    assert answer.dtheta_deg == pytest.approx(rig.world.odometry_turn_deg - turn_before, abs=1e-4)
    assert 270.0 <= answer.dtheta_deg < 300.0


def test_a_turn_beyond_the_field_range_is_carried_into_the_next_answer() -> None:
    # The s32 Q16 field holds +-32768 degrees; more is sent saturated and the rest comes next.
    rig = Rig()
    rig.ok(set_velocity(0.0, 0.0))
    turn_before = rig.world.odometry_turn_deg
    rig.world._odometry_turn_deg += 40_000.0  # ~111 turns on the spot since the last request
    first = decode_answer("SET_V_AND_GET_DEADRECKON", OK, rig.ok(set_velocity(0.0, 0.0), 13))
    second = decode_answer("SET_V_AND_GET_DEADRECKON", OK, rig.ok(set_velocity(0.0, 0.0), 13))
    assert isinstance(first, SetVAndGetDeadreckonAnswer) and isinstance(second, SetVAndGetDeadreckonAnswer)
    assert first.dtheta_deg_q16 == 2**31 - 1
    assert first.dtheta_deg + second.dtheta_deg == pytest.approx(
        rig.world.odometry_turn_deg - turn_before, abs=1e-3
    )


def test_set_base_motor_drives_the_wheels_and_a_bad_checksum_does_not() -> None:
    rig = Rig()
    bad = bytearray(encode(CTRL_BUS, set_motor(-200, -200)))
    bad[-1] ^= 0x01
    (answer,) = rig.frames(bytes(bad))
    assert (answer.cmd, answer.payload) == (ERROR, b"\x40\x00")
    rig.wait(0.5)
    assert rig.world.commanded_wheel_speeds == (0.0, 0.0) and rig.world.encoders_mm == (0.0, 0.0)
    assert rig.ok(set_motor(-200, -100), 0) == b""
    assert rig.world.commanded_wheel_speeds == (-200, -100)
    rig.wait(0.5)
    left, right, _ = struct.unpack("<iiB", rig.ok(b"\x31"))
    assert left < right < 0


def test_the_watchdog_stops_the_simulated_robot() -> None:
    rig = Rig()
    rig.ok(set_velocity(-0.15, 0.0))  # backwards: there is room behind the start pose
    for _ in range(12):  # only SYNC for 1.2 s: it does not feed the watchdog
        rig.wait(0.1)
        assert rig.stack.receive(SYNC, rig.now) == SYNC
    assert rig.world.commanded_wheel_speeds == (0.0, 0.0)
    assert rig.stack.counters().watchdog_trips == 1
    rig.wait(1.0)  # the wheels have run down by now
    stopped = rig.world.encoders_mm
    rig.wait(1.0)
    assert rig.world.encoders_mm == stopped and stopped[0] < 0
    flags, count = rig.ok(b"\x90\x01")
    assert flags & 0x01 and count == 1


def test_low_battery_health_is_re_evaluated_every_100_ms() -> None:
    rig = Rig()
    assert rig.ok(b"\x90\x01") == b"\x00\x00"
    rig.world.set_battery_percent(25)
    rig.wait(0.1)
    assert rig.ok(b"\x90\x01") == b"\x01\x01"
    assert rig.ok(b"\x90\x02\x00")[:4] == struct.pack("<I", LOW_BATTERY_WARNING_CODE)
    assert LOW_BATTERY_WARNING_CODE == 0x01020100 and LOW_BATTERY_ERROR_CODE == 0x02020100
    rig.world.set_battery_percent(5)
    rig.wait(0.1)
    assert rig.ok(b"\x90\x01") == b"\x02\x01"
    error = rig.ok(b"\x90\x02\x00", 36)
    assert error[:4] == struct.pack("<I", LOW_BATTERY_ERROR_CODE)
    assert error[4:].split(b"\0")[0] == b"battery critically low"
    # The Core may clear it, but it comes back while the battery stays low, as on the reference.
    assert rig.ok(b"\x90\x03" + struct.pack("<I", LOW_BATTERY_ERROR_CODE), 0) == b""
    assert rig.ok(b"\x90\x01") == b"\x00\x00"
    rig.wait(0.1)
    assert rig.ok(b"\x90\x01") == b"\x02\x01"
    rig.world.set_battery_percent(60)
    rig.wait(0.1)
    assert rig.ok(b"\x90\x01") == b"\x00\x00"


def test_binary_config_is_served_when_configured() -> None:
    assert Rig().ask(b"\x21") == Frame(ERROR, b"\x00\x80", long=True)
    blob = binconf.example_blob()
    rig = Rig(SimulatedBase(binary_config=blob))
    assert rig.ok(b"\x21") == blob
    assert binconf.decode(rig.ok(b"\x21")) == binconf.example_config()


def test_time_scale_runs_the_world_faster() -> None:
    rig = Rig(SimulatedBase(time_scale=4.0))
    rig.wait(0.5)
    assert rig.world.time_s == pytest.approx(2.0)


def test_external_commands_queued_on_the_simulator_are_polled() -> None:
    rig = Rig()
    rig.sim.queue_external_command(0xA4)  # GO_HOME
    assert rig.ok(b"\x50") == b"\xa4\x00"
    assert rig.sim.snapshot()["pending_commands"] == [0xA4]
    rig.ok(b"\x5f")
    assert rig.ok(b"\x50") == b""


def test_events_are_recorded_and_reboot_restarts_the_robot() -> None:
    rig = Rig()
    rig.ok(b"\x60\x63")
    assert list(rig.sim.events) == [0x63]
    start = rig.world.true_pose
    rig.ok(set_velocity(-0.2, 0.0))
    rig.wait(0.5)
    rig.ok(set_velocity(-0.2, 0.0))
    assert rig.world.true_pose != start
    assert rig.ask(b"\x02", cmd=0xF9) == Frame(OK, b"", long=True)
    rig.wait(0.01)  # the reset comes once the answer has been handed over
    assert rig.sim.reboots == 1
    assert rig.world.true_pose == start and rig.world.time_s == pytest.approx(0.01)  # a new world
    assert rig.ok(set_velocity(0.0, 0.0))[:12] == b"\0" * 12  # the first deadreckon after power-up


def test_sdk2020_profile_over_the_simulator() -> None:
    rig = Rig(config=BaseConfig(profile=Profile.SDK2020))
    rig.ok(b"\x10\x01", 39)
    rig.wait(0.25)
    answer = rig.ok(set_velocity(0.0, 0.0), 17)
    assert struct.unpack_from("<I", answer, 13)[0] == 250


def test_snapshot_follows_the_dashboard_schema() -> None:
    from ctrlbus.web import schema

    rig = Rig(SimulatedBase(time_scale=2.0))
    rig.sim.queue_external_command(0xA0)
    snapshot = rig.sim.snapshot()
    assert snapshot["speed"] == 2.0 and snapshot["pending_commands"] == [0xA0]
    # odometry_origin is the Core's knowledge; the Core emulator adds it.
    snapshot["odometry_origin"] = {"x_mm": 0.0, "y_mm": 0.0, "theta_deg": 0.0}
    problems: list[str] = []
    schema._check(snapshot, schema.SIM, "sim", problems)
    assert problems == []


def test_simulated_base_rejects_bad_arguments() -> None:
    from ctrlbus.errors import UsageError

    for scale in (0, -1, float("inf"), float("nan")):
        with pytest.raises(UsageError, match="time scale"):
            SimulatedBase(time_scale=scale)
    with pytest.raises(UsageError, match="binary_config"):
        SimulatedBase(binary_config="blob")  # type: ignore[arg-type]


def read_frames(link: Any, count: int, limit_s: float = 5.0) -> list[Frame]:
    decoder = StreamDecoder()
    frames: list[Frame] = []
    deadline = time.monotonic() + limit_s
    while len(frames) < count:
        assert time.monotonic() < deadline, f"only {len(frames)} of {count} answers within {limit_s} s"
        frames += decoder.feed(link.read(0.05))
    return frames


def test_end_to_end_over_a_link_pair_in_real_time() -> None:
    core_end, base_end = link_pair()
    sim = SimulatedBase()
    stack = BaseStack(sim)
    try:
        with BaseRunner(stack, base_end):
            core_end.write(encode(CTRL_BUS, b"\x10\x01") + encode(CTRL_BUS, set_velocity(0.2, 0.0)))
            connect, first = read_frames(core_end, 2)
            assert connect.payload[:11] == b"ctrlbus sim" and first.payload[:12] == b"\0" * 12
            time.sleep(0.3)
            core_end.write(encode(CTRL_BUS, set_velocity(0.0, 0.0)))
            (moved,) = read_frames(core_end, 1)
            dx_mm = struct.unpack_from("<i", moved.payload)[0] / 65536
            assert dx_mm > 5  # 0.3 s at up to 0.2 m/s, after the wheels' acceleration
            assert sim.world.time_s > 0.3
    finally:
        core_end.close()
