# SPDX-License-Identifier: MIT
"""What a connected Core asks for next, and when (docs/protocol.md §11.4).

`PollSchedule` keeps each periodic request's next due time and the follow-ups that go before
them (POLL_BASE_ANS_CMD after an offered command, HEALTH_GET_ERROR for each listed error). It
sends nothing and reads no clock: the session asks it, with the time, which request is due.
"""

from __future__ import annotations

from collections import deque

from ctrlbus.core.config import PollRates
from ctrlbus.messages import (
    GetBaseBumperData,
    GetBaseMotorData,
    GetBaseSensorData,
    GetBaseStatus,
    GetChargerData,
    HealthGetHealth,
    PollBaseCmd,
    RequestMessage,
)

__all__ = ["SCHEDULE", "PollSchedule"]

# (name, request) in the order §11.4 sends them when several are due; each one's rate is the
# PollRates attribute `<name>_hz`. SET_V_AND_GET_DEADRECKON (None) is built at send time from the
# current velocity command.
SCHEDULE: tuple[tuple[str, RequestMessage | None], ...] = (
    ("set_v", None),
    ("bumper", GetBaseBumperData()),
    ("sensor", GetBaseSensorData()),
    ("status", GetBaseStatus()),
    ("motor", GetBaseMotorData()),
    ("poll_cmd", PollBaseCmd()),
    ("health", HealthGetHealth()),
    ("charger", GetChargerData(0)),
)
_DOCKING_ONLY = frozenset({"charger"})


class PollSchedule:
    """The polling schedule of one connection: next due times, and follow-ups first."""

    def __init__(self, rates: PollRates) -> None:
        self._rates = rates
        self._next_due: dict[str, float] = {}
        # Requests an answer calls for; they go before the schedule, oldest first.
        self._followups: deque[RequestMessage] = deque()

    def restart(self) -> None:
        """A new connection polls from scratch: everything is due at once."""
        self._next_due = {}
        self._followups.clear()

    def follow_up(self, *messages: RequestMessage, first: bool = False) -> None:
        """Ask `messages` before the periodic requests: after the follow-ups already waiting, or
        before them if `first`."""
        if first:
            self._followups.extendleft(reversed(messages))
        else:
            self._followups.extend(messages)

    def forget_follow_ups(self) -> None:
        """The connection is gone: what its answers called for is no longer asked."""
        self._followups.clear()

    def rate(self, name: str, *, docking: bool) -> float:
        """Hz of the request `name` (0: not polled); `docking` while the Core goes home."""
        rates = self._rates
        if name in _DOCKING_ONLY:
            return rates.charger_hz if docking else 0.0
        rate: float = getattr(rates, f"{name}_hz")
        if name == "status" and docking:
            return max(rate, rates.charger_hz)  # see the on-dock bit promptly while docking
        return rate

    def due_time(self, now: float, *, docking: bool) -> float | None:
        """When the next request is due (`now` if a follow-up waits); None if nothing is polled."""
        if self._followups:
            return now
        dues = [due for name, due in self._next_due.items() if self.rate(name, docking=docking) > 0]
        return min(dues) if dues else None

    def take_due(self, now: float, *, docking: bool) -> tuple[str | None, RequestMessage | None] | None:
        """The request to ask at `now`, as (name, request): the oldest follow-up (name None), else
        the first periodic request due, its next period booked (request None: SET_V, built by
        the caller); None if nothing is due. A request due for the first time is due at once."""
        if self._followups:
            return None, self._followups.popleft()
        for name, message in SCHEDULE:
            rate = self.rate(name, docking=docking)
            if rate <= 0:
                continue
            due = self._next_due.setdefault(name, now)
            if due > now:
                continue
            period = 1.0 / rate
            due += period
            self._next_due[name] = due if due > now else now + period
            return name, message
        return None

    def period_due(self, name: str | None, now: float) -> bool:
        """Whether the periodic request `name` is due again at `now` (False for a one-off)."""
        return name is not None and self._next_due.get(name, now) <= now

    def hurry(self, name: str) -> None:
        """Make `name` due at once (its rate has just gone up)."""
        self._next_due.pop(name, None)
