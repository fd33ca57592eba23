# SPDX-License-Identifier: MIT
"""The simulated robot in its room: physics only, no protocol, no clock.

`World.step(dt_s)` advances simulated time; the caller decides how simulated time relates to the
wall clock. Everything a base reports is read from the world: encoders (with wheel-slip noise,
so odometry drifts from the ground truth), bumpers, cliff sensors, distance sensors (ray casting),
the dock's beacons as the probes see them, battery and power status. docs/simulator.md describes
the model; the descriptions come from ctrlbus.sim.description and ctrlbus.sim.room.
"""

from __future__ import annotations

import math
import random
from collections import deque
from typing import Any

from ctrlbus.constants import (
    MOTION_STALL,
    MOTION_TRACTION_LOST,
    POWER_CHARGING,
    POWER_DC_CONNECTED,
    POWER_ON_DOCK,
)
from ctrlbus.errors import SimConfigError, UsageError
from ctrlbus.kinematics import (
    Pose,
    deadreckon_from_wheel_travel,
    integrate_pose,
    normalize_angle_deg,
    to_world,
    wheel_speeds_from_velocity,
)
from ctrlbus.sim.description import BaseDescription, default_base_description
from ctrlbus.sim.geometry import (
    Point,
    angle_between_deg,
    angle_in_arc,
    closest_point_on_segment,
    distance_to_segment,
    line_of_sight,
    nearest_hit,
    point_in_polygon,
)
from ctrlbus.sim.room import Room, default_room

__all__ = [
    "BEACON_HOLD_S",
    "BEACON_SAMPLE_PERIOD_S",
    "BUMPER_TRAVEL_MM",
    "HELD_BY_CLIFF",
    "HELD_BY_WALL",
    "MAX_SUBSTEP_S",
    "RAYS_PER_BEAM",
    "STALL_BLIND_S",
    "TRAIL_LENGTH",
    "TRAIL_STEP_MM",
    "World",
]

MAX_SUBSTEP_S = 0.005  # one step(dt) is cut into pieces no longer than this
BEACON_SAMPLE_PERIOD_S = 0.05  # how often the probes look for the dock's beacons
BEACON_HOLD_S = 0.26  # a beacon bit expires this long after the beacon was last seen (reference)
STALL_BLIND_S = 0.6  # the stall detector ignores the first 0.6 s after the wheels start (reference)
BUMPER_TRAVEL_MM = 1.0  # a bumper closes when a wall comes this close to the rim
RAYS_PER_BEAM = 5  # rays cast across a distance sensor's beam; the nearest echo wins
TRAIL_STEP_MM = 20.0
TRAIL_LENGTH = 2000

# Power status bits of GET_BASE_STATUS and motion status bits of GET_BASE_MOTOR_DATA / 0x41.

HELD_BY_WALL = "wall"
HELD_BY_CLIFF = "cliff"

_OVERLAP_TOLERANCE_MM = 1e-6  # float slack when the body rests exactly against a wall
_BISECTION_STEPS = 30


def _ramp(speed: float, target: float, max_change: float) -> float:
    if target > speed:
        return min(target, speed + max_change)
    return max(target, speed - max_change)


class World:
    """A differential-drive robot in a room, advanced by step(dt_s) in simulated time.

    Poses are in the room frame (mm, degrees). The odometry pose starts at the true start pose and
    is integrated from the encoder counts, so with the noise off it equals the true pose.
    """

    def __init__(
        self,
        base: BaseDescription | None = None,
        room: Room | None = None,
        *,
        seed: int | None = None,
        start_pose: Pose | None = None,
    ) -> None:
        self._base = base if base is not None else default_base_description()
        self._room = room if room is not None else default_room()
        pose = self._room.start_pose if start_pose is None else _checked_pose(start_pose)
        problem = self._placement_problem(pose)
        if problem is not None:
            raise SimConfigError(f"{self._room.source}: start_pose: {problem}")
        chosen_seed = self._base.seed if seed is None else seed
        self._slip_rng = random.Random(chosen_seed)
        # Sensor noise draws from its own stream so that reading the sensors more or less often
        # never changes the odometry drift.
        self._sensor_rng = random.Random(chosen_seed + 1)

        self._time_s = 0.0
        self._pose = pose
        self._odometry = pose
        # The odometry's heading as a total turn, not wrapped: what deadreckon deltas are made of.
        self._odometry_turn_deg = pose.theta_deg
        self._commanded = (0.0, 0.0)
        self._wheels = (0.0, 0.0)
        self._encoders = (0.0, 0.0)
        self._held_by: str | None = None
        self._wheels_started_s: float | None = None
        self._dc_connected = False
        battery = self._base.battery
        self._charge_mah = battery.capacity_mah * battery.initial_percent / 100.0
        self._trail: deque[Point] = deque([(pose.x_mm, pose.y_mm)], maxlen=TRAIL_LENGTH)
        self._readings: tuple[tuple[float | None, ...], tuple[float, ...]] | None = None
        dock = self._room.dock
        beacon_count = 0 if dock is None else len(dock.beacons)
        self._beacon_seen_s: list[list[float | None]] = [
            [None] * beacon_count for _ in self._base.beacon_probes
        ]
        self._bumpers = self._pressed_bumpers()
        self._cliffs = self._triggered_cliffs()
        self._docked = self._contacts_on_dock()
        self._sample_beacons()
        self._next_beacon_sample_s = BEACON_SAMPLE_PERIOD_S

    # ----------------------------------------------------------------- description and time

    @property
    def base(self) -> BaseDescription:
        return self._base

    @property
    def room(self) -> Room:
        return self._room

    @property
    def time_s(self) -> float:
        """Simulated seconds since the world was made."""
        return self._time_s

    # ----------------------------------------------------------------------------- commands

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        """Command the wheels (mm/s, signed, forward positive).

        Speeds beyond the motors' limit are clipped. While a bumper is pressed a forward speed is
        refused (taken as 0), as the reference base does.
        """
        if not (math.isfinite(left_mm_s) and math.isfinite(right_mm_s)):
            raise UsageError(f"wheel speeds must be finite numbers, got {left_mm_s!r}, {right_mm_s!r}")
        limit = self._base.max_wheel_speed_mm_s
        left = min(limit, max(-limit, left_mm_s))
        right = min(limit, max(-limit, right_mm_s))
        if any(self._bumpers):
            left = min(left, 0.0)
            right = min(right, 0.0)
        self._commanded = (left, right)

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        """Command a forward speed (m/s) and turn rate (rad/s, positive = left), as 0x41 does."""
        if not (math.isfinite(vx_mps) and math.isfinite(omega_radps)):
            raise UsageError(f"velocity must be finite numbers, got {vx_mps!r}, {omega_radps!r}")
        self.set_wheel_speeds(*wheel_speeds_from_velocity(vx_mps, omega_radps, self._base.wheel_track_mm))

    def stop(self) -> None:
        self._commanded = (0.0, 0.0)

    def place_robot(self, pose: Pose, *, reset_odometry: bool = True) -> None:
        """Put the robot somewhere else, at rest; raises UsageError if that overlaps a wall or a cliff.

        With `reset_odometry=False` the odometry keeps its belief: the robot was kidnapped.
        """
        pose = _checked_pose(pose)
        problem = self._placement_problem(pose)
        if problem is not None:
            raise UsageError(problem)
        self._pose = pose
        if reset_odometry:
            self._odometry_turn_deg += normalize_angle_deg(pose.theta_deg - self._odometry.theta_deg)
            self._odometry = pose
        self._commanded = (0.0, 0.0)
        self._wheels = (0.0, 0.0)
        self._held_by = None
        self._wheels_started_s = None
        self._trail.append((pose.x_mm, pose.y_mm))
        self._readings = None
        self._bumpers = self._pressed_bumpers()
        self._cliffs = self._triggered_cliffs()
        self._docked = self._contacts_on_dock()
        self._sample_beacons()

    def set_battery_percent(self, percent: float) -> None:
        if not (math.isfinite(percent) and 0.0 <= percent <= 100.0):
            raise UsageError(f"battery percent must be 0..100, got {percent!r}")
        self._charge_mah = self._base.battery.capacity_mah * percent / 100.0

    def set_dc_connected(self, connected: bool) -> None:
        """Plug in (or pull) a charging cable."""
        self._dc_connected = connected

    # ----------------------------------------------------------------------------- stepping

    def step(self, dt_s: float) -> None:
        """Advance simulated time by `dt_s` seconds, in sub-steps of at most MAX_SUBSTEP_S."""
        if not (math.isfinite(dt_s) and dt_s >= 0.0):
            raise UsageError(f"time step must be a finite number of seconds >= 0, got {dt_s!r}")
        if dt_s == 0.0:
            return
        count = max(1, math.ceil(dt_s / MAX_SUBSTEP_S - 1e-9))
        start = self._time_s
        for index in range(1, count + 1):
            self._substep(dt_s / count, start + dt_s * index / count)
        self._readings = None

    def _substep(self, h: float, end_s: float) -> None:
        targets = self._wheel_targets()
        if targets == (0.0, 0.0):
            self._wheels_started_s = None
        elif self._wheels_started_s is None:
            self._wheels_started_s = self._time_s

        max_change = self._base.max_wheel_accel_mm_s2 * h
        old_left, old_right = self._wheels
        new_left = _ramp(old_left, targets[0], max_change)
        new_right = _ramp(old_right, targets[1], max_change)
        self._wheels = (new_left, new_right)
        # The speeds change linearly over the sub-step, so the travel is their mean times h.
        left_mm = (old_left + new_left) / 2.0 * h
        right_mm = (old_right + new_right) / 2.0 * h
        self._held_by = None
        if left_mm != 0.0 or right_mm != 0.0:
            left_mm, right_mm = self._move(left_mm, right_mm)
        self._drain_battery(h, (abs(left_mm) + abs(right_mm)) / 2.0 / h)
        self._time_s = end_s

        bumpers = self._pressed_bumpers()
        if any(now and not before for now, before in zip(bumpers, self._bumpers, strict=True)):
            # A bumper just closed: the base stops and forgets the command (reference safety).
            self._commanded = (0.0, 0.0)
            self._wheels = (0.0, 0.0)
        self._bumpers = bumpers
        self._cliffs = self._triggered_cliffs()
        self._docked = self._contacts_on_dock()
        last_x, last_y = self._trail[-1]
        if math.hypot(self._pose.x_mm - last_x, self._pose.y_mm - last_y) >= TRAIL_STEP_MM:
            self._trail.append((self._pose.x_mm, self._pose.y_mm))
        if self._time_s >= self._next_beacon_sample_s - 1e-12:
            self._sample_beacons()
            while self._next_beacon_sample_s <= self._time_s + 1e-12:
                self._next_beacon_sample_s += BEACON_SAMPLE_PERIOD_S

    def _wheel_targets(self) -> tuple[float, float]:
        if self._charge_mah <= 0.0:
            return 0.0, 0.0  # an empty battery cuts the motors
        return self._commanded

    def _move(self, left_mm: float, right_mm: float) -> tuple[float, float]:
        """Move the body along the wheels' arc as far as walls and cliff edges allow; count the
        encoders for the travel really made. Returns that travel."""
        track = self._base.wheel_track_mm
        candidate = integrate_pose(self._pose, deadreckon_from_wheel_travel(left_mm, right_mm, track))
        blocker = self._blocker(candidate)
        if blocker is not None:
            free, blocked = 0.0, 1.0
            for _ in range(_BISECTION_STEPS):
                middle = (free + blocked) / 2.0
                trial = integrate_pose(
                    self._pose, deadreckon_from_wheel_travel(left_mm * middle, right_mm * middle, track)
                )
                if self._blocker(trial) is None:
                    free = middle
                else:
                    blocked = middle
            left_mm *= free
            right_mm *= free
            candidate = integrate_pose(self._pose, deadreckon_from_wheel_travel(left_mm, right_mm, track))
            self._wheels = (0.0, 0.0)
            self._held_by = blocker
        self._pose = candidate
        self._count_encoders(left_mm, right_mm)
        return left_mm, right_mm

    def _count_encoders(self, left_mm: float, right_mm: float) -> None:
        slip = self._base.wheel_slip
        measured_left = left_mm * (1.0 + slip.left_scale_error) + self._slip_noise(left_mm)
        measured_right = right_mm * (1.0 + slip.right_scale_error) + self._slip_noise(right_mm)
        self._encoders = (self._encoders[0] + measured_left, self._encoders[1] + measured_right)
        delta = deadreckon_from_wheel_travel(measured_left, measured_right, self._base.wheel_track_mm)
        self._odometry = integrate_pose(self._odometry, delta)
        self._odometry_turn_deg += delta.dtheta_deg

    def _slip_noise(self, travel_mm: float) -> float:
        # Standard deviation grows with the square root of the distance, so the drift per metre
        # does not depend on how finely time is cut.
        fraction = self._base.wheel_slip.random_fraction
        if fraction == 0.0 or travel_mm == 0.0:
            return 0.0
        return self._slip_rng.gauss(0.0, fraction * math.sqrt(abs(travel_mm) * 1000.0))

    def _drain_battery(self, h: float, mean_wheel_speed_mm_s: float) -> None:
        battery = self._base.battery
        if self._on_charger:
            self._charge_mah = min(
                battery.capacity_mah, self._charge_mah + battery.charge_current_ma * h / 3600.0
            )
            return
        current_ma = (
            battery.idle_current_ma + battery.drive_current_ma_per_m_s * mean_wheel_speed_mm_s / 1000.0
        )
        self._charge_mah = max(0.0, self._charge_mah - current_ma * h / 3600.0)

    # ------------------------------------------------------------------------------ contact

    def _clearance_mm(self, pose: Pose) -> float:
        centre = (pose.x_mm, pose.y_mm)
        return min(distance_to_segment(centre, segment) for segment in self._room.wall_segments)

    def _wheel_points(self, pose: Pose) -> tuple[Point, Point]:
        half_track = self._base.wheel_track_mm / 2.0
        return to_world(pose, 0.0, half_track), to_world(pose, 0.0, -half_track)

    def _blocker(self, pose: Pose) -> str | None:
        """What would stop the robot standing at `pose`: a wall in its body, a wheel over a cliff."""
        if self._clearance_mm(pose) < self._base.radius_mm - _OVERLAP_TOLERANCE_MM:
            return HELD_BY_WALL
        for wheel in self._wheel_points(pose):
            if any(point_in_polygon(wheel, cliff.points) for cliff in self._room.cliffs):
                return HELD_BY_CLIFF
        return None

    def _placement_problem(self, pose: Pose) -> str | None:
        blocker = self._blocker(pose)
        where = f"({pose.x_mm:g}, {pose.y_mm:g}) mm"
        if blocker == HELD_BY_WALL:
            return f"the robot (radius {self._base.radius_mm:g} mm) at {where} overlaps a wall"
        if blocker == HELD_BY_CLIFF:
            return f"a wheel of the robot at {where} stands over a cliff area"
        return None

    def _pressed_bumpers(self) -> tuple[bool, ...]:
        pressed = [False] * len(self._base.bumpers)
        centre = (self._pose.x_mm, self._pose.y_mm)
        reach = self._base.radius_mm + BUMPER_TRAVEL_MM
        for segment in self._room.wall_segments:
            touch_x, touch_y = closest_point_on_segment(centre, segment)
            if math.hypot(touch_x - centre[0], touch_y - centre[1]) > reach:
                continue
            direction = (
                math.degrees(math.atan2(touch_y - centre[1], touch_x - centre[0])) - self._pose.theta_deg
            )
            for index, bumper in enumerate(self._base.bumpers):
                if angle_in_arc(direction % 360.0, bumper.start_deg, bumper.end_deg):
                    pressed[index] = True
        return tuple(pressed)

    def _triggered_cliffs(self) -> tuple[bool, ...]:
        return tuple(
            any(
                point_in_polygon(to_world(self._pose, sensor.x_mm, sensor.y_mm), cliff.points)
                for cliff in self._room.cliffs
            )
            for sensor in self._base.cliff_sensors
        )

    def _contacts_on_dock(self) -> bool:
        dock = self._room.dock
        if dock is None:
            return False
        contacts = self._base.charging_contacts
        x, y = to_world(self._pose, contacts.x_mm, contacts.y_mm)
        if math.hypot(x - dock.x_mm, y - dock.y_mm) > dock.contact_radius_mm:
            return False
        facing = self._pose.theta_deg + contacts.yaw_deg
        return angle_between_deg(facing, dock.heading_deg + 180.0) <= dock.contact_angle_deg

    # ------------------------------------------------------------------------------ beacons

    def _sample_beacons(self) -> None:
        dock = self._room.dock
        if dock is None:
            return
        walls = self._room.wall_segments
        for probe_index, probe in enumerate(self._base.beacon_probes):
            probe_at = to_world(self._pose, probe.mount.x_mm, probe.mount.y_mm)
            probe_heading = self._pose.theta_deg + probe.mount.yaw_deg
            for beacon_index, beacon in enumerate(dock.beacons):
                beacon_pose = dock.beacon_pose(beacon)
                dx = probe_at[0] - beacon_pose.x_mm
                dy = probe_at[1] - beacon_pose.y_mm
                distance = math.hypot(dx, dy)
                if distance > beacon.range_mm:
                    continue
                if distance > 1e-9:
                    towards_probe = math.degrees(math.atan2(dy, dx))
                    if angle_between_deg(towards_probe, beacon_pose.theta_deg) > beacon.cone_deg / 2.0:
                        continue
                    if angle_between_deg(towards_probe + 180.0, probe_heading) > probe.fov_deg / 2.0:
                        continue
                    if not line_of_sight(probe_at, (beacon_pose.x_mm, beacon_pose.y_mm), walls):
                        continue
                self._beacon_seen_s[probe_index][beacon_index] = self._time_s

    def beacon_bits(self) -> tuple[int, ...]:
        """Per probe (description order): bit i set when dock beacon i was seen in the last 260 ms."""
        bits: list[int] = []
        for seen_row in self._beacon_seen_s:
            value = 0
            for beacon_index, seen_s in enumerate(seen_row):
                if seen_s is not None and self._time_s - seen_s < BEACON_HOLD_S:
                    value |= 1 << beacon_index
            bits.append(value)
        return tuple(bits)

    # ----------------------------------------------------------------------- distance sensors

    def _sense_distances(self) -> tuple[tuple[float | None, ...], tuple[float, ...]]:
        if self._readings is not None:
            return self._readings
        hits: list[float | None] = []
        readings: list[float] = []
        walls = self._room.wall_segments
        for sensor in self._base.distance_sensors:
            origin = to_world(self._pose, sensor.mount.x_mm, sensor.mount.y_mm)
            heading = self._pose.theta_deg + sensor.mount.yaw_deg
            if sensor.beam_deg == 0.0:
                headings = [heading]
            else:
                headings = [
                    heading - sensor.beam_deg / 2.0 + sensor.beam_deg * index / (RAYS_PER_BEAM - 1)
                    for index in range(RAYS_PER_BEAM)
                ]
            found = [hit for hit in (nearest_hit(origin, ray, walls) for ray in headings) if hit is not None]
            nearest = min(found) if found else None
            if nearest is not None and nearest > sensor.max_range_mm:
                nearest = None
            hits.append(nearest)
            if nearest is None:
                readings.append(sensor.no_echo_reading_mm)
                continue
            if sensor.noise_stddev_mm > 0.0:
                nearest += self._sensor_rng.gauss(0.0, sensor.noise_stddev_mm)
            readings.append(min(sensor.max_range_mm, max(0.0, nearest)))
        self._readings = (tuple(hits), tuple(readings))
        return self._readings

    def distance_hits_mm(self) -> tuple[float | None, ...]:
        """True distance from each distance sensor to the nearest wall in its beam, None past range."""
        return self._sense_distances()[0]

    def distance_readings_mm(self) -> tuple[float, ...]:
        """What each distance sensor reports: the hit plus noise, or its no-echo value."""
        return self._sense_distances()[1]

    # ------------------------------------------------------------------------------- state

    @property
    def true_pose(self) -> Pose:
        return self._pose

    @property
    def odometry_pose(self) -> Pose:
        """The pose dead-reckoned from the encoder counts (what the base itself believes)."""
        return self._odometry

    @property
    def odometry_turn_deg(self) -> float:
        """The odometry's heading without wrapping: its start heading plus every turn since, so
        two full turns left read 720 more (the deadreckon deltas are differences of it)."""
        return self._odometry_turn_deg

    @property
    def encoders_mm(self) -> tuple[float, float]:
        """Accumulated (left, right) wheel travel as the encoders count it, signed."""
        return self._encoders

    @property
    def commanded_wheel_speeds(self) -> tuple[float, float]:
        """(left, right) mm/s the wheels are asked to reach (after clipping and bumper refusal)."""
        return self._commanded

    @property
    def wheel_speeds(self) -> tuple[float, float]:
        """(left, right) mm/s the wheels run at now (acceleration-limited)."""
        return self._wheels

    @property
    def bumpers_pressed(self) -> tuple[bool, ...]:
        return self._bumpers

    @property
    def cliffs_triggered(self) -> tuple[bool, ...]:
        return self._cliffs

    @property
    def held_by(self) -> str | None:
        """HELD_BY_WALL or HELD_BY_CLIFF when the last sub-step's motion was cut short, else None."""
        return self._held_by

    @property
    def stalled(self) -> bool:
        """The wheels push against a wall (after the stall detector's blind time)."""
        return (
            self._held_by == HELD_BY_WALL
            and self._wheels_started_s is not None
            and self._time_s - self._wheels_started_s >= STALL_BLIND_S
        )

    @property
    def traction_lost(self) -> bool:
        """A wheel has reached a cliff edge and the robot cannot go on."""
        return self._held_by == HELD_BY_CLIFF

    @property
    def motion_status(self) -> int:
        """Status bits of GET_BASE_MOTOR_DATA and SET_V_AND_GET_DEADRECKON."""
        return (MOTION_STALL if self.stalled else 0) | (MOTION_TRACTION_LOST if self.traction_lost else 0)

    @property
    def battery_percent(self) -> float:
        return 100.0 * self._charge_mah / self._base.battery.capacity_mah

    @property
    def docked(self) -> bool:
        """The charging contacts meet the dock."""
        return self._docked

    @property
    def dc_connected(self) -> bool:
        return self._dc_connected

    @property
    def _on_charger(self) -> bool:
        return self._docked or self._dc_connected

    @property
    def charging(self) -> bool:
        return self._on_charger and self._charge_mah < self._base.battery.capacity_mah

    @property
    def power_status(self) -> int:
        """GET_BASE_STATUS bits: charging, DC connected, on the dock (5 = charging on the dock)."""
        return (
            (POWER_CHARGING if self.charging else 0)
            | (POWER_DC_CONNECTED if self._dc_connected else 0)
            | (POWER_ON_DOCK if self._docked else 0)
        )

    # ----------------------------------------------------------------------------- snapshot

    def room_snapshot(self) -> dict[str, Any]:
        """The static part of the picture: walls, cliff areas, dock and beacon cones."""
        room = self._room
        dock_data: dict[str, Any] | None = None
        if room.dock is not None:
            dock = room.dock
            beacons = []
            for beacon in dock.beacons:
                pose = dock.beacon_pose(beacon)
                beacons.append(
                    {
                        "name": beacon.name,
                        "code": beacon.code,
                        "x_mm": pose.x_mm,
                        "y_mm": pose.y_mm,
                        "heading_deg": pose.theta_deg,
                        "cone_deg": beacon.cone_deg,
                        "range_mm": beacon.range_mm,
                    }
                )
            dock_data = {
                "x_mm": dock.x_mm,
                "y_mm": dock.y_mm,
                "heading_deg": dock.heading_deg,
                "contact_radius_mm": dock.contact_radius_mm,
                "beacons": beacons,
            }
        return {
            "name": room.name,
            "walls": [
                {"points": [list(p) for p in wall.points], "closed": wall.closed} for wall in room.walls
            ],
            "cliffs": [
                {"name": cliff.name, "points": [list(p) for p in cliff.points]} for cliff in room.cliffs
            ],
            "dock": dock_data,
        }

    def snapshot(self, *, include_room: bool = True, include_trail: bool = True) -> dict[str, Any]:
        """Everything a dashboard draws, as plain JSON-ready values (mm, degrees, seconds)."""
        pose = self._pose
        base = self._base
        sensors = []
        hits, readings = self._sense_distances()
        for sensor, hit, reading in zip(base.distance_sensors, hits, readings, strict=True):
            x, y = to_world(pose, sensor.mount.x_mm, sensor.mount.y_mm)
            sensors.append(
                {
                    "name": sensor.name,
                    "type": sensor.kind,
                    "x_mm": x,
                    "y_mm": y,
                    "heading_deg": normalize_angle_deg(pose.theta_deg + sensor.mount.yaw_deg),
                    "beam_deg": sensor.beam_deg,
                    "max_range_mm": sensor.max_range_mm,
                    "hit_mm": hit,
                    "reading_mm": reading,
                }
            )
        cliffs = []
        for cliff_sensor, triggered in zip(base.cliff_sensors, self._cliffs, strict=True):
            x, y = to_world(pose, cliff_sensor.x_mm, cliff_sensor.y_mm)
            cliffs.append({"name": cliff_sensor.name, "x_mm": x, "y_mm": y, "triggered": triggered})
        probes = []
        for probe, bits in zip(base.beacon_probes, self.beacon_bits(), strict=True):
            x, y = to_world(pose, probe.mount.x_mm, probe.mount.y_mm)
            probes.append(
                {
                    "name": probe.name,
                    "x_mm": x,
                    "y_mm": y,
                    "heading_deg": normalize_angle_deg(pose.theta_deg + probe.mount.yaw_deg),
                    "fov_deg": probe.fov_deg,
                    "beacon_bits": bits,
                }
            )
        data: dict[str, Any] = {
            "time_s": self._time_s,
            "robot": {
                "model": base.model,
                "radius_mm": base.radius_mm,
                "wheel_track_mm": base.wheel_track_mm,
            },
            "pose": _pose_dict(pose),
            "odometry_pose": _pose_dict(self._odometry),
            "wheels": {
                "commanded_mm_s": list(self._commanded),
                "speed_mm_s": list(self._wheels),
                "encoders_mm": list(self._encoders),
            },
            "distance_sensors": sensors,
            "bumpers": [
                {
                    "name": bumper.name,
                    "start_deg": bumper.start_deg,
                    "end_deg": bumper.end_deg,
                    "pressed": pressed,
                }
                for bumper, pressed in zip(base.bumpers, self._bumpers, strict=True)
            ],
            "cliff_sensors": cliffs,
            "beacon_probes": probes,
            "battery": {
                "percent": self.battery_percent,
                "charging": self.charging,
                "dc_connected": self._dc_connected,
                "docked": self._docked,
                "power_status": self.power_status,
            },
            "motion": {
                "held_by": self._held_by,
                "stalled": self.stalled,
                "traction_lost": self.traction_lost,
            },
        }
        if include_trail:
            data["trail"] = [list(point) for point in self._trail]
        if include_room:
            data["room"] = self.room_snapshot()
        return data


def _checked_pose(pose: Pose) -> Pose:
    if not all(math.isfinite(value) for value in pose):
        raise UsageError(f"pose must be finite numbers, got {tuple(pose)!r}")
    return Pose(pose.x_mm, pose.y_mm, normalize_angle_deg(pose.theta_deg))


def _pose_dict(pose: Pose) -> dict[str, float]:
    return {"x_mm": pose.x_mm, "y_mm": pose.y_mm, "theta_deg": pose.theta_deg}
