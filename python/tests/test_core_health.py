# SPDX-License-Identifier: MIT
"""How the Core reads the base's health list (ctrlbus.core.health)."""

from __future__ import annotations

from support.core_fakes import FakeBase
from support.core_session import start


def test_health_errors_are_fetched_with_their_messages() -> None:
    health = [(0x01038000, "motor watchdog tripped"), (0x02020100, "battery critically low")]
    core, base, bus = start(FakeBase(health=list(health)))
    bus.run_for(1.5)
    state = core.health
    assert state.flags == 0x03
    assert [(error.code, error.message) for error in state.errors] == health
    assert core.link_stats()["watchdog_reported"] == 1
    texts = [event.text for event in core.events()]
    assert "health: 0x01038000 motor watchdog tripped" in texts
    base.health.pop(0)
    bus.run_for(1.2)
    assert [error.code for error in core.health.errors] == [0x02020100]
    assert "health: 0x01038000 cleared" in [event.text for event in core.events()]
