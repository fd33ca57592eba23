# SPDX-License-Identifier: MIT
"""What a polled reading means: the answers that update the telemetry model and feed the action.

`apply_reading` takes one answer to a periodic request (deadreckon, bumpers, sensors, status,
motor data, charger data), puts its values into the model (the deadreckon delta into the pose)
and tells the running action what it needs to know. It keeps no state of its own and sends
nothing; it says which topics changed. Answers that lead to more requests (POLL_BASE_CMD,
HEALTH_GET_HEALTH) are the session's.
"""

from __future__ import annotations

from ctrlbus.core.actions import Action
from ctrlbus.core.telemetry import BaseTelemetry
from ctrlbus.kinematics import DeadreckonDelta
from ctrlbus.messages import (
    AnswerMessage,
    GetBaseBumperDataAnswer,
    GetBaseMotorDataAnswer,
    GetBaseSensorDataAnswer,
    GetBaseStatusAnswer,
    GetChargerDataAnswer,
    SetVAndGetDeadreckonAnswer,
)

__all__ = ["apply_reading"]


def apply_reading(
    telemetry: BaseTelemetry, action: Action | None, answer: AnswerMessage, now: float
) -> tuple[str, ...]:
    """Put the reading `answer` (received at `now`) into `telemetry` and tell `action` of it;
    returns the topics that changed (none if `answer` is not a reading)."""
    if isinstance(answer, SetVAndGetDeadreckonAnswer):
        delta = DeadreckonDelta(answer.dx_mm, answer.dy_mm, answer.dtheta_deg)
        telemetry.move(delta)
        telemetry.motion_status = answer.status
        telemetry.deadreckon_timestamp_ms = answer.timestamp_ms
        if action is not None:
            action.on_motion(delta)
        return ("pose", "motion")
    if isinstance(answer, GetBaseBumperDataAnswer):
        telemetry.bumper_bitmap = answer.bitmap
        if action is not None:
            action.on_bumpers(any(telemetry.bumpers_pressed), now)
        return ("bumpers",)
    if isinstance(answer, GetBaseSensorDataAnswer):
        telemetry.distances_mm = answer.distances_mm
        return ("sensors",)
    if isinstance(answer, GetBaseStatusAnswer):
        telemetry.battery_percent = answer.battery_percent
        telemetry.power_status = answer.power_status
        if action is not None:
            action.on_status(answer.power_status, now)
        return ("battery",)
    if isinstance(answer, GetBaseMotorDataAnswer):
        telemetry.motor_totals_mm = (answer.left_distance_mm, answer.right_distance_mm)
        telemetry.motion_status = answer.status
        return ("motion",)
    if isinstance(answer, GetChargerDataAnswer):
        telemetry.charger = answer
        if action is not None:
            action.on_charger(answer.probes, now)
        return ("charger",)
    return ()
