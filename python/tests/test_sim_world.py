# SPDX-License-Identifier: MIT
"""The simulated world (ctrlbus.sim) and the shared differential-drive math (ctrlbus.kinematics)."""

from __future__ import annotations

import copy
import json
import math
import random
from importlib import resources
from pathlib import Path
from typing import Any

import pytest

from ctrlbus.constants import POWER_CHARGING, POWER_DC_CONNECTED, POWER_ON_DOCK
from ctrlbus.errors import CtrlbusError, SimConfigError, UsageError
from ctrlbus.kinematics import (
    DeadreckonDelta,
    Pose,
    deadreckon_from_wheel_travel,
    integrate_pose,
    normalize_angle_deg,
    relative_pose,
    velocity_from_wheel_speeds,
    wheel_speeds_from_velocity,
)
from ctrlbus.sim import World, load_base_description, load_room
from ctrlbus.sim.description import base_description_from_dict
from ctrlbus.sim.room import room_from_dict
from ctrlbus.sim.world import BEACON_HOLD_S, BUMPER_TRAVEL_MM

TRACK = 236.0
RADIUS = 170.0
ACCEL = 1000.0


def default_base_dict() -> dict[str, Any]:
    text = (resources.files("ctrlbus") / "data" / "sim-base.json").read_text(encoding="utf-8")
    data: dict[str, Any] = json.loads(text)
    return data


def default_room_dict() -> dict[str, Any]:
    text = (resources.files("ctrlbus") / "data" / "sim-room.json").read_text(encoding="utf-8")
    data: dict[str, Any] = json.loads(text)
    return data


def quiet_base_dict() -> dict[str, Any]:
    """The default robot with exact encoders and a known drive."""
    data = default_base_dict()
    data["wheel_slip"] = {"random_fraction": 0.0, "left_scale_error": 0.0, "right_scale_error": 0.0}
    data["radius_mm"] = RADIUS
    data["wheel_track_mm"] = TRACK
    data["max_wheel_accel_mm_s2"] = ACCEL
    data["max_wheel_speed_mm_s"] = 700
    return data


def open_room_dict(**extra: Any) -> dict[str, Any]:
    """A 20 m square with the robot in the middle, facing +x."""
    room: dict[str, Any] = {
        "walls": [
            {"points": [[-10000, -10000], [10000, -10000], [10000, 10000], [-10000, 10000]], "closed": True}
        ],
        "start_pose": {"x_mm": 0, "y_mm": 0, "theta_deg": 0},
    }
    room.update(extra)
    return room


def make_world(
    base: dict[str, Any] | None = None, room: dict[str, Any] | None = None, **kwargs: Any
) -> World:
    return World(
        base_description_from_dict(base if base is not None else quiet_base_dict()),
        room_from_dict(room if room is not None else open_room_dict()),
        **kwargs,
    )


def run(world: World, seconds: float, dt: float = 0.02) -> None:
    for _ in range(round(seconds / dt)):
        world.step(dt)


# ------------------------------------------------------------------------------- kinematics


def test_velocity_and_wheel_speeds_convert_both_ways() -> None:
    left, right = wheel_speeds_from_velocity(0.2, 0.5, TRACK)
    assert left == pytest.approx(200.0 - 0.5 * TRACK / 2)
    assert right == pytest.approx(200.0 + 0.5 * TRACK / 2)
    vx, omega = velocity_from_wheel_speeds(left, right, TRACK)
    assert vx == pytest.approx(0.2)
    assert omega == pytest.approx(0.5)


def test_deadreckon_straight_turn_and_quarter_circle() -> None:
    assert deadreckon_from_wheel_travel(100.0, 100.0, TRACK) == DeadreckonDelta(100.0, 0.0, 0.0)
    spin = deadreckon_from_wheel_travel(-50.0, 50.0, TRACK)
    assert spin.dx_mm == pytest.approx(0.0, abs=1e-12)
    assert spin.dy_mm == pytest.approx(0.0, abs=1e-12)
    assert spin.dtheta_deg == pytest.approx(math.degrees(100.0 / TRACK))
    # Left wheel still, right wheel a quarter circle around it: the centre ends half a track
    # ahead and half a track to the left, turned by 90 degrees.
    quarter = deadreckon_from_wheel_travel(0.0, math.pi / 2 * TRACK, TRACK)
    assert quarter.dx_mm == pytest.approx(TRACK / 2)
    assert quarter.dy_mm == pytest.approx(TRACK / 2)
    assert quarter.dtheta_deg == pytest.approx(90.0)


def test_deadreckon_arc_matches_fine_integration() -> None:
    rng = random.Random(7)
    for _ in range(50):
        left = rng.uniform(-300.0, 300.0)
        right = rng.uniform(-300.0, 300.0)
        arc = integrate_pose(Pose(0.0, 0.0, 0.0), deadreckon_from_wheel_travel(left, right, TRACK))
        x = y = theta = 0.0
        pieces = 20000
        for _ in range(pieces):  # midpoint rule, tiny steps
            distance = (left + right) / 2 / pieces
            turn = (right - left) / TRACK / pieces
            x += distance * math.cos(theta + turn / 2)
            y += distance * math.sin(theta + turn / 2)
            theta += turn
        assert arc.x_mm == pytest.approx(x, abs=1e-6)
        assert arc.y_mm == pytest.approx(y, abs=1e-6)
        assert normalize_angle_deg(arc.theta_deg - math.degrees(theta)) == pytest.approx(0.0, abs=1e-9)


def test_deadreckon_small_turns_are_continuous() -> None:
    # Either side of the series/closed-form switch (a 1e-4 rad turn: 0.0118 mm here) the results agree.
    for turn_mm in (1e-9, 1e-6, 0.0117, 0.0119, 0.03, 1.0):
        delta = deadreckon_from_wheel_travel(500.0 - turn_mm, 500.0 + turn_mm, TRACK)
        angle = 2 * turn_mm / TRACK
        radius = 500.0 / angle
        assert delta.dx_mm == pytest.approx(radius * math.sin(angle), rel=1e-12)
        assert delta.dy_mm == pytest.approx(2.0 * radius * math.sin(angle / 2) ** 2, rel=1e-12)


def test_relative_pose_inverts_integrate_pose() -> None:
    rng = random.Random(3)
    for _ in range(100):
        start = Pose(rng.uniform(-5000, 5000), rng.uniform(-5000, 5000), rng.uniform(-180, 180))
        delta = DeadreckonDelta(rng.uniform(-500, 500), rng.uniform(-500, 500), rng.uniform(-179, 179))
        back = relative_pose(start, integrate_pose(start, delta))
        assert back.dx_mm == pytest.approx(delta.dx_mm, abs=1e-9)
        assert back.dy_mm == pytest.approx(delta.dy_mm, abs=1e-9)
        assert back.dtheta_deg == pytest.approx(delta.dtheta_deg, abs=1e-9)


def test_integrating_reported_deltas_gives_the_odometry_pose() -> None:
    # What a base reports through 0x41 (relative poses of its odometry between calls) and what
    # the Core integrates must land on the base's own dead-reckoned pose.
    world = make_world(default_base_dict())
    core_pose = world.odometry_pose
    last = world.odometry_pose
    rng = random.Random(11)
    for _ in range(60):
        world.set_velocity(rng.uniform(-0.3, 0.5), rng.uniform(-1.5, 1.5))
        world.step(rng.choice((0.013, 0.05, 0.2)))
        now = world.odometry_pose
        core_pose = integrate_pose(core_pose, relative_pose(last, now))
        last = now
    assert core_pose.x_mm == pytest.approx(world.odometry_pose.x_mm, abs=1e-6)
    assert core_pose.y_mm == pytest.approx(world.odometry_pose.y_mm, abs=1e-6)
    assert normalize_angle_deg(core_pose.theta_deg - world.odometry_pose.theta_deg) == pytest.approx(
        0.0, abs=1e-9
    )
    assert math.hypot(world.odometry_pose.x_mm, world.odometry_pose.y_mm) > 100.0  # it did move


# ------------------------------------------------------------------------------- driving


def test_straight_drive_distance() -> None:
    world = make_world()
    world.set_wheel_speeds(200.0, 200.0)
    run(world, 3.0)
    # 0.2 s ramp at 1000 mm/s^2 covers 20 mm, then 2.8 s at 200 mm/s.
    assert world.true_pose.x_mm == pytest.approx(20.0 + 200.0 * 2.8, abs=1e-6)
    assert world.true_pose.y_mm == pytest.approx(0.0, abs=1e-9)
    assert world.true_pose.theta_deg == pytest.approx(0.0, abs=1e-9)
    assert world.encoders_mm[0] == pytest.approx(580.0, abs=1e-6)
    assert world.encoders_mm[1] == pytest.approx(580.0, abs=1e-6)


def test_backward_drive_counts_encoders_negative() -> None:
    world = make_world()
    world.set_velocity(-0.1, 0.0)
    run(world, 2.0)
    assert world.true_pose.x_mm == pytest.approx(-(5.0 + 100.0 * 1.9), abs=1e-6)
    assert world.encoders_mm[0] == pytest.approx(-195.0, abs=1e-6)


def test_turn_in_place_angle() -> None:
    world = make_world()
    world.set_velocity(0.0, 200.0 / TRACK)  # wheels at -100 / +100 mm/s
    assert world.commanded_wheel_speeds == pytest.approx((-100.0, 100.0))
    run(world, 2.0)
    wheel_travel = 5.0 + 100.0 * 1.9  # 0.1 s ramp, then full speed
    expected = math.degrees(2 * wheel_travel / TRACK)
    assert world.true_pose.theta_deg == pytest.approx(expected, abs=1e-6)
    assert world.true_pose.x_mm == pytest.approx(0.0, abs=1e-9)
    assert world.true_pose.y_mm == pytest.approx(0.0, abs=1e-9)


def test_acceleration_limit_respected() -> None:
    world = make_world()
    world.set_wheel_speeds(600.0, -300.0)
    dt = 0.013
    previous = world.wheel_speeds
    for _ in range(60):
        world.step(dt)
        now = world.wheel_speeds
        assert abs(now[0] - previous[0]) <= ACCEL * dt + 1e-9
        assert abs(now[1] - previous[1]) <= ACCEL * dt + 1e-9
        previous = now
    assert world.wheel_speeds == (600.0, -300.0)
    world.step(0.05)
    world.set_wheel_speeds(0.0, 0.0)
    world.step(0.1)
    assert world.wheel_speeds == pytest.approx((500.0, -200.0))


def test_wheel_speeds_clipped_to_motor_limit_and_bad_values_refused() -> None:
    world = make_world()
    world.set_wheel_speeds(5000.0, -5000.0)
    assert world.commanded_wheel_speeds == (700.0, -700.0)
    with pytest.raises(UsageError):
        world.set_wheel_speeds(math.nan, 0.0)
    with pytest.raises(UsageError):
        world.set_velocity(0.1, math.inf)
    with pytest.raises(UsageError):
        world.step(-0.1)


def test_one_large_step_equals_many_small_ones() -> None:
    coarse = make_world(default_base_dict())
    fine = make_world(default_base_dict())
    for world in (coarse, fine):
        world.set_wheel_speeds(300.0, 150.0)
    coarse.step(2.0)
    for _ in range(400):
        fine.step(0.005)
    assert coarse.true_pose == pytest.approx(fine.true_pose, abs=1e-9)
    assert coarse.odometry_pose == pytest.approx(fine.odometry_pose, abs=1e-9)


# ------------------------------------------------------------------------------- odometry


def test_odometry_equals_truth_without_noise() -> None:
    world = make_world()
    for left, right in ((300.0, 200.0), (-150.0, 150.0), (250.0, 250.0), (-100.0, -300.0)):
        world.set_wheel_speeds(left, right)
        run(world, 1.5)
    assert world.odometry_pose == world.true_pose
    assert math.hypot(world.true_pose.x_mm, world.true_pose.y_mm) > 100.0


def drive_pattern(world: World) -> None:
    for left, right in ((300.0, 200.0), (-150.0, 150.0), (250.0, 250.0), (300.0, 320.0)):
        world.set_wheel_speeds(left, right)
        run(world, 2.0)


def test_odometry_drifts_with_noise_deterministically() -> None:
    base = quiet_base_dict()
    base["wheel_slip"] = {"random_fraction": 0.01, "left_scale_error": 0.0, "right_scale_error": 0.0}
    first = make_world(base, seed=42)
    second = make_world(base, seed=42)
    other = make_world(base, seed=43)
    for world in (first, second, other):
        drive_pattern(world)
    truth = first.true_pose
    drift = math.hypot(first.odometry_pose.x_mm - truth.x_mm, first.odometry_pose.y_mm - truth.y_mm)
    assert drift > 1.0
    assert first.odometry_pose == second.odometry_pose
    assert first.encoders_mm == second.encoders_mm
    assert other.odometry_pose != first.odometry_pose
    assert other.true_pose == truth  # noise is in the encoders, not in the motion


def test_scale_error_makes_encoders_overcount() -> None:
    base = quiet_base_dict()
    base["wheel_slip"] = {"random_fraction": 0.0, "left_scale_error": 0.01, "right_scale_error": 0.0}
    world = make_world(base)
    world.set_wheel_speeds(200.0, 200.0)
    run(world, 2.0)
    assert world.encoders_mm[0] == pytest.approx(world.encoders_mm[1] * 1.01)
    assert world.odometry_pose.theta_deg < 0.0  # the left wheel seems faster: odometry turns right
    assert world.true_pose.theta_deg == 0.0


# ------------------------------------------------------------------------------- sensors


def single_sensor_base(**sensor: Any) -> dict[str, Any]:
    base = quiet_base_dict()
    entry = {"name": "probe", "x_mm": 100, "y_mm": 0, "yaw_deg": 0, "max_range_mm": 3000, "beam_deg": 0}
    entry.update(sensor)
    base["distance_sensors"] = [entry]
    return base


def test_ray_cast_distance_to_a_known_wall() -> None:
    room = open_room_dict(walls=[{"points": [[2000, -5000], [2000, 5000]]}])
    world = make_world(single_sensor_base(), room)
    assert world.distance_hits_mm() == pytest.approx((1900.0,))
    assert world.distance_readings_mm() == pytest.approx((1900.0,))
    world.place_robot(Pose(500.0, 0.0, 30.0))
    # Sensor 100 mm ahead along the 30 degree heading, ray at 30 degrees to the wall's normal.
    sensor_x = 500.0 + 100.0 * math.cos(math.radians(30))
    assert world.distance_hits_mm()[0] == pytest.approx((2000.0 - sensor_x) / math.cos(math.radians(30)))


def test_ray_cast_beam_reports_nearest_echo() -> None:
    # A wall off to the side, missed by the centre ray, is caught by the edge of a 30 degree beam.
    room = open_room_dict(walls=[{"points": [[500, 200], [2000, 200]]}])
    narrow = make_world(single_sensor_base(beam_deg=0, y_mm=0), room)
    wide = make_world(single_sensor_base(beam_deg=30, y_mm=0), room)
    assert narrow.distance_hits_mm() == (None,)
    assert wide.distance_hits_mm()[0] == pytest.approx(200.0 / math.sin(math.radians(15)))


@pytest.mark.parametrize(("no_echo", "expected"), [("zero", 0.0), ("max_range", 1000.0)])
def test_out_of_range_reports_per_description(no_echo: str, expected: float) -> None:
    room = open_room_dict(walls=[{"points": [[2000, -5000], [2000, 5000]]}])
    world = make_world(single_sensor_base(max_range_mm=1000, no_echo=no_echo), room)
    assert world.distance_hits_mm() == (None,)
    assert world.distance_readings_mm() == (expected,)


def test_sensor_noise_is_seeded_and_bounded() -> None:
    room = open_room_dict(walls=[{"points": [[2000, -5000], [2000, 5000]]}])
    base = single_sensor_base(noise_stddev_mm=5)
    first = make_world(base, room, seed=5)
    second = make_world(base, room, seed=5)
    readings = []
    for world in (first, second):
        values = []
        for _ in range(20):
            world.step(0.01)
            values.append(world.distance_readings_mm()[0])
        readings.append(values)
    assert readings[0] == readings[1]
    assert len(set(readings[0])) > 1
    assert all(abs(value - 1900.0) < 50.0 for value in readings[0])


# ------------------------------------------------------------------------------- bumpers


def wall_ahead_room(wall_x: float = 1000.0) -> dict[str, Any]:
    return open_room_dict(
        walls=[{"points": [[wall_x, -5000], [wall_x, 5000]]}, {"points": [[-3000, -5000], [-3000, 5000]]}]
    )


def test_bumper_triggers_at_a_wall_stops_and_refuses_forward() -> None:
    world = make_world(room=wall_ahead_room())
    world.set_velocity(0.3, 0.0)
    run(world, 5.0)
    gap = 1000.0 - world.true_pose.x_mm - RADIUS
    assert 0.0 <= gap <= BUMPER_TRAVEL_MM
    assert world.bumpers_pressed == (True, True)  # head-on: both arcs meet at 0 degrees
    assert world.commanded_wheel_speeds == (0.0, 0.0)
    assert world.wheel_speeds == (0.0, 0.0)
    assert world.odometry_pose == world.true_pose  # the encoders stopped with the robot

    stopped_at = world.true_pose
    world.set_wheel_speeds(200.0, 200.0)
    assert world.commanded_wheel_speeds == (0.0, 0.0)
    world.set_wheel_speeds(200.0, -100.0)  # the forward wheel is refused, the reverse one kept
    assert world.commanded_wheel_speeds == (0.0, -100.0)
    world.stop()
    run(world, 1.0)
    assert world.true_pose == stopped_at

    world.set_wheel_speeds(-100.0, -100.0)
    run(world, 1.0)
    assert world.bumpers_pressed == (False, False)
    world.set_wheel_speeds(100.0, 100.0)
    assert world.commanded_wheel_speeds == (100.0, 100.0)


def test_oblique_contact_presses_only_one_bumper() -> None:
    world = make_world(room=wall_ahead_room())
    world.place_robot(Pose(0.0, 0.0, -40.0))  # the wall ahead is now 40 degrees to the left
    world.set_velocity(0.3, 0.0)
    run(world, 6.0)
    assert world.bumpers_pressed == (True, False)
    assert 1000.0 - world.true_pose.x_mm - RADIUS <= BUMPER_TRAVEL_MM


def test_wall_behind_stalls_without_bumper() -> None:
    world = make_world(room=wall_ahead_room())
    world.place_robot(Pose(-3000.0 + RADIUS + 50.0, 0.0, 0.0))
    world.set_velocity(-0.2, 0.0)
    run(world, 0.5)
    assert world.held_by == "wall"
    assert not world.stalled  # the detector is blind for the first 0.6 s
    run(world, 0.5)
    assert world.stalled
    assert world.motion_status == 0x02
    assert world.bumpers_pressed == (False, False)
    assert world.true_pose.x_mm - (-3000.0) == pytest.approx(RADIUS, abs=1e-3)
    world.set_velocity(0.2, 0.0)
    world.step(0.1)
    assert not world.stalled
    assert world.held_by is None


# ------------------------------------------------------------------------------- cliffs


def test_cliff_sensors_trigger_and_robot_stops_at_the_edge() -> None:
    room = open_room_dict(
        cliffs=[{"name": "stairs", "points": [[800, -2000], [3000, -2000], [3000, 2000], [800, 2000]]}]
    )
    world = make_world(room=room)
    assert world.cliffs_triggered == (False, False, False, False)
    world.set_velocity(0.2, 0.0)
    run(world, 8.0)
    names = [sensor.name for sensor in world.base.cliff_sensors]
    triggered = dict(zip(names, world.cliffs_triggered, strict=True))
    assert triggered == {"front_left": True, "front_right": True, "left": True, "right": True}
    assert world.traction_lost
    assert world.motion_status & 0x04
    assert world.true_pose.x_mm == pytest.approx(800.0, abs=1e-3)  # wheel axle at the edge
    world.set_velocity(-0.2, 0.0)
    run(world, 2.0)
    assert world.cliffs_triggered == (False, False, False, False)
    assert not world.traction_lost


# ------------------------------------------------------------------------------- battery and dock


def docked_pose(world: World) -> Pose:
    dock = world.room.dock
    assert dock is not None
    contacts_x = world.base.charging_contacts.x_mm
    # Facing the dock, contacts on its point.
    heading = math.radians(dock.heading_deg)
    return Pose(
        dock.x_mm + contacts_x * math.cos(heading),
        dock.y_mm + contacts_x * math.sin(heading),
        normalize_angle_deg(dock.heading_deg + 180.0),
    )


def test_battery_drains_faster_when_driving() -> None:
    idle = make_world()
    driving = make_world()
    driving.set_velocity(0.4, 0.0)
    run(idle, 10.0)
    run(driving, 10.0)
    start = 80.0
    idle_used = start - idle.battery_percent
    driving_used = start - driving.battery_percent
    assert idle_used == pytest.approx(150.0 * 10.0 / 3600.0 / 2600.0 * 100.0, rel=1e-6)
    assert driving_used > 2.0 * idle_used
    assert idle.power_status == 0
    assert not idle.charging


def test_docking_charges_and_sets_power_bits() -> None:
    world = make_world(quiet_base_dict(), default_room_dict())
    assert not world.docked
    dock_pose = docked_pose(world)
    # Drive into the dock from 300 mm out.
    heading = math.radians(dock_pose.theta_deg)
    world.place_robot(
        Pose(
            dock_pose.x_mm - 300.0 * math.cos(heading),
            dock_pose.y_mm - 300 * math.sin(heading),
            dock_pose.theta_deg,
        )
    )
    world.set_velocity(0.1, 0.0)
    for _ in range(400):
        world.step(0.02)
        if world.docked:
            world.stop()
            break
    assert world.docked
    assert world.power_status == POWER_CHARGING | POWER_ON_DOCK == 5
    before = world.battery_percent
    run(world, 60.0, dt=0.5)
    assert world.battery_percent == pytest.approx(before + 1300.0 * 60.0 / 3600.0 / 2600.0 * 100.0, rel=1e-6)
    world.set_battery_percent(100.0)
    world.step(0.1)
    assert world.power_status == POWER_ON_DOCK  # full: on the dock, no longer charging
    world.set_velocity(-0.2, 0.0)
    run(world, 1.0)
    assert not world.docked
    assert world.power_status == 0


def test_docking_needs_the_contacts_to_face_the_dock() -> None:
    world = make_world(quiet_base_dict(), default_room_dict())
    pose = docked_pose(world)
    world.place_robot(pose)
    assert world.docked
    world.place_robot(Pose(pose.x_mm, pose.y_mm, pose.theta_deg + 60.0))
    assert not world.docked


def test_dc_cable_charges_anywhere() -> None:
    world = make_world()
    world.set_dc_connected(True)
    world.step(0.1)
    assert world.power_status == POWER_CHARGING | POWER_DC_CONNECTED == 3
    assert world.battery_percent > 80.0


def test_empty_battery_stops_the_motors() -> None:
    world = make_world()
    world.set_battery_percent(0.0)
    world.set_velocity(0.3, 0.0)
    run(world, 1.0)
    assert world.true_pose == Pose(0.0, 0.0, 0.0)
    with pytest.raises(UsageError):
        world.set_battery_percent(101.0)


# ------------------------------------------------------------------------------- beacons


LEFT, MAIN, RIGHT = 0b001, 0b010, 0b100


def beacon_world(**room_extra: Any) -> World:
    room = default_room_dict()
    room.update(room_extra)
    return make_world(quiet_base_dict(), room)


def probe_bits(world: World) -> dict[str, int]:
    return {
        probe.name: bits for probe, bits in zip(world.base.beacon_probes, world.beacon_bits(), strict=True)
    }


def test_beacons_seen_from_in_front_of_the_dock() -> None:
    world = beacon_world()
    world.place_robot(Pose(1500.0, 2000.0, 180.0))  # on the centre line, facing the dock
    world.step(0.1)
    bits = probe_bits(world)
    assert bits["main"] & MAIN
    assert all(bits[name] & MAIN == 0 for name in ("left", "right"))  # the main cone is narrow


def test_side_beacons_tell_which_side_of_the_centre_line() -> None:
    world = beacon_world()
    # Facing the dock, the robot's left is the room's -y side here (dock faces +x).
    world.place_robot(Pose(1200.0, 1200.0, 160.0))
    world.step(0.1)
    seen = probe_bits(world)
    assert seen["main"] == LEFT
    world.place_robot(Pose(1200.0, 2800.0, 200.0))
    world.step(0.1)
    assert probe_bits(world)["main"] == LEFT | RIGHT  # the left beacon is held for 260 ms
    world.step(0.3)
    assert probe_bits(world)["main"] == RIGHT


def test_beacons_not_seen_from_behind_facing_away_or_through_a_wall() -> None:
    world = beacon_world()
    world.place_robot(Pose(1500.0, 2000.0, 0.0))  # in front but facing away
    world.step(0.5)
    assert world.beacon_bits() == (0, 0, 0)
    world.place_robot(Pose(-1000.0, 2000.0, 0.0))  # behind the dock's wall, facing it
    world.step(0.5)
    assert world.beacon_bits() == (0, 0, 0)
    room = default_room_dict()
    room["walls"].append({"points": [[700, 1500], [700, 2500]]})  # a screen between dock and robot
    screened = make_world(quiet_base_dict(), room)
    screened.place_robot(Pose(1500.0, 2000.0, 180.0))
    screened.step(0.5)
    assert screened.beacon_bits() == (0, 0, 0)


def test_beacon_bits_expire_260_ms_after_last_seen() -> None:
    world = beacon_world()
    world.place_robot(Pose(1500.0, 2000.0, 180.0))
    world.step(0.2)
    assert probe_bits(world)["main"] & MAIN
    world.place_robot(Pose(1500.0, 2000.0, 0.0), reset_odometry=False)
    turned_at = world.time_s
    world.step(0.2)
    assert probe_bits(world)["main"] & MAIN  # still held
    world.step(BEACON_HOLD_S - 0.2 + 0.01)
    assert world.time_s - turned_at > BEACON_HOLD_S
    assert world.beacon_bits() == (0, 0, 0)


def test_no_dock_no_beacons() -> None:
    world = make_world()
    world.step(0.1)
    assert world.beacon_bits() == (0, 0, 0)
    assert not world.docked


# ------------------------------------------------------------------------------- snapshot


def test_snapshot_is_json_ready_and_complete() -> None:
    world = World()  # the packaged defaults
    world.set_velocity(0.2, 0.3)
    world.step(1.0)
    snapshot = json.loads(json.dumps(world.snapshot()))
    assert snapshot["pose"]["x_mm"] == pytest.approx(world.true_pose.x_mm)
    assert snapshot["odometry_pose"]["theta_deg"] == pytest.approx(world.odometry_pose.theta_deg)
    assert len(snapshot["distance_sensors"]) == len(world.base.distance_sensors) == 6
    assert [sensor["reading_mm"] for sensor in snapshot["distance_sensors"]] == list(
        world.distance_readings_mm()
    )
    assert [bumper["name"] for bumper in snapshot["bumpers"]] == ["left", "right"]
    assert len(snapshot["cliff_sensors"]) == 4
    assert [probe["name"] for probe in snapshot["beacon_probes"]] == ["left", "main", "right"]
    assert [beacon["name"] for beacon in snapshot["room"]["dock"]["beacons"]] == ["left", "main", "right"]
    assert snapshot["room"]["walls"][0]["closed"] is True
    assert snapshot["battery"]["percent"] < 80.0
    assert len(snapshot["trail"]) > 1
    assert "room" not in world.snapshot(include_room=False)


# ------------------------------------------------------------------------------- descriptions


def test_packaged_defaults_load() -> None:
    base = load_base_description()
    room = load_room()
    assert base.radius_mm == 170.0
    assert base.wheel_track_mm == 236.0
    assert 5 <= len(base.distance_sensors) <= 8
    assert [probe.name for probe in base.beacon_probes] == ["left", "main", "right"]
    assert room.dock is not None
    assert [beacon.code for beacon in room.dock.beacons] == [80, 12, 2]
    mounts = base.bumper_mounts()
    assert mounts[0].yaw_deg == 45.0 and mounts[1].yaw_deg == 315.0
    assert mounts[0].x_mm == pytest.approx(RADIUS * math.cos(math.radians(45)))


def test_description_files_load_from_disk(tmp_path: Path) -> None:
    path = tmp_path / "base.json"
    data = quiet_base_dict()
    data["model"] = "mine"
    path.write_text(json.dumps(data), encoding="utf-8")
    assert load_base_description(path).model == "mine"
    room_path = tmp_path / "room.json"
    room_path.write_text(json.dumps(open_room_dict()), encoding="utf-8")
    assert load_room(room_path).start_pose == Pose(0.0, 0.0, 0.0)


def broken(change: Any) -> dict[str, Any]:
    data = copy.deepcopy(quiet_base_dict())
    change(data)
    return data


@pytest.mark.parametrize(
    ("change", "key"),
    [
        (lambda d: d.pop("radius_mm"), "radius_mm"),
        (lambda d: d.update(radius_mm="big"), "radius_mm"),
        (lambda d: d.update(radius_mm=-5), "radius_mm"),
        (lambda d: d.update(wheel_track_mm=400), "wheel_track_mm"),
        (lambda d: d.update(radius_m=170), "radius_m"),
        (lambda d: d.update(model="a model name too long"), "model"),
        (lambda d: d["distance_sensors"][1].update(yaw_deg=400), "distance_sensors[1].yaw_deg"),
        (lambda d: d["distance_sensors"][2].update(yaw_deg=True), "distance_sensors[2].yaw_deg"),
        (lambda d: d["distance_sensors"][0].update(type="lidar"), "distance_sensors[0].type"),
        (lambda d: d["distance_sensors"][0].update(no_echo="none"), "distance_sensors[0].no_echo"),
        (lambda d: d["distance_sensors"][0].pop("max_range_mm"), "distance_sensors[0].max_range_mm"),
        (lambda d: d["distance_sensors"][3].update(x_mm=400), "distance_sensors[3]"),
        (lambda d: d["distance_sensors"][4].update(name="sonar_front"), "distance_sensors[4].name"),
        (lambda d: d.update(distance_sensors=d["distance_sensors"] * 2), "distance_sensors"),
        (lambda d: d["bumpers"][0].update(end_deg=0), "bumpers[0].end_deg"),
        (lambda d: d["cliff_sensors"].append({"x_mm": 0, "y_mm": 0}), "cliff_sensors"),
        (lambda d: d["beacon_probes"][1].update(fov_deg=0), "beacon_probes[1].fov_deg"),
        (lambda d: d["charging_contacts"].update(yaw_deg=-1), "charging_contacts.yaw_deg"),
        (lambda d: d["battery"].update(initial_percent=120), "battery.initial_percent"),
        (lambda d: d["battery"].update(capacity_mah=0), "battery.capacity_mah"),
        (lambda d: d.update(battery=[]), "battery"),
        (lambda d: d["wheel_slip"].update(random_fraction=-0.1), "wheel_slip.random_fraction"),
        (lambda d: d.update(seed=1.5), "seed"),
    ],
)
def test_bad_base_description_names_the_key(change: Any, key: str) -> None:
    with pytest.raises(SimConfigError) as caught:
        base_description_from_dict(broken(change), "robot.json")
    message = str(caught.value)
    assert message.startswith(f"robot.json: {key}:"), message
    assert isinstance(caught.value, CtrlbusError)


@pytest.mark.parametrize(
    ("room", "key"),
    [
        ({"start_pose": {"x_mm": 0, "y_mm": 0}}, "walls"),
        (open_room_dict(walls=[]), "walls"),
        (open_room_dict(walls=[{"points": [[0, 0]]}]), "walls[0].points"),
        (open_room_dict(walls=[{"points": [[0, 0], [1, "x"]]}]), "walls[0].points[1]"),
        (open_room_dict(cliffs=[{"points": [[0, 0], [1, 1]]}]), "cliffs[0].points"),
        (open_room_dict(dock={"x_mm": 0, "y_mm": 0, "heading_deg": 500}), "dock.heading_deg"),
        (
            open_room_dict(dock={"x_mm": 0, "y_mm": 0, "heading_deg": 0, "beacons": [{"cone_deg": 10}]}),
            "dock.beacons[0].range_mm",
        ),
        ({"walls": [{"points": [[0, 0], [1, 1]]}]}, "start_pose"),
        (open_room_dict(start_pose={"x_mm": 0, "y_mm": 0, "theta": 0}), "start_pose.theta"),
        ([1, 2], "top level"),
    ],
)
def test_bad_room_names_the_key(room: Any, key: str) -> None:
    with pytest.raises(SimConfigError) as caught:
        room_from_dict(room, "room.json")
    assert str(caught.value).startswith(f"room.json: {key}:"), str(caught.value)


def test_start_pose_inside_a_wall_or_over_a_cliff_is_refused() -> None:
    base = base_description_from_dict(quiet_base_dict())
    room = room_from_dict(wall_ahead_room(wall_x=100.0), "room.json")
    with pytest.raises(SimConfigError, match=r"^room.json: start_pose: .*overlaps a wall"):
        World(base, room)
    cliff_room = room_from_dict(
        open_room_dict(cliffs=[{"points": [[-50, -500], [50, -500], [50, 500]]}]), "r.json"
    )
    with pytest.raises(SimConfigError, match="cliff"):
        World(base, cliff_room)
    world = World(base, room_from_dict(open_room_dict()))
    with pytest.raises(UsageError, match="overlaps a wall"):
        world.place_robot(Pose(9950.0, 0.0, 0.0))


def test_unreadable_description_files(tmp_path: Path) -> None:
    with pytest.raises(SimConfigError, match="cannot read"):
        load_base_description(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"radius_mm": 170,', encoding="utf-8")
    with pytest.raises(SimConfigError, match=r"bad.json: not valid JSON: .*line 1"):
        load_base_description(bad)
    nan = tmp_path / "nan.json"
    nan.write_text('{"radius_mm": NaN, "wheel_track_mm": 236}', encoding="utf-8")
    with pytest.raises(SimConfigError, match="NaN"):
        load_base_description(nan)
    listing = tmp_path / "list.json"
    listing.write_text("[]", encoding="utf-8")
    with pytest.raises(SimConfigError, match=r"list.json: top level: expected an object"):
        load_room(listing)
