# SPDX-License-Identifier: MIT
"""The Core emulator (ctrlbus.core): protocol behaviour of docs/protocol.md §11, telemetry,
controls, actions, statistics and the snapshot, all in virtual time (ctrlbus.vtime) against a
scriptable fake base and the simulated base; plus the real-time runner over in-process links."""

from __future__ import annotations

import itertools
import math
import subprocess
import sys
import threading
import time
from collections import Counter
from collections.abc import Callable
from typing import Any

import pytest
from core_fakes import FakeBase, describe

from ctrlbus import binconf
from ctrlbus.base import BaseConfig, BaseRunner, BaseStack
from ctrlbus.core import CoreConfig, CoreRunner, CoreSession, DockingConfig, PollRates
from ctrlbus.core.docking import GoHome, on_dock
from ctrlbus.core.geometry import geometry_from_tree
from ctrlbus.errors import LinkError, UsageError
from ctrlbus.frame import StreamDecoder, encode
from ctrlbus.kinematics import Pose, relative_pose
from ctrlbus.link import PipeLink, link_pair
from ctrlbus.messages import (
    ErrorAnswer,
    ExternalCommand,
    InvalidAnswer,
    SetVAndGetDeadreckon,
    answer_frame,
    decode_request,
)
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.schema import check_snapshot
from ctrlbus.web.snapshot import dashboard_snapshot
from ctrlbus.web.source import CoreSource, DashboardSource

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


# --- connect and configuration (§11.1-§11.3) -------------------------------------------------------


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


# --- polling schedule (§11.4) ----------------------------------------------------------------


def test_default_schedule_rates() -> None:
    core, base, bus = start()
    t0 = bus.now
    bus.run_for(10.0)
    counts = Counter(names_after(base, t0))
    expected = {
        "SET_V_AND_GET_DEADRECKON": 200,
        "GET_BASE_BUMPER_DATA": 100,
        "GET_BASE_SENSOR_DATA": 100,
        "GET_BASE_STATUS": 10,
        "GET_BASE_MOTOR_DATA": 10,
        "POLL_BASE_CMD": 50,
        "HEALTH_GET_HEALTH": 10,
    }
    for name, count in expected.items():
        assert abs(counts[name] - count) <= 1, (name, counts)
    assert "GET_CHARGER_DATA" not in counts  # only while docking
    assert core.link_stats()["requests_per_s"] == pytest.approx(48.0, abs=1.0)


def test_rates_are_configurable_and_zero_switches_off() -> None:
    rates = PollRates.parse("set_v=50,sensor=0,bumper=0,poll_cmd=1")
    _, base, bus = start(config=CoreConfig(rates=rates))
    t0 = bus.now
    bus.run_for(4.0)
    counts = Counter(names_after(base, t0))
    assert abs(counts["SET_V_AND_GET_DEADRECKON"] - 200) <= 1
    assert counts["GET_BASE_SENSOR_DATA"] == counts["GET_BASE_BUMPER_DATA"] == 0
    assert abs(counts["POLL_BASE_CMD"] - 4) <= 1


@pytest.mark.parametrize("text", ["set_v", "nope=3", "set_v=x", "set_v=-1", "set_v=1,set_v=2", "status=2000"])
def test_bad_rates_are_refused(text: str) -> None:
    with pytest.raises(UsageError):
        PollRates.parse(text)


def test_one_request_outstanding_at_a_time() -> None:
    base = FakeBase()
    core = CoreSession(port="fake")
    sent: list[float] = []

    def watch(data: bytes, now: float) -> bytes:
        if data:
            sent.append(now)
        return data

    bus = VirtualBus(core, base, to_base=watch, base_latency_s=0.004)
    bus.run_for(3.0)
    # Each request goes out only after the previous answer is in: at least the answer's latency apart.
    assert len(sent) > 100
    assert min(later - earlier for earlier, later in itertools.pairwise(sent)) >= 0.004


# --- every variant a master must accept (§6.1) -----------------------------------------------


@pytest.mark.parametrize(
    ("connect_suffix", "timestamp", "bumper_size", "poll_form", "long_answers"),
    [
        (None, False, 4, "empty", True),
        ("-rc1", True, 1, "ff", False),
        ("", False, 2, "ff", True),
        (None, True, 3, "empty", False),
    ],
)
def test_answer_variants_are_accepted(
    connect_suffix: str | None, timestamp: bool, bumper_size: int, poll_form: str, long_answers: bool
) -> None:
    base = FakeBase(
        connect_suffix=connect_suffix,
        deadreckon_timestamp=timestamp,
        bumper_size=bumper_size,
        bumper_bitmap=0xFFFF_FFFE,  # bumper 0 pressed (active low)
        poll_nothing_form=poll_form,
        long_answers=long_answers,
    )
    core, base, bus = start(base)
    core.set_velocity(0.2, 0.0)
    bus.run_for(2.0)
    core.set_velocity(0.0, 0.0)
    bus.run_for(0.5)
    stats = core.link_stats()
    assert stats["malformed_answers"] == stats["retries"] == stats["timeouts"] == 0
    assert core.connected
    assert core.bumpers_pressed == (True, False)
    assert core.bumper_bitmap == 0xFFFF_FFFE & ((1 << 8 * bumper_size) - 1)
    assert core.pose.x_mm == pytest.approx(base.pose.x_mm, abs=0.01)
    assert core.pose.x_mm > 350.0


@pytest.mark.parametrize("code", [0x0040, 0x00C0, 0x0020])
def test_transport_error_answers_are_retried_after_the_grace_period(code: int) -> None:
    core, base, bus = start()
    t0 = bus.now
    base.error_once["GET_BASE_STATUS"] = code
    bus.run_for(1.2)
    statuses = [when for when, request in base.requests if request.NAME == "GET_BASE_STATUS" and when >= t0]
    grace = core.config.transport_error_grace_s
    # sent again once the grace period for a late real answer has passed, well before the timeout
    assert len(statuses) == 2
    assert grace <= statuses[1] - statuses[0] < grace + 0.02
    stats = core.link_stats()
    assert stats["retries"] == 1
    assert stats["errors_by_code"] == {f"0x{code:04X}": 1}  # 0x21's 0x8000 (no blob) is no error
    assert core.battery_percent == 80 and core.connected


def test_invalid_answer_is_a_failed_attempt() -> None:
    core, base, bus = start()
    base.prefix_once["GET_BASE_STATUS"] = answer_frame(InvalidAnswer(), long=True)
    base.silent = False
    t0 = bus.now
    # The INVALID comes first, then the real answer arrives while the Core is sending again: it
    # is counted as stray, and the repeated request gets its own answer.
    bus.run_for(1.2)
    stats = core.link_stats()
    assert stats["invalid_answers"] == 1 and stats["retries"] == 1
    assert names_after(base, t0).count("GET_BASE_STATUS") == 2
    assert core.connected


def test_not_synced_report_does_not_end_the_wait() -> None:
    core, base, bus = start()
    base.prefix_once["GET_BASE_STATUS"] = answer_frame(ErrorAnswer(0x0010), long=True)
    bus.run_for(1.2)
    stats = core.link_stats()
    assert stats["not_synced_reports"] == 1
    assert stats["errors_by_code"] == {"0x0010": 1}
    assert stats["retries"] == 0  # the answer that followed was taken
    assert core.battery_percent == 80


def test_other_error_codes_are_answers_not_retried() -> None:
    core, _, bus = start(FakeBase(errors={"GET_BASE_SENSOR_DATA": 0x8000}))
    bus.run_for(2.0)
    stats = core.link_stats()
    assert stats["retries"] == 0 and core.connected
    assert stats["errors_by_code"]["0x8000"] >= 20
    # Logged once, not at 10 Hz.
    assert [event.text for event in core.events()].count("ERROR 0x8000 to GET_BASE_SENSOR_DATA") == 1


def test_malformed_answer_is_retried_and_a_persistent_one_disconnects() -> None:
    core, base, bus = start()
    base.raw_ok["GET_BASE_STATUS"] = b"\x50"  # 1 byte: the 2015 form, a format error (§5.4)
    assert bus.run_until(lambda: core.link_stats()["disconnects"] >= 1, 2.0)
    stats = core.link_stats()
    # A base that answers every attempt is there: the status is asked again and again (each
    # connection asks it at once), until line_fault_attempts faulty answers make the Core give up.
    attempts = CoreConfig().line_fault_attempts
    assert stats["malformed_answers"] == attempts * stats["disconnects"]
    assert stats["lost_requests"] == 0
    assert any("malformed answer to GET_BASE_STATUS" in event.text for event in core.events())


def test_lost_answer_times_out_and_is_sent_again() -> None:
    dropped: list[float] = []

    def drop_first_status_answer(data: bytes, now: float) -> bytes:
        # The status answer is the only 7-byte long OK frame the fake base sends.
        if len(data) == 7 and data[:4] == b"\x50\x03\x00\x02" and not dropped:
            dropped.append(now)
            return b""
        return data

    base = FakeBase()
    core = CoreSession(port="fake")
    bus = VirtualBus(core, base, to_core=drop_first_status_answer)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S)
    bus.run_for(1.5)
    assert dropped
    stats = core.link_stats()
    assert stats["timeouts"] == 1 and stats["retries"] == 1 and stats["disconnects"] == 0
    statuses = [when for when, request in base.requests if request.NAME == "GET_BASE_STATUS"]
    # The timeout, then a flushing SYNC (512 bytes out, copied back) before the resend (§11.6).
    assert any(size == 512 and statuses[0] < when < statuses[1] for when, size in base.syncs)
    assert statuses[1] - statuses[0] == pytest.approx(0.2 + 5 * 86.8e-6 + 2 * 512 * 86.8e-6, abs=0.006)


def test_requests_in_long_frames_in_the_sdk2020_profile() -> None:
    flags: set[int] = set()

    def watch(data: bytes, now: float) -> bytes:
        if data:
            flags.add(data[0])
        return data

    base = FakeBase()
    core = CoreSession(CoreConfig(long_frames=True), port="fake")
    bus = VirtualBus(core, base, to_base=watch)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S)
    bus.run_for(0.5)
    assert flags == {0x50}


# --- disconnect and reconnect (§11.7) ----------------------------------------------------------


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


# --- external commands (§11.5) and actions -----------------------------------------------------


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


# --- controls ----------------------------------------------------------------------------------


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


# --- telemetry and statistics --------------------------------------------------------------------


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


def test_latency_is_measured_from_send_to_complete_answer() -> None:
    rates = only_set_v(20.0)
    byte_time = 86.8e-6
    core, _, bus = start(config=CoreConfig(rates=rates), byte_time_s=byte_time, base_latency_s=0.002)
    bus.run_for(30.0)  # enough answers that the window holds SET_V answers only
    p50 = core.link_stats()["latency_p50_ms"]
    p99 = core.link_stats()["latency_p99_ms"]
    # SET_V request: 17 bytes (standard frame); its answer: 18 bytes (long frame, 13-byte payload).
    expected_ms = ((17 + 18) * byte_time + 0.002) * 1000.0
    assert p50 == pytest.approx(expected_ms, abs=0.002)
    assert p99 == pytest.approx(expected_ms, abs=0.002)
    assert core.link_stats()["requests_per_s"] == pytest.approx(20.0, abs=0.5)


def test_latency_is_unknown_before_any_answer() -> None:
    core = CoreSession(port="fake")
    stats = core.link_stats()
    assert (stats["latency_p50_ms"], stats["latency_p99_ms"]) == (None, None)


def test_watchdog_gaps_are_counted() -> None:
    rates = only_set_v(0.5)
    core, _, bus = start(config=CoreConfig(rates=rates))
    bus.run_for(6.5)
    assert core.link_stats()["watchdog_trips"] == 3


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


def test_event_log_and_trail_are_bounded() -> None:
    core = CoreSession(port="fake")
    bus = VirtualBus(core, FakeBase(silent=True))
    bus.run_for(40.0)  # an absent base: connect attempts, quietly
    events = core.events()
    assert len(events) <= 200
    assert any("no answer yet" in event.text for event in events)


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


# --- docking and the acceptance run against the simulated base ------------------------------


def simulated(world: World, blob: bytes | None = None) -> tuple[CoreSession, BaseStack, VirtualBus]:
    stack = BaseStack(SimulatedBase(world, binary_config=blob), BaseConfig())
    core = CoreSession(port="vtime")
    bus = VirtualBus(core, stack)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S)
    return core, stack, bus


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


# --- the real-time runner ------------------------------------------------------------------------


def wait_for(condition: Callable[[], bool], limit_s: float = 5.0) -> bool:
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        if condition():
            return True
        time.sleep(0.01)
    return False


def test_runner_drives_a_base_in_real_time_and_stops_cleanly() -> None:
    core_end, base_end = link_pair()
    sim = SimulatedBase(World())
    base_runner = BaseRunner(BaseStack(sim, BaseConfig()), base_end)
    session = CoreSession(port="pair")
    runner = CoreRunner(session, core_end)
    try:
        base_runner.start()
        runner.start()
        assert wait_for(lambda: session.connected), session.events()
        with runner.lock:
            session.set_velocity(0.2, 0.0)
        assert wait_for(lambda: session.pose.x_mm > 20.0)
    finally:
        runner.stop()
        base_runner.stop()
    assert not runner.running and runner.failure is None
    assert session.stopped
    assert 0x65 in sim.events  # CORE_DISCONNECT reached the base


def test_runner_reports_a_failed_link_as_a_state_and_reopens() -> None:
    core_end, base_end = link_pair()
    opened: list[int] = []
    fake = FakeBase()
    lock = threading.Lock()

    def reopen() -> PipeLink:
        new_core, new_base = link_pair()
        opened.append(1)
        threading.Thread(target=answer_forever, args=(new_base,), daemon=True).start()
        return new_core

    def answer_forever(link: PipeLink) -> None:
        while True:
            try:
                data = link.read(0.05)
                if data:
                    with lock:
                        answer = fake.receive(data, time.monotonic())
                    link.write(answer)
            except LinkError:
                return

    session = CoreSession(port="pair")
    runner = CoreRunner(session, core_end, reopen=reopen, reopen_interval_s=0.05)
    try:
        runner.start()
        base_end.close()  # the other end goes away: reads fail
        assert wait_for(lambda: bool(opened) and session.connected)
        assert any("link failed" in event.text for event in session.events())
    finally:
        runner.stop()
    assert runner.failure is None and runner.link_errors >= 1


def test_request_frames_decode_as_the_requests_of_the_schedule() -> None:
    """What poll() returns is whole, valid request frames (checked without any base)."""
    core = CoreSession(port="none")
    frame = core.poll(0.0)
    assert frame is not None
    decoded = StreamDecoder().feed(frame)
    assert len(decoded) == 1
    assert decode_request(decoded[0].cmd, decoded[0].payload).NAME == "CONNECT_BASE"
    assert core.poll(0.1) is None  # one outstanding
    assert core.next_poll_time() == pytest.approx(0.2 + len(frame) * 86.8e-6, abs=1e-6)
    flush = core.poll(0.3)
    assert flush == encode(0x00, bytes(507), long=True) and len(flush) == 512


def test_the_core_is_a_dashboard_source_under_its_runner_lock_and_never_imports_the_web_layer() -> None:
    assert isinstance(CoreSource(CoreSession(), threading.RLock()), DashboardSource)
    code = (
        "import sys, ctrlbus.core, ctrlbus.vtime; "
        "print(sorted(name for name in sys.modules if name.startswith('ctrlbus.web')))"
    )
    result = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, timeout=60, check=True
    )
    assert result.stdout.strip() == "[]"


def test_garbage_before_an_intact_request_neither_retries_nor_desynchronises() -> None:
    """A false long header in front of a request: the base answers ERROR 0x0020 for it, then the
    request itself. The Core must take that answer, not resend and take it for the next one."""
    planted: list[float] = []

    def plant_false_header(data: bytes, now: float) -> bytes:
        # Once, in front of a GET_BASE_STATUS request (10 02 F8 30 DA): 50 FF FF claims 64 KiB.
        if not planted and data.startswith(bytes.fromhex("1002F830")):
            planted.append(now)
            return bytes.fromhex("50FFFF") + data
        return data

    base = BaseStack(SimulatedBase(World()), BaseConfig())
    core = CoreSession(port="sim")
    bus = VirtualBus(core, base, to_base=plant_false_header)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S), core.events()
    core.set_velocity(0.1, 0.0)
    bus.run_for(5.0)
    stats = core.link_stats()
    assert planted, "no GET_BASE_STATUS went out to plant the garbage in front of"
    assert stats["errors_by_code"].get("0x0020") == 1
    assert stats["retries"] == 0 and stats["malformed_answers"] == 0 and stats["timeouts"] == 0
    assert core.connected and stats["disconnects"] == 0


def test_answer_behind_a_false_frame_start_is_recovered_by_the_inter_byte_timeout() -> None:
    """A false `50 00 01` (claims 256 bytes) in front of an answer holds it in the Core's decoder
    until the line has been idle for the inter-byte timeout. The Core must apply that timeout while
    it waits, not only when more bytes arrive, or the request times out and is sent again."""
    planted: list[float] = []

    def plant_false_header(data: bytes, now: float) -> bytes:
        if not planted and data.startswith(bytes.fromhex("50030002")):  # a status answer
            planted.append(now)
            return bytes.fromhex("500001") + data
        return data

    base = BaseStack(SimulatedBase(World()), BaseConfig())
    core = CoreSession(port="sim")
    bus = VirtualBus(core, base, to_core=plant_false_header)
    assert bus.run_until(lambda: core.connected, CONNECT_LIMIT_S), core.events()
    bus.run_for(3.0)
    stats = core.link_stats()
    assert planted, "no status answer went out to plant the false header in front of"
    assert stats["timeouts"] == 0 and stats["retries"] == 0, stats
    assert core.battery_percent is not None and core.connected


def test_with_no_retries_one_silent_attempt_disconnects_and_nothing_is_lost() -> None:
    core, base, bus = start(config=CoreConfig(retries=0))
    base.silent = True
    assert bus.run_until(lambda: core.state == "disconnected", 2.0)
    stats = core.link_stats()
    assert stats["timeouts"] == 1 and stats["disconnects"] == 1
    assert stats["abandoned_at_disconnect"] == 1 and stats["lost_requests"] == 0


def test_a_combined_line_fault_code_is_never_taken_for_the_answer() -> None:
    """0x0030, 0x0090, 0x00D0, ...: the reference's receiver bits ORed (§11.6 [line-faults])."""
    core, base, bus = start()
    bus.run_for(0.5)
    answered = core.link_stats()["requests_answered"]
    base.errors["GET_BASE_SENSOR_DATA"] = 0x00D0
    bus.run_for(0.5)
    stats = core.link_stats()
    assert stats["errors_by_code"]["0x00D0"] >= 2
    assert stats["line_faults_by_bit"] == {
        "0x10": stats["errors_by_code"]["0x00D0"],
        "0x20": 0,
        "0x40": stats["errors_by_code"]["0x00D0"],
        "0x80": stats["errors_by_code"]["0x00D0"],
    }
    assert stats["lost_requests"] == 0 and stats["requests_answered"] > answered
    del base.errors["GET_BASE_SENSOR_DATA"]
    bus.run_for(0.5)
    assert core.distances_mm is not None
