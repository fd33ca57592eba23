# SPDX-License-Identifier: MIT
"""The dashboard's edges (issue 17, findings 3 and 4): every repeated log path is throttled, error
pages carry the security headers, the Server header hides the aiohttp version, a request without
a Host header is not loopback, a non-loopback bind needs a strong token (and can generate one), a
token from the environment is never echoed, and a velocity during an emergency stop is refused.
"""

from __future__ import annotations

import asyncio
import logging
import os
import re
import socket
import subprocess
import sys
from typing import Any

import aiohttp
import pytest
from test_web import TOKEN, FakeSimSource, base_url, next_reply, run, serve

from ctrlbus.errors import CtrlbusError, UsageError
from ctrlbus.web.options import TOKEN_ENV, DashboardOptions
from ctrlbus.web.server import DashboardServer

WEB_LOGGER = "ctrlbus.web"
# However many repeats come in, a throttled path writes a few lines: a burst, then about one a
# second (a test runs for a second or two).
MAX_LINES_PER_PATH = 15


class FullQueueSource(FakeSimSource):
    """A simulator whose external-command queue fills after 16 commands, as the real one does."""

    def __init__(self) -> None:
        super().__init__()
        self.queued = 0

    def queue_external_command(self, code: int) -> None:
        if self.queued >= 16:
            raise UsageError("the external command queue is full (16 commands)")
        self.queued += 1


def web_lines(caplog: pytest.LogCaptureFixture) -> list[str]:
    return [record.getMessage() for record in caplog.records if record.name == WEB_LOGGER]


def send_many(server: DashboardServer, text: str, count: int, **connect: Any) -> list[dict[str, Any]]:
    replies: list[dict[str, Any]] = []

    async def scenario() -> None:
        url = base_url(server) + "/ws"
        async with aiohttp.ClientSession() as session, session.ws_connect(url, **connect) as ws:
            for _ in range(count):
                await ws.send_str(text)
                replies.append(await next_reply(ws))

    run(scenario)
    return replies


# -- finding 3: log flooding ----------------------------------------------------------------------


def test_refused_external_commands_are_logged_with_a_rate_limit(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger=WEB_LOGGER)
    source = FullQueueSource()
    srv = serve(source)
    try:
        replies = send_many(srv, '{"type":"external_command","code":160}', 200)
    finally:
        srv.stop()
    assert sum(reply["type"] == "error" for reply in replies) == 200 - 16
    refused = [line for line in web_lines(caplog) if "refused" in line]
    assert 1 <= len(refused) <= MAX_LINES_PER_PATH, f"{len(refused)} lines for 184 refusals"
    assert srv.counters.source_errors == 184  # every refusal is counted, logged or not


@pytest.mark.parametrize(
    ("text", "what"),
    [
        ('{"type":"estop"}', "emergency stop"),
        ('{"type":"release"}', "released"),
    ],
)
def test_repeated_stop_messages_are_logged_with_a_rate_limit(
    caplog: pytest.LogCaptureFixture, text: str, what: str
) -> None:
    caplog.set_level(logging.INFO, logger=WEB_LOGGER)
    srv = serve(FakeSimSource())
    try:
        send_many(srv, text, 300)
    finally:
        srv.stop()
    lines = [line for line in web_lines(caplog) if what in line]
    assert 1 <= len(lines) <= MAX_LINES_PER_PATH, f"{len(lines)} lines for 300 messages"


def test_refused_requests_are_logged_with_a_rate_limit(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger=WEB_LOGGER)
    srv = serve(FakeSimSource(), token=TOKEN)
    try:

        async def scenario() -> None:
            async with aiohttp.ClientSession() as session:
                for _ in range(300):
                    async with session.get(base_url(srv) + "/api/snapshot") as response:
                        assert response.status == 401

        run(scenario)
    finally:
        srv.stop()
    lines = [line for line in web_lines(caplog) if "refused GET" in line]
    assert 1 <= len(lines) <= MAX_LINES_PER_PATH, f"{len(lines)} lines for 300 refused requests"


def test_a_failing_source_is_logged_with_a_rate_limit(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger=WEB_LOGGER)

    class Failing(FakeSimSource):
        def go_home(self) -> None:
            raise CtrlbusError("no charger known")

    srv = serve(Failing())
    try:
        replies = send_many(srv, '{"type":"go_home"}', 300)
    finally:
        srv.stop()
    assert all(reply["type"] == "error" for reply in replies)
    lines = [line for line in web_lines(caplog) if "refused" in line]
    assert 1 <= len(lines) <= MAX_LINES_PER_PATH, f"{len(lines)} lines for 300 refusals"


def test_a_failing_snapshot_is_logged_with_a_rate_limit(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.INFO, logger=WEB_LOGGER)

    class Broken(FakeSimSource):
        def snapshot(self) -> dict[str, Any]:
            raise RuntimeError("the Core's state is being rebuilt")

    srv = serve(Broken(), push_hz=100.0)
    try:

        async def scenario() -> None:
            async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws"):
                await asyncio.sleep(1.0)  # about 100 pushes, each failing

        run(scenario)
    finally:
        srv.stop()
    lines = [line for line in web_lines(caplog) if "snapshot() failed" in line]
    assert srv.counters.source_errors >= 50
    assert 1 <= len(lines) <= MAX_LINES_PER_PATH, f"{len(lines)} lines for the failures"


# -- finding 4: edges -----------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "token", "status"),
    [
        ("/api/snapshot", None, 401),
        ("/no/such/page", TOKEN, 404),
        ("/static/no-such-file.js", None, 404),
    ],
)
def test_error_pages_carry_the_security_headers(path: str, token: str | None, status: int) -> None:
    srv = serve(FakeSimSource(), token=TOKEN)
    seen: dict[str, Any] = {}
    try:

        async def scenario() -> None:
            params = {"token": token} if token else None
            url = base_url(srv) + path
            async with aiohttp.ClientSession() as session, session.get(url, params=params) as r:
                seen["status"] = r.status
                seen["headers"] = dict(r.headers)

        run(scenario)
    finally:
        srv.stop()
    assert seen["status"] == status
    headers = seen["headers"]
    assert "default-src 'self'" in headers.get("Content-Security-Policy", ""), headers
    assert headers.get("X-Content-Type-Options") == "nosniff", headers
    assert "aiohttp" not in headers.get("Server", "").lower(), headers


def test_forbidden_pages_carry_the_security_headers() -> None:
    srv = serve(FakeSimSource())
    try:
        status, headers = raw_get(srv, "GET /api/snapshot HTTP/1.1\r\nHost: evil.example\r\n\r\n")
    finally:
        srv.stop()
    assert status == 403
    assert "default-src 'self'" in headers.get("content-security-policy", ""), headers
    assert headers.get("x-content-type-options") == "nosniff", headers
    assert "aiohttp" not in headers.get("server", "").lower(), headers


def raw_get(server: DashboardServer, request: str) -> tuple[int, dict[str, str]]:
    """Send a raw HTTP request (so that headers are exactly as written); status and headers."""
    with socket.create_connection(("127.0.0.1", server.port), timeout=10) as sock:
        sock.sendall(request.encode())
        data = b""
        while b"\r\n\r\n" not in data:
            chunk = sock.recv(4096)
            if not chunk:
                break
            data += chunk
    head = data.split(b"\r\n\r\n", 1)[0].decode("latin-1").split("\r\n")
    status = int(head[0].split()[1])
    headers = {}
    for line in head[1:]:
        name, _, value = line.partition(":")
        headers[name.strip().lower()] = value.strip()
    return status, headers


def test_a_request_without_a_host_header_is_not_loopback(monkeypatch: pytest.MonkeyPatch) -> None:
    # Without a Host header, aiohttp reports the machine's name: on many machines "localhost".
    monkeypatch.setattr(socket, "getfqdn", lambda *args: "localhost")
    srv = serve(FakeSimSource())
    try:
        status, _headers = raw_get(srv, "GET /api/snapshot HTTP/1.0\r\n\r\n")
        good, _ = raw_get(srv, "GET /api/snapshot HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n")
    finally:
        srv.stop()
    assert (status, good) == (403, 200)


def test_a_non_loopback_bind_needs_a_strong_token() -> None:
    for weak in ("X", "a" * 15):
        with pytest.raises(UsageError, match=r"at least 16 characters.*--token generate"):
            DashboardOptions(host="0.0.0.0", token=weak)
    assert DashboardOptions(host="0.0.0.0", token="a" * 16).token == "a" * 16
    assert DashboardOptions(host="127.0.0.1", token="X").token == "X"  # loopback: the user's choice


def test_token_generate_makes_a_strong_random_token() -> None:
    from ctrlbus.cli import build_parser

    parser = build_parser()
    tokens = set()
    for _ in range(3):
        command = ["core", "--port", "loop://", "--dashboard", "--http", "0.0.0.0:0", "--token", "generate"]
        args = parser.parse_args(command)
        options = DashboardOptions.from_args(args)
        assert options.token is not None and len(options.token) >= 16
        assert options.token_generated and options.token != "generate"
        tokens.add(options.token)
    assert len(tokens) == 3


def test_a_token_from_the_environment_is_never_echoed(monkeypatch: pytest.MonkeyPatch) -> None:
    secret = "env-secret-0123456789"
    options = DashboardOptions(host="127.0.0.1", port=8080, token=secret, token_from_env=True)
    assert secret not in options.display_url and TOKEN_ENV in options.display_url
    given = DashboardOptions(host="127.0.0.1", port=8080, token=secret)
    assert given.display_url == given.url  # given on the command line: the user has it already
    # The demo, as a user runs it: the dashboard line on stdout/stderr names the variable only.
    demo = subprocess.Popen(
        [sys.executable, "-m", "ctrlbus.demo", "--listen", "127.0.0.1:0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        env={**os.environ, TOKEN_ENV: secret},
    )
    try:
        assert demo.stdout is not None
        output = []
        for line in demo.stdout:
            output.append(line)
            if "dashboard at" in line:
                break
    finally:
        demo.terminate()
        rest = demo.communicate(timeout=30)[0]
    text = "".join(output) + (rest or "")
    assert "dashboard at" in text, text
    assert secret not in text, text


def test_a_velocity_during_an_emergency_stop_is_refused() -> None:
    source = FakeSimSource()
    srv = serve(source)
    replies: list[dict[str, Any]] = []
    try:

        async def scenario() -> None:
            async with aiohttp.ClientSession() as session, session.ws_connect(base_url(srv) + "/ws") as ws:
                for text in (
                    '{"type":"estop"}',
                    '{"type":"velocity","vx_mps":0.2,"omega_radps":0}',
                    '{"type":"velocity","vx_mps":0,"omega_radps":0}',
                    '{"type":"release"}',
                    '{"type":"velocity","vx_mps":0.2,"omega_radps":0}',
                ):
                    await ws.send_str(text)
                    replies.append(await next_reply(ws))

        run(scenario)
    finally:
        srv.stop()
    estop, during, zero, release, after = replies
    assert estop["type"] == "ack" and release["type"] == "ack"
    assert zero["type"] == "ack" and zero["vx_mps"] == 0.0  # what the stop holds anyway
    assert during["type"] == "error" and re.search("emergency stop", during["error"]), during
    assert after["type"] == "ack" and after["for"] == "velocity"
    assert ("set_velocity", 0.2, 0.0) not in source.calls[: source.calls.index(("release_stop",))]
