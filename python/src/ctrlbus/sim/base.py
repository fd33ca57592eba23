# SPDX-License-Identifier: MIT
"""The simulated base: the simulator's World answering the Control Bus through ctrlbus.base.

`SimulatedBase` is an ordinary `ctrlbus.base.Base` application: it reads everything it reports
from the world (docs/simulator.md) and drives the world with the Core's commands. The world steps
with the time the stack passes in (`advance`), times `time_scale`.

    sim = SimulatedBase(World())
    stack = BaseStack(sim, BaseConfig())
    serve(stack, link)          # or stack.receive(data, now) in a virtual-time loop
"""

from __future__ import annotations

import math
from collections import deque
from typing import Any

from ctrlbus import __version__
from ctrlbus.base import (
    COMPONENT_POWER,
    HEALTH_ERROR,
    HEALTH_WARNING,
    Base,
    health_code,
)
from ctrlbus.errors import UsageError
from ctrlbus.kinematics import DeadreckonDelta, Pose, integrate_pose, relative_pose
from ctrlbus.messages import (
    S32,
    ConnectBaseAnswer,
    GetBaseBumperDataAnswer,
    GetBaseConfAnswer,
    GetBaseMotorDataAnswer,
    GetBaseSensorDataAnswer,
    GetBaseStatusAnswer,
    GetChargerDataAnswer,
    Position,
    SetVAndGetDeadreckonAnswer,
    from_q16,
)
from ctrlbus.sim.world import World

__all__ = [
    "HEALTH_PERIOD_S",
    "LOW_BATTERY_ERROR_BELOW",
    "LOW_BATTERY_ERROR_CODE",
    "LOW_BATTERY_WARNING_BELOW",
    "LOW_BATTERY_WARNING_CODE",
    "SimulatedBase",
]

HEALTH_PERIOD_S = 0.1  # the reference re-evaluates health every 100 ms
LOW_BATTERY_WARNING_BELOW = 30  # percent
LOW_BATTERY_ERROR_BELOW = 10
_TYPE_LOW_BATTERY = 0x01  # power component, type 0x01, index 0: as the reference registers it
LOW_BATTERY_WARNING_CODE = health_code(HEALTH_WARNING, COMPONENT_POWER, _TYPE_LOW_BATTERY)  # 0x01020100
LOW_BATTERY_ERROR_CODE = health_code(HEALTH_ERROR, COMPONENT_POWER, _TYPE_LOW_BATTERY)  # 0x02020100
LOW_BATTERY_WARNING_MESSAGE = "battery low"
LOW_BATTERY_ERROR_MESSAGE = "battery critically low"

_MAX_Q16_DISTANCE_MM = 0xFFFF_FFFF / 65536  # the largest distance a u32 Q16 reading holds
_RECENT_EVENTS = 50
_TIME_SLACK_S = 1e-9  # simulated time is a sum of float steps: 10 x 0.01 s may fall short of 0.1 s


def _version_word(version: str) -> int:
    """(major << 8) | minor of "major.minor[.patch]" (each part capped at 255)."""
    parts = version.split(".")
    try:
        major, minor = int(parts[0]), int(parts[1]) if len(parts) > 1 else 0
    except ValueError:
        return 0
    return (min(major, 0xFF) << 8) | min(minor, 0xFF)


def _s32(value: float) -> int:
    """A travel total as the s32 the wire carries (wrapping, as a firmware counter would)."""
    raw = round(value) & 0xFFFF_FFFF
    return raw - (1 << 32) if raw >= 1 << 31 else raw


def _saturated_q16(value: float) -> int:
    """`value` in Q16, saturated at the s32 range (the caller carries what did not fit)."""
    low, high = S32
    return max(low, min(high, round(value * 65536)))


class SimulatedBase(Base):
    """A `Base` that is the simulated robot.

    - `world`: the World to serve (its base description and room give the answers).
    - `binary_config`: the blob for GET_BASE_CONF_ADV (`ctrlbus.binconf.encode` of a JSON
      configuration); None answers ERROR 0x8000, so the Core falls back to GET_BASE_CONF.
    - `time_scale`: simulated seconds per second of the stack's time.
    - `firmware_version`, `hardware_version`, `serial`: what CONNECT_BASE reports (defaults:
      ctrlbus's major.minor, 1, and "ctrl" "bus" plus the seed).
    - `seed`: the noise seed of the world made here when `world` is None, and of the fresh world
      a REBOOT makes (None: the description's `seed`). A reboot puts the robot at the room's
      start pose.

    Thread-safety: the stack calls it under `stack.lock`; `snapshot()` and
    `queue_external_command()` take that lock, so a dashboard thread may call them.
    """

    def __init__(
        self,
        world: World | None = None,
        *,
        binary_config: bytes | None = None,
        time_scale: float = 1.0,
        firmware_version: int | None = None,
        hardware_version: int = 1,
        serial: tuple[int, int, int] | None = None,
        seed: int | None = None,
    ) -> None:
        if isinstance(time_scale, bool) or not isinstance(time_scale, int | float):
            raise UsageError(f"time scale must be a number, got {time_scale!r}")
        if not (math.isfinite(time_scale) and time_scale > 0):
            raise UsageError(f"time scale must be a finite number > 0, got {time_scale!r}")
        if binary_config is not None and not isinstance(binary_config, bytes):
            raise UsageError(f"binary_config must be bytes or None, got {type(binary_config).__name__}")
        self._seed = seed
        self._world = world if world is not None else World(seed=seed)
        self.binary_config_blob = binary_config
        self.time_scale = float(time_scale)
        chosen_seed = self._world.base.seed if seed is None else seed
        self._identity = ConnectBaseAnswer(
            self._world.base.model,
            _version_word(__version__) if firmware_version is None else firmware_version,
            hardware_version,
            serial if serial is not None else (0x6C727463, 0x00737562, chosen_seed & 0xFFFF_FFFF),
        )
        self._last_now: float | None = None
        self._next_health_s = 0.0
        # The pose the Core has been told about: the sum of every deadreckon answer so far, in the
        # odometry frame. Deltas are measured from it, so the Q16 rounding never accumulates.
        self._reported_pose: Pose | None = None
        self._reported_turn_deg = 0.0  # the odometry turn (not wrapped) at that pose
        self.events: deque[int] = deque(maxlen=_RECENT_EVENTS)
        self.reboots = 0

    @property
    def world(self) -> World:
        return self._world

    # -- time ---------------------------------------------------------------------------------

    def advance(self, now: float) -> None:
        if self._last_now is None:
            self._last_now = now
        elapsed = now - self._last_now
        if elapsed > 0:
            self._last_now = now
            self._world.step(elapsed * self.time_scale)
        if self._world.time_s >= self._next_health_s - _TIME_SLACK_S:
            self._evaluate_health()
            periods = math.floor(self._world.time_s / HEALTH_PERIOD_S + 1e-9) + 1
            self._next_health_s = periods * HEALTH_PERIOD_S

    def _battery_percent(self) -> int:
        return max(0, min(100, round(self._world.battery_percent)))

    def _evaluate_health(self) -> None:
        """Low battery: a warning below 30 %, an error below 10 % (the reference's thresholds)."""
        percent = self._battery_percent()
        health = self.stack.health
        if percent < LOW_BATTERY_ERROR_BELOW:
            health.clear(LOW_BATTERY_WARNING_CODE)
            health.add(LOW_BATTERY_ERROR_CODE, LOW_BATTERY_ERROR_MESSAGE)
        elif percent < LOW_BATTERY_WARNING_BELOW:
            health.clear(LOW_BATTERY_ERROR_CODE)
            health.add(LOW_BATTERY_WARNING_CODE, LOW_BATTERY_WARNING_MESSAGE)
        else:
            health.clear(LOW_BATTERY_ERROR_CODE)
            health.clear(LOW_BATTERY_WARNING_CODE)

    # -- what the base reports ----------------------------------------------------------------

    def connect_info(self) -> ConnectBaseAnswer:
        return self._identity

    def base_config(self) -> GetBaseConfAnswer:
        base = self._world.base
        sensors = [
            Position.from_si(sensor.mount.x_mm, sensor.mount.y_mm, sensor.mount.z_mm, sensor.mount.yaw_deg)
            for sensor in base.distance_sensors
        ]
        bumpers = [
            Position.from_si(mount.x_mm, mount.y_mm, mount.z_mm, mount.yaw_deg)
            for mount in base.bumper_mounts()
        ]
        return GetBaseConfAnswer.from_si(
            base_type=0, base_radius_mm=base.radius_mm, motor_type=0, sensors=sensors, bumpers=bumpers
        )

    def binary_config(self) -> bytes:
        if self.binary_config_blob is None:
            raise NotImplementedError
        return self.binary_config_blob

    def status(self) -> GetBaseStatusAnswer:
        return GetBaseStatusAnswer(self._battery_percent(), self._world.power_status)

    def motor_data(self) -> GetBaseMotorDataAnswer:
        left, right = self._world.encoders_mm
        return GetBaseMotorDataAnswer(_s32(left), _s32(right), self._world.motion_status)

    def sensor_data(self) -> GetBaseSensorDataAnswer:
        readings = [min(reading, _MAX_Q16_DISTANCE_MM) for reading in self._world.distance_readings_mm()]
        return GetBaseSensorDataAnswer.from_si(readings)

    def bumper_data(self) -> GetBaseBumperDataAnswer:
        """ACTIVE LOW: bumper i is bit i, cliff sensor j is bit (bumper count + j), as the
        reference's bits 0-1 bumpers and 2-5 cliffs; every other bit reads 1 (clear)."""
        bitmap = 0xFFFF_FFFF
        bumpers = self._world.bumpers_pressed
        for index, pressed in enumerate(bumpers):
            if pressed:
                bitmap &= ~(1 << index)
        for index, triggered in enumerate(self._world.cliffs_triggered):
            if triggered:
                bitmap &= ~(1 << (len(bumpers) + index))
        return GetBaseBumperDataAnswer(bitmap, 4)

    def charger_data(self) -> GetChargerDataAnswer:
        dock = self._world.room.dock
        probes = self._world.beacon_bits()
        return GetChargerDataAnswer(0 if dock is None else len(dock.beacons), len(probes), probes)

    # -- what the Core commands ---------------------------------------------------------------

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        self._world.set_wheel_speeds(left_mm_s, right_mm_s)

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        """Deltas since the previous call (zeros the first time), then the new velocity; vy is
        ignored (differential drive).

        The turn is the whole rotation since the previous call, not the shortest angle between
        the two headings: three quarters of a turn left read +270, not -90. A value beyond what
        the s32 field holds is sent saturated and the excess is carried into the next answer,
        as the C stack does (ctrlbus_diffdrive_take_deadreckon)."""
        current = self._world.odometry_pose
        turn = self._world.odometry_turn_deg
        if self._reported_pose is None:
            answer = SetVAndGetDeadreckonAnswer(0, 0, 0, self._world.motion_status)
            self._reported_pose = current
            self._reported_turn_deg = turn
        else:
            delta = relative_pose(self._reported_pose, current)
            answer = SetVAndGetDeadreckonAnswer(
                _saturated_q16(delta.dx_mm),
                _saturated_q16(delta.dy_mm),
                _saturated_q16(turn - self._reported_turn_deg),
                self._world.motion_status,
            )
            # Integrate what the Core will integrate: the rounded (and saturated) deltas.
            self._reported_pose = integrate_pose(
                self._reported_pose,
                DeadreckonDelta(from_q16(answer.dx_mm_q16), from_q16(answer.dy_mm_q16), answer.dtheta_deg),
            )
            self._reported_turn_deg += answer.dtheta_deg
        self._world.set_velocity(vx_mps, omega_radps)
        return answer

    def stop_motors(self) -> None:
        self._world.stop()

    def on_event(self, event: int) -> None:
        self.events.append(event)

    def on_reboot(self) -> None:
        """Power-cycle the robot: a fresh world (same description, room and seed), at its start."""
        self._world = World(self._world.base, self._world.room, seed=self._seed)
        self._reported_pose = None
        self._next_health_s = 0.0
        self.reboots += 1

    # -- for the dashboard and scripts --------------------------------------------------------

    def queue_external_command(self, code: int) -> None:
        """Offer an external command (ExternalCommand code) to the Core through POLL_BASE_CMD."""
        self.stack.queue_external_command(code)

    def snapshot(self) -> dict[str, Any]:
        """The world's snapshot (docs/simulator.md) plus `speed` (the time scale) and
        `pending_commands`: the `sim` part of the dashboard's schema, minus odometry_origin,
        which only the Core knows."""
        with self.stack.lock:
            data = self._world.snapshot()
            data["speed"] = self.time_scale
            data["pending_commands"] = list(self.stack.pending_commands)
            return data
