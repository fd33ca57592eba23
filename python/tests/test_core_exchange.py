# SPDX-License-Identifier: MIT
"""The request in flight (ctrlbus.core.exchange): every answer variant a master must accept (§6.1),
retries, lost and malformed answers, line faults."""

from __future__ import annotations

import pytest
from support.core_fakes import FakeBase
from support.core_session import CONNECT_LIMIT_S, names_after, start

from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.core import CoreConfig, CoreSession
from ctrlbus.messages import (
    ErrorAnswer,
    InvalidAnswer,
    answer_frame,
)
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.vtime import VirtualBus


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
