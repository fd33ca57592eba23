# SPDX-License-Identifier: MIT
"""A Core session's time and its record of itself: the event log and the topics that changed.

Every part of the session writes here: the time it was last given (the first `now` is the
session's zero), what it did in words (`EventLog`, ctrlbus.core.events) and which topics changed
since the subscribers were last told. The time is only ever passed in (never read from a clock).
"""

from __future__ import annotations

import logging
from collections.abc import Callable

from ctrlbus.core.events import CoreEvent, EventLog

__all__ = ["Journal"]

log = logging.getLogger("ctrlbus.core")


class Journal:
    """The session's clock (as given), event log, changed topics and subscribers."""

    def __init__(self) -> None:
        self.t0: float | None = None  # the first `now` seen
        self.now = 0.0  # the latest `now` seen (time never runs backwards here)
        self._events = EventLog()
        self._changed: set[str] = set()
        self._subscribers: list[Callable[[str], None]] = []

    def advance(self, now: float) -> bool:
        """Take the time `now`; True if it is the first time seen (the session's zero)."""
        if self.t0 is None:
            self.t0 = self.now = now
            return True
        if now > self.now:
            self.now = now
        return False

    def elapsed(self, t: float) -> float:
        """Session seconds at time `t` (0 before the first time seen)."""
        return 0.0 if self.t0 is None else t - self.t0

    def log(self, direction: str, text: str) -> None:
        """Add an event at the current time: `direction` is "core" or "base"."""
        event = self._events.add(self.elapsed(self.now), direction, text)
        self._changed.add("events")
        log.debug("%s %.3f %s", direction, event.t_s, text)

    def changed(self, *topics: str) -> None:
        """Note topics whose subscribers the next notify() tells."""
        self._changed.update(topics)

    def events(self, since_seq: int = 0) -> list[CoreEvent]:
        return self._events.since(since_seq)

    def subscribe(self, callback: Callable[[str], None]) -> Callable[[], None]:
        self._subscribers.append(callback)

        def unsubscribe() -> None:
            if callback in self._subscribers:
                self._subscribers.remove(callback)

        return unsubscribe

    def notify(self) -> None:
        """Tell every subscriber of every changed topic, sorted, and forget the changes."""
        if not self._changed:
            return
        topics = sorted(self._changed)
        self._changed.clear()
        subscribers = list(self._subscribers)
        for topic in topics:
            for callback in subscribers:
                try:
                    callback(topic)
                except Exception:  # a subscriber's bug must not stop the Core
                    log.exception("a Core subscriber failed on %r", topic)
