# SPDX-License-Identifier: MIT
"""The Core emulator as a sans-IO session: bytes and time in, request frames out.

`CoreSession` behaves as docs/protocol.md §11 describes: it repeats CONNECT_BASE until the base
answers (with a flushing SYNC after each unanswered attempt), reads the configuration
(GET_BASE_CONF_ADV, falling back to GET_BASE_CONF), sends SEND_EVENT SYSTEM_UP_OK, and then polls
on its schedule, one request outstanding at a time, with timeouts, retries, disconnect detection
and reconnection. It integrates the deadreckon deltas into a pose, acts on the base's external
commands (POLL_BASE_CMD) and runs actions (drive, turn, go home).

It never reads a clock or a port:

    request = session.poll(now)          # the next request frame to send, or None
    session.receive(answer_bytes, now)   # bytes from the link
    session.next_poll_time()             # when poll() may next have something to do

This module is the session's face: the byte stream (its decoder), the controls and the readings.
The work is done by its parts, each owning its own state: the connection's steps
(ctrlbus.core.protocol), the request in flight (ctrlbus.core.exchange), the polling schedule
(ctrlbus.core.schedule), the health list (ctrlbus.core.health), the velocity command and actions
(ctrlbus.core.motion), and the time, event log and change topics (ctrlbus.core.journal).

What it learns about the base is a typed model (`telemetry`, ctrlbus.core.telemetry), what it did
is an event log (ctrlbus.core.events); the dashboard's JSON is made from both in ctrlbus.web.snapshot.
The session holds no lock: it is driven from one thread at a time. A program that drives it from
one thread and reads or commands it from another holds the lock of the runner that owns the
thread (`CoreRunner.lock`) around each call.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

from ctrlbus.core.actions import DriveDistance, TurnAngle
from ctrlbus.core.config import CoreConfig
from ctrlbus.core.docking import GoHome
from ctrlbus.core.events import CoreEvent, describe_request
from ctrlbus.core.exchange import FLUSH_FILLER
from ctrlbus.core.geometry import BaseGeometry
from ctrlbus.core.journal import Journal
from ctrlbus.core.motion import MotionControl
from ctrlbus.core.protocol import CoreProtocol
from ctrlbus.core.stats import LinkStats
from ctrlbus.core.telemetry import (
    BaseIdentity,
    BaseTelemetry,
    CommandState,
    ConnectionState,
    HealthError,
    HealthState,
    LinkTelemetry,
)
from ctrlbus.errors import UsageError
from ctrlbus.frame import EventKind, Frame, StreamDecoder
from ctrlbus.kinematics import Pose

# The session's own names, and the model's that its API returns (kept importable from here).
__all__ = [
    "FLUSH_FILLER",
    "BaseIdentity",
    "CommandState",
    "ConnectionState",
    "CoreEvent",
    "CoreSession",
    "HealthError",
    "HealthState",
    "describe_request",
]


# Decoder rejections that a damaged answer leaves behind (a garbage byte alone does not count).
DAMAGE_KINDS = frozenset({EventKind.CHECKSUM_ERROR, EventKind.OVERSIZE, EventKind.TIMEOUT})


def _check_finite(**values: float) -> None:
    for name, value in values.items():
        if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
            raise UsageError(f"{name} must be a finite number, got {value!r}")


class CoreSession:
    """The Core emulator's protocol state machine (sans-IO, one thread at a time)."""

    def __init__(self, config: CoreConfig | None = None, *, port: str = "") -> None:
        self.config = config if config is not None else CoreConfig()
        self.port = port
        self._decoder = StreamDecoder(max_frame=self.config.max_frame, timeout=self.config.decoder_timeout_s)
        self._stats = LinkStats()
        self._journal = Journal()
        self._telemetry = BaseTelemetry()
        self._motion = MotionControl(self.config, self._journal)
        self._protocol = CoreProtocol(self.config, self._stats, self._journal, self._telemetry, self._motion)

    # ===================================================================== sans-IO interface

    def poll(self, now: float) -> bytes | None:
        """The next request frame to send at time `now` (seconds), or None if nothing is due."""
        self._advance(now)
        # A false frame start can hold a real answer behind it until the line has been idle
        # for the inter-byte timeout; apply it now rather than only when more bytes come.
        if self._decoder.buffered:
            for frame_in in self._decoder.feed(b"", now):
                self._protocol.on_frame(frame_in, now)
        frame = self._protocol.next_request(now)
        self._journal.notify()
        return frame

    def receive(self, data: bytes, now: float) -> None:
        """Bytes read from the link at time `now`."""
        self._advance(now)
        self._protocol.expire(now)
        rejected = False
        for item in self._decoder.feed_items(data, now):
            if isinstance(item, Frame):
                self._protocol.on_frame(item, now)
            elif item.kind in DAMAGE_KINDS:
                rejected = True
        if data:
            self._protocol.heard(now, rejected=rejected)
        self._journal.notify()

    def next_poll_time(self) -> float | None:
        """The earliest time at which poll() may return a frame or time something out, if no
        bytes arrive first; None when only arriving bytes (or a command) can change anything."""
        decoder_due = self._decoder.timeout_due
        due = self._protocol.next_due_time()
        if decoder_due is None:
            return due
        return decoder_due if due is None else min(due, decoder_due)

    def request_stop(self) -> None:
        """Stop on purpose: once the request in flight is settled, send SEND_EVENT CORE_DISCONNECT
        (if connected), then stop. `stopped` tells when it is done."""
        self._protocol.request_stop()
        self._journal.notify()

    @property
    def stopped(self) -> bool:
        return self._protocol.stopped

    def link_failed(self, reason: str, now: float) -> None:
        """The runner could not read or write the link: the connection is gone."""
        self._advance(now)
        self._protocol.link_failed(reason, now)
        self._journal.notify()

    def _advance(self, now: float) -> None:
        if not math.isfinite(now):
            raise UsageError(f"time must be a finite number of seconds, got {now!r}")
        if self._journal.advance(now):
            self._protocol.begin(now)

    # ============================================================================== controls

    def limits(self) -> tuple[float, float]:
        """(max |vx| m/s, max |omega| rad/s): the configured limits once the base's configuration
        is known, (0, 0) before."""
        if not self._telemetry.configured:
            return 0.0, 0.0
        return self.config.max_vx_mps, self.config.max_omega_radps

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        """Command a body velocity (clamped to limits()); cancels a running action; ignored while
        the emergency stop is latched."""
        _check_finite(vx_mps=vx_mps, omega_radps=omega_radps)
        self._motion.set_velocity(vx_mps, omega_radps, self.limits())
        self._journal.notify()

    def emergency_stop(self) -> None:
        """Zero velocity at once, cancel any action, latch until release_stop()."""
        self._motion.emergency_stop()
        self._journal.notify()

    def release_stop(self) -> None:
        """Unlatch the emergency stop; the velocity stays zero until commanded again."""
        self._motion.release_stop()
        self._journal.notify()

    def go_home(self) -> None:
        """Start docking on the charger using its beacons (ignored while the stop is latched)."""
        self._protocol.start_action(GoHome(self.config.docking), "requested")
        self._journal.notify()

    def drive(self, distance_m: float, speed_mps: float | None = None) -> None:
        """Drive straight `distance_m` (negative: backwards), as MOVE_FORWARD/BACKWARD do."""
        speed = self.config.move_speed_mps if speed_mps is None else speed_mps
        _check_finite(distance_m=distance_m, speed_mps=speed)
        if speed <= 0:
            raise UsageError(f"speed_mps must be positive, got {speed!r}")
        action = DriveDistance(distance_m, min(speed, self.config.max_vx_mps))
        self._protocol.start_action(action, "requested")
        self._journal.notify()

    def turn(self, angle_deg: float, rate_radps: float | None = None) -> None:
        """Turn in place by `angle_deg` (positive: left), as TURN_LEFT/RIGHT do."""
        rate = self.config.turn_rate_radps if rate_radps is None else rate_radps
        _check_finite(angle_deg=angle_deg, rate_radps=rate)
        if rate <= 0:
            raise UsageError(f"rate_radps must be positive, got {rate!r}")
        action = TurnAngle(angle_deg, min(rate, self.config.max_omega_radps))
        self._protocol.start_action(action, "requested")
        self._journal.notify()

    def cancel_action(self) -> None:
        """Stop whatever action runs, as CANCEL_ACTION does."""
        self._motion.halt("cancelled")
        self._journal.changed("command")
        self._journal.notify()

    def subscribe(self, callback: Callable[[str], None]) -> Callable[[], None]:
        """Call `callback(topic)` after each change; returns a function that unsubscribes.

        Topics: connection, base, pose, command, battery, motion, bumpers, sensors, charger,
        health, events. Callbacks run in the thread that called poll/receive (or the control),
        under whatever lock that thread holds (a runner's); they must be quick and must not wait
        for another thread. An exception in one is logged and does not reach the session.
        """
        return self._journal.subscribe(callback)

    # ============================================================================= telemetry
    @property
    def state(self) -> ConnectionState:
        return self._protocol.state

    @property
    def connected(self) -> bool:
        return self.state is ConnectionState.CONNECTED

    @property
    def connects(self) -> int:
        """Successful connections so far."""
        return self._stats.connects

    @property
    def time_s(self) -> float:
        """Seconds since the session's first poll/receive."""
        return self._journal.elapsed(self._journal.now)

    @property
    def pose(self) -> Pose:
        """The dead-reckoned pose, in the frame of the robot when the Core started."""
        return self._telemetry.pose

    @property
    def identity(self) -> BaseIdentity | None:
        return self._telemetry.identity

    @property
    def geometry(self) -> BaseGeometry | None:
        return self._telemetry.geometry

    @property
    def battery_percent(self) -> int | None:
        return self._telemetry.battery_percent

    @property
    def power_status(self) -> int | None:
        return self._telemetry.power_status

    @property
    def bumper_bitmap(self) -> int | None:
        return self._telemetry.bumper_bitmap

    @property
    def bumpers_pressed(self) -> tuple[bool, ...]:
        """One flag per configured bumper (the bitmap is active low)."""
        return self._telemetry.bumpers_pressed

    @property
    def distances_mm(self) -> tuple[float, ...] | None:
        """The 16 distances of the last GET_BASE_SENSOR_DATA (None before the first)."""
        return self._telemetry.distances_mm

    @property
    def charger_probes(self) -> tuple[int, ...] | None:
        return self._telemetry.charger_probes

    @property
    def motion_status(self) -> int | None:
        return self._telemetry.motion_status

    @property
    def motor_totals_mm(self) -> tuple[int, int] | None:
        return self._telemetry.motor_totals_mm

    @property
    def health(self) -> HealthState:
        return self._telemetry.health

    @property
    def command(self) -> CommandState:
        return self._motion.state()

    @property
    def last_outcome(self) -> str | None:
        """How the last action ended."""
        return self._motion.last_outcome

    @property
    def offered_command(self) -> int | None:
        """The external command the base offered last (None before any)."""
        return self._protocol.offered_command

    @property
    def telemetry(self) -> BaseTelemetry:
        """The model of the base (ctrlbus.core.telemetry), live: read it, never change it."""
        return self._telemetry

    def events(self, since_seq: int = 0) -> list[CoreEvent]:
        """Logged events with seq > since_seq, oldest first (the last MAX_EVENTS of ctrlbus.core.events)."""
        return self._journal.events(since_seq)

    def link_telemetry(self) -> LinkTelemetry:
        """The connection and the link's counters."""
        journal = self._journal
        since = journal.t0 if journal.t0 is not None else journal.now
        return LinkTelemetry(
            state=self._protocol.state,
            port=self.port,
            since_s=journal.elapsed(self._protocol.state_since),
            reason=self._protocol.state_reason,
            requests_per_s=self._stats.requests_per_s(journal.now, since),
            stats=self._stats,
            decoder=self._decoder.stats,
        )

    def link_stats(self) -> dict[str, Any]:
        """Link statistics as plain values (a superset of the dashboard snapshot's `link` part)."""
        return self.link_telemetry().as_dict()
