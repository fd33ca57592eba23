# SPDX-License-Identifier: MIT
"""The real-time runner over in-process links (ctrlbus.core.runner)."""

from __future__ import annotations

import subprocess
import sys
import threading
import time
from collections.abc import Callable

from support.core_fakes import FakeBase

from ctrlbus.base import BaseConfig, BaseRunner, BaseStack
from ctrlbus.core import CoreRunner, CoreSession
from ctrlbus.errors import LinkError
from ctrlbus.link import PipeLink, link_pair
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.web.source import CoreSource, DashboardSource


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
