# SPDX-License-Identifier: MIT
"""Link statistics of a Core session: answer latency, watchdog gaps (ctrlbus.core.stats)."""

from __future__ import annotations

import pytest
from support.core_session import only_set_v, start

from ctrlbus.core import CoreConfig, CoreSession


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
