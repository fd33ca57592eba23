# SPDX-License-Identifier: MIT
"""The Core's event log and its subscribers (ctrlbus.core.journal, ctrlbus.core.events)."""

from __future__ import annotations

from support.core_fakes import FakeBase
from support.core_session import CONNECT_LIMIT_S

from ctrlbus.core import CoreSession
from ctrlbus.vtime import VirtualBus


def test_subscribers_hear_changes_and_a_failing_one_does_no_harm() -> None:
    heard: list[str] = []

    def broken(topic: str) -> None:
        raise RuntimeError("subscriber bug")

    core = CoreSession(port="fake")
    core.subscribe(broken)
    unsubscribe = core.subscribe(heard.append)
    bus = VirtualBus(core, FakeBase())
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S)
    bus.run_for(0.5)
    assert {"connection", "base", "pose", "bumpers", "sensors", "events"} <= set(heard)
    unsubscribe()
    count = len(heard)
    bus.run_for(0.5)
    assert len(heard) == count


def test_event_log_and_trail_are_bounded() -> None:
    core = CoreSession(port="fake")
    bus = VirtualBus(core, FakeBase(silent=True))
    bus.run_for(40.0)  # an absent base: connect attempts, quietly
    events = core.events()
    assert len(events) <= 200
    assert any("no answer yet" in event.text for event in events)
