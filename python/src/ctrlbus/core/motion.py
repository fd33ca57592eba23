# SPDX-License-Identifier: MIT
"""What the Core tells the base to do: the velocity command, the emergency stop and the action.

`MotionControl` holds the commanded body velocity, the latched emergency stop and the running
action (ctrlbus.core.actions, ctrlbus.core.docking), and turns them into the velocity of each
SET_V_AND_GET_DEADRECKON. Whether the base is connected, and what the Core polls, are the
session's: it says so when it starts an action. `action_for_command` is what an acknowledged
external command (§11.5) asks the Core to do.
"""

from __future__ import annotations

from ctrlbus.core.actions import Action, DriveDistance, TurnAngle
from ctrlbus.core.config import CoreConfig
from ctrlbus.core.docking import GoHome
from ctrlbus.core.journal import Journal
from ctrlbus.core.telemetry import CommandState
from ctrlbus.messages import ExternalCommand, SetVAndGetDeadreckon

__all__ = ["MotionControl", "action_for_command"]


def action_for_command(code: int, config: CoreConfig) -> Action | None:
    """The action an external command starts (MOVE_*, TURN_*, GO_HOME); None for the others
    (CANCEL_ACTION stops instead; the rest the Core emulator only notes)."""
    if code == ExternalCommand.MOVE_FORWARD:
        return DriveDistance(config.move_distance_m, config.move_speed_mps)
    if code == ExternalCommand.MOVE_BACKWARD:
        return DriveDistance(-config.move_distance_m, config.move_speed_mps)
    if code == ExternalCommand.TURN_LEFT:
        return TurnAngle(config.turn_angle_deg, config.turn_rate_radps)
    if code == ExternalCommand.TURN_RIGHT:
        return TurnAngle(-config.turn_angle_deg, config.turn_rate_radps)
    if code == ExternalCommand.GO_HOME:
        return GoHome(config.docking)
    return None


class MotionControl:
    """The Core's command to the base: velocity, emergency stop latch, running action."""

    def __init__(self, config: CoreConfig, journal: Journal) -> None:
        self._config = config
        self._journal = journal
        self._log = journal.log
        self._vx = 0.0
        self._omega = 0.0
        self._estop = False
        self._action: Action | None = None
        self._last_outcome: str | None = None

    @property
    def action(self) -> Action | None:
        """The running action, told what the Core learns (None when there is none)."""
        return self._action

    @property
    def docking(self) -> bool:
        """Whether the running action is GO_HOME (the schedule polls the charger then)."""
        return isinstance(self._action, GoHome)

    @property
    def last_outcome(self) -> str | None:
        return self._last_outcome

    def state(self) -> CommandState:
        """What the Core sends, and why: estop, the action's mode, teleop or idle."""
        action = self._action
        if self._estop:
            mode = "estop"
        elif action is not None:
            mode = action.mode
        elif self._vx or self._omega:
            mode = "teleop"
        else:
            mode = "idle"
        return CommandState(
            self._vx, self._omega, self._estop, mode, None if action is None else action.activity
        )

    # ============================================================================== commands

    def set_velocity(self, vx_mps: float, omega_radps: float, limits: tuple[float, float]) -> None:
        """Command a body velocity, clamped to `limits` (max |vx|, max |omega|); cancels a
        running action; ignored while the emergency stop is latched."""
        if self._estop:
            return
        self._cancel("cancelled by a velocity command")
        self._command(vx_mps, omega_radps, limits)
        self._journal.changed("command")

    def _command(self, vx_mps: float, omega_radps: float, limits: tuple[float, float]) -> None:
        max_vx, max_omega = limits
        self._vx = max(-max_vx, min(max_vx, float(vx_mps)))
        self._omega = max(-max_omega, min(max_omega, float(omega_radps)))

    def emergency_stop(self) -> None:
        self.halt("cancelled by the emergency stop")
        if not self._estop:
            self._estop = True
            self._log("core", "emergency stop")
        self._journal.changed("command")

    def release_stop(self) -> None:
        if self._estop:
            self._estop = False
            self._log("core", "emergency stop released")
        self._vx = self._omega = 0.0
        self._journal.changed("command")

    def halt(self, why: str) -> None:
        """Cancel the running action (saying `why`) and command zero velocity."""
        self._cancel(why)
        self._vx = self._omega = 0.0

    # =============================================================================== actions

    def start(self, action: Action, why: str, *, connected: bool) -> bool:
        """Start `action` in place of the running one; refused (False) while the emergency stop
        is latched or the base is not `connected`."""
        if self._estop:
            self._log("core", f"{action.description} refused: the emergency stop is latched")
            return False
        if not connected:
            self._log("core", f"{action.description} refused: the base is not connected")
            return False
        self.halt(f"replaced by {action.description}")
        self._action = action
        self._log("core", f"{action.description}: started ({why})")
        self._journal.changed("command")
        return True

    def _cancel(self, why: str) -> None:
        action = self._action
        if action is not None:
            self._action = None
            action.finish(f"{action.description}: {why}", failed=True)
            self._last_outcome = action.outcome
            self._log("core", action.outcome or why)
            self._journal.changed("command")

    def check(self) -> None:
        """End the action if what it was last told finished it."""
        action = self._action
        if action is not None and action.finished:
            self._end(action)

    def _end(self, action: Action) -> None:
        if self._action is action:
            self._action = None
            self._vx = self._omega = 0.0
            self._last_outcome = action.outcome
            self._log("core", action.outcome or f"{action.description}: done")
            self._journal.changed("command")

    def velocity_request(self, now: float) -> SetVAndGetDeadreckon:
        """The SET_V_AND_GET_DEADRECKON to send at `now`: the action's velocity if one runs
        (clamped to the configured limits), zero while the emergency stop is latched."""
        action = self._action
        if action is not None:
            vx, omega = action.command(now)
            self._command(vx, omega, (self._config.max_vx_mps, self._config.max_omega_radps))
            if action.finished:
                self._end(action)
            self._journal.changed("command")
        if self._estop:
            self._vx = self._omega = 0.0
        return SetVAndGetDeadreckon.from_si(self._vx, 0.0, self._omega)
