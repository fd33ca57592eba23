# SPDX-License-Identifier: MIT
"""What the Core tells the base to do: the velocity command, its limits and the emergency stop
(ctrlbus.core.motion)."""

from __future__ import annotations

import math

import pytest
from support.core_session import set_v_requests, start

from ctrlbus.core import CoreSession
from ctrlbus.errors import UsageError


def test_velocity_is_clamped_and_the_emergency_stop_latches() -> None:
    core = CoreSession(port="fake")
    assert core.limits() == (0.0, 0.0)  # unknown before the configuration
    core.set_velocity(0.3, 0.3)
    assert (core.command.vx_mps, core.command.omega_radps) == (0.0, 0.0)
    core, base, bus = start()
    core.set_velocity(5.0, -10.0)
    assert (core.command.vx_mps, core.command.omega_radps, core.command.mode) == (0.5, -2.0, "teleop")
    bus.run_for(0.2)
    last = set_v_requests(base)[-1]
    assert (last.vx_mps, last.omega_radps) == (0.5, -2.0)
    core.emergency_stop()
    core.set_velocity(0.2, 0.0)
    core.go_home()
    bus.run_for(0.2)
    last = set_v_requests(base)[-1]
    assert (last.vx_mps, last.omega_radps) == (0.0, 0.0)
    assert core.command.mode == "estop" and core.command.estop
    core.release_stop()
    bus.run_for(0.2)
    assert core.command.mode == "idle" and not core.command.estop
    core.set_velocity(0.1, 0.0)
    assert core.command.mode == "teleop"
    with pytest.raises(UsageError):
        core.set_velocity(math.nan, 0.0)
    with pytest.raises(UsageError):
        core.drive(math.inf)
    with pytest.raises(UsageError):
        core.turn(90.0, rate_radps=0.0)


def test_set_velocity_cancels_an_action() -> None:
    core, _, bus = start()
    core.drive(1.0)
    bus.run_for(0.5)
    assert core.command.mode == "external"
    core.set_velocity(0.0, 0.5)
    assert core.command.mode == "teleop"
    assert "cancelled by a velocity command" in (core.last_outcome or "")
