# SPDX-License-Identifier: MIT
"""Actions the Core carries out on its own: drive a distance, turn an angle (and go home, in
ctrlbus.core.docking).

An action is told what the Core learns (motion deltas from SET_V_AND_GET_DEADRECKON, beacon data,
power status, bumpers) and is asked, before each SET_V_AND_GET_DEADRECKON, which velocity to
send. It never reads a clock: `command(now)` gets the session's time. Progress is measured from
the dead-reckoned motion, as a real Core would.
"""

from __future__ import annotations

import math

from ctrlbus.kinematics import DeadreckonDelta, Pose, integrate_pose

__all__ = [
    "ANGLE_TOLERANCE_DEG",
    "DISTANCE_TOLERANCE_MM",
    "MIN_SPEED_MPS",
    "MIN_TURN_RADPS",
    "MODE_EXTERNAL",
    "MODE_GO_HOME",
    "SLOWDOWN_GAIN_PER_S",
    "STALL_LIMIT_S",
    "Action",
    "DriveDistance",
    "TurnAngle",
]

MODE_EXTERNAL = "external"
MODE_GO_HOME = "go_home"

# Below these the remaining motion counts as done (the base's acceleration makes finer pointless).
DISTANCE_TOLERANCE_MM = 2.0
ANGLE_TOLERANCE_DEG = 0.5
# Slow down over the last part of a move so that it stops close to the target.
SLOWDOWN_GAIN_PER_S = 2.0
MIN_SPEED_MPS = 0.03
MIN_TURN_RADPS = 0.08
# A move that makes no progress for this long is given up (held by a wall, a cliff, a bumper).
STALL_LIMIT_S = 3.0


class Action:
    """Base of the actions. Subclasses override `command` and whichever `on_*` they need."""

    mode = MODE_EXTERNAL

    def __init__(self, description: str) -> None:
        self.description = description
        self.activity = description
        self.finished = False
        self.outcome: str | None = None  # set when finished: what happened
        self.failed = False
        self.heading_deg = 0.0  # turned since the action started, not wrapped
        self.pose = Pose(0.0, 0.0, 0.0)  # moved since the action started, in its start frame
        self._started_s: float | None = None

    def on_motion(self, delta: DeadreckonDelta) -> None:
        self.heading_deg += delta.dtheta_deg
        self.pose = integrate_pose(self.pose, delta)

    def on_charger(self, probes: tuple[int, ...], now: float) -> None:
        """A GET_CHARGER_DATA answer: one beacon bitmap per probe (left, main, right)."""

    def on_charger_error(self, reason: str) -> None:
        """GET_CHARGER_DATA was refused."""

    def on_status(self, power_status: int, now: float) -> None:
        """A GET_BASE_STATUS answer."""

    def on_bumpers(self, pressed: bool, now: float) -> None:
        """A GET_BASE_BUMPER_DATA answer: whether any configured bumper is pressed."""

    def started_s(self, now: float) -> float:
        if self._started_s is None:
            self._started_s = now
        return self._started_s

    def finish(self, outcome: str, *, failed: bool = False) -> None:
        if not self.finished:
            self.finished = True
            self.failed = failed
            self.outcome = outcome
            self.activity = outcome

    def command(self, now: float) -> tuple[float, float]:
        """(vx m/s, omega rad/s) to send now; (0, 0) once finished."""
        raise NotImplementedError


class DriveDistance(Action):
    """Drive straight `distance_m` (negative: backwards) at up to `speed_mps`."""

    def __init__(self, distance_m: float, speed_mps: float) -> None:
        direction = "forward" if distance_m >= 0 else "backward"
        super().__init__(f"drive {direction} {abs(distance_m):.2f} m")
        self.distance_mm = distance_m * 1000.0
        self.speed_mps = abs(speed_mps)
        self.bumper_pressed = False
        self._best_mm = 0.0
        self._progress_s: float | None = None

    def on_bumpers(self, pressed: bool, now: float) -> None:
        self.bumper_pressed = pressed

    def command(self, now: float) -> tuple[float, float]:
        if self.finished:
            return 0.0, 0.0
        self.started_s(now)
        sign = 1.0 if self.distance_mm >= 0 else -1.0
        travelled = self.pose.x_mm * sign
        remaining_mm = abs(self.distance_mm) - travelled
        if remaining_mm <= DISTANCE_TOLERANCE_MM:
            self.finish(f"{self.description}: done ({travelled:.0f} mm)")
            return 0.0, 0.0
        if sign > 0 and self.bumper_pressed:
            self.finish(f"{self.description}: stopped by a bumper after {travelled:.0f} mm", failed=True)
            return 0.0, 0.0
        if self._progress_s is None or travelled > self._best_mm + 1.0:
            self._best_mm = max(self._best_mm, travelled)
            self._progress_s = now
        elif now - self._progress_s > STALL_LIMIT_S:
            self.finish(f"{self.description}: no progress after {travelled:.0f} mm", failed=True)
            return 0.0, 0.0
        speed = min(self.speed_mps, max(MIN_SPEED_MPS, SLOWDOWN_GAIN_PER_S * remaining_mm / 1000.0))
        self.activity = f"{self.description}: {remaining_mm:.0f} mm to go"
        return sign * speed, 0.0


class TurnAngle(Action):
    """Turn in place by `angle_deg` (positive: left, anticlockwise) at up to `rate_radps`."""

    def __init__(self, angle_deg: float, rate_radps: float) -> None:
        direction = "left" if angle_deg >= 0 else "right"
        super().__init__(f"turn {direction} {abs(angle_deg):.0f}°")
        self.angle_deg = angle_deg
        self.rate_radps = abs(rate_radps)
        self._best_deg = 0.0
        self._progress_s: float | None = None

    def command(self, now: float) -> tuple[float, float]:
        if self.finished:
            return 0.0, 0.0
        self.started_s(now)
        sign = 1.0 if self.angle_deg >= 0 else -1.0
        turned = self.heading_deg * sign
        remaining_deg = abs(self.angle_deg) - turned
        if remaining_deg <= ANGLE_TOLERANCE_DEG:
            self.finish(f"{self.description}: done ({turned:.1f}°)")
            return 0.0, 0.0
        if self._progress_s is None or turned > self._best_deg + 0.5:
            self._best_deg = max(self._best_deg, turned)
            self._progress_s = now
        elif now - self._progress_s > STALL_LIMIT_S:
            self.finish(f"{self.description}: no progress after {turned:.1f}°", failed=True)
            return 0.0, 0.0
        rate = min(self.rate_radps, max(MIN_TURN_RADPS, SLOWDOWN_GAIN_PER_S * math.radians(remaining_deg)))
        self.activity = f"{self.description}: {remaining_deg:.1f}° to go"
        return 0.0, sign * rate
