# SPDX-License-Identifier: MIT
"""Acceptance: the whole demo (simulated base on a pty, Core emulator, dashboard) in a real browser.

Headless Chromium is Debian's /usr/bin/chromium (scripts/setup.sh installs it), driven by
Playwright; nothing is downloaded. Screenshots are saved in python/test-artifacts/; the one of
the robot driving forward also in docs/img/dashboard.png (docs/dashboard.md shows it), so that the
picture in the docs is retaken on every run and never goes stale.
"""

from __future__ import annotations

import contextlib
import fcntl
import json
import math
import os
import pty
import queue
import re
import select
import signal
import socket
import subprocess
import sys
import tempfile
import termios
import threading
import time
import urllib.request
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from ctrlbus.web.schema import check_snapshot

PYTHON_DIR = Path(__file__).resolve().parents[1]
REPO_ROOT = PYTHON_DIR.parent
ARTIFACTS = PYTHON_DIR / "test-artifacts"
DOCS_SCREENSHOT = REPO_ROOT / "docs" / "img" / "dashboard.png"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]
URL_LINE = re.compile(r"dashboard at (http://\S+)")
COMMANDED_FORWARD = "Number(document.querySelector('#cmd-vx').dataset.value) > 0"
COMMANDED_STOP = "Number(document.querySelector('#cmd-vx').dataset.value) === 0"
START_LIMIT_S = 60.0
STOP_LIMIT_S = 20.0


@dataclass
class Demo:
    process: subprocess.Popen[str]
    url: str
    output: list[str]
    lines: queue.Queue[str | None]  # the rest of its output, as it comes

    def rest_of_output(self) -> str:
        """Everything it printed after the URL line, once it has exited."""
        rest = []
        while (line := self.lines.get(timeout=10)) is not None:
            rest.append(line)
        return "".join(rest)

    def snapshot(self) -> dict[str, Any]:
        api = self.url.split("?")[0].rstrip("/") + "/api/snapshot"
        with urllib.request.urlopen(api, timeout=10) as response:
            data: dict[str, Any] = json.load(response)["data"]
        return data


def free_port() -> int:
    with socket.socket() as probe:
        probe.bind(("127.0.0.1", 0))
        port: int = probe.getsockname()[1]
        return port


def start_demo(*args: str) -> Demo:
    """Start `python -m ctrlbus.demo` in a session of its own and wait for its URL line."""
    process = subprocess.Popen(
        [sys.executable, "-m", "ctrlbus.demo", "--http", f"127.0.0.1:{free_port()}", *args],
        cwd=PYTHON_DIR,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,  # its session id is its pid: how leftovers are found afterwards
    )
    lines: queue.Queue[str | None] = queue.Queue()
    output: list[str] = []

    def pump() -> None:
        assert process.stdout is not None
        for line in process.stdout:
            lines.put(line)
        lines.put(None)

    threading.Thread(target=pump, name="demo-output", daemon=True).start()
    deadline = time.monotonic() + START_LIMIT_S
    while time.monotonic() < deadline:
        try:
            line = lines.get(timeout=0.5)
        except queue.Empty:
            continue
        if line is None:
            break
        output.append(line)
        match = URL_LINE.search(line)
        if match:
            return Demo(process, match.group(1), output, lines)
    stop_demo_forcibly(process)
    raise AssertionError("the demo did not print its dashboard URL:\n" + "".join(output))


def session_members(session_id: int) -> list[int]:
    """Pids of every process whose session is `session_id` (from /proc)."""
    members = []
    for entry in os.listdir("/proc"):
        if not entry.isdigit():
            continue
        try:
            stat = Path(f"/proc/{entry}/stat").read_text()
        except OSError:
            continue
        fields = stat.rpartition(")")[2].split()
        if int(fields[3]) == session_id:  # fields after the name: state ppid pgrp session ...
            members.append(int(entry))
    return members


def stop_demo_forcibly(process: subprocess.Popen[str]) -> None:
    for pid in session_members(process.pid):
        with contextlib.suppress(ProcessLookupError):
            os.kill(pid, signal.SIGKILL)
    with contextlib.suppress(subprocess.TimeoutExpired):
        process.wait(10)


def interrupt_and_check_clean_exit(demo: Demo) -> None:
    """Ctrl-C: the demo must exit 0 on its own, leaving no process of its session behind."""
    demo.process.send_signal(signal.SIGINT)
    try:
        demo.process.wait(STOP_LIMIT_S)
    except subprocess.TimeoutExpired:
        stop_demo_forcibly(demo.process)
        raise AssertionError(f"the demo did not stop within {STOP_LIMIT_S:g} s of SIGINT") from None
    rest = demo.rest_of_output()
    leftovers = session_members(demo.process.pid)
    if leftovers:
        stop_demo_forcibly(demo.process)
    assert leftovers == [], f"processes left behind: {leftovers}"
    assert demo.process.returncode == 0, "".join(demo.output) + rest
    assert "stopped" in rest


@pytest.fixture
def demo() -> Iterator[Demo]:
    running = start_demo("--base", "sim")
    try:
        yield running
    finally:
        if running.process.poll() is None:
            interrupt_and_check_clean_exit(running)


@pytest.fixture
def page(demo: Demo) -> Iterator[Any]:
    if not os.access(CHROMIUM, os.X_OK):
        pytest.fail(f"{CHROMIUM} is missing: scripts/setup.sh installs the Debian package chromium")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory(prefix="ctrlbus-chromium-") as profile, sync_playwright() as playwright:
        context = playwright.chromium.launch_persistent_context(
            profile,
            executable_path=CHROMIUM,
            headless=True,
            args=CHROMIUM_ARGS,
            viewport={"width": 1500, "height": 1000},
            bypass_csp=True,  # the page forbids eval; Playwright's wait_for_function needs it
        )
        try:
            browser_page = context.new_page()
            errors: list[str] = []
            browser_page.on("pageerror", lambda exc: errors.append(str(exc)))
            browser_page.goto(demo.url)
            # Telemetry: the Core is connected and its numbers reach the page.
            browser_page.wait_for_selector('#link-state[data-value="connected"]', timeout=30_000)
            browser_page.wait_for_function(
                "Number(document.querySelector('#link-requests').dataset.value) > 0", timeout=30_000
            )
            yield browser_page
            assert errors == [], errors
        finally:
            context.close()


def value(page: Any, element_id: str) -> float:
    text = page.get_attribute(f"#{element_id}", "data-value")
    assert text not in (None, ""), f"#{element_id} has no value"
    return float(text)


def pose(page: Any) -> tuple[float, float, float]:
    return value(page, "pose-x"), value(page, "pose-y"), value(page, "pose-theta")


def screenshot(page: Any, name: str) -> None:
    ARTIFACTS.mkdir(exist_ok=True)
    page.screenshot(path=str(ARTIFACTS / name), full_page=True)


def test_arrow_up_drives_forward_and_the_link_panel_counts(demo: Demo, page: Any) -> None:
    x0, y0, theta0 = pose(page)
    requests0 = value(page, "link-requests")
    page.keyboard.down("ArrowUp")
    try:
        page.wait_for_function(COMMANDED_FORWARD, timeout=10_000)
        # Drive until the dead-reckoned pose is well ahead of where it started.
        page.wait_for_function(
            """([x0, y0, t0]) => {
                const v = (id) => Number(document.getElementById(id).dataset.value);
                const t = t0 * Math.PI / 180;
                return (v('pose-x') - x0) * Math.cos(t) + (v('pose-y') - y0) * Math.sin(t) > 300;
            }""",
            arg=[x0, y0, theta0],
            timeout=30_000,
        )
        screenshot(page, "dashboard-driving-forward.png")
        page.screenshot(path=str(DOCS_SCREENSHOT))
    finally:
        page.keyboard.up("ArrowUp")
    x1, y1, theta1 = pose(page)
    heading = math.radians(theta0)
    forward = (x1 - x0) * math.cos(heading) + (y1 - y0) * math.sin(heading)
    sideways = -(x1 - x0) * math.sin(heading) + (y1 - y0) * math.cos(heading)
    assert forward > 300 and abs(sideways) < forward / 4, (forward, sideways)
    assert abs((theta1 - theta0 + 180) % 360 - 180) < 15
    # The link panel counts the requests that did it.
    assert value(page, "link-requests") > requests0
    assert value(page, "link-rps") > 0
    # Releasing the key stops the robot.
    page.wait_for_function(COMMANDED_STOP, timeout=10_000)
    # What the page shows is what the demo serves, in the documented schema, ground truth included.
    served = demo.snapshot()
    assert check_snapshot(served) == []
    assert "sim" in served and served["pose"]["x_mm"] > 300


def test_emergency_stop_keeps_the_commanded_velocity_at_zero(demo: Demo, page: Any) -> None:
    page.keyboard.down("ArrowUp")
    try:
        page.wait_for_function(COMMANDED_FORWARD, timeout=10_000)
        page.click("#estop")
        page.wait_for_selector("#estop-banner", state="visible", timeout=10_000)
        page.wait_for_function(COMMANDED_STOP, timeout=10_000)
        assert page.get_attribute("#cmd-mode", "data-value") == "estop"
        # The key is still held, so the page keeps sending forward velocity: the latch holds.
        # Pressing the key again does not undo it either.
        page.keyboard.up("ArrowUp")
        page.keyboard.down("ArrowUp")
        settled = pose(page)
        samples = []
        for _ in range(20):
            page.wait_for_timeout(100)
            samples.append((value(page, "cmd-vx"), value(page, "cmd-omega")))
        assert set(samples) == {(0.0, 0.0)}, samples
        snapshot = demo.snapshot()
        assert snapshot["command"]["estop"] is True
        assert (snapshot["command"]["vx_mps"], snapshot["command"]["omega_radps"]) == (0.0, 0.0)
        # And the robot really stopped (after braking): the pose no longer changes.
        page.wait_for_timeout(500)
        before = pose(page)
        page.wait_for_timeout(1000)
        after = pose(page)
        assert math.dist(before[:2], after[:2]) < 2.0, (settled, before, after)
        screenshot(page, "dashboard-emergency-stop.png")
    finally:
        page.keyboard.up("ArrowUp")


def test_an_external_command_button_goes_through_poll_and_ans(demo: Demo, page: Any) -> None:
    """The simulated base offers MOVE_FORWARD; the Core polls, takes it and drives."""
    x0, y0, _ = pose(page)
    page.click('[data-testid="ext-MOVE_FORWARD"]')
    page.wait_for_selector('#events li:has-text("base offers MOVE_FORWARD")', timeout=15_000)
    page.wait_for_function(
        """([x0, y0]) => {
            const v = (id) => Number(document.getElementById(id).dataset.value);
            return Math.hypot(v('pose-x') - x0, v('pose-y') - y0) > 50;
        }""",
        arg=[x0, y0],
        timeout=30_000,
    )
    screenshot(page, "dashboard-external-command.png")
    texts = [event["text"] for event in demo.snapshot()["events"]]
    offered = next(i for i, text in enumerate(texts) if "base offers MOVE_FORWARD" in text)
    after = texts[offered + 1 :]
    assert "POLL_BASE_ANS_CMD" in after, texts
    assert any("external command MOVE_FORWARD" in text for text in after), texts


def demo_bases() -> list[str]:
    """Every base the demo offers: make py-test builds the C base and the firmware first."""
    return ["sim", "c", "qemu"]


@pytest.mark.parametrize("base", demo_bases())
def test_the_demo_stops_cleanly_on_sigint(base: str) -> None:
    running = start_demo("--base", base)
    try:
        deadline = time.monotonic() + 30
        while running.snapshot()["link"]["connection"]["state"] != "connected":
            assert time.monotonic() < deadline, "the Core never connected"
            time.sleep(0.2)
    except BaseException:
        stop_demo_forcibly(running.process)
        raise
    interrupt_and_check_clean_exit(running)


def read_terminal(master: int, until: re.Pattern[str] | None, limit_s: float) -> str:
    """What a terminal shows, until `until` matches it, the program closes it, or limit_s."""
    shown = b""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline:
        if until is not None and until.search(shown.decode(errors="replace")):
            break
        ready, _, _ = select.select([master], [], [], 0.2)
        if not ready:
            continue
        try:
            chunk = os.read(master, 4096)
        except OSError:  # EIO: every process holding the terminal has gone
            break
        if not chunk:
            break
        shown += chunk
    return shown.decode(errors="replace")


def test_make_demo_in_a_terminal_stops_on_ctrl_c() -> None:
    """`make demo` as a user runs it: in a terminal, stopped by typing Ctrl-C, which the terminal
    sends as SIGINT to the whole foreground process group (make and the demo together)."""
    master, slave = pty.openpty()
    process = subprocess.Popen(
        ["make", "--no-print-directory", "demo", f"DEMO_ARGS=--http 127.0.0.1:{free_port()}"],
        cwd=REPO_ROOT,
        stdin=slave,
        stdout=slave,
        stderr=slave,
        start_new_session=True,
        preexec_fn=lambda: fcntl.ioctl(0, termios.TIOCSCTTY, 0),  # the pty is its terminal
    )
    os.close(slave)
    try:
        shown = read_terminal(master, URL_LINE, START_LIMIT_S * 2)  # make may build first
        match = URL_LINE.search(shown)
        assert match, f"make demo printed no dashboard URL:\n{shown}"
        api = match.group(1).split("?")[0].rstrip("/") + "/api/snapshot"
        deadline = time.monotonic() + 30
        while True:
            with urllib.request.urlopen(api, timeout=10) as response:
                if json.load(response)["data"]["link"]["connection"]["state"] == "connected":
                    break
            assert time.monotonic() < deadline, "the Core never connected"
            time.sleep(0.2)
        os.write(master, b"\x03")  # Ctrl-C
        try:
            process.wait(STOP_LIMIT_S)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"make demo did not stop within {STOP_LIMIT_S:g} s of Ctrl-C") from None
        shown += read_terminal(master, None, 5)
        assert "stopped" in shown, shown
        leftovers = session_members(process.pid)
        assert leftovers == [], f"processes left behind: {leftovers}\n{shown}"
    finally:
        for pid in session_members(process.pid):
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        with contextlib.suppress(subprocess.TimeoutExpired):
            process.wait(10)
        os.close(master)
