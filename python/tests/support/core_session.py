# SPDX-License-Identifier: MIT
"""A Core session against a scriptable fake base in virtual time, for the tests of ctrlbus.core
(test_core_*.py)."""

from __future__ import annotations

from ctrlbus.core import CoreConfig, CoreSession, PollRates
from ctrlbus.messages import SetVAndGetDeadreckon
from ctrlbus.vtime import VirtualBus
from support.core_fakes import FakeBase, describe

CONNECT_LIMIT_S = 5.0


def start(
    base: FakeBase | None = None, config: CoreConfig | None = None, **bus_options: float
) -> tuple[CoreSession, FakeBase, VirtualBus]:
    """A Core and a fake base in virtual time, run until connected."""
    base = base if base is not None else FakeBase()
    core = CoreSession(config, port="fake")
    bus = VirtualBus(core, base, **bus_options)  # type: ignore[arg-type]
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S), core.events()
    return core, base, bus


def only_set_v(hz: float) -> PollRates:
    return PollRates(
        set_v_hz=hz, bumper_hz=0, sensor_hz=0, status_hz=0, motor_hz=0, poll_cmd_hz=0, health_hz=0
    )


def names_after(base: FakeBase, t: float) -> list[str]:
    return [describe(request) for when, request in base.requests if when >= t]


def set_v_requests(base: FakeBase) -> list[SetVAndGetDeadreckon]:
    return [request for request in base.requests_named("SET_V_AND_GET_DEADRECKON")]  # type: ignore[misc]
