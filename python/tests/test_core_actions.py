# SPDX-License-Identifier: MIT
"""External commands (§11.5) and the actions they start: ctrlbus.core.actions."""

from __future__ import annotations

from collections import Counter

import pytest
from support.core_fakes import FakeBase
from support.core_session import names_after, start

from ctrlbus.core import CoreConfig, DockingConfig
from ctrlbus.kinematics import relative_pose
from ctrlbus.messages import (
    ExternalCommand,
)
from ctrlbus.vtime import VirtualBus


def offer(base: FakeBase, bus: VirtualBus, code: int, run_s: float) -> float:
    t0 = bus.now
    base.commands.append(code)
    bus.run_for(run_s)
    return t0


@pytest.mark.parametrize(
    ("code", "dx_mm", "dtheta_deg"),
    [
        (ExternalCommand.MOVE_FORWARD, 300.0, 0.0),
        (ExternalCommand.MOVE_BACKWARD, -300.0, 0.0),
        (ExternalCommand.TURN_LEFT, 0.0, 90.0),
        (ExternalCommand.TURN_RIGHT, 0.0, -90.0),
    ],
)
def test_poll_ans_flow_then_move_or_turn(code: int, dx_mm: float, dtheta_deg: float) -> None:
    core, base, bus = start()
    start_pose = base.pose
    t0 = offer(base, bus, code, 4.0)
    heard = names_after(base, t0)
    offered = heard.index("POLL_BASE_CMD")
    assert heard[offered + 1] == "POLL_BASE_ANS_CMD"  # acknowledged at once
    assert heard.count("POLL_BASE_ANS_CMD") == 1
    assert f"base offers {ExternalCommand(code).name} (0x{code:02X})" in [e.text for e in core.events()]
    moved = relative_pose(start_pose, base.pose)
    assert moved.dx_mm == pytest.approx(dx_mm, abs=12.0)
    assert moved.dtheta_deg == pytest.approx(dtheta_deg, abs=1.5)
    assert core.command.mode == "idle" and (core.command.vx_mps, core.command.omega_radps) == (0.0, 0.0)
    assert "done" in (core.last_outcome or "")


def test_cancel_action_stops_a_move() -> None:
    core, base, bus = start()
    offer(base, bus, ExternalCommand.MOVE_FORWARD, 0.6)
    assert core.command.mode == "external"
    offer(base, bus, ExternalCommand.CANCEL_ACTION, 1.0)
    assert core.command.mode == "idle"
    assert 40.0 < base.pose.x_mm < 200.0
    assert "CANCEL_ACTION" in (core.last_outcome or "")


def test_commands_without_an_action_are_acknowledged_and_noted() -> None:
    core, base, bus = start()
    offer(base, bus, ExternalCommand.START_SWEEP, 1.0)
    assert base.requests_named("POLL_BASE_ANS_CMD")
    assert core.command.mode == "idle"
    assert any("START_SWEEP (0x80) noted" in event.text for event in core.events())


def test_go_home_from_poll_starts_docking_and_polls_charger_data() -> None:
    core, base, bus = start(config=CoreConfig(docking=DockingConfig(max_search_turns=1.0)))
    t0 = offer(base, bus, ExternalCommand.GO_HOME, 1.0)
    assert core.command.mode == "go_home"
    counts = Counter(names_after(base, t0 + 0.3))
    assert counts["GET_CHARGER_DATA"] >= 6 and counts["GET_BASE_STATUS"] >= 6  # 10 Hz while docking
    # The fake base's probes never see a beacon: after a full turn of searching it gives up.
    assert bus.run_until(lambda: core.command.mode == "idle", 15.0)
    assert "not in sight" in (core.last_outcome or "")
    assert core.pose.theta_deg != 0.0


def test_external_commands_are_ignored_while_the_stop_is_latched() -> None:
    core, base, bus = start()
    core.emergency_stop()
    offer(base, bus, ExternalCommand.MOVE_FORWARD, 1.0)
    assert core.command.mode == "estop"
    assert base.pose.x_mm == 0.0
    assert any("refused" in event.text for event in core.events())
