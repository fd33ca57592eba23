# SPDX-License-Identifier: MIT
"""The dashboard's HTTP + WebSocket server, running in its own thread and event loop.

It serves the page, pushes `{"type": "snapshot", ...}` messages to every open WebSocket at
`push_hz`, and turns control messages from the page into calls on a `DashboardSource`. It never
blocks the Core's runner: it only calls the source's quick, thread-safe methods, and a slow
browser just misses snapshots rather than queueing them.

Access: without a token it accepts only requests addressed to a loopback name (so a web page
elsewhere cannot reach it by DNS rebinding) and WebSockets from its own origin (so another site
open in the same browser cannot drive the robot). With a token, every request that reads or
controls must carry it (`?token=`, `X-Ctrlbus-Token:` or `Authorization: Bearer`); the page's
static files are public, they are the same as in the source tree.

Teleop safety: a velocity from the page holds for `teleop_hold_s` only; the page repeats it while
a key is held. If the repeats stop (tab closed, network gone) the server commands zero.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import hmac
import json
import logging
import math
import os
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

from aiohttp import WSMsgType, web
from aiohttp.http_exceptions import HttpProcessingError

from ctrlbus import __version__
from ctrlbus.errors import CtrlbusError, LinkError
from ctrlbus.web.control import (
    EXTERNAL_COMMAND_BUTTONS,
    EXTERNAL_COMMANDS,
    MAX_MESSAGE_CHARS,
    ControlMessage,
    ControlMessageError,
    EmergencyStop,
    ExternalCommand,
    GoHome,
    ReleaseStop,
    Velocity,
    clamp_velocity,
    parse_control_message,
)
from ctrlbus.web.options import DashboardOptions, is_loopback
from ctrlbus.web.source import DashboardSource, accepts_external_commands

__all__ = [
    "MAX_FRAME_BYTES",
    "PUBLIC_PATHS",
    "PUBLIC_PREFIXES",
    "SECURITY_HEADERS",
    "STATIC_DIR",
    "DashboardServer",
    "ServerCounters",
    "start_dashboard",
]

log = logging.getLogger("ctrlbus.web")

STATIC_DIR = Path(__file__).parent / "static"
# WebSocket frames larger than this close the connection; anything between MAX_MESSAGE_CHARS
# and this gets an error reply instead.
MAX_FRAME_BYTES = 64 * 1024
PUBLIC_PREFIXES = ("/static/",)
PUBLIC_PATHS = frozenset({"/favicon.ico"})
# The log rate of each kind of message a client can trigger (LogLimiter).
LOG_BURST = 10
LOG_LINES_PER_SECOND = 1.0
SERVER_NAME = "ctrlbus-dashboard"  # in the Server header instead of aiohttp's name and version
SECURITY_HEADERS = {
    "Content-Security-Policy": "default-src 'self'; connect-src 'self'; img-src 'self' data:; "
    "frame-ancestors 'none'; base-uri 'none'; form-action 'none'",
    "X-Content-Type-Options": "nosniff",
    "Referrer-Policy": "no-referrer",
    "Cache-Control": "no-store",
}


@dataclass(eq=False)  # each connection is its own client, kept in a set
class _Client:
    ws: web.WebSocketResponse
    peer: str
    sending: asyncio.Task[None] | None = None
    rejected: int = 0


@dataclass
class ServerCounters:
    """What the server did, for tests and the log (read from any thread: plain ints)."""

    connections: int = 0
    snapshots_sent: int = 0
    accepted: int = 0
    rejected: int = 0
    source_errors: int = 0
    teleop_timeouts: int = 0
    unauthorized: int = 0
    malformed_requests: int = 0  # refused by aiohttp's parser (a duplicate Host header, ...)
    refused_during_estop: int = 0
    by_type: dict[str, int] = field(default_factory=dict)


class EmergencyStopLatched(CtrlbusError):
    """A velocity from the page while the emergency stop is latched: refused, not acknowledged."""


class LogLimiter:
    """Every log path the network can trigger goes through here, so that no client can flood the
    log: each kind of message (`key`) gets a burst of `burst` lines, then `per_second` lines a
    second on average; the lines left out are counted and the next line of that kind says how
    many. Used from the server's event loop thread only."""

    def __init__(
        self,
        logger: logging.Logger,
        *,
        burst: int = LOG_BURST,
        per_second: float = LOG_LINES_PER_SECOND,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self._logger = logger
        self._burst = burst
        self._per_second = per_second
        self._clock = clock
        self._credit: dict[str, float] = {}
        self._last: dict[str, float] = {}
        self._suppressed: dict[str, int] = {}

    def log(
        self, level: int, key: str, message: str, *args: object, exc_info: bool | BaseException = False
    ) -> bool:
        """Log `message % args` at `level` unless `key` is over its rate; returns whether it did."""
        now = self._clock()
        credit = self._credit.get(key, float(self._burst))
        if key in self._last:
            credit = min(float(self._burst), credit + (now - self._last[key]) * self._per_second)
        self._last[key] = now
        if credit < 1.0:
            self._credit[key] = credit
            self._suppressed[key] = self._suppressed.get(key, 0) + 1
            return False
        self._credit[key] = credit - 1.0
        suppressed = self._suppressed.pop(key, 0)
        if suppressed:
            message += f" ({suppressed} similar messages suppressed)"
        self._logger.log(level, message, *args, exc_info=exc_info)
        return True


class _HttpParserLog:
    """The logger aiohttp's connection handler is given. A request its parser refuses (a
    duplicate Host header, a bad request line, ...) is answered 400 by aiohttp before any handler
    or token check runs, and would be logged with a traceback each time: here it is counted and
    logged as one line through the server's LogLimiter. Anything else aiohttp reports (a handler
    that raised: our bug) keeps its traceback, rate-limited too; its debug lines stay debug lines."""

    def __init__(self, limiter: LogLimiter, counters: ServerCounters) -> None:
        self._limiter = limiter
        self._counters = counters

    def exception(self, message: str, *args: object, exc_info: object = None, **_: object) -> None:
        if isinstance(exc_info, HttpProcessingError):
            self._counters.malformed_requests += 1
            reason = " ".join(str(exc_info.message).split())[:200] or "no reason given"
            text = (message % args).replace("Error handling request", "refused a malformed request")
            self._limiter.log(logging.WARNING, "malformed-request", "%s: %s", text, reason)
            return
        error = exc_info if isinstance(exc_info, BaseException) else False
        self._limiter.log(logging.ERROR, "server-error", message, *args, exc_info=error)

    error = warning = exception

    def debug(self, message: str, *args: object, **_: object) -> None:
        log.debug(message, *args)

    info = debug


class DashboardServer:
    """Serve the dashboard for `source` as `options` say; `start()`, then `stop()`."""

    def __init__(self, source: DashboardSource, options: DashboardOptions) -> None:
        self.source = source
        self.options = options
        self.counters = ServerCounters()
        self._thread: threading.Thread | None = None
        self._loop: asyncio.AbstractEventLoop | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._startup_error: BaseException | None = None
        self._port: int | None = None
        self._clients: set[_Client] = set()
        self._teleop_owner: _Client | None = None
        self._teleop_deadline: float | None = None
        self._snapshot_seq = 0
        self._started_at = 0.0
        self._token = options.token.encode() if options.token else None
        self._log = LogLimiter(log)

    # -- life cycle (any thread) ----------------------------------------------------------------

    def start(self, timeout: float = 10.0) -> None:
        """Bind and start serving; LinkError if the address cannot be used."""
        if self._thread is not None:
            raise CtrlbusError("the dashboard server is already started")
        self._thread = threading.Thread(target=self._run, name="ctrlbus-dashboard", daemon=True)
        self._thread.start()
        if not self._ready.wait(timeout):
            raise LinkError("the dashboard server did not start in time")
        if self._startup_error is not None:
            self._thread.join(timeout)
            error = self._startup_error
            if isinstance(error, OSError):
                reason = os.strerror(error.errno) if error.errno else str(error)
                raise LinkError(
                    f"cannot listen on {self.options.host}:{self.options.port}: {reason}"
                ) from None
            raise error

    def stop(self, timeout: float = 5.0) -> None:
        """Close every WebSocket, stop listening and end the thread; idempotent."""
        thread, loop, stop = self._thread, self._loop, self._stop
        if thread is None:
            return
        if loop is not None and stop is not None and thread.is_alive():
            with contextlib.suppress(RuntimeError):  # the loop may have just closed
                loop.call_soon_threadsafe(stop.set)
        thread.join(timeout)
        if thread.is_alive():
            log.warning("dashboard server thread did not stop within %.1f s", timeout)
        self._thread = None

    @property
    def port(self) -> int:
        if self._port is None:
            raise CtrlbusError("the dashboard server is not started")
        return self._port

    @property
    def url(self) -> str:
        """The page's address, the token included."""
        return self._bound_options().url

    @property
    def display_url(self) -> str:
        """The address to print: a token from the environment is not shown (options.display_url)."""
        return self._bound_options().display_url

    def _bound_options(self) -> DashboardOptions:
        return dataclasses.replace(self.options, port=self.port)

    def __enter__(self) -> DashboardServer:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    # -- the event loop thread ------------------------------------------------------------------

    def _run(self) -> None:
        loop = asyncio.new_event_loop()
        self._loop = loop
        try:
            loop.run_until_complete(self._serve())
        except BaseException as exc:  # reported to start(); the thread must not die silently
            if not self._ready.is_set():
                self._startup_error = exc
            else:
                log.exception("dashboard server failed")
        finally:
            self._ready.set()
            with contextlib.suppress(Exception):
                loop.run_until_complete(loop.shutdown_asyncgens())
            loop.close()

    async def _serve(self) -> None:
        self._stop = asyncio.Event()
        app = web.Application(middlewares=[self._guard], client_max_size=4096)
        app.on_response_prepare.append(_add_security_headers)
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._websocket)
        app.router.add_get("/api/snapshot", self._snapshot_http)
        app.router.add_get("/favicon.ico", self._no_icon)
        app.router.add_static("/static/", STATIC_DIR, follow_symlinks=False, append_version=False)
        runner = web.AppRunner(
            app,
            access_log=None,
            handle_signals=False,
            shutdown_timeout=1.0,
            logger=_HttpParserLog(self._log, self.counters),
        )
        await runner.setup()
        try:
            site = web.TCPSite(runner, self.options.host, self.options.port)
            await site.start()
            addresses = runner.addresses  # the bound port, when port 0 asked for any free one
            self._port = int(addresses[0][1]) if addresses else self.options.port
            self._started_at = asyncio.get_running_loop().time()
            self._ready.set()
            log.info("dashboard listening on %s:%s", self.options.host, self._port)
            pusher = asyncio.create_task(self._push_loop())
            await self._stop.wait()
            pusher.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await pusher
            await self._close_clients()
        finally:
            await runner.cleanup()

    async def _close_clients(self) -> None:
        clients = list(self._clients)
        for client in clients:
            if client.sending is not None:
                client.sending.cancel()
        if clients:
            await asyncio.wait(
                [asyncio.ensure_future(c.ws.close(code=1001, message=b"server stopping")) for c in clients],
                timeout=2.0,
            )

    # -- HTTP -----------------------------------------------------------------------------------

    @web.middleware
    async def _guard(self, request: web.Request, handler: Any) -> web.StreamResponse:
        if request.path not in PUBLIC_PATHS and not request.path.startswith(PUBLIC_PREFIXES):
            refusal = self._refusal(request)
            if refusal is not None:
                self.counters.unauthorized += 1
                self._log.log(
                    logging.WARNING,
                    "refused-request",
                    "refused %s %s from %s: %s",
                    request.method,
                    request.path,
                    request.remote,
                    refusal.text,
                )
                return refusal
        response: web.StreamResponse = await handler(request)
        return response

    def _refusal(self, request: web.Request) -> web.Response | None:
        host = request.headers.get("Host", "")
        if self._token is not None:
            presented = _presented_token(request)
            if presented is None or not hmac.compare_digest(presented.encode(), self._token):
                return web.Response(
                    status=401,
                    text="missing or wrong dashboard token",
                    headers={"WWW-Authenticate": 'Bearer realm="ctrlbus"'},
                )
        elif not is_loopback(_host_name(host)):
            # No token means loopback only; a foreign Host header means DNS rebinding, and none
            # at all is no proof of loopback (aiohttp would put the machine's name in its place).
            return web.Response(status=403, text="this dashboard answers only to localhost")
        origin = request.headers.get("Origin")
        if request.path == "/ws" and origin is not None and urlsplit(origin).netloc != host:
            return web.Response(status=403, text="WebSocket from another origin refused")
        return None

    async def _index(self, request: web.Request) -> web.StreamResponse:
        page = STATIC_DIR / "index.html"
        return web.FileResponse(page, headers={"Content-Type": "text/html; charset=utf-8"})

    async def _no_icon(self, request: web.Request) -> web.StreamResponse:
        return web.Response(status=204)

    async def _snapshot_http(self, request: web.Request) -> web.StreamResponse:
        text = self._snapshot_message()
        if text is None:
            return web.Response(status=503, text="the Core's snapshot is unavailable")
        return web.Response(text=text, content_type="application/json")

    # -- WebSocket ------------------------------------------------------------------------------

    async def _websocket(self, request: web.Request) -> web.StreamResponse:
        ws = web.WebSocketResponse(heartbeat=10.0, max_msg_size=MAX_FRAME_BYTES, compress=False)
        await ws.prepare(request)
        client = _Client(ws, str(request.remote))
        self._clients.add(client)
        self.counters.connections += 1
        try:
            await ws.send_str(_dumps(self._hello()))
            async for message in ws:
                if message.type == WSMsgType.TEXT:
                    await self._handle_text(client, message.data)
                elif message.type == WSMsgType.BINARY:
                    await self._reject(client, "binary frames are not accepted; send JSON text")
                elif message.type == WSMsgType.ERROR:
                    self._log.log(
                        logging.INFO,
                        "websocket-error",
                        "WebSocket from %s closed with an error: %s",
                        client.peer,
                        ws.exception(),
                    )
                    break
        except (ConnectionError, RuntimeError) as exc:
            self._log.log(logging.INFO, "websocket-ended", "WebSocket from %s ended: %s", client.peer, exc)
        finally:
            self._clients.discard(client)
            if client.sending is not None:
                client.sending.cancel()
            if self._teleop_owner is client and self._teleop_deadline is not None:
                self._end_teleop("the page that was driving disconnected")
        return ws

    def _hello(self) -> dict[str, Any]:
        buttons: list[dict[str, Any]] = []
        if accepts_external_commands(self.source):
            buttons = [{"code": EXTERNAL_COMMANDS[name], "name": name} for name in EXTERNAL_COMMAND_BUTTONS]
        return {
            "type": "hello",
            "version": __version__,
            "push_hz": self.options.push_hz,
            "teleop_hold_s": self.options.teleop_hold_s,
            "max_message_chars": MAX_MESSAGE_CHARS,
            "external_commands": buttons,
        }

    async def _handle_text(self, client: _Client, text: str) -> None:
        try:
            command = parse_control_message(text)
        except ControlMessageError as exc:
            await self._reject(client, str(exc))
            return
        try:
            reply = self._apply(client, command)
        except EmergencyStopLatched as exc:
            self.counters.refused_during_estop += 1
            reply = {"type": "error", "error": f"refused: {exc}"}
        except CtrlbusError as exc:
            self.counters.source_errors += 1
            self._log.log(
                logging.WARNING, "core-refused", "the Core refused %s: %s", type(command).__name__, exc
            )
            reply = {"type": "error", "error": f"refused: {exc}"}
        except Exception:
            self.counters.source_errors += 1
            self._log.log(
                logging.ERROR, "core-failed", "the Core failed on %s", type(command).__name__, exc_info=True
            )
            reply = {"type": "error", "error": "the Core failed on this command (see its log)"}
        else:
            self.counters.accepted += 1
            kind = str(reply["for"])
            self.counters.by_type[kind] = self.counters.by_type.get(kind, 0) + 1
        if command.message_id is not None:
            reply["id"] = command.message_id
        await _send(client, _dumps(reply))

    async def _reject(self, client: _Client, reason: str) -> None:
        self.counters.rejected += 1
        client.rejected += 1
        # A misbehaving page could send thousands; the first few are enough to diagnose it.
        self._log.log(
            logging.WARNING,
            "rejected-message",
            "rejected a control message from %s (#%d): %s",
            client.peer,
            client.rejected,
            reason,
        )
        await _send(client, _dumps({"type": "error", "error": reason}))

    def _apply(self, client: _Client, command: ControlMessage) -> dict[str, Any]:
        """Call the source; the ack reply says what was done."""
        if isinstance(command, Velocity):
            moving = command.vx_mps != 0.0 or command.omega_radps != 0.0
            if moving and self._estop_latched():
                # The source would ignore it: say so rather than acknowledge a motion not made.
                # (A zero velocity is what the stop holds anyway: acknowledged.)
                raise EmergencyStopLatched("the emergency stop is latched; release it first")
            vx, omega = clamp_velocity(command.vx_mps, command.omega_radps, self.source.limits())
            self.source.set_velocity(vx, omega)
            self._teleop_owner = client
            moving = vx != 0.0 or omega != 0.0
            now = asyncio.get_running_loop().time()
            self._teleop_deadline = now + self.options.teleop_hold_s if moving else None
            clamped = (vx, omega) != (command.vx_mps, command.omega_radps)
            return {"type": "ack", "for": "velocity", "vx_mps": vx, "omega_radps": omega, "clamped": clamped}
        # Every other command takes over from teleop: the hold timer must not zero it later.
        self._teleop_owner = None
        self._teleop_deadline = None
        if isinstance(command, EmergencyStop):
            self.source.emergency_stop()
            self._log.log(logging.WARNING, "estop", "emergency stop from %s", client.peer)
            return {"type": "ack", "for": "estop"}
        if isinstance(command, ReleaseStop):
            self.source.release_stop()
            self._log.log(logging.INFO, "release", "emergency stop released from %s", client.peer)
            return {"type": "ack", "for": "release"}
        if isinstance(command, GoHome):
            self.source.go_home()
            return {"type": "ack", "for": "go_home"}
        assert isinstance(command, ExternalCommand)
        queue = getattr(self.source, "queue_external_command", None)
        if queue is None:
            raise ControlMessageError("this base takes no external commands (not our simulator)")
        queue(command.code)
        return {"type": "ack", "for": "external_command", "code": command.code, "name": command.name}

    def _end_teleop(self, why: str) -> None:
        self._teleop_owner = None
        self._teleop_deadline = None
        try:
            self.source.set_velocity(0.0, 0.0)
        except Exception:
            self.counters.source_errors += 1
            self._log.log(logging.ERROR, "teleop-failed", "could not stop teleop (%s)", why, exc_info=True)
            return
        self.counters.teleop_timeouts += 1
        self._log.log(logging.INFO, "teleop-stopped", "teleop stopped: %s", why)

    def _estop_latched(self) -> bool:
        """Whether the source's emergency stop is latched, from its snapshot (the protocol has no
        other way to ask); False when the snapshot cannot say."""
        try:
            command = self.source.snapshot().get("command")
        except Exception:
            return False
        return isinstance(command, dict) and command.get("estop") is True

    # -- pushing snapshots ----------------------------------------------------------------------

    async def _push_loop(self) -> None:
        loop = asyncio.get_running_loop()
        period = 1.0 / self.options.push_hz
        deadline = loop.time()
        while True:
            deadline += period
            delay = deadline - loop.time()
            if delay < -period:
                deadline = loop.time()  # fell behind (machine busy): skip ahead, never burst
                delay = 0.0
            await asyncio.sleep(max(0.0, delay))
            now = loop.time()
            if self._teleop_deadline is not None and now > self._teleop_deadline:
                self._end_teleop(f"no velocity from the page for {self.options.teleop_hold_s:g} s")
            if not self._clients:
                continue
            text = self._snapshot_message()
            if text is None:
                continue
            for client in list(self._clients):
                if client.sending is None or client.sending.done():
                    client.sending = asyncio.create_task(_send(client, text))
                    self.counters.snapshots_sent += 1

    def _snapshot_message(self) -> str | None:
        try:
            data = self.source.snapshot()
        except Exception:
            self.counters.source_errors += 1
            self._log.log(logging.ERROR, "snapshot-failed", "the Core's snapshot() failed", exc_info=True)
            return None
        self._snapshot_seq += 1
        loop = asyncio.get_running_loop()
        message = {
            "type": "snapshot",
            "seq": self._snapshot_seq,
            "t_s": round(loop.time() - self._started_at, 4),
            "data": data,
        }
        try:
            return _dumps(message)
        except ValueError:  # NaN or infinity somewhere: JSON has no such numbers, send null
            return _dumps(_finite_only(message))
        except TypeError:
            self.counters.source_errors += 1
            self._log.log(
                logging.ERROR, "snapshot-not-json", "the Core's snapshot is not plain JSON", exc_info=True
            )
            return None


async def _add_security_headers(request: web.Request, response: web.StreamResponse) -> None:
    """Every response, error pages (401, 403, 404, ...) and the WebSocket upgrade included: the
    security headers, and a Server header that does not say which aiohttp version runs."""
    for name, value in SECURITY_HEADERS.items():
        response.headers.setdefault(name, value)
    response.headers["Server"] = SERVER_NAME


async def _send(client: _Client, text: str) -> None:
    if client.ws.closed:
        return
    with contextlib.suppress(ConnectionError, RuntimeError):
        await client.ws.send_str(text)


def _dumps(value: object) -> str:
    return json.dumps(value, separators=(",", ":"), allow_nan=False)


def _finite_only(value: Any) -> Any:
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {key: _finite_only(item) for key, item in value.items()}
    if isinstance(value, list | tuple):
        return [_finite_only(item) for item in value]
    return value


def _presented_token(request: web.Request) -> str | None:
    token = request.query.get("token") or request.headers.get("X-Ctrlbus-Token")
    if token:
        return token
    scheme, _, credentials = request.headers.get("Authorization", "").partition(" ")
    if scheme.lower() == "bearer" and credentials.strip():
        return credentials.strip()
    return None


def _host_name(host_header: str) -> str:
    """'127.0.0.1:8080' -> '127.0.0.1', '[::1]:8080' -> '::1'."""
    if host_header.startswith("["):
        return host_header[1:].partition("]")[0]
    return host_header.rpartition(":")[0] if host_header.count(":") == 1 else host_header


def start_dashboard(source: DashboardSource, options: DashboardOptions) -> DashboardServer:
    """Start a dashboard server for `source` and return it (call `stop()` when done)."""
    server = DashboardServer(source, options)
    server.start()
    return server
