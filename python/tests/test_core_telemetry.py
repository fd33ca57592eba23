# SPDX-License-Identifier: MIT
"""What the Core knows of the base, as the dashboard's snapshot shows it (ctrlbus.core.telemetry)."""

from __future__ import annotations

import threading

from support.core_fakes import FakeBase
from support.core_session import CONNECT_LIMIT_S

from ctrlbus import binconf
from ctrlbus.core import CoreSession
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.schema import check_snapshot
from ctrlbus.web.snapshot import dashboard_snapshot
from ctrlbus.web.source import CoreSource


def test_snapshot_follows_the_dashboard_schema_in_every_state() -> None:
    core = CoreSession(port="fake")
    assert check_snapshot(dashboard_snapshot(core)) == []  # nothing known yet
    base = FakeBase(
        blob=binconf.example_blob(),
        health=[(0x01020100, "battery low")],
        probes=(1, 3, 4),
        power_status=0x05,
        bumper_bitmap=0xFFFF_FFFA,
    )
    bus = VirtualBus(core, base)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S)
    core.set_velocity(0.2, 0.3)
    bus.run_for(2.0)
    snap = dashboard_snapshot(core)
    assert check_snapshot(snap) == []
    assert snap["charger"] is None
    assert snap["health"]["errors"] == [{"code": 0x01020100, "message": "battery low"}]
    assert snap["bumpers"][0]["pressed"] and not snap["bumpers"][1]["pressed"]
    assert snap["cliffs"][0]["triggered"]  # bit 2
    assert snap["battery"]["on_dock"] and snap["battery"]["charging"]
    assert len(snap["trail"]) > 10
    base.power_status = 0  # off the dock, so that docking starts
    bus.run_for(1.1)
    core.go_home()
    bus.run_for(0.5)
    snap = dashboard_snapshot(core)
    assert check_snapshot(snap) == []
    assert snap["command"]["mode"] == "go_home" and snap["command"]["activity"]
    assert snap["charger"] == {"beacon_count": 3, "probe_count": 3, "probes": [1, 3, 4]}
    core.emergency_stop()
    base.silent = True
    bus.run_for(2.0)
    snap = dashboard_snapshot(core)
    assert check_snapshot(snap) == []
    assert snap["link"]["connection"]["state"] == "disconnected" and snap["command"]["mode"] == "estop"


def test_snapshot_and_controls_from_another_thread() -> None:
    """The session holds no lock: the loop that drives it and the dashboard share one."""
    core = CoreSession(port="fake")
    lock = threading.RLock()
    bus = VirtualBus(core, FakeBase(), lock=lock)
    source = CoreSource(core, lock)
    problems: list[str] = []
    done = threading.Event()

    def dashboard() -> None:
        try:
            while not done.is_set():
                problems.extend(check_snapshot(source.snapshot()))
                source.set_velocity(0.1, 0.2)
        except Exception as exc:  # a race would show here, not only as a thread warning
            problems.append(repr(exc))

    thread = threading.Thread(target=dashboard)
    thread.start()
    try:
        bus.run_for(5.0)
    finally:
        done.set()
        thread.join(10)
    assert problems == []
    assert core.connected
