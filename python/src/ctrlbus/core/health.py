# SPDX-License-Identifier: MIT
"""How the Core reads the base's health list: HEALTH_GET_HEALTH, then HEALTH_GET_ERROR for each.

`HealthReader` collects the errors a HEALTH_GET_HEALTH announces, one HEALTH_GET_ERROR answer at a
time, and puts the complete list into the telemetry model; it logs each error as it appears and
as it clears, and counts the base's own report of a watchdog trip. It sends nothing: it says
which requests to ask, and the session queues them.
"""

from __future__ import annotations

from ctrlbus.constants import WATCHDOG_TRIPPED_CODE
from ctrlbus.core.journal import Journal
from ctrlbus.core.stats import LinkStats
from ctrlbus.core.telemetry import BaseTelemetry, HealthError, HealthState
from ctrlbus.messages import HealthGetError, HealthGetHealthAnswer

__all__ = ["HealthReader"]


class HealthReader:
    """The health list being read, and the telemetry's health once it is complete."""

    def __init__(self, telemetry: BaseTelemetry, stats: LinkStats, journal: Journal) -> None:
        self._telemetry = telemetry
        self._stats = stats
        self._journal = journal
        self._log = journal.log
        self._collect: list[HealthError | None] | None = None  # one slot per announced error
        self._flags_pending: int | None = None

    def on_health(self, answer: HealthGetHealthAnswer) -> list[HealthGetError]:
        """A HEALTH_GET_HEALTH answer; returns the HEALTH_GET_ERROR requests it calls for (none
        while a list is still being read)."""
        if answer.error_count == 0 or self._collect is not None:
            if answer.error_count == 0:
                self._set(answer.flags, ())
            return []
        self._flags_pending = answer.flags
        self._collect = [None] * answer.error_count
        return [HealthGetError(index) for index in range(answer.error_count)]

    def on_error(self, index: int, error: HealthError | None) -> None:
        """The answer to HEALTH_GET_ERROR #index (None: refused); the last one completes the list."""
        collect = self._collect
        if collect is None or index >= len(collect):
            return
        collect[index] = error
        if index == len(collect) - 1:
            self._collect = None
            self._set(self._flags_pending, tuple(item for item in collect if item is not None))

    def forget(self) -> None:
        """The connection is gone: a list half read is dropped."""
        self._collect = None

    def _set(self, flags: int | None, errors: tuple[HealthError, ...]) -> None:
        previous = {error.code for error in self._telemetry.health.errors}
        for error in errors:
            if error.code not in previous:
                self._log("base", f"health: 0x{error.code:08X} {error.message}")
                if error.code == WATCHDOG_TRIPPED_CODE:
                    self._stats.watchdog_reported += 1
        current = {error.code for error in errors}
        for code in sorted(previous - current):
            self._log("base", f"health: 0x{code:08X} cleared")
        if self._telemetry.health != HealthState(flags, errors):
            self._telemetry.health = HealthState(flags, errors)
            self._journal.changed("health")
