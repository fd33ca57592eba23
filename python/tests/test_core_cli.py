# SPDX-License-Identifier: MIT
"""`ctrlbus core`: bad ports and options end with one line and exit code 2; against a real pty
(`ctrlbus sim --pty`, or a fake base served in this process) it reports a connected base as
JSON lines or status lines, serves the dashboard when asked, and stops cleanly.

Every child process is started in its own session, waited for with a bound, and always killed."""

from __future__ import annotations

import io
import json
import os
import re
import select
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager, suppress
from typing import Any

import pytest
from core_fakes import FakeBase

from ctrlbus import binconf
from ctrlbus.cli import main
from ctrlbus.cli.core_cmd import StatusOutput
from ctrlbus.cli.core_status import SCREEN_HOME_CLEAR, json_status, render_screen, status_line
from ctrlbus.core import CoreSession
from ctrlbus.link import PtyLink
from ctrlbus.vtime import VirtualBus

LIMIT_S = 30.0  # generous bound for anything a child process does on a busy 2-core machine


def ctrlbus_command(*args: str) -> list[str]:
    return [sys.executable, "-m", "ctrlbus", *args]


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ctrlbus_command(*args), capture_output=True, text=True, timeout=LIMIT_S, start_new_session=True
    )


def assert_one_line_error(result: subprocess.CompletedProcess[str], fragment: str) -> None:
    assert result.returncode == 2, result
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert lines[0].startswith("ctrlbus core: error: ") and fragment in lines[0], lines[0]
    assert "Traceback" not in result.stderr


@pytest.mark.parametrize(
    ("port", "fragment"),
    [
        ("socket://127.0.0.1:1", "Connection refused"),
        ("nosuch://x", "nosuch"),
        ("/dev/ctrlbus-no-such-port", "/dev/ctrlbus-no-such-port"),
    ],
)
def test_a_port_that_cannot_be_opened_is_one_line_and_exit_2(port: str, fragment: str) -> None:
    assert_one_line_error(run_cli("core", "--port", port), fragment)


def test_a_base_that_never_answers_is_one_line_and_exit_2() -> None:
    # loop:// gives the Core its own requests back: never an answer to CONNECT_BASE.
    result = run_cli("core", "--port", "loop://", "--connect-timeout", "1", "--interval", "0.2")
    assert_one_line_error(result, "no answer to CONNECT_BASE from loop:// within 1 s")


@pytest.mark.parametrize(
    ("options", "fragment"),
    [
        (["--rates", "bogus=1"], "bad rate"),
        (["--rates", "set_v=-5"], "set_v_hz"),
        (["--timeout-ms", "0"], "--timeout-ms"),
        (["--retries", "1.5"], "--retries"),
        (["--connect-timeout", "soon"], "--connect-timeout"),
        (["--interval", "-1"], "--interval"),
        (["--dashboard", "--http", "0.0.0.0:0"], "--token"),
        (["--baud", "0"], "baud"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(
    options: list[str], fragment: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["core", "--port", "loop://", *options]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ctrlbus core: error: ") and fragment in err, err


# --- against a base on a pty ---------------------------------------------------------------------


class Child:
    """A child process in its own session, its stdout read line by line with a deadline."""

    def __init__(self, args: list[str]) -> None:
        self.process = subprocess.Popen(
            args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            start_new_session=True,
        )
        self._buffer = b""

    def read_line(self, limit_s: float = LIMIT_S) -> str | None:
        """The next stdout line, or None at the end of the output; fails after limit_s."""
        assert self.process.stdout is not None
        fd = self.process.stdout.fileno()
        deadline = time.monotonic() + limit_s
        while b"\n" not in self._buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"no line from {self.process.args!r} within {limit_s} s")
            ready, _, _ = select.select([fd], [], [], remaining)
            if ready:
                chunk = os.read(fd, 65536)
                if not chunk:
                    if self._buffer:
                        break
                    return None
                self._buffer += chunk
        line, _, self._buffer = self._buffer.partition(b"\n")
        return line.decode()

    def lines(self, limit_s: float = LIMIT_S) -> Iterator[str]:
        deadline = time.monotonic() + limit_s
        while True:
            line = self.read_line(max(0.1, deadline - time.monotonic()))
            if line is None:
                return
            yield line

    def stop(self) -> None:
        """Kill the whole session if it is still running and reap it."""
        if self.process.poll() is None:
            with suppress(ProcessLookupError):
                os.killpg(self.process.pid, signal.SIGKILL)
        self.process.wait(LIMIT_S)
        for stream in (self.process.stdout, self.process.stderr):
            if stream is not None:
                stream.close()


@contextmanager
def child(args: list[str]) -> Iterator[Child]:
    process = Child(args)
    try:
        yield process
    finally:
        process.stop()


@contextmanager
def simulated_base() -> Iterator[str]:
    """`ctrlbus sim --pty` as a child; yields its pty path."""
    with child(ctrlbus_command("sim", "--pty")) as sim:
        line = sim.read_line()
        assert line is not None and line.startswith("pty: "), line
        yield line.removeprefix("pty: ").strip()


def test_json_lines_against_the_simulated_base_show_a_connected_state() -> None:
    with (
        simulated_base() as pty,
        child(
            ctrlbus_command("core", "--port", pty, "--json", "--interval", "0.25", "--duration", "4")
        ) as core,
    ):
        statuses = [json.loads(line) for line in core.lines()]
        assert core.process.wait(LIMIT_S) == 0
    connected = [status for status in statuses if status["state"] == "connected"]
    assert connected, statuses[-1]
    last = connected[-1]
    assert last["base"]["model"] == "ctrlbus sim" and last["port"] == pty
    assert last["connects"] == 1 and last["link"]["requests"] > 50
    assert last["link"]["timeouts"] == 0
    assert len(last["distances_mm"]) == 6 and last["battery"]["percent"] is not None
    texts = [event["text"] for status in statuses for event in status["events"]]
    assert "SEND_EVENT SYSTEM_UP_OK" in texts
    assert texts.count("SEND_EVENT SYSTEM_UP_OK") == 1  # each event is reported once
    assert statuses[-1]["state"] == "disconnected" and statuses[-1]["reason"] == "stopped"


def test_sigterm_stops_it_with_exit_0() -> None:
    with (
        simulated_base() as pty,
        child(ctrlbus_command("core", "--port", pty, "--json", "--interval", "0.2")) as core,
    ):
        for line in core.lines():
            if json.loads(line)["state"] == "connected":
                break
        else:
            pytest.fail("never connected")
        core.process.send_signal(signal.SIGTERM)
        assert core.process.wait(LIMIT_S) == 0
        assert core.process.stderr is not None
        assert b"Traceback" not in core.process.stderr.read()


def test_dashboard_serves_the_core_snapshot() -> None:
    pytest.importorskip("aiohttp")
    args = ["--json", "--interval", "0.25", "--duration", "8", "--dashboard", "--http", "127.0.0.1:0"]
    with simulated_base() as pty, child(ctrlbus_command("core", "--port", pty, *args)) as core:
        assert core.process.stderr is not None
        url = read_dashboard_url(core.process.stderr.fileno())
        snapshot: dict[str, Any] = {}
        deadline = time.monotonic() + LIMIT_S
        while time.monotonic() < deadline:
            with urllib.request.urlopen(url.rstrip("/") + "/api/snapshot", timeout=5) as response:
                snapshot = json.loads(response.read())["data"]
            if snapshot["link"]["connection"]["state"] == "connected":
                break
            time.sleep(0.1)
        assert snapshot["link"]["connection"]["state"] == "connected"
        assert snapshot["base"]["model"] == "ctrlbus sim"
        assert next(core.lines(), None) is not None  # the JSON lines go on beside the dashboard


def read_dashboard_url(fd: int) -> str:
    buffer = b""
    deadline = time.monotonic() + LIMIT_S
    while time.monotonic() < deadline:
        ready, _, _ = select.select([fd], [], [], 0.1)
        if ready:
            chunk = os.read(fd, 4096)
            if not chunk:
                break
            buffer += chunk
            match = re.search(rb"dashboard at (http://\S+)", buffer)
            if match:
                return match.group(1).decode()
    raise AssertionError(f"no dashboard URL on stderr: {buffer!r}")


def test_plain_lines_in_process_against_a_fake_base_and_a_clean_stop(
    capsys: pytest.CaptureFixture[str],
) -> None:
    link = PtyLink()
    base = FakeBase()
    done = threading.Event()

    def serve_fake() -> None:
        while not done.is_set():
            data = link.read(0.02)
            answer = base.receive(data, time.monotonic()) if data else base.tick(time.monotonic())
            if answer:
                link.write(answer)

    thread = threading.Thread(target=serve_fake)
    thread.start()
    try:
        code = main(["core", "--port", link.path, "--interval", "0.3", "--duration", "1.5"])
    finally:
        done.set()
        thread.join(LIMIT_S)
        link.close()
    assert code == 0
    out = capsys.readouterr().out
    assert re.search(r"^ +\d+\.\d+ s connected ", out, re.MULTILINE), out
    assert "base CONNECT_BASE answered: 'fake base'" in out
    assert "\x1b[" not in out  # not a terminal: no screen codes
    assert base.names()[-1] == "SEND_EVENT:0x65"  # CORE_DISCONNECT on the way out


# --- the status views --------------------------------------------------------------------------

JSON_KEYS = {
    "t_s", "state", "port", "since_s", "connects", "reason", "base", "pose", "command", "battery",
    "motion_status", "bumper_bitmap", "bumpers_pressed", "cliffs_triggered", "distances_mm",
    "ignored_sensors", "warnings", "charger_probes", "health", "link", "events",
}  # fmt: skip


def test_status_views_show_the_session() -> None:
    core = CoreSession(port="fake")
    base = FakeBase(blob=binconf.example_blob(), health=[(0x01020100, "battery low")], probes=(1, 2, 4))
    bus = VirtualBus(core, base)
    assert bus.run_until(lambda: core.connected, 5.0)
    bus.run_for(1.2)
    core.go_home()
    bus.run_for(0.5)
    screen = render_screen(core)
    assert "ctrlbus core  fake  connected" in screen
    assert "health    flags 0x01  0x01020100 battery low" in screen
    assert "charger   probes 0x01 0x02 0x04" in screen
    assert "go home: " in screen and "(GET_BASE_CONF_ADV)" in screen
    assert " connected " in status_line(core)
    status = json_status(core)
    assert set(status) == JSON_KEYS
    json.dumps(status, allow_nan=False)
    assert status["charger_probes"] == [1, 2, 4] and status["command"]["mode"] == "go_home"
    assert status["events"] and json_status(core, status["events"][-1]["seq"])["events"] == []


class _Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


class _ClosedPipe(io.StringIO):
    def write(self, text: str) -> int:
        raise BrokenPipeError


def test_output_redraws_on_a_terminal_and_stops_on_a_closed_pipe() -> None:
    core = CoreSession(port="fake")
    terminal = _Terminal()
    output = StatusOutput(terminal, json_lines=False)
    output.note = "dashboard http://127.0.0.1:8080/"
    assert output.show(core)
    assert terminal.getvalue().startswith(SCREEN_HOME_CLEAR)
    assert terminal.getvalue().splitlines()[1] == "dashboard http://127.0.0.1:8080/"
    closed = StatusOutput(_ClosedPipe(), json_lines=True)
    assert not closed.show(core)
    assert not closed.show(core)
