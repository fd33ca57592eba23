# SPDX-License-Identifier: MIT
"""GO_HOME: dock on the charger by following its infrared beacons.

The dock has three beacons (left, main, right) and the base three probes (left, main, right);
GET_CHARGER_DATA gives, per probe, the beacons it sees (protocol §5.8). The main beacon's cone is
narrow and marks the dock's centre line; the main probe looks straight ahead. The controller:

1. **search**: turn left until the main probe sees the main beacon;
2. **measure**: find the beacon's direction from the edges of the main probe's view. A beacon bit
   is reported late (it is sampled, polled, and held for 260 ms after it was last seen), so one
   sweep's midpoint lies off by the delay times the turn rate, in the direction of the turn. The
   controller sweeps across the beacon once in each direction and averages the two midpoints,
   which cancels that delay without knowing it;
3. **turn** to that direction (dead-reckoned heading);
4. **approach**: drive straight at the beacon. If the main probe loses it, stop and measure again
   (starting on the side where a side probe still sees it);
5. **docked** when GET_BASE_STATUS reports the robot on the dock (power bit2, or charging without
   the DC cable). A bumper pressed before that, a beacon never found, or the time limit ends the
   action as failed.

It assumes the robot starts where the main probe can see the main beacon from some heading: in
front of the dock, within the main beacon's cone and range.
"""

from __future__ import annotations

import enum
import math

from ctrlbus.constants import POWER_CHARGING, POWER_DC_CONNECTED, POWER_ON_DOCK
from ctrlbus.core.actions import MODE_GO_HOME, Action
from ctrlbus.core.config import DockingConfig

__all__ = [
    "BEACON_MAIN",
    "MAX_REALIGNMENTS",
    "MIN_TURN_RADPS",
    "PROBE_LEFT",
    "PROBE_MAIN",
    "PROBE_RIGHT",
    "TURN_GAIN_PER_S",
    "GoHome",
    "Phase",
    "on_dock",
]

PROBE_LEFT, PROBE_MAIN, PROBE_RIGHT = 0, 1, 2
BEACON_MAIN = 0x02  # bit of the main beacon in each probe's bitmap
TURN_GAIN_PER_S = 2.0
MIN_TURN_RADPS = 0.04
MAX_REALIGNMENTS = 8


def on_dock(power_status: int) -> bool:
    """On the dock: bit2, or charging (bit0) without the DC cable (bit1)."""
    if power_status & POWER_ON_DOCK:
        return True
    return bool(power_status & POWER_CHARGING) and not power_status & POWER_DC_CONNECTED


class Phase(enum.Enum):
    SEARCH = "searching for the main beacon"
    CLEAR = "turning off the main beacon"
    SWEEP_FIRST = "measuring the main beacon's direction"
    SWEEP_SECOND = "measuring the main beacon's direction again"
    TURN = "turning to the main beacon"
    APPROACH = "approaching the dock"
    BUMPED = "bumper pressed: checking whether docked"


class GoHome(Action):
    mode = MODE_GO_HOME

    def __init__(self, config: DockingConfig) -> None:
        super().__init__("go home")
        self.config = config
        self.phase = Phase.SEARCH
        self.main_seen: bool | None = None
        self.realignments = 0
        self.target_deg: float | None = None
        self._direction = 1.0  # the CLEAR turn; the first sweep goes the other way
        self._phase_start_deg = 0.0
        self._entry_deg: float | None = None
        self._first_mid_deg: float | None = None
        self._status_after_bump = False
        self._set_activity()

    # -- what the Core learns ---------------------------------------------------------------

    def on_status(self, power_status: int, now: float) -> None:
        if self.finished:
            return
        if on_dock(power_status):
            self.finish("go home: docked")
        elif self.phase is Phase.BUMPED:
            if self._status_after_bump:
                self.finish("go home: a bumper was pressed before the robot reached the dock", failed=True)
            self._status_after_bump = True  # the next status is certainly newer than the bump

    def on_bumpers(self, pressed: bool, now: float) -> None:
        if self.finished or not pressed or self.phase is not Phase.APPROACH:
            return
        self._enter(Phase.BUMPED)
        self._status_after_bump = False

    def on_charger_error(self, reason: str) -> None:
        self.finish(f"go home: no beacon data ({reason})", failed=True)

    def on_charger(self, probes: tuple[int, ...], now: float) -> None:
        if self.finished:
            return
        if len(probes) <= PROBE_MAIN:
            self.finish("go home: the base reports no main beacon probe", failed=True)
            return
        seen = bool(probes[PROBE_MAIN] & BEACON_MAIN)
        self.main_seen = seen
        heading = self.heading_deg
        phase = self.phase
        if phase is Phase.SEARCH and seen:
            self._direction = 1.0  # keep turning left until past the beacon
            self._enter(Phase.CLEAR)
        elif phase is Phase.CLEAR and not seen:
            self._enter(Phase.SWEEP_FIRST)
        elif phase in (Phase.SWEEP_FIRST, Phase.SWEEP_SECOND):
            if self._entry_deg is None:
                if seen:
                    self._entry_deg = heading
            elif not seen:
                middle = (self._entry_deg + heading) / 2.0
                if phase is Phase.SWEEP_FIRST:
                    self._first_mid_deg = middle
                    self._enter(Phase.SWEEP_SECOND)
                else:
                    assert self._first_mid_deg is not None
                    self.target_deg = (self._first_mid_deg + middle) / 2.0
                    self._enter(Phase.TURN)
        elif phase is Phase.APPROACH and not seen:
            self.realignments += 1
            if self.realignments > MAX_REALIGNMENTS:
                self.finish("go home: keeps losing the main beacon", failed=True)
                return
            # Sweep first towards the side where a side probe still sees the main beacon.
            left = len(probes) > PROBE_LEFT and probes[PROBE_LEFT] & BEACON_MAIN
            right = len(probes) > PROBE_RIGHT and probes[PROBE_RIGHT] & BEACON_MAIN
            self._direction = 1.0 if right and not left else -1.0
            self._enter(Phase.SWEEP_FIRST)

    # -- what the Core sends ----------------------------------------------------------------

    def command(self, now: float) -> tuple[float, float]:
        if self.finished:
            return 0.0, 0.0
        config = self.config
        if now - self.started_s(now) > config.timeout_s:
            self.finish(f"go home: not docked within {config.timeout_s:g} s", failed=True)
            return 0.0, 0.0
        phase = self.phase
        if phase in (Phase.SEARCH, Phase.CLEAR, Phase.SWEEP_FIRST, Phase.SWEEP_SECOND):
            if abs(self.heading_deg - self._phase_start_deg) > 360.0 * config.max_search_turns:
                self.finish("go home: the main beacon is not in sight", failed=True)
                return 0.0, 0.0
            if phase is Phase.SEARCH:
                return 0.0, config.search_radps
            # CLEAR turns one way, the first sweep the other, the second sweep back again.
            sign = -self._direction if phase is Phase.SWEEP_FIRST else self._direction
            return 0.0, sign * config.sweep_radps
        if phase is Phase.TURN:
            assert self.target_deg is not None
            error_deg = self.target_deg - self.heading_deg
            if abs(error_deg) <= config.aligned_deg:
                self._enter(Phase.APPROACH)
                return config.approach_mps, 0.0
            rate = min(
                config.sweep_radps, max(MIN_TURN_RADPS, TURN_GAIN_PER_S * math.radians(abs(error_deg)))
            )
            return 0.0, rate if error_deg > 0 else -rate
        if phase is Phase.APPROACH:
            return config.approach_mps, 0.0
        return 0.0, 0.0  # BUMPED: wait for the status

    def _enter(self, phase: Phase) -> None:
        self.phase = phase
        self._phase_start_deg = self.heading_deg
        self._entry_deg = None
        if phase is Phase.SWEEP_FIRST:
            self._first_mid_deg = None
        self._set_activity()

    def _set_activity(self) -> None:
        self.activity = f"go home: {self.phase.value}"
