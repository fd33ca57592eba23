# SPDX-License-Identifier: MIT
"""Differential-drive math, written once for every Python layer that needs it.

The simulator moves its robot with it, the base framework turns SET_V_AND_GET_DEADRECKON commands
into wheel speeds with it, and the Core emulator integrates the deadreckon deltas it receives with
it. All functions are pure.

Conventions (the wire's): millimetres, x forward, y left, angles anticlockwise. A `Pose` carries its
heading in degrees, normalised to (-180, 180]; angular velocity is in rad/s as on the wire.
"""

from __future__ import annotations

import math
from typing import NamedTuple

__all__ = [
    "DeadreckonDelta",
    "Pose",
    "deadreckon_from_wheel_travel",
    "integrate_pose",
    "normalize_angle_deg",
    "relative_pose",
    "to_world",
    "velocity_from_wheel_speeds",
    "wheel_speeds_from_velocity",
]

# Below this turn (radians) sin(t)/t is taken from its series (and t = 0 needs no special case);
# the series' next term is then far below float resolution.
_SMALL_TURN_RAD = 1e-4


class Pose(NamedTuple):
    """Position (mm) and heading (degrees anticlockwise, in (-180, 180]) in some fixed frame."""

    x_mm: float
    y_mm: float
    theta_deg: float


class DeadreckonDelta(NamedTuple):
    """Motion over an interval, in the robot frame at the interval's start (as 0x41 reports it)."""

    dx_mm: float
    dy_mm: float
    dtheta_deg: float


def normalize_angle_deg(angle_deg: float) -> float:
    """The same direction as `angle_deg`, in (-180, 180]."""
    wrapped = math.fmod(angle_deg, 360.0)
    if wrapped <= -180.0:
        wrapped += 360.0
    elif wrapped > 180.0:
        wrapped -= 360.0
    return wrapped


def wheel_speeds_from_velocity(
    vx_mps: float, omega_radps: float, wheel_track_mm: float
) -> tuple[float, float]:
    """(left, right) wheel speeds in mm/s for a forward speed (m/s) and a turn rate (rad/s).

    Positive omega turns left (anticlockwise), so the right wheel runs faster.
    """
    forward_mm_s = vx_mps * 1000.0
    turn_mm_s = omega_radps * wheel_track_mm / 2.0
    return forward_mm_s - turn_mm_s, forward_mm_s + turn_mm_s


def velocity_from_wheel_speeds(
    left_mm_s: float, right_mm_s: float, wheel_track_mm: float
) -> tuple[float, float]:
    """(vx m/s, omega rad/s) of a base whose wheels run at these speeds; the inverse of the above."""
    return (left_mm_s + right_mm_s) / 2000.0, (right_mm_s - left_mm_s) / wheel_track_mm


def deadreckon_from_wheel_travel(left_mm: float, right_mm: float, wheel_track_mm: float) -> DeadreckonDelta:
    """The motion of the base while its wheels travel `left_mm` and `right_mm` (signed).

    Exact when the ratio of the wheel speeds is constant over the interval: the centre then
    follows a circular arc (a straight line when the wheels travel alike).
    """
    distance = (left_mm + right_mm) / 2.0
    turn = (right_mm - left_mm) / wheel_track_mm
    if abs(turn) < _SMALL_TURN_RAD:
        along = 1.0 - turn * turn / 6.0  # sin(t) / t
        across = turn / 2.0 - turn * turn * turn / 24.0  # (1 - cos(t)) / t
    else:
        half_sin = math.sin(turn / 2.0)
        along = math.sin(turn) / turn
        across = 2.0 * half_sin * half_sin / turn  # (1 - cos(t)) / t without the cancellation
    return DeadreckonDelta(distance * along, distance * across, math.degrees(turn))


def integrate_pose(pose: Pose, delta: DeadreckonDelta) -> Pose:
    """The pose reached from `pose` by a motion given in the robot frame at `pose`."""
    heading = math.radians(pose.theta_deg)
    cos_h = math.cos(heading)
    sin_h = math.sin(heading)
    return Pose(
        pose.x_mm + delta.dx_mm * cos_h - delta.dy_mm * sin_h,
        pose.y_mm + delta.dx_mm * sin_h + delta.dy_mm * cos_h,
        normalize_angle_deg(pose.theta_deg + delta.dtheta_deg),
    )


def relative_pose(start: Pose, end: Pose) -> DeadreckonDelta:
    """The motion from `start` to `end` in the robot frame at `start`; inverse of integrate_pose.

    The turn is the shortest one, in (-180, 180].
    """
    heading = math.radians(start.theta_deg)
    cos_h = math.cos(heading)
    sin_h = math.sin(heading)
    dx_world = end.x_mm - start.x_mm
    dy_world = end.y_mm - start.y_mm
    return DeadreckonDelta(
        dx_world * cos_h + dy_world * sin_h,
        -dx_world * sin_h + dy_world * cos_h,
        normalize_angle_deg(end.theta_deg - start.theta_deg),
    )


def to_world(pose: Pose, x_mm: float, y_mm: float) -> tuple[float, float]:
    """World coordinates of a point given in the frame of a robot at `pose`."""
    heading = math.radians(pose.theta_deg)
    cos_h = math.cos(heading)
    sin_h = math.sin(heading)
    return pose.x_mm + x_mm * cos_h - y_mm * sin_h, pose.y_mm + x_mm * sin_h + y_mm * cos_h
