# SPDX-License-Identifier: MIT
"""The Core's side of docs/protocol.md §11 as a state machine over decoded frames.

`CoreProtocol` walks the steps of a connection: CONNECT_BASE until the base answers, the
configuration (GET_BASE_CONF_ADV, falling back to GET_BASE_CONF), SEND_EVENT SYSTEM_UP_OK, then
polling; after a lost connection a best-effort CORE_DISCONNECT and the CONNECT_BASE loop again;
when stopped on purpose a CORE_DISCONNECT and the end. It owns the connection state and its
parts: the request in flight (ctrlbus.core.exchange), the polling schedule
(ctrlbus.core.schedule) and the health list being read (ctrlbus.core.health). It fills in the
telemetry model from the answers and tells the motion control (ctrlbus.core.motion) what the base
reports and asks for. Bytes, the decoder and the public face are ctrlbus.core.session's.
"""

from __future__ import annotations

import enum

from ctrlbus import binconf
from ctrlbus.core.actions import Action
from ctrlbus.core.config import CoreConfig
from ctrlbus.core.events import command_name, describe_request
from ctrlbus.core.exchange import CONFIG_READS, Exchange, Outstanding, Purpose, Verdict
from ctrlbus.core.geometry import (
    SOURCE_CONF,
    SOURCE_CONF_ADV,
    BaseGeometry,
    compare_geometries,
    geometry_from_conf,
    geometry_from_tree,
    shared_bits,
)
from ctrlbus.core.health import HealthReader
from ctrlbus.core.journal import Journal
from ctrlbus.core.motion import MotionControl, action_for_command
from ctrlbus.core.readings import apply_reading
from ctrlbus.core.schedule import PollSchedule
from ctrlbus.core.stats import LinkStats
from ctrlbus.core.telemetry import (
    BLOB_NOT_SUPPORTED,
    BLOB_PENDING,
    BLOB_UNUSABLE,
    BaseIdentity,
    BaseTelemetry,
    ConnectionState,
    HealthError,
)
from ctrlbus.errors import BinaryConfigError
from ctrlbus.frame import Frame
from ctrlbus.messages import (
    AnswerMessage,
    Cmd,
    ConnectBase,
    ConnectBaseAnswer,
    ErrorAnswer,
    ErrorCode,
    Event,
    ExternalCommand,
    GetBaseConf,
    GetBaseConfAdv,
    GetBaseConfAdvAnswer,
    GetBaseConfAnswer,
    GetChargerData,
    HealthGetError,
    HealthGetErrorAnswer,
    HealthGetHealthAnswer,
    PollBaseAnsCmd,
    PollBaseCmdAnswer,
    RequestMessage,
    SendEvent,
)

__all__ = ["CONFIG_RETRY_MAX_S", "PRIMARY_CONF_ATTEMPTS", "CoreProtocol"]

# §11.2 [core-config-retry]: GET_BASE_CONF as the only geometry is asked this many times while
# connecting (each failure in which the base was heard counts toward no disconnect) before the
# Core goes on without a geometry; later asks while polling wait up to this long apart.
PRIMARY_CONF_ATTEMPTS = 64
CONFIG_RETRY_MAX_S = 4.0


class _Step(enum.Enum):
    CONNECT = "connect"
    CONFIG_ADV = "config_adv"
    CONFIG = "config"
    SYSTEM_UP = "system_up"
    POLLING = "polling"
    NOTICE = "notice"
    STOPPED = "stopped"


class CoreProtocol:
    """The connection's steps and state, over frames (sans-IO: times are given)."""

    def __init__(
        self,
        config: CoreConfig,
        stats: LinkStats,
        journal: Journal,
        telemetry: BaseTelemetry,
        motion: MotionControl,
    ) -> None:
        self._config = config
        self._stats = stats
        self._journal = journal
        self._log = journal.log
        self._telemetry = telemetry
        self._motion = motion
        self._exchange = Exchange(config, stats, journal)
        self._schedule = PollSchedule(config.rates)
        self._health = HealthReader(telemetry, stats, journal)
        self._step = _Step.CONNECT
        self._state = ConnectionState.CONNECTING
        self._state_since = 0.0
        self._state_reason: str | None = None
        self._next_connect_at: float | None = None
        self._last_connect_at: float | None = None
        self._connect_attempts = 0  # since the last successful connection
        self._stop_requested = False
        self._last_ctrl_sent: float | None = None
        self._offered_command: int | None = None
        # §11.2 [core-config-retry]: configuration reads to ask again while polling.
        self._later: list[Purpose] = []  # CONFIG_ADV and/or CONFIG, in that order
        self._later_at = 0.0
        self._later_wait_s = config.config_retry_s

    def begin(self, now: float) -> None:
        """The session's first time: the state dates from it, and CONNECT_BASE is due."""
        self._state_since = now
        self._next_connect_at = now

    @property
    def state(self) -> ConnectionState:
        return self._state

    @property
    def state_since(self) -> float:
        return self._state_since

    @property
    def state_reason(self) -> str | None:
        return self._state_reason

    @property
    def stopped(self) -> bool:
        return self._step is _Step.STOPPED

    @property
    def offered_command(self) -> int | None:
        return self._offered_command

    def connected_to_base(self) -> bool:
        return self._state in (ConnectionState.CONNECTED, ConnectionState.CONFIGURING)

    # ============================================================================ requests

    def next_due_time(self) -> float | None:
        """When next_request() may next have something to do; None if only a frame can tell."""
        now = self._journal.now
        due = self._exchange.due_time(now)
        if due is not None:
            return due
        step = self._step
        if step is _Step.STOPPED:
            return None
        if self._stop_requested:
            return now
        if step is _Step.CONNECT:
            return self._next_connect_at if self._next_connect_at is not None else now
        if step is not _Step.POLLING:
            return now
        due = self._schedule.due_time(now, docking=self._motion.docking)
        if self._later:
            return self._later_at if due is None else min(due, self._later_at)
        return due

    def next_request(self, now: float) -> bytes | None:
        """The next request frame to send at `now`, or None."""
        self.expire(now)
        frame = self._choose_request(now)
        sent = self._exchange.outstanding
        if frame is not None and sent is not None and sent.message.CMD == Cmd.CTRL_BUS:
            self._watch_ctrl_gap(now)
        return frame

    def _choose_request(self, now: float) -> bytes | None:
        exchange = self._exchange
        frame = exchange.resume(now, may_flush=self.connected_to_base())
        if frame is not None or exchange.outstanding is not None:
            return frame
        step = self._step
        if step is _Step.STOPPED:
            return None
        if self._stop_requested:
            if self.connected_to_base():
                return exchange.start(SendEvent(Event.CORE_DISCONNECT), Purpose.STOP, now, attempts=1)
            self._finish_stop()
            return None
        if step is _Step.NOTICE:
            return exchange.start(SendEvent(Event.CORE_DISCONNECT), Purpose.NOTICE, now, attempts=1)
        if step is _Step.CONNECT:
            return self._connect_request(now)
        if step is _Step.CONFIG_ADV:
            return exchange.start(
                GetBaseConfAdv(), Purpose.CONFIG_ADV, now, attempts=self._config.config_attempts
            )
        if step is _Step.CONFIG:
            # As the only geometry it is asked until answered (while the base is heard); as the
            # second view, beside a blob, as often as the blob.
            attempts = self._config.config_attempts if self._telemetry.configured else PRIMARY_CONF_ATTEMPTS
            return exchange.start(GetBaseConf(), Purpose.CONFIG, now, attempts=attempts)
        if step is _Step.SYSTEM_UP:
            return exchange.start(SendEvent(Event.SYSTEM_UP_OK), Purpose.SYSTEM_UP, now)
        if self._later and now >= self._later_at:
            later = GetBaseConfAdv() if self._later[0] is Purpose.CONFIG_ADV else GetBaseConf()
            return exchange.start(later, Purpose.CONFIG_LATER, now, attempts=1, quiet=True)
        # Polling: follow-ups first (POLL_BASE_ANS_CMD, HEALTH_GET_ERROR), then the schedule.
        due = self._schedule.take_due(now, docking=self._motion.docking)
        if due is None:
            return None
        name, message = due
        if message is None:
            message = self._motion.velocity_request(now)
        return exchange.start(message, Purpose.POLL, now, schedule_name=name)

    def _connect_request(self, now: float) -> bytes | None:
        if self._next_connect_at is not None and now < self._next_connect_at:
            return None
        self._last_connect_at = now
        self._connect_attempts += 1
        self._stats.connect_attempts += 1
        attempt = self._connect_attempts
        # The first attempt is logged as the request it is; then the second and third with their
        # count, and every tenth: a base that is off must not flood the log.
        if attempt > 1 and (attempt <= 3 or attempt % 10 == 0):
            self._log("core", f"CONNECT_BASE v1 (attempt {attempt}, no answer yet)")
        return self._exchange.start(ConnectBase(1), Purpose.CONNECT, now, attempts=1, quiet=attempt > 1)

    def _watch_ctrl_gap(self, now: float) -> None:
        """A CTRL_BUS request went out at `now`: a connected base's watchdog tripped if the last
        one is more than watchdog_s ago."""
        if self._state is not ConnectionState.CONNECTED:
            return
        last = self._last_ctrl_sent
        if last is not None and now - last > self._config.watchdog_s:
            self._stats.watchdog_trips += 1
            self._log("core", f"no CTRL_BUS request for {now - last:.2f} s: the base's watchdog tripped")
        self._last_ctrl_sent = now

    # ============================================================= timeouts, failures, the end

    def expire(self, now: float) -> None:
        """Time out the request in flight if its deadline has passed."""
        outstanding = self._exchange.expired(now)
        if outstanding is None:
            return
        purpose = outstanding.purpose
        if purpose is Purpose.FLUSH:
            self._end_flush(now)
            return
        if purpose is Purpose.CONNECT:
            self._exchange.drop()
            if self._config.flush_sync:
                self._exchange.prepare_flush()
            else:
                self._schedule_next_connect(now)
            return
        if outstanding.transport_error is not None:
            self._failed_attempt(outstanding, outstanding.transport_error, now, silent=False)
            return
        self._stats.timeouts += 1
        if purpose in CONFIG_READS and (outstanding.damaged or outstanding.heard):
            # The base answered, but nothing intact came of it: a damaged answer, not silence.
            self._stats.damaged_config_answers += 1
            what = f"answer to {describe_request(outstanding.message)} arrived damaged"
            self._failed_attempt(outstanding, what, now, silent=False)
            return
        self._failed_attempt(
            outstanding, f"no answer to {describe_request(outstanding.message)}", now, silent=True
        )

    def _end_flush(self, now: float) -> None:
        """The flushing SYNC's window is over: go on with the held request, or the connect loop."""
        connecting = self._step is _Step.CONNECT
        self._exchange.end_flush(resume_held=not connecting)
        if connecting:
            self._schedule_next_connect(now)

    def _failed_attempt(self, outstanding: Outstanding, reason: str, now: float, *, silent: bool) -> None:
        """An attempt failed (Exchange.fail says how that is counted): act on what it comes to."""
        period_due = self._schedule.period_due(outstanding.schedule_name, now)
        verdict = self._exchange.fail(outstanding, reason, silent=silent, period_due=period_due)
        if verdict is Verdict.DISCONNECTED:
            self._drop_connection(reason, now, notify_base=True)
        if verdict is not Verdict.GIVEN_UP:
            return
        purpose = outstanding.purpose
        if purpose is Purpose.STOP or self._stop_requested:
            self._finish_stop()
        elif purpose is Purpose.NOTICE:
            self._enter_connect_loop(now)
        elif purpose is Purpose.CONNECT:
            self._schedule_next_connect(now)
        elif purpose in CONFIG_READS:
            self._stats.superseded += 1  # its fallback, or its next ask while polling, replaces it
            self._config_read_given_up(outstanding, reason, now)
        else:
            # A request that matters given up while the base still counts as connected.
            self._stats.lost_requests += 1
            self._log("core", f"{reason}: {describe_request(outstanding.message)} given up (lost)")

    def request_stop(self) -> None:
        """Stop on purpose (see CoreSession.request_stop); nothing if already stopping."""
        if self._step is _Step.STOPPED or self._stop_requested:
            return
        self._stop_requested = True
        self._motion.halt("the Core is stopping")
        if not self.connected_to_base():
            self._finish_stop()

    def link_failed(self, reason: str, now: float) -> None:
        """The link cannot be read or written: the connection is gone."""
        self._exchange.abandon()
        if self._step is _Step.STOPPED:
            pass
        elif self._stop_requested:
            self._finish_stop()
        elif self._state is not ConnectionState.DISCONNECTED or self._state_reason != reason:
            self._log("core", f"link failed: {reason}")
            self._drop_connection(reason, now, notify_base=False)

    def _drop_connection(self, reason: str, now: float, *, notify_base: bool) -> None:
        self._exchange.abandon()
        self._exchange.forget_streaks()
        self._set_state(ConnectionState.DISCONNECTED, now, reason)
        self._motion.halt("cancelled: the base is disconnected")
        self._schedule.forget_follow_ups()
        self._health.forget()
        self._last_ctrl_sent = None
        self._telemetry.configured = False
        self._later = []
        if notify_base:
            self._step = _Step.NOTICE
        else:
            self._enter_connect_loop(now)

    def _enter_connect_loop(self, now: float) -> None:
        self._step = _Step.CONNECT
        self._next_connect_at = now

    def _schedule_next_connect(self, now: float) -> None:
        """§11.1: CONNECT_BASE every connect_interval_s, and never before `now`."""
        last = self._last_connect_at if self._last_connect_at is not None else now
        self._next_connect_at = max(now, last + self._config.connect_interval_s)

    def _finish_stop(self) -> None:
        self._exchange.abandon()
        self._step = _Step.STOPPED
        self._set_state(ConnectionState.DISCONNECTED, self._journal.now, "stopped")
        self._log("core", "stopped")

    def _set_state(self, state: ConnectionState, now: float, reason: str | None = None) -> None:
        if state is not self._state:
            self._state = state
            self._state_since = now
            self._journal.changed("connection")
        self._state_reason = reason

    # ============================================================================== answers

    def heard(self, now: float, *, rejected: bool) -> None:
        """Bytes from the base arrived at `now`, after their frames were handled; `rejected`: the
        decoder threw one away among them."""
        self._exchange.on_bytes(now, rejected=rejected)

    def on_frame(self, frame: Frame, now: float) -> None:
        """A frame from the base at `now`."""
        reply = self._exchange.on_frame(frame, now, connecting=self._step is _Step.CONNECT)
        if reply is None:
            return
        if reply.answer is None:
            self._failed_attempt(reply.request, reply.failed, now, silent=False)
        else:
            self._on_answer(reply.request, reply.answer, now)

    def _on_answer(self, outstanding: Outstanding, answer: AnswerMessage, now: float) -> None:
        purpose = outstanding.purpose
        if purpose is Purpose.CONNECT:
            if isinstance(answer, ConnectBaseAnswer):
                self._on_connected(answer, now)
            else:
                self._schedule_next_connect(now)
        elif purpose is Purpose.CONFIG_ADV:
            self._on_config_adv(answer)
        elif purpose is Purpose.CONFIG:
            if isinstance(answer, GetBaseConfAnswer) and self._telemetry.configured:
                self._note_second_view(geometry_from_conf(answer))  # asked besides a usable blob
            elif isinstance(answer, GetBaseConfAnswer):
                self._use_geometry(geometry_from_conf(answer))
            elif self._telemetry.configured:
                pass  # no GET_BASE_CONF besides the blob: only one view
            else:
                self._log("core", "no configuration from the base: going on without its geometry")
                self._use_geometry(None)
            self._step = _Step.SYSTEM_UP
        elif purpose is Purpose.CONFIG_LATER:
            self._on_config_later(answer, now)
        elif purpose is Purpose.SYSTEM_UP:
            self._on_system_up(now)
        elif purpose is Purpose.NOTICE:
            self._enter_connect_loop(now)
        elif purpose is Purpose.STOP:
            self._finish_stop()
        elif purpose is Purpose.POLL:
            self._on_poll_answer(outstanding.message, answer, now)

    def _on_connected(self, answer: ConnectBaseAnswer, now: float) -> None:
        identity = BaseIdentity.from_answer(answer)
        self._telemetry.identity = identity
        self._stats.connects += 1
        self._connect_attempts = 0
        suffix = f" {identity.firmware_version_suffix}" if identity.firmware_version_suffix else ""
        self._log(
            "base",
            f"CONNECT_BASE answered: {identity.model!r}, firmware {identity.firmware_version}{suffix}, "
            f"hardware {identity.hardware_version}, serial {identity.serial}",
        )
        self._set_state(ConnectionState.CONFIGURING, now)
        self._step = _Step.CONFIG_ADV
        self._journal.changed("base")

    def _on_config_adv(self, answer: AnswerMessage) -> None:
        if isinstance(answer, GetBaseConfAdvAnswer):
            try:
                tree = binconf.decode(answer.blob)
            except BinaryConfigError as exc:
                self._log("core", f"binary configuration does not decode ({exc}): asking GET_BASE_CONF")
                self._telemetry.blob_status = BLOB_UNUSABLE
                self._step = _Step.CONFIG
                return
            geometry = geometry_from_tree(tree)
            if geometry is None:
                self._log("core", "binary configuration has no `base` object: asking GET_BASE_CONF")
                self._telemetry.blob_status = BLOB_UNUSABLE
                self._step = _Step.CONFIG
                return
            self._log("base", f"binary configuration: {len(answer.blob)} bytes")
            self._use_geometry(geometry)
            self._step = _Step.CONFIG if self._config.read_both_configs else _Step.SYSTEM_UP
            return
        self._step = _Step.CONFIG  # ERROR 0x8000 (no blob), or any other refusal
        self._note_refused_blob(answer)

    def _note_refused_blob(self, answer: AnswerMessage) -> None:
        """An ERROR to GET_BASE_CONF_ADV: 0x8000 is the base saying it has no blob, an expected
        fallback that the telemetry shows apart from errors; other codes are refusals."""
        if isinstance(answer, ErrorAnswer) and answer.error_code == ErrorCode.UNSUPPORTED:
            self._telemetry.blob_status = BLOB_NOT_SUPPORTED
            self._log(
                "core", "the base serves no binary configuration (0x21 not supported): using GET_BASE_CONF"
            )
        else:
            self._telemetry.blob_status = BLOB_UNUSABLE
        self._journal.changed("base")

    def _config_read_given_up(self, outstanding: Outstanding, reason: str, now: float) -> None:
        """A configuration read used its attempts: fall back or go on, and ask again later."""
        purpose = outstanding.purpose
        is_blob = isinstance(outstanding.message, GetBaseConfAdv)
        wanted = Purpose.CONFIG_ADV if is_blob else Purpose.CONFIG
        if purpose is Purpose.CONFIG_LATER:
            self._later_wait_s = min(CONFIG_RETRY_MAX_S, self._later_wait_s * 2)
            self._later_at = now + self._later_wait_s
            return
        if wanted not in self._later:
            self._later.append(wanted)
            self._later.sort(key=lambda item: item is not Purpose.CONFIG_ADV)
        self._later_wait_s = self._config.config_retry_s
        self._later_at = now + self._later_wait_s
        if is_blob:
            self._telemetry.blob_status = BLOB_PENDING
            self._log(
                "core", f"{reason}: going on with GET_BASE_CONF, asking for the blob again while polling"
            )
            self._step = _Step.CONFIG
        else:
            if not self._telemetry.configured:
                self._log(
                    "core", f"{reason}: going on without the base's geometry, asking again while polling"
                )
                self._use_geometry(None)
            else:
                self._log("core", f"{reason}: asking again while polling")
            self._step = _Step.SYSTEM_UP
        self._journal.changed("base")

    def _on_config_later(self, answer: AnswerMessage, now: float) -> None:
        """The answer to a configuration read asked again while polling."""
        wanted = self._later.pop(0) if self._later else None
        self._later_wait_s = self._config.config_retry_s
        self._later_at = now + self._later_wait_s
        if wanted is Purpose.CONFIG_ADV:
            if not isinstance(answer, GetBaseConfAdvAnswer):
                self._note_refused_blob(answer)
                return
            try:
                geometry = geometry_from_tree(binconf.decode(answer.blob))
            except BinaryConfigError as exc:
                geometry = None
                self._log("core", f"binary configuration does not decode ({exc})")
            if geometry is None:
                self._telemetry.blob_status = BLOB_UNUSABLE
                self._journal.changed("base")
                return
            self._log("base", f"binary configuration: {len(answer.blob)} bytes (asked again): using it")
            conf = self._telemetry.views.get(SOURCE_CONF)
            self._use_geometry(geometry)
            if conf is not None:
                self._note_second_view(conf)
            return
        if isinstance(answer, GetBaseConfAnswer):
            conf_geometry = geometry_from_conf(answer)
            if self._telemetry.geometry is None:
                self._use_geometry(conf_geometry)
            else:
                self._note_second_view(conf_geometry)

    def _note_second_view(self, conf: BaseGeometry) -> None:
        self._telemetry.views[conf.source] = conf
        adv = self._telemetry.views.get(SOURCE_CONF_ADV)
        if adv is not None:
            for problem in compare_geometries(adv, conf):
                self._log("core", f"the two configurations disagree: {problem}")
        self._journal.changed("base")

    def _use_geometry(self, geometry: BaseGeometry | None) -> None:
        shared = () if geometry is None else shared_bits(geometry)
        if shared:
            bits = ", ".join(map(str, shared))
            self._log(
                "core",
                f"the configuration gives a bumper and a cliff sensor the same bit ({bits}): a cliff's "
                "id is its bitmap bit (protocol §5.7: the reference's cliffs are 2-5)",
            )
        self._telemetry.use_geometry(geometry)
        self._journal.changed("base")

    def _on_system_up(self, now: float) -> None:
        self._step = _Step.POLLING
        self._schedule.restart()
        self._last_ctrl_sent = now
        self._set_state(ConnectionState.CONNECTED, now)
        self._log("core", "polling")

    def _on_poll_answer(self, request: RequestMessage, answer: AnswerMessage, now: float) -> None:
        action = self._motion.action
        if isinstance(answer, ErrorAnswer):
            if isinstance(request, GetChargerData) and action is not None:
                action.on_charger_error(f"ERROR 0x{answer.error_code:04X}")
                self._motion.check()
            elif isinstance(request, HealthGetError):
                self._health.on_error(request.index, None)
            elif isinstance(request, PollBaseAnsCmd):
                self._log("core", "the base refused POLL_BASE_ANS_CMD: the command stays pending")
            return
        topics = apply_reading(self._telemetry, action, answer, now)
        if topics:
            self._journal.changed(*topics)
        elif isinstance(answer, PollBaseCmdAnswer):
            if answer.command is not None:
                self._offered_command = answer.command
                self._log("base", f"base offers {command_name(answer.command)} (0x{answer.command:02X})")
                self._schedule.follow_up(PollBaseAnsCmd(), first=True)
        elif isinstance(answer, HealthGetHealthAnswer):
            self._schedule.follow_up(*self._health.on_health(answer))
        elif isinstance(answer, HealthGetErrorAnswer) and isinstance(request, HealthGetError):
            self._health.on_error(request.index, HealthError(answer.error_code, answer.message))
        elif isinstance(request, PollBaseAnsCmd) and self._offered_command is not None:
            self._act_on(self._offered_command)
        self._motion.check()

    # ============================================================================== actions

    def start_action(self, action: Action, why: str) -> None:
        """Start `action` (refused while the stop is latched or the base is not connected)."""
        started = self._motion.start(action, why, connected=self._state is ConnectionState.CONNECTED)
        if started and self._motion.docking:
            self._schedule.hurry("status")  # polled faster while docking: from now on

    def _act_on(self, code: int) -> None:
        """What the Core does with an external command it has acknowledged (§11.5)."""
        name = command_name(code)
        if code == ExternalCommand.CANCEL_ACTION:
            self._motion.halt("cancelled by CANCEL_ACTION")
            self._journal.changed("command")
            return
        action = action_for_command(code, self._config)
        if action is None:
            self._log("core", f"{name} (0x{code:02X}) noted; the Core emulator has nothing to do for it")
            return
        self.start_action(action, f"external command {name}")
