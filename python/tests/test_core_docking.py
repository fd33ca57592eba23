# SPDX-License-Identifier: MIT
"""GO_HOME against the simulated base, and the long acceptance run (ctrlbus.core.docking)."""

from __future__ import annotations

import math

import pytest
from support.core_session import CONNECT_LIMIT_S

from ctrlbus import binconf
from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.core import CoreSession, DockingConfig
from ctrlbus.core.docking import GoHome, on_dock
from ctrlbus.kinematics import Pose, relative_pose
from ctrlbus.messages import (
    ExternalCommand,
)
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.schema import check_snapshot
from ctrlbus.web.snapshot import dashboard_snapshot


def simulated(world: World, blob: bytes | None = None) -> tuple[CoreSession, BaseStack, VirtualBus]:
    stack = BaseStack(SimulatedBase(world, binary_config=blob), BaseConfig())
    core = CoreSession(port="vtime")
    bus = VirtualBus(core, stack)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S)
    return core, stack, bus


@pytest.mark.slow  # a soak or long end-to-end run: make check leaves it out
def test_sixty_seconds_against_the_simulated_base_pose_matches_its_odometry() -> None:
    world = World()
    start_odometry = world.odometry_pose
    core, _, bus = simulated(world, binconf.example_blob())
    # A figure of eight, a turn in place, gentle arcs forwards and backwards, then rest.
    path = [(15.7, 0.2, 0.4), (15.7, 0.2, -0.4), (3.6, 0.0, 1.0), (10.0, 0.15, 0.1), (10.0, -0.15, -0.2)]
    for duration, vx, omega in path:
        core.set_velocity(vx, omega)
        bus.run_for(duration)
        assert world.held_by is None  # the path stays clear of walls and cliffs
    core.set_velocity(0.0, 0.0)
    bus.run_for(60.0 - bus.elapsed_s)
    assert bus.elapsed_s == pytest.approx(60.0)
    stats = core.link_stats()
    assert stats["connection"]["state"] == "connected" and stats["connection"]["connects"] == 1
    faults = ("timeouts", "retries", "checksum_failures", "resyncs", "malformed_answers", "stray_answers")
    problems = {key: stats[key] for key in faults if stats[key]}
    assert problems == {} and stats["errors_by_code"] == {} and stats["watchdog_trips"] == 0
    assert stats["requests"] == pytest.approx(60 * 48, rel=0.02)
    odometry = relative_pose(start_odometry, world.odometry_pose)
    pose = core.pose
    assert math.hypot(pose.x_mm - odometry.dx_mm, pose.y_mm - odometry.dy_mm) < 1.0
    assert abs(pose.theta_deg - odometry.dtheta_deg) < 0.1
    assert math.hypot(pose.x_mm, pose.y_mm) > 300.0  # it really went somewhere
    truth = relative_pose(start_odometry, world.true_pose)
    assert math.hypot(truth.dx_mm - pose.x_mm, truth.dy_mm - pose.y_mm) > 1.0  # slip: odometry drifts
    assert check_snapshot(dashboard_snapshot(core)) == []


@pytest.mark.parametrize("start_pose", [Pose(1000.0, 2000.0, 0.0), Pose(2000.0, 1900.0, 45.0)])
def test_go_home_docks_the_simulated_robot(start_pose: Pose) -> None:
    world = World(start_pose=start_pose)
    core, _, bus = simulated(world)
    core.go_home()
    assert core.command.mode == "go_home"
    assert bus.run_until(lambda: core.command.mode != "go_home", 90.0), core.command.activity
    assert core.last_outcome == "go home: docked"
    assert world.docked and on_dock(world.power_status)
    assert dashboard_snapshot(core)["battery"]["on_dock"]
    assert core.link_stats()["timeouts"] == 0


def test_go_home_from_an_external_command_on_the_simulated_base() -> None:
    world = World()
    core, stack, bus = simulated(world)
    stack.queue_external_command(ExternalCommand.GO_HOME)
    assert bus.run_until(lambda: core.command.mode == "go_home", 1.0)
    assert bus.run_until(lambda: core.command.mode != "go_home", 90.0)
    assert world.docked


def test_go_home_gives_up_after_its_time_limit() -> None:
    action = GoHome(DockingConfig(timeout_s=1.0))
    assert action.command(10.0) == (0.0, DockingConfig().search_radps)
    action.command(11.5)
    assert action.finished and action.failed and "within 1 s" in (action.outcome or "")
