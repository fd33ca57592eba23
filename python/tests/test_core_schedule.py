# SPDX-License-Identifier: MIT
"""What a connected Core asks for, and when (§11.4): ctrlbus.core.schedule and the rates of
ctrlbus.core.config."""

from __future__ import annotations

import itertools
from collections import Counter

import pytest
from support.core_fakes import FakeBase
from support.core_session import names_after, start

from ctrlbus.core import CoreConfig, CoreSession, PollRates
from ctrlbus.errors import UsageError
from ctrlbus.frame import StreamDecoder, encode
from ctrlbus.messages import (
    decode_request,
)
from ctrlbus.vtime import VirtualBus


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
