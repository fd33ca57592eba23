# SPDX-License-Identifier: MIT
"""Connecting, the configuration, disconnecting and reconnecting (docs/protocol.md §11.1-§11.3,
§11.7): ctrlbus.core.protocol."""

from __future__ import annotations

import itertools
from typing import Any

import pytest
from support.core_fakes import FakeBase
from support.core_session import names_after, start

from ctrlbus import binconf
from ctrlbus.core import CoreSession
from ctrlbus.core.geometry import geometry_from_tree
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.snapshot import dashboard_snapshot


def test_connect_then_fallback_from_conf_adv_to_conf_then_system_up() -> None:
    core, base, _ = start(FakeBase(blob=None))
    assert base.names()[:4] == ["CONNECT_BASE", "GET_BASE_CONF_ADV", "GET_BASE_CONF", "SEND_EVENT:0x63"]
    texts = [event.text for event in core.events()]
    assert "ERROR 0x8000 to GET_BASE_CONF_ADV" in texts
    snap = dashboard_snapshot(core)
    assert snap["base"]["config_source"] == "GET_BASE_CONF"
    assert snap["base"]["model"] == "fake base"
    assert snap["base"]["firmware_version"] == "1.20"
    assert snap["base"]["serial"] == "000000010000000200000003"
    assert snap["base"]["radius_mm"] == pytest.approx(170.0)
    assert [sensor["angle_deg"] for sensor in snap["sensors"]] == [0.0, 45.0]
    assert [(bumper["bit"], bumper["angle_deg"]) for bumper in snap["bumpers"]] == [(0, 45.0), (1, 315.0)]
    assert [cliff["bit"] for cliff in snap["cliffs"]] == [2, 3, 4, 5]  # where the reference puts them
    assert core.limits() == (0.5, 2.0)


def test_binary_configuration_is_preferred_when_served() -> None:
    core, base, bus = start(FakeBase(blob=binconf.example_blob(), distances_mm=tuple(range(100, 1700, 100))))
    bus.run_for(0.5)
    # The blob is used; GET_BASE_CONF is asked besides it only to show its view (§11.2).
    assert base.names()[:4] == ["CONNECT_BASE", "GET_BASE_CONF_ADV", "GET_BASE_CONF", "SEND_EVENT:0x63"]
    snap = dashboard_snapshot(core)
    assert set(snap["base"]["views"]) == {"GET_BASE_CONF", "GET_BASE_CONF_ADV"}
    tree: Any = binconf.decode(binconf.example_blob())
    geometry = geometry_from_tree(tree)
    assert geometry is not None
    assert snap["base"]["config_source"] == "GET_BASE_CONF_ADV"
    assert snap["base"]["radius_mm"] == pytest.approx(1000.0 * tree["base"]["robot_size"] / 2)  # a diameter
    # Each distance sensor's reading is taken from its slot (its id in the tree).
    distances = core.distances_mm
    assert distances is not None
    assert [sensor["distance_mm"] for sensor in snap["sensors"]] == [
        distances[sensor.slot] for sensor in geometry.sensors
    ]
    sonars = [entry for entry in tree["base"]["sensors"] if entry["type"] == {"dict": "sonar"}]
    assert len(snap["sensors"]) == len(sonars)
    first_pose = sonars[0]["installation_pose"]
    assert snap["sensors"][0]["x_mm"] == pytest.approx(first_pose["x"] * 1000.0)
    assert [bumper["bit"] for bumper in snap["bumpers"]] == [0, 1]
    assert [cliff["bit"] for cliff in snap["cliffs"]] == [2, 3, 4, 5]


@pytest.mark.parametrize("blob", [b"\x50\x05\x04", b"\x40\x00", b"\x50\x00"])
def test_unusable_binary_configuration_falls_back_to_conf(blob: bytes) -> None:
    core, base, _ = start(FakeBase(blob=blob))
    assert base.names()[:4] == ["CONNECT_BASE", "GET_BASE_CONF_ADV", "GET_BASE_CONF", "SEND_EVENT:0x63"]
    assert dashboard_snapshot(core)["base"]["config_source"] == "GET_BASE_CONF"
    assert any("GET_BASE_CONF" in event.text and "asking" in event.text for event in core.events())


def test_connect_is_repeated_with_a_flushing_sync_until_answered() -> None:
    base = FakeBase(silent=True)
    core = CoreSession(port="fake")
    bus = VirtualBus(core, base)
    bus.run_for(2.0)
    assert core.state == "connecting"
    connects = [when for when, request in base.requests if request.NAME == "CONNECT_BASE"]
    assert len(connects) >= 3
    assert all(later - earlier >= 0.5 - 1e-9 for earlier, later in itertools.pairwise(connects))
    # One 512-byte SYNC after each unanswered CONNECT_BASE, before the next one.
    assert [size for _, size in base.syncs] == [512] * len(base.syncs)
    for earlier, later in itertools.pairwise(connects):
        assert sum(1 for when, _ in base.syncs if earlier < when < later) == 1
    assert core.link_stats()["timeouts"] == 0  # the connect loop is not a run of timeouts
    base.silent = False
    assert bus.run_until(lambda: core.connected, 2.0)
    assert core.connects == 1


def test_error_answer_to_connect_is_logged_and_the_loop_continues() -> None:
    base = FakeBase(errors={"CONNECT_BASE": 0x8000})
    core = CoreSession(port="fake")
    bus = VirtualBus(core, base)
    bus.run_for(1.6)
    assert len(base.requests_named("CONNECT_BASE")) == 4  # at 0, 0.5, 1.0, 1.5 s
    assert base.syncs == []  # answered, so nothing to flush
    assert "ERROR 0x8000 to CONNECT_BASE" in [event.text for event in core.events()]
    del base.errors["CONNECT_BASE"]
    assert bus.run_until(lambda: core.connected, 1.0)


def test_reconnect_after_the_base_goes_silent() -> None:
    core, base, bus = start()
    bus.run_for(1.0)
    silent_at = bus.now
    base.silent = True
    assert bus.run_until(lambda: core.state == "disconnected", 2.0)
    heard = names_after(base, silent_at)
    # Three attempts in a row go unanswered (a periodic request whose next period has come is
    # superseded by it rather than resent), then CORE_DISCONNECT, then the connect loop.
    notice = heard.index("SEND_EVENT:0x65")
    assert notice == 3
    stats = core.link_stats()
    assert stats["timeouts"] == 3
    assert stats["superseded"] + stats["retries"] == 2
    assert stats["abandoned_at_disconnect"] == 1 and stats["lost_requests"] == 0
    bus.run_for(1.0)
    heard = names_after(base, silent_at)
    assert heard[notice + 1] == "CONNECT_BASE"
    assert any(size == 512 for when, size in base.syncs if when > silent_at)
    assert core.link_stats()["disconnects"] == 1
    back_at = bus.now
    base.silent = False
    assert bus.run_until(lambda: core.connected, 2.0)
    assert names_after(base, back_at)[:3] == ["CONNECT_BASE", "GET_BASE_CONF_ADV", "GET_BASE_CONF"]
    assert "SEND_EVENT:0x63" in names_after(base, back_at)
    assert core.connects == 2
    assert core.link_stats()["connection"]["connects"] == 2


def test_stop_on_purpose_sends_core_disconnect() -> None:
    core, base, bus = start()
    core.set_velocity(0.1, 0.0)
    bus.run_for(0.3)
    stop_at = bus.now
    core.request_stop()
    bus.run_for(0.5)
    assert core.stopped and core.state == "disconnected"
    assert names_after(base, stop_at)[-1] == "SEND_EVENT:0x65"
    assert core.poll(bus.now + 1.0) is None and core.next_poll_time() is None


def test_stop_before_connecting_sends_nothing() -> None:
    core = CoreSession(port="fake")
    core.request_stop()
    assert core.stopped
    assert core.poll(0.0) is None
