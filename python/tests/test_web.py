# SPDX-License-Identifier: MIT
"""The dashboard server against a recording fake source: pushes, controls, validation, access.

The fake implements `ctrlbus.web.source.DashboardSource` and produces snapshots that follow the
schema of docs/dashboard.md (checked with `ctrlbus.web.schema.check_snapshot`, so the fake cannot
drift from the schema the real Core must follow). The browser and the real Core + simulator are
tested in test_dashboard_browser.py.

Run as a script (`python tests/test_web.py netns-check`), this file serves the check that runs
inside a private network namespace, where binding 0.0.0.0 exposes nothing but loopback.
"""

from __future__ import annotations

import asyncio
import contextlib
import copy
import itertools
import json
import math
import os
import random
import shutil
import signal
import socket
import statistics
import subprocess
import sys
import threading
import time
import urllib.request
from collections.abc import Awaitable, Callable, Iterator
from pathlib import Path
from typing import Any

import aiohttp
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctrlbus.demo import SimulatorAttached
from ctrlbus.errors import CtrlbusError, LinkError, UsageError
from ctrlbus.sim.server import SimSettings, build_simulated_stack
from ctrlbus.web.control import (
    EXTERNAL_COMMANDS,
    MAX_MESSAGE_CHARS,
    ControlMessageError,
    EmergencyStop,
    ExternalCommand,
    GoHome,
    ReleaseStop,
    Velocity,
    clamp_velocity,
    parse_control_message,
)
from ctrlbus.web.options import DashboardOptions, is_loopback, parse_http_address
from ctrlbus.web.schema import SCHEMA_VERSION, check_snapshot
from ctrlbus.web.server import DashboardServer
from ctrlbus.web.source import DashboardSource, accepts_external_commands

TOKEN = "s3cret-token-for-tests"
MAX_VX = 0.5
MAX_OMEGA = 2.0
PYTHON_DIR = Path(__file__).resolve().parents[1]


# -- the fake source ----------------------------------------------------------------------------


class FakeSource:
    """Records every call; integrates the commanded velocity into a pose on each snapshot."""

    def __init__(self, *, with_sim: bool = False) -> None:
        self.calls: list[tuple[Any, ...]] = []
        self.with_sim = with_sim
        self.vx = 0.0
        self.omega = 0.0
        self.estop = False
        self.mode = "idle"
        self.pose = [0.0, 0.0, 0.0]
        self.trail: list[list[float]] = [[0.0, 0.0]]
        self.fail_next = False
        self.snapshots = 0
        self._lock = threading.Lock()
        self._last = time.monotonic()
        # With a simulator, the ground truth is a real simulated base driven by the same velocity.
        self.simulated = build_simulated_stack(SimSettings(seed=1))[0] if with_sim else None

    def _record(self, *call: Any) -> None:
        if self.fail_next:
            self.fail_next = False
            raise CtrlbusError("the fake refuses this once")
        self.calls.append(call)

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        with self._lock:
            self._record("set_velocity", vx_mps, omega_radps)
            if not self.estop:
                self.vx, self.omega = vx_mps, omega_radps
                self.mode = "teleop" if (vx_mps or omega_radps) else "idle"

    def emergency_stop(self) -> None:
        with self._lock:
            self._record("emergency_stop")
            self.estop, self.vx, self.omega, self.mode = True, 0.0, 0.0, "estop"

    def release_stop(self) -> None:
        with self._lock:
            self._record("release_stop")
            self.estop, self.mode = False, "idle"

    def go_home(self) -> None:
        with self._lock:
            self._record("go_home")
            self.mode = "go_home"

    def limits(self) -> tuple[float, float]:
        return MAX_VX, MAX_OMEGA

    def snapshot(self) -> dict[str, Any]:
        with self._lock:
            now = time.monotonic()
            dt, self._last = now - self._last, now
            x, y, theta = self.pose
            x += self.vx * 1000 * dt * math.cos(math.radians(theta))
            y += self.vx * 1000 * dt * math.sin(math.radians(theta))
            theta = (theta + math.degrees(self.omega * dt) + 180) % 360 - 180
            self.pose = [x, y, theta]
            self.trail = [*self.trail[-999:], [x, y]]
            if self.simulated is not None:
                with self.simulated.stack.lock:
                    self.simulated.world.set_velocity(self.vx, self.omega)
                    self.simulated.world.step(min(dt, 1.0))
            self.snapshots += 1
            return fake_snapshot(self, with_sim=self.with_sim)


class FakeSimSource(FakeSource):
    """A fake whose base is 'our simulator': it has ground truth and takes external commands."""

    def __init__(self) -> None:
        super().__init__(with_sim=True)

    def queue_external_command(self, code: int) -> None:
        with self._lock:
            self._record("queue_external_command", code)


def fake_snapshot(source: FakeSource, *, with_sim: bool) -> dict[str, Any]:
    x, y, theta = source.pose
    mount = {"x_mm": 170.0, "y_mm": 0.0, "z_mm": 50.0, "angle_deg": 0.0}
    snapshot: dict[str, Any] = {
        "schema": SCHEMA_VERSION,
        "time_s": 12.5,
        "base": {
            "model": "fake base",
            "firmware_version": "1.20",
            "hardware_version": 256,
            "serial": "000102030405060708090a0b",
            "shape": "circle",
            "radius_mm": 170.0,
            "config_source": "GET_BASE_CONF",
        },
        "limits": {"vx_mps": MAX_VX, "omega_radps": MAX_OMEGA},
        "pose": {"x_mm": x, "y_mm": y, "theta_deg": theta},
        "trail": [list(p) for p in source.trail],
        "command": {
            "vx_mps": source.vx,
            "omega_radps": source.omega,
            "estop": source.estop,
            "mode": source.mode,
            "activity": None,
        },
        "motion": {"status": 0, "stall": False, "traction_lost": False},
        "battery": {
            "percent": 80,
            "power_status": 0,
            "charging": False,
            "dc_connected": False,
            "on_dock": False,
        },
        "sensors": [{**mount, "distance_mm": 1234.5}, {**mount, "angle_deg": 180.0, "distance_mm": None}],
        "bumper_bitmap": 0xFFFFFFFE,
        "bumpers": [{**mount, "bit": 0, "pressed": True}, {**mount, "bit": 1, "pressed": False}],
        "cliffs": [{"bit": 2, "triggered": False}],
        "charger": {"beacon_count": 3, "probe_count": 3, "probes": [0, 2, 0]},
        "health": {
            "flags": 1,
            "warning": True,
            "error": False,
            "fatal": False,
            "errors": [{"code": 0x01020100, "message": "low battery"}],
        },
        "events": [
            {"seq": 0, "t_s": 0.1, "direction": "core", "text": "CONNECT_BASE v1"},
            {"seq": 1, "t_s": 0.2, "direction": "base", "text": "offers MOVE_FORWARD"},
        ],
        "link": {
            "connection": {"state": "connected", "port": "/dev/pts/9", "since_s": 0.2, "connects": 1},
            "requests": 100 + source.snapshots,
            "requests_per_s": 52.0,
            "latency_p50_ms": 1.5,
            "latency_p99_ms": 4.0,
            "errors_by_code": {"0x8000": 1},
            "checksum_failures": 0,
            "resyncs": 0,
            "timeouts": 0,
            "watchdog_trips": 0,
            "retries": 0,
        },
    }
    if with_sim:
        assert source.simulated is not None
        origin = source.simulated.world.room.start_pose
        snapshot["sim"] = {
            **source.simulated.snapshot(),
            "odometry_origin": {"x_mm": origin.x_mm, "y_mm": origin.y_mm, "theta_deg": origin.theta_deg},
        }
    return snapshot


# -- helpers ------------------------------------------------------------------------------------


def serve(source: DashboardSource, **options: Any) -> DashboardServer:
    server = DashboardServer(source, DashboardOptions(host="127.0.0.1", port=0, **options))
    server.start()
    return server


@pytest.fixture
def fake() -> FakeSimSource:
    return FakeSimSource()


@pytest.fixture
def server(fake: FakeSimSource) -> Iterator[DashboardServer]:
    srv = serve(fake, push_hz=20.0)
    yield srv
    srv.stop()


def run(coroutine_function: Callable[[], Awaitable[None]]) -> None:
    asyncio.run(asyncio.wait_for(coroutine_function(), 60))


def base_url(server: DashboardServer) -> str:
    return f"http://127.0.0.1:{server.port}"


async def next_of_type(
    ws: aiohttp.ClientWebSocketResponse[bool], kind: str, limit: int = 500
) -> dict[str, Any]:
    """The next message of `kind`, skipping snapshots and others in between."""
    for _ in range(limit):
        message = await ws.receive(timeout=10)
        assert message.type == aiohttp.WSMsgType.TEXT, message
        data: dict[str, Any] = json.loads(message.data)
        if data["type"] == kind:
            return data
    raise AssertionError(f"no {kind} message among {limit}")


async def next_reply(ws: aiohttp.ClientWebSocketResponse[bool]) -> dict[str, Any]:
    """The next ack or error: the reply to the last control message sent."""
    for _ in range(500):
        message = await ws.receive(timeout=10)
        assert message.type == aiohttp.WSMsgType.TEXT, message
        data: dict[str, Any] = json.loads(message.data)
        if data["type"] in ("ack", "error"):
            return data
    raise AssertionError("no reply")


async def wait_until(condition: Callable[[], bool], limit_s: float = 10.0) -> None:
    deadline = time.monotonic() + limit_s
    while not condition():
        assert time.monotonic() < deadline, "condition not reached"
        await asyncio.sleep(0.01)


# -- the schema ---------------------------------------------------------------------------------


def test_fake_snapshots_follow_the_schema() -> None:
    assert check_snapshot(FakeSource().snapshot()) == []
    assert check_snapshot(FakeSimSource().snapshot()) == []


def test_schema_checker_names_each_departure() -> None:
    good = FakeSimSource().snapshot()
    cases: list[tuple[Callable[[dict[str, Any]], None], str]] = [
        (lambda s: s.pop("pose"), "snapshot.pose: missing"),
        (lambda s: s["pose"].update(x_mm="1"), "snapshot.pose.x_mm: expected num"),
        (lambda s: s["pose"].update(x_mm=math.nan), "snapshot.pose.x_mm: expected num"),
        (lambda s: s["command"].update(estop=1), "snapshot.command.estop: expected bool"),
        (lambda s: s["command"].update(mode="flying"), "snapshot.command.mode: 'flying' is not one of"),
        (lambda s: s["link"].update(requests=True), "snapshot.link.requests: expected int"),
        (
            lambda s: s["link"]["errors_by_code"].update({"0x0040": 1.5}),
            "errors_by_code.0x0040: expected int",
        ),
        (lambda s: s.update(extra=1), "snapshot.extra: not in the schema"),
        (lambda s: s["trail"].append([1.0]), "expected [x_mm, y_mm], got [1.0]"),
        (lambda s: s["events"][0].update(direction="up"), "snapshot.events[0].direction"),
        (lambda s: s["sim"]["room"].pop("walls"), "snapshot.sim.room.walls: missing"),
        (lambda s: s["sim"].pop("odometry_origin"), "snapshot.sim.odometry_origin: missing"),
        (lambda s: s.update(schema=SCHEMA_VERSION + 1), "snapshot.schema: expected"),
        (lambda s: s.update(trail=[[0.0, 0.0]] * 2001), "snapshot.trail: more than"),
    ]
    for mutate, expected in cases:
        bad = copy.deepcopy(good)
        mutate(bad)
        problems = check_snapshot(bad)
        assert any(expected in p for p in problems), (expected, problems)
    without_sim = copy.deepcopy(good)
    del without_sim["sim"]  # "sim" is optional
    assert check_snapshot(without_sim) == []
    assert check_snapshot([]) == ["snapshot: expected an object, got list"]


def test_the_demo_puts_the_simulator_beside_the_core_view() -> None:
    core = FakeSource()
    simulated, stack = build_simulated_stack(SimSettings(seed=1))
    source = SimulatorAttached(core, simulated)
    snapshot = source.snapshot()
    assert check_snapshot(snapshot) == []
    start = simulated.world.room.start_pose
    assert snapshot["sim"]["odometry_origin"] == {
        "x_mm": start.x_mm,
        "y_mm": start.y_mm,
        "theta_deg": start.theta_deg,
    }
    assert snapshot["sim"]["pose"] == snapshot["sim"]["odometry_origin"]  # nothing moved yet
    # Controls go to the Core; external commands to the simulated base's POLL_BASE_CMD queue.
    assert accepts_external_commands(source) and not accepts_external_commands(core)
    source.queue_external_command(EXTERNAL_COMMANDS["START_SWEEP"])
    assert stack.pending_commands == (EXTERNAL_COMMANDS["START_SWEEP"],)
    assert source.snapshot()["sim"]["pending_commands"] == [EXTERNAL_COMMANDS["START_SWEEP"]]
    source.set_velocity(0.1, 0.2)
    source.emergency_stop()
    source.release_stop()
    source.go_home()
    assert source.limits() == (MAX_VX, MAX_OMEGA)
    assert core.calls == [("set_velocity", 0.1, 0.2), ("emergency_stop",), ("release_stop",), ("go_home",)]


# -- control messages (pure) --------------------------------------------------------------------


def test_each_control_message_type_parses() -> None:
    assert parse_control_message('{"type":"velocity","vx_mps":0.25,"omega_radps":-1}') == Velocity(0.25, -1.0)
    assert parse_control_message('{"type":"estop","id":7}') == EmergencyStop(7)
    assert parse_control_message('{"type":"release","id":"r1"}') == ReleaseStop("r1")
    assert parse_control_message('{"type":"go_home"}') == GoHome()
    code = EXTERNAL_COMMANDS["START_SWEEP"]
    parsed = parse_control_message(json.dumps({"type": "external_command", "code": code}))
    assert parsed == ExternalCommand(code) and isinstance(parsed, ExternalCommand)
    assert parsed.name == "START_SWEEP"


@pytest.mark.parametrize(
    ("text", "reason"),
    [
        ("", "not valid JSON"),
        ("{", "not valid JSON"),
        ("[1, 2]", "expected a JSON object"),
        ('"velocity"', "expected a JSON object"),
        ("{}", '"type"'),
        ('{"type": 3}', '"type"'),
        ('{"type": "fly"}', "unknown message type"),
        ('{"type": "velocity", "vx_mps": 1}', "missing key(s) omega_radps"),
        ('{"type": "velocity", "vx_mps": 1, "omega_radps": 0, "vy_mps": 0}', "unknown key(s) vy_mps"),
        ('{"type": "velocity", "vx_mps": "1", "omega_radps": 0}', "vx_mps must be a number"),
        ('{"type": "velocity", "vx_mps": true, "omega_radps": 0}', "vx_mps must be a number"),
        ('{"type": "velocity", "vx_mps": null, "omega_radps": 0}', "vx_mps must be a number"),
        ('{"type": "velocity", "vx_mps": NaN, "omega_radps": 0}', "NaN is not a number"),
        ('{"type": "velocity", "vx_mps": Infinity, "omega_radps": 0}', "Infinity is not a number"),
        ('{"type": "velocity", "vx_mps": 1e999, "omega_radps": 0}', "must be finite"),
        ('{"type": "velocity", "vx_mps": ' + "9" * 400 + ', "omega_radps": 0}', "must be finite"),
        ('{"type": "estop", "type": "release"}', "duplicate key"),
        ('{"type": "estop", "now": true}', "unknown key(s) now"),
        ('{"type": "external_command"}', "missing key(s) code"),
        ('{"type": "external_command", "code": 1}', "unknown command code 1"),
        ('{"type": "external_command", "code": 160.0}', "code must be an integer"),
        ('{"type": "external_command", "code": true}', "code must be an integer"),
        ('{"type": "estop", "id": [1]}', "id must be"),
        ('{"type": "estop", "id": -1}', "id out of range"),
        ('{"type": "estop", "id": "' + "x" * 65 + '"}', "id longer than"),
        ('{"type": "estop", "pad": "' + "x" * MAX_MESSAGE_CHARS + '"}', "message too long"),
        ("[" * 600 + "]" * 600, "message too long"),
    ],
)
def test_malformed_control_messages_are_rejected_with_a_reason(text: str, reason: str) -> None:
    with pytest.raises(ControlMessageError) as info:
        parse_control_message(text)
    assert reason in str(info.value)
    assert isinstance(info.value, UsageError)


json_values = st.recursive(
    st.none() | st.booleans() | st.integers() | st.floats() | st.text(max_size=20),
    lambda children: (
        st.lists(children, max_size=4) | st.dictionaries(st.text(max_size=12), children, max_size=4)
    ),
    max_leaves=12,
)


@settings(max_examples=300, deadline=None)
@given(
    kind=st.sampled_from(["velocity", "estop", "release", "go_home", "external_command", "other"]),
    fields=st.dictionaries(
        st.sampled_from(["vx_mps", "omega_radps", "code", "id", "extra"]), json_values, max_size=4
    ),
)
def test_parsing_near_valid_messages_either_succeeds_or_says_why(kind: str, fields: dict[str, Any]) -> None:
    text = json.dumps({"type": kind, **fields})
    try:
        message = parse_control_message(text)
    except ControlMessageError:
        return
    if isinstance(message, Velocity):
        assert math.isfinite(message.vx_mps) and math.isfinite(message.omega_radps)


@settings(max_examples=300, deadline=None)
@given(text=st.text(max_size=200) | json_values.map(json.dumps))
def test_parsing_arbitrary_text_never_raises_anything_else(text: str) -> None:
    with contextlib.suppress(ControlMessageError):
        parse_control_message(text)


def test_clamping_keeps_sign_and_limits() -> None:
    assert clamp_velocity(2.0, -9.0, (0.5, 2.0)) == (0.5, -2.0)
    assert clamp_velocity(-2.0, 9.0, (0.5, 2.0)) == (-0.5, 2.0)
    assert clamp_velocity(0.1, 0.2, (0.5, 2.0)) == (0.1, 0.2)
    assert clamp_velocity(0.1, 0.2, (math.nan, -1.0)) == (0.0, 0.0)  # unknown limits: no motion


# -- options --------------------------------------------------------------------------------------


def test_addresses_and_the_token_rule() -> None:
    assert parse_http_address("127.0.0.1:9000") == ("127.0.0.1", 9000)
    assert parse_http_address("0.0.0.0") == ("0.0.0.0", 8080)
    assert parse_http_address("[::1]:81") == ("::1", 81)
    assert parse_http_address("::") == ("::", 8080)
    for bad in ("", ":80", "host:port", "1.2.3.4:70000", "[::1"):
        with pytest.raises(UsageError):
            parse_http_address(bad)
    assert is_loopback("127.0.0.1") and is_loopback("::1") and is_loopback("localhost")
    assert not is_loopback("0.0.0.0") and not is_loopback("192.168.1.2") and not is_loopback("robot.local")
    with pytest.raises(UsageError, match="give --token"):
        DashboardOptions(host="0.0.0.0")
    with pytest.raises(UsageError, match="--token"):
        DashboardOptions(host="192.168.1.2")
    assert DashboardOptions(host="0.0.0.0", token=TOKEN).url == f"http://127.0.0.1:8080/?token={TOKEN}"
    for bad_token in ("", "has space", "a&b", "é"):
        with pytest.raises(UsageError):
            DashboardOptions(token=bad_token)
    with pytest.raises(UsageError):
        DashboardOptions(push_hz=0.5)


def test_demo_refuses_a_public_address_without_a_token() -> None:
    result = subprocess.run(
        [sys.executable, "-m", "ctrlbus.demo", "--listen", "0.0.0.0"],
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "CTRLBUS_DASHBOARD_TOKEN": ""},
    )
    assert result.returncode == 2
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and "--token" in lines[0], result.stderr


# -- the server -----------------------------------------------------------------------------------


def test_hello_then_snapshots_that_follow_the_schema_at_the_configured_rate(server: DashboardServer) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(base_url(server) + "/ws") as ws:
            hello = await next_of_type(ws, "hello")
            assert hello["push_hz"] == 20.0
            assert [c["name"] for c in hello["external_commands"]][:2] == ["MOVE_FORWARD", "MOVE_BACKWARD"]
            snapshots = [await next_of_type(ws, "snapshot") for _ in range(21)]
        seqs = [s["seq"] for s in snapshots]
        assert seqs == sorted(seqs) and len(set(seqs)) == len(seqs)
        for s in snapshots:
            assert check_snapshot(s["data"]) == []
        # The server stamps each push with its own clock; the typical gap is the configured period.
        gaps = [b["t_s"] - a["t_s"] for a, b in itertools.pairwise(snapshots)]
        assert 0.5 / 20 <= statistics.median(gaps) <= 1.5 / 20

    run(scenario)


def test_page_and_snapshot_endpoint_are_served(server: DashboardServer) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session:
            async with session.get(base_url(server) + "/") as page:
                assert page.status == 200
                text = await page.text()
                assert 'id="map"' in text and "/static/app.js" in text
                assert "default-src 'self'" in page.headers["Content-Security-Policy"]
            for asset in ("app.js", "style.css"):
                async with session.get(base_url(server) + "/static/" + asset) as response:
                    assert response.status == 200
            async with session.get(base_url(server) + "/static/../server.py") as response:
                assert response.status in (403, 404)
            async with session.get(base_url(server) + "/api/snapshot") as response:
                assert response.status == 200
                assert check_snapshot((await response.json())["data"]) == []

    run(scenario)


def test_control_messages_reach_the_source_and_are_acknowledged(
    server: DashboardServer, fake: FakeSimSource
) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(base_url(server) + "/ws") as ws:
            await ws.send_str('{"type":"velocity","vx_mps":0.2,"omega_radps":0.5,"id":1}')
            assert await next_reply(ws) == {
                "type": "ack",
                "for": "velocity",
                "vx_mps": 0.2,
                "omega_radps": 0.5,
                "clamped": False,
                "id": 1,
            }
            for kind in ("estop", "release", "go_home"):
                await ws.send_str(json.dumps({"type": kind, "id": kind}))
                reply = await next_reply(ws)
                assert reply["type"] == "ack" and reply["for"] == kind and reply["id"] == kind
            await ws.send_str(json.dumps({"type": "external_command", "code": 0xA0}))
            reply = await next_reply(ws)
            assert reply["name"] == "MOVE_FORWARD"

    run(scenario)
    assert fake.calls == [
        ("set_velocity", 0.2, 0.5),
        ("emergency_stop",),
        ("release_stop",),
        ("go_home",),
        ("queue_external_command", 0xA0),
    ]
    assert server.counters.accepted == 5 and server.counters.rejected == 0


def test_velocities_are_clamped_to_the_base_limits(server: DashboardServer, fake: FakeSimSource) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(base_url(server) + "/ws") as ws:
            await ws.send_str('{"type":"velocity","vx_mps":25,"omega_radps":-1e300}')
            reply = await next_reply(ws)
            assert (reply["vx_mps"], reply["omega_radps"], reply["clamped"]) == (MAX_VX, -MAX_OMEGA, True)
            await ws.send_str('{"type":"velocity","vx_mps":0,"omega_radps":0}')
            await next_reply(ws)

    run(scenario)
    assert fake.calls == [("set_velocity", MAX_VX, -MAX_OMEGA), ("set_velocity", 0.0, 0.0)]


def random_message(rng: random.Random) -> str:
    """Mostly near-valid messages with one thing wrong, some valid ones, some plain garbage."""
    choice = rng.random()
    if choice < 0.15:
        return "".join(chr(rng.randrange(1, 0x3000)) for _ in range(rng.randrange(0, 60)))
    if choice < 0.2:
        return "{" * rng.randrange(1, 300)
    kind = rng.choice(["velocity", "estop", "release", "go_home", "external_command", "bogus", 7, None])
    message: dict[str, Any] = {"type": kind}
    values: list[Any] = [
        0,
        -0.3,
        0.3,
        1e308,
        -1e308,
        2**70,
        True,
        None,
        "0.1",
        [],
        {},
        0xA0,
        0x80,
        3,
        255,
        256,
        1.5e-300,
    ]
    for key in rng.sample(["vx_mps", "omega_radps", "code", "id", "junk"], rng.randrange(0, 4)):
        message[key] = rng.choice(values)
    text = json.dumps(message)
    if rng.random() < 0.1:
        text = text.replace("0.3", "NaN").replace("1e+308", "Infinity")
    if rng.random() < 0.05:
        text = text[: rng.randrange(len(text))]
    return text


def test_a_few_hundred_malformed_messages_get_error_replies_and_the_server_keeps_going(
    server: DashboardServer, fake: FakeSimSource
) -> None:
    rng = random.Random(20240521)
    messages = [random_message(rng) for _ in range(400)]
    replies: list[dict[str, Any]] = []

    async def scenario() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(base_url(server) + "/ws") as ws:
            for text in messages:
                await ws.send_str(text)
                replies.append(await next_reply(ws))
            await ws.send_bytes(b"\x10\x01\x00\x11")
            assert "binary" in (await next_reply(ws))["error"]
            await ws.send_str('{"type":"velocity","vx_mps":0,"omega_radps":0}')
            assert (await next_reply(ws))["type"] == "ack"
            await next_of_type(ws, "snapshot")  # still pushing

    run(scenario)
    errors = [r for r in replies if r["type"] == "error"]
    acks = [r for r in replies if r["type"] == "ack"]
    assert len(errors) > 300 and acks, (len(errors), len(acks))
    # Exactly the accepted messages reached the source (and the zero velocity of each teleop hold
    # that ran out), and every velocity it saw is within limits.
    assert len(fake.calls) == len(acks) + 1 + server.counters.teleop_timeouts
    for call in fake.calls:
        if call[0] == "set_velocity":
            assert abs(call[1]) <= MAX_VX and abs(call[2]) <= MAX_OMEGA
    assert server.counters.rejected == len(errors) + 1


def test_an_oversized_frame_closes_only_that_connection(server: DashboardServer) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session:
            async with session.ws_connect(base_url(server) + "/ws") as ws:
                await ws.send_str('{"type":"estop","pad":"' + "x" * 70_000 + '"}')
                while True:
                    message = await ws.receive(timeout=10)
                    if message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED):
                        break
            async with session.ws_connect(base_url(server) + "/ws") as ws:
                await next_of_type(ws, "snapshot")

    run(scenario)


def test_a_failing_source_gets_an_error_reply_not_a_dead_server(
    server: DashboardServer, fake: FakeSimSource
) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(base_url(server) + "/ws") as ws:
            fake.fail_next = True
            await ws.send_str('{"type":"go_home"}')
            reply = await next_reply(ws)
            assert reply["type"] == "error" and "refuses" in reply["error"]
            await ws.send_str('{"type":"go_home"}')
            assert (await next_reply(ws))["type"] == "ack"

    run(scenario)
    assert fake.calls == [("go_home",)]


def test_external_commands_are_refused_without_a_simulator() -> None:
    plain = FakeSource()
    assert not accepts_external_commands(plain) and accepts_external_commands(FakeSimSource())
    srv = serve(plain)
    try:

        async def scenario() -> None:
            async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws") as ws:
                assert (await next_of_type(ws, "hello"))["external_commands"] == []
                await ws.send_str('{"type":"external_command","code":160}')
                reply = await next_reply(ws)
                assert reply["type"] == "error" and "external commands" in reply["error"]

        run(scenario)
    finally:
        srv.stop()
    assert plain.calls == []


def test_teleop_stops_when_the_page_stops_repeating(fake: FakeSimSource) -> None:
    srv = serve(fake, push_hz=20.0, teleop_hold_s=0.2)
    try:

        async def scenario() -> None:
            async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws") as ws:
                await ws.send_str('{"type":"velocity","vx_mps":0.3,"omega_radps":0}')
                await next_reply(ws)
                await wait_until(lambda: len(fake.calls) >= 2)
            assert fake.calls == [("set_velocity", 0.3, 0.0), ("set_velocity", 0.0, 0.0)]
            # Closing the page while driving stops too.
            fake.calls.clear()
            async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws") as ws:
                await ws.send_str('{"type":"velocity","vx_mps":0.3,"omega_radps":0}')
                await next_reply(ws)
            await wait_until(lambda: len(fake.calls) >= 2)
            assert fake.calls == [("set_velocity", 0.3, 0.0), ("set_velocity", 0.0, 0.0)]

        run(scenario)
    finally:
        srv.stop()


def test_go_home_is_not_cancelled_by_the_teleop_hold(fake: FakeSimSource) -> None:
    srv = serve(fake, push_hz=20.0, teleop_hold_s=0.1)
    try:

        async def scenario() -> None:
            async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws") as ws:
                await ws.send_str('{"type":"velocity","vx_mps":0.3,"omega_radps":0}')
                await next_reply(ws)
                await ws.send_str('{"type":"go_home"}')
                await next_reply(ws)
                # Long past the hold: only snapshots in between, nothing zeroed go_home.
                for _ in range(10):
                    await next_of_type(ws, "snapshot")

        run(scenario)
    finally:
        srv.stop()
    assert fake.calls == [("set_velocity", 0.3, 0.0), ("go_home",)]


# -- access ---------------------------------------------------------------------------------------


def test_loopback_without_a_token_works_but_only_for_loopback_names(server: DashboardServer) -> None:
    async def scenario() -> None:
        async with aiohttp.ClientSession() as session:
            async with session.get(base_url(server) + "/", headers={"Host": f"localhost:{server.port}"}) as r:
                assert r.status == 200
            # DNS rebinding: a foreign name pointing at 127.0.0.1.
            async with session.get(base_url(server) + "/api/snapshot", headers={"Host": "evil.example"}) as r:
                assert r.status == 403
            # Another site open in the same browser must not drive the robot.
            with pytest.raises(aiohttp.WSServerHandshakeError) as info:
                await session.ws_connect(base_url(server) + "/ws", headers={"Origin": "http://evil.example"})
            assert info.value.status == 403
            origin = {"Origin": f"http://127.0.0.1:{server.port}"}
            async with session.ws_connect(base_url(server) + "/ws", headers=origin) as ws:
                await ws.send_str('{"type":"estop"}')
                assert (await next_reply(ws))["type"] == "ack"

    run(scenario)


def token_checks(url: str, token: str) -> dict[str, Any]:
    """What a client without, with a wrong, and with the right token gets (used twice below)."""
    results: dict[str, Any] = {}

    async def scenario() -> None:
        async with aiohttp.ClientSession() as session:
            for path in ("/", "/api/snapshot"):
                async with session.get(url + path) as r:
                    results[f"GET {path} no token"] = r.status
                async with session.get(url + path, params={"token": token + "x"}) as r:
                    results[f"GET {path} wrong token"] = r.status
                async with session.get(url + path, params={"token": token}) as r:
                    results[f"GET {path} query token"] = r.status
            async with session.get(url + "/api/snapshot", headers={"X-Ctrlbus-Token": token}) as r:
                results["GET header token"] = r.status
            async with session.get(url + "/api/snapshot", headers={"Authorization": f"Bearer {token}"}) as r:
                results["GET bearer token"] = r.status
            async with session.get(url + "/static/app.js") as r:
                results["GET static no token"] = r.status
            try:
                async with session.ws_connect(url + "/ws") as ws:
                    await ws.send_str('{"type":"estop"}')
                    results["WS control no token"] = "accepted"
            except aiohttp.WSServerHandshakeError as exc:
                results["WS control no token"] = exc.status
            async with session.ws_connect(url + "/ws", params={"token": token}) as ws:
                await ws.send_str('{"type":"estop"}')
                results["WS control with token"] = (await next_reply(ws))["type"]

    run(scenario)
    return results


EXPECTED_TOKEN_RESULTS = {
    "GET / no token": 401,
    "GET / wrong token": 401,
    "GET / query token": 200,
    "GET /api/snapshot no token": 401,
    "GET /api/snapshot wrong token": 401,
    "GET /api/snapshot query token": 200,
    "GET header token": 200,
    "GET bearer token": 200,
    "GET static no token": 200,
    "WS control no token": 401,
    "WS control with token": "ack",
}


def test_with_a_token_every_read_and_control_needs_it(fake: FakeSimSource) -> None:
    srv = serve(fake, token=TOKEN)
    try:
        assert token_checks(base_url(srv), TOKEN) == EXPECTED_TOKEN_RESULTS
        assert srv.url == f"http://127.0.0.1:{srv.port}/?token={TOKEN}"
    finally:
        srv.stop()
    assert fake.calls == [("emergency_stop",)]  # only the message that carried the token


def netns_check(mode: str) -> int:
    """Inside a private network namespace: listen on 0.0.0.0 with a token (issue 17 made the
    one-character token of the original acceptance case too weak for a non-loopback address), and
    print what clients get as one JSON line. `mode` "server": the dashboard server over the fake;
    "demo": `python -m ctrlbus.demo --listen 0.0.0.0 --token TOKEN`, the real Core and simulator
    behind it."""
    if mode == "server":
        fake = FakeSimSource()
        srv = DashboardServer(fake, DashboardOptions(host="0.0.0.0", port=0, token=TOKEN))
        srv.start()
        try:
            results = token_checks(f"http://127.0.0.1:{srv.port}", TOKEN)
        finally:
            srv.stop()
        results["estop latched"] = [list(call) for call in fake.calls] == [["emergency_stop"]]
        print(json.dumps(results))
        return 0
    demo = subprocess.Popen(
        [sys.executable, "-m", "ctrlbus.demo", "--listen", "0.0.0.0", "--token", TOKEN],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
    )
    try:
        assert demo.stdout is not None
        output = []
        for line in demo.stdout:
            output.append(line)
            if f"dashboard at http://127.0.0.1:8080/?token={TOKEN}" in line:
                break
        else:
            raise AssertionError("the demo did not start:\n" + "".join(output))
        results = token_checks("http://127.0.0.1:8080", TOKEN)
        request = urllib.request.Request(
            "http://127.0.0.1:8080/api/snapshot", headers={"X-Ctrlbus-Token": TOKEN}
        )
        with urllib.request.urlopen(request, timeout=10) as response:
            results["estop latched"] = json.load(response)["data"]["command"]["estop"]
    finally:
        demo.send_signal(signal.SIGINT)
        demo.wait(30)
    results["demo exit"] = demo.returncode
    print(json.dumps(results))
    return 0


@pytest.mark.parametrize("mode", ["server", "demo"])
def test_listening_on_0_0_0_0_with_token_x_refuses_control_without_it(mode: str) -> None:
    """The acceptance case, literally, in a network namespace of its own (only loopback in it)."""
    unshare, ip = shutil.which("unshare"), shutil.which("ip")
    if unshare is None or ip is None:
        pytest.skip("needs unshare and ip (util-linux, iproute2) for a private network namespace")
    probe = subprocess.run([unshare, "-rn", "true"], capture_output=True, timeout=30)
    if probe.returncode != 0:
        pytest.skip(f"no user/network namespaces here: {probe.stderr.decode(errors='replace').strip()}")
    this_file = Path(__file__).resolve()
    script = f'"{ip}" link set lo up && exec "{sys.executable}" "{this_file}" netns-check {mode}'
    result = subprocess.run(
        [unshare, "-rn", "sh", "-c", script], capture_output=True, text=True, timeout=120, cwd=PYTHON_DIR
    )
    assert result.returncode == 0, result.stdout + result.stderr
    results = json.loads(result.stdout.strip().splitlines()[-1])
    # The control message without the token was refused, the one with it latched the stop.
    assert results.pop("estop latched") is True
    if mode == "demo":
        assert results.pop("demo exit") == 0
    assert results == EXPECTED_TOKEN_RESULTS


# -- life cycle -----------------------------------------------------------------------------------


def test_stop_closes_pages_and_frees_the_port(fake: FakeSimSource) -> None:
    srv = serve(fake)
    port = srv.port

    async def scenario() -> None:
        async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws") as ws:
            await next_of_type(ws, "snapshot")
            await asyncio.get_running_loop().run_in_executor(None, srv.stop)
            while True:
                message = await ws.receive(timeout=10)
                if message.type in (aiohttp.WSMsgType.CLOSE, aiohttp.WSMsgType.CLOSED):
                    break

    run(scenario)
    srv.stop()  # idempotent
    assert not any(t.name == "ctrlbus-dashboard" for t in threading.enumerate())
    with socket.socket() as probe:  # nothing listens there any more (closed connections may linger)
        probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        probe.bind(("127.0.0.1", port))
        probe.listen(1)


def test_a_port_in_use_is_a_clear_error(fake: FakeSimSource) -> None:
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen(1)
        port = taken.getsockname()[1]
        srv = DashboardServer(fake, DashboardOptions(host="127.0.0.1", port=port))
        with pytest.raises(LinkError, match=f"cannot listen on 127.0.0.1:{port}"):
            srv.start()


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "netns-check" and sys.argv[2] in ("server", "demo"):
        sys.exit(netns_check(sys.argv[2]))
    sys.exit(f"usage: {sys.argv[0]} netns-check server|demo")
