# SPDX-License-Identifier: MIT
"""The checker's sense of time (issue 24): it runs in simulated time against an in-process base
(vtime.VirtualLink gives it the clock and the sleep), so its verdicts do not depend on how busy
the host is; and its own decoder's inter-byte timeout is an option, for bases in an emulator
whose answers pause whenever the host is busy."""

from __future__ import annotations

import time

import pytest
from support.broken_bases import simulated_base

from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.checker import CHECKS, CheckOptions, Status, check_base
from ctrlbus.cli import main
from ctrlbus.vtime import VirtualLink

NUMBER_OF = {check.name: check.number for check in CHECKS}


class PausesMidAnswer:
    """A base whose every answer stops after its first 3 bytes for `pause_s`, as an emulated UART
    does when the host does not run the emulator for a while."""

    def __init__(self, pause_s: float) -> None:
        self.stack = BaseStack(simulated_base(), BaseConfig())
        self.pause_s = pause_s
        self.held: list[tuple[float, bytes]] = []

    def receive(self, data: bytes, now: float) -> bytes:
        answer = self.stack.receive(data, now)
        if len(answer) > 3:
            self.held.append((now + self.pause_s, answer[3:]))
            answer = answer[:3]
        return answer

    def tick(self, now: float) -> bytes:
        due = b"".join(rest for when, rest in self.held if when <= now)
        self.held = [(when, rest) for when, rest in self.held if when > now]
        return self.stack.tick(now) + due


def run(base: PausesMidAnswer | BaseStack, options: CheckOptions) -> dict[str, Status]:
    link = VirtualLink(base)
    report = check_base(link, options, clock=link.clock, sleep=link.sleep)
    return {result.check.name: result.status for result in report.results}


def test_an_answer_paused_longer_than_the_interbyte_timeout_is_cut() -> None:
    only = frozenset({NUMBER_OF["link"], NUMBER_OF["connect"]})
    # The link check fails (every answer cut in two); the later checks cannot run and say so.
    assert run(PausesMidAnswer(0.3), CheckOptions(only=only)) == {"link": Status.FAIL, "connect": Status.SKIP}


def test_a_longer_interbyte_timeout_reads_the_paused_answer_whole() -> None:
    only = frozenset({NUMBER_OF["link"], NUMBER_OF["connect"]})
    options = CheckOptions(only=only, timeout_s=1.0, interbyte_timeout_s=0.5)
    assert run(PausesMidAnswer(0.3), options) == {"link": Status.PASS, "connect": Status.PASS}


def test_the_watchdog_check_takes_simulated_seconds_not_host_seconds() -> None:
    began = time.monotonic()
    link = VirtualLink(BaseStack(simulated_base(), BaseConfig()))
    report = check_base(
        link, CheckOptions(only=frozenset({NUMBER_OF["watchdog"]})), clock=link.clock, sleep=link.sleep
    )
    (result,) = report.results
    assert result.status is Status.PASS, result.message
    assert link.clock() > 1.0  # the watchdog (1 s) was waited for on the simulated clock
    assert time.monotonic() - began < 60  # (a bound against hanging, not a speed goal)


def test_virtual_link_sleep_runs_the_base_and_keeps_what_it_sent() -> None:
    link = VirtualLink(BaseStack(simulated_base(), BaseConfig()))
    link.write(bytes.fromhex("10 01 00 11"))  # SYNC, answered verbatim
    link.sleep(0.5)
    assert link.clock() == pytest.approx(0.5)
    assert link.read(0.0) == bytes.fromhex("10 01 00 11")
    assert link.read(0.2) == b"" and link.clock() == pytest.approx(0.7)


def test_the_interbyte_timeout_option_is_checked(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["check", "--port", "loop://", "--interbyte-timeout-ms", "0"]) == 2
    assert "--interbyte-timeout-ms wants a number > 0" in capsys.readouterr().err


@pytest.mark.parametrize("latency_s", [0.0, 0.05, 0.12, 0.15, 0.2])
def test_the_watchdog_check_waits_for_the_copy_of_its_last_sync_from_a_slow_base(latency_s: float) -> None:
    """A base answering 50-200 ms late (QEMU's AVR on a loaded host): the copy of the last SYNC
    sent to keep the line busy must not be taken for the answer to the measuring request."""
    link = VirtualLink(BaseStack(simulated_base(), BaseConfig()), base_latency_s=latency_s)
    options = CheckOptions(only=frozenset({NUMBER_OF["watchdog"]}), timeout_s=1.0)
    (result,) = check_base(link, options, clock=link.clock, sleep=link.sleep).results
    assert result.status is Status.PASS, result.message
