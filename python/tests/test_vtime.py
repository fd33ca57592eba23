# SPDX-License-Identifier: MIT
"""The virtual-time harness (ctrlbus.vtime): line timing, base latency and ticks, filters in
both directions, determinism, and its argument checks."""

from __future__ import annotations

from typing import Any

import pytest
from support.core_fakes import FakeBase

from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.core import CoreConfig, CoreSession, PollRates
from ctrlbus.errors import UsageError
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.vtime import DEFAULT_BYTE_TIME_S, SerialLine, VirtualBus
from ctrlbus.web.snapshot import dashboard_snapshot


def test_serial_line_delivers_each_write_when_its_last_byte_has_arrived() -> None:
    line = SerialLine(0.001)
    line.send(b"0123456789", 0.0)
    line.send(b"abcde", 0.005)  # queues behind the first write
    assert line.next_arrival() == pytest.approx(0.010)
    assert line.take(0.0099) == b""
    assert line.take(0.010) == b"0123456789"
    assert line.next_arrival() == pytest.approx(0.015)
    assert line.take(1.0) == b"abcde"
    assert line.idle and line.bytes_sent == 15
    line.send(b"xy", 2.0)  # an idle line starts at once
    assert line.next_arrival() == pytest.approx(2.002)


def test_serial_line_in_pieces() -> None:
    line = SerialLine(0.001, chunk_bytes=2)
    line.send(b"abcde", 0.0)
    assert line.take(0.0025) == b"ab"
    assert line.take(0.0045) == b"cd"
    assert line.take(0.0050) == b"e"


def test_instant_line_latency_is_the_base_latency() -> None:
    rates = PollRates(
        set_v_hz=20, bumper_hz=0, sensor_hz=0, status_hz=0, motor_hz=0, poll_cmd_hz=0, health_hz=0
    )
    core = CoreSession(CoreConfig(rates=rates, byte_time_s=0.0))
    bus = VirtualBus(core, FakeBase(), byte_time_s=0.0, base_latency_s=0.003)
    bus.run_for(30.0)
    stats = core.link_stats()
    assert stats["latency_p50_ms"] == pytest.approx(3.0, abs=1e-6)
    assert stats["latency_p99_ms"] == pytest.approx(3.0, abs=1e-6)


def test_base_ticks_at_its_period_and_time_ends_where_asked() -> None:
    base = FakeBase()
    bus = VirtualBus(CoreSession(), base, tick_period_s=0.01)
    bus.run_for(1.0)
    assert bus.elapsed_s == pytest.approx(1.0)
    assert base.ticks == bus.base_ticks == 100
    bus.run_for(0.0)
    assert base.ticks == 100


def test_run_until_reports_whether_the_condition_held() -> None:
    core = CoreSession()
    bus = VirtualBus(core, FakeBase(silent=True))
    assert not bus.run_until(lambda: core.connected, 1.0)
    assert bus.elapsed_s == pytest.approx(1.0)
    bus.base.silent = False  # type: ignore[attr-defined]
    assert bus.run_until(lambda: core.connected, 1.0)
    assert bus.elapsed_s < 1.6


def run_simulated(seconds: float) -> tuple[CoreSession, World, VirtualBus]:
    world = World()
    core = CoreSession(port="vtime")
    bus = VirtualBus(core, BaseStack(SimulatedBase(world), BaseConfig()))
    bus.run_until(lambda: core.connected, 5.0)
    core.set_velocity(0.25, 0.3)
    bus.run_for(seconds)
    return core, world, bus


def test_runs_are_deterministic() -> None:
    first_core, first_world, first_bus = run_simulated(5.0)
    second_core, second_world, second_bus = run_simulated(5.0)
    assert first_core.pose == second_core.pose
    assert first_world.true_pose == second_world.true_pose
    assert dashboard_snapshot(first_core) == dashboard_snapshot(second_core)
    assert first_bus.to_base_line.bytes_sent == second_bus.to_base_line.bytes_sent
    assert first_bus.to_core_line.bytes_sent == second_bus.to_core_line.bytes_sent


def test_line_rate_is_modelled() -> None:
    core, _, bus = run_simulated(5.0)
    sent = bus.to_base_line.bytes_sent + bus.to_core_line.bytes_sent
    # §11.4: about 0.5 kB/s from the Core and 1.2 kB/s from the base at the default rates.
    assert 400 < bus.to_base_line.bytes_sent / bus.elapsed_s < 700
    assert 900 < bus.to_core_line.bytes_sent / bus.elapsed_s < 1500
    assert sent * DEFAULT_BYTE_TIME_S < bus.elapsed_s  # the line is far from full
    assert core.link_stats()["latency_p50_ms"] > 1.0 + 30 * DEFAULT_BYTE_TIME_S * 1000.0


def test_a_filter_can_corrupt_requests_and_the_core_recovers() -> None:
    corrupted: list[float] = []
    empty_calls: list[float] = []

    def corrupt_first_status_request(data: bytes, now: float) -> bytes:
        if not data:
            empty_calls.append(now)
        elif data == bytes.fromhex("10 02 F8 30 DA") and not corrupted:
            corrupted.append(now)
            return bytes.fromhex("10 02 F8 30 DB")  # wrong checksum
        return data

    world = World()
    stack = BaseStack(SimulatedBase(world), BaseConfig())
    core = CoreSession()
    bus = VirtualBus(core, stack, to_base=corrupt_first_status_request)
    bus.run_for(2.0)
    assert corrupted and core.connected
    stats = core.link_stats()
    assert stats["errors_by_code"].get("0x0040") == 1  # the base answered the checksum error
    assert stats["retries"] == 1 and stats["timeouts"] == 0
    assert core.battery_percent is not None
    assert len(empty_calls) == bus.base_ticks  # the filter also sees every tick


def test_a_filter_can_silence_the_base() -> None:
    cut = {"from": 1e9}
    heard_events: list[int] = []

    def cut_answers(data: bytes, now: float) -> bytes:
        return b"" if now >= cut["from"] else data

    class Recorder(SimulatedBase):
        def on_event(self, event: int) -> None:
            heard_events.append(event)

    core = CoreSession()
    bus = VirtualBus(core, BaseStack(Recorder(World()), BaseConfig()), to_core=cut_answers)
    assert bus.run_until(lambda: core.connected, 2.0)
    cut["from"] = bus.now
    assert bus.run_until(lambda: core.state == "disconnected", 2.0)
    bus.run_for(0.5)
    assert heard_events == [0x63, 0x65]  # SYSTEM_UP_OK, then CORE_DISCONNECT after the silence
    cut["from"] = 1e9
    assert bus.run_until(lambda: core.connected, 2.0)
    assert heard_events == [0x63, 0x65, 0x63]


def test_pieces_arrive_separately() -> None:
    calls: list[int] = []

    class CountingBase(FakeBase):
        def receive(self, data: bytes, now: float) -> bytes:
            calls.append(len(data))
            return super().receive(data, now)

    core = CoreSession()
    bus = VirtualBus(core, CountingBase(), chunk_bytes=1)
    assert bus.run_until(lambda: core.connected, 2.0)
    assert set(calls) == {1}


@pytest.mark.parametrize(
    "options",
    [
        {"byte_time_s": -1.0},
        {"base_latency_s": float("nan")},
        {"tick_period_s": 0.0},
        {"chunk_bytes": -1},
    ],
)
def test_bad_settings_are_refused(options: dict[str, Any]) -> None:
    with pytest.raises(UsageError):
        VirtualBus(CoreSession(), FakeBase(), **options)


def test_bad_durations_are_refused() -> None:
    bus = VirtualBus(CoreSession(), FakeBase())
    with pytest.raises(UsageError):
        bus.run_for(-1.0)
    with pytest.raises(UsageError):
        bus.run_for(float("inf"))
