# SPDX-License-Identifier: MIT
"""The Core emulator's session on ROS 2 topics over DDS (docs/ros2.md).

`Ros2Bridge` sits beside a `CoreRunner` (which drives the session and owns its lock): a thread
publishes the topics on their schedule (ctrlbus.ros2.pump), and DDS listeners turn the commands
(cmd_vel, dock, undock, reset_odometry, emergency_stop) into the session's controls at once,
under the runner's lock. The command watchdog stops the wheels when no cmd_vel has come for
`cmd_vel_timeout_s`; if the bridge itself dies the Core stops polling and the base's own motor
watchdog stops them.

A cmd_vel is checked before it reaches the base: NaN or Inf in any used field, or a speed more than
ABSURD_FACTOR times the base's limit, is dropped (never sent; counted in diagnostics); a speed
beyond the limit is clamped (counted). Only linear.x and angular.z mean something to a
differential-drive base; the other fields are ignored.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.core import Listener
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ctrlbus.core.runner import CoreRunner
from ctrlbus.core.session import CoreSession
from ctrlbus.ros2 import msgs
from ctrlbus.ros2.dds import DEFAULT_QOS, QosKind, dds_topic_name, qos_for
from ctrlbus.ros2.pump import Rates, Sink, TopicPump
from ctrlbus.ros2.topics import BaseState, BridgeCounters, MessageMaker, TopicNames, absolute_name

__all__ = ["ABSURD_FACTOR", "BridgeOptions", "DdsSink", "Ros2Bridge", "session_state"]

log = logging.getLogger("ctrlbus.ros2")

ABSURD_FACTOR = 10.0  # a cmd_vel this many times over the limit is a broken planner: dropped
DEFAULT_CMD_VEL_TIMEOUT_S = 0.5
MAX_WAIT_S = 0.5  # the publishing thread wakes at least this often (to see stop())


@dataclass(frozen=True)
class BridgeOptions:
    namespace: str = ""
    distro: str = "jazzy"
    stamped: bool = False  # cmd_vel is geometry_msgs/TwistStamped
    cmd_vel_timeout_s: float = DEFAULT_CMD_VEL_TIMEOUT_S
    rates: Rates = field(default_factory=Rates)
    names: TopicNames = field(default_factory=TopicNames)
    maker: MessageMaker = field(default_factory=MessageMaker)


def session_state(session: CoreSession, stamp_s: float) -> BaseState:
    """One moment of the session (call it under the runner's lock)."""
    telemetry = session.telemetry
    identity = session.identity
    return BaseState(
        stamp_s=stamp_s,
        connected=session.connected,
        pose=telemetry.pose,
        geometry=telemetry.geometry,
        battery_percent=telemetry.battery_percent,
        charging=telemetry.charging,
        dc_connected=telemetry.dc_connected,
        on_dock=telemetry.on_dock,
        bumper_bitmap=telemetry.bumper_bitmap,
        bumpers_pressed=telemetry.bumpers_pressed,
        cliffs_triggered=telemetry.cliffs_triggered,
        distances_mm=telemetry.distances_mm,
        health=telemetry.health,
        command=session.command,
        serial="" if identity is None else identity.serial,
        link=session.link_stats(),
    )


class DdsSink:
    """Publishes on DDS: one Topic and DataWriter per ROS 2 topic, made on first use."""

    def __init__(self, participant: DomainParticipant) -> None:
        self.participant = participant
        self._writers: dict[str, DataWriter[Any]] = {}

    def writer(self, ros_name: str, message_type: type[IdlStruct], qos: QosKind) -> DataWriter[Any]:
        writer = self._writers.get(ros_name)
        if writer is None:
            topic = Topic(self.participant, dds_topic_name(ros_name), message_type, qos=qos_for(qos))
            writer = DataWriter(self.participant, topic, qos=qos_for(qos))
            self._writers[ros_name] = writer
        return writer

    def publish(self, ros_name: str, message: IdlStruct, qos: QosKind, stamp_ns: int) -> None:
        self.writer(ros_name, type(message), qos).write(message)


class Ros2Bridge:
    """A runner's session on ROS 2 topics (see the module). `start()`, then `stop()`."""

    def __init__(
        self,
        runner: CoreRunner,
        options: BridgeOptions | None = None,
        *,
        domain_id: int = 0,
        dds_config: str | None = None,
        extra_sinks: Sequence[Sink] = (),
        clock: Callable[[], float] = time.time,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.runner = runner
        self.session = runner.session
        self.options = options if options is not None else BridgeOptions()
        self.counters = BridgeCounters()
        self._clock = clock
        self._monotonic = monotonic
        # A configuration given here wins over CYCLONEDDS_URI; it must exist before the participant.
        self._domain = Domain(domain_id, dds_config) if dds_config is not None else None
        self.participant = DomainParticipant(domain_id)
        self.dds = DdsSink(self.participant)
        self.pump = TopicPump(
            self.options.maker,
            self.options.rates,
            [self.dds, *extra_sinks],
            names=self.options.names,
            namespace=self.options.namespace,
        )
        self._wake = threading.Event()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._last_cmd_vel: float | None = None  # monotonic time of the last applied cmd_vel
        self._readers: list[DataReader[Any]] = []
        self.failure: str | None = None

    # ------------------------------------------------------------------------------ lifecycle

    def start(self) -> None:
        self._subscribe()
        self._thread = threading.Thread(target=self._run, name="ctrlbus-ros2", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._wake.set()
        if self._thread is not None:
            self._thread.join(2.0)
        for reader in self._readers:
            reader.set_listener(None)

    def _subscribe(self) -> None:
        options = self.options
        names = options.names

        def reader(ros_name: str, kind: type[IdlStruct], on_data: Callable[[Any], None]) -> None:
            name = absolute_name(ros_name, options.namespace)
            topic = Topic(self.participant, dds_topic_name(name), kind, qos=qos_for(DEFAULT_QOS))

            def on_data_available(data_reader: DataReader[Any]) -> None:
                try:
                    for sample in data_reader.take(N=100):
                        if isinstance(sample, kind):  # not a writer's dispose or unregister
                            on_data(sample)
                except Exception:  # a bad sample must not kill DDS's listener thread
                    log.exception("the ros2 bridge failed on a %s message", ros_name)

            listener = Listener(on_data_available=on_data_available)  # type: ignore[no-untyped-call]
            self._readers.append(
                DataReader(self.participant, topic, qos=qos_for(DEFAULT_QOS), listener=listener)
            )

        if options.stamped:
            reader(names.cmd_vel, msgs.TwistStamped, lambda sample: self.on_cmd_vel(sample.twist))
        else:
            reader(names.cmd_vel, msgs.Twist, self.on_cmd_vel)
        reader(names.dock, msgs.Empty, lambda _: self.on_dock())
        reader(names.undock, msgs.Empty, lambda _: self.on_undock())
        reader(names.reset_odometry, msgs.Empty, lambda _: self.on_reset_odometry())
        reader(names.emergency_stop, msgs.Bool, lambda sample: self.on_emergency_stop(bool(sample.data)))

    # ------------------------------------------------------------------------------- commands

    def on_cmd_vel(self, twist: msgs.Twist) -> None:
        """A cmd_vel: checked, clamped, applied at once (the next SET_V carries it)."""
        counters = self.counters
        counters.cmd_vel_received += 1
        vx, omega = float(twist.linear.x), float(twist.angular.z)
        if not (math.isfinite(vx) and math.isfinite(omega)):
            counters.cmd_vel_dropped_nonfinite += 1
            return
        with self.runner.lock:
            max_vx, max_omega = self.session.limits()
            if max_vx <= 0 or not self.session.connected:
                counters.cmd_vel_not_ready += 1
                return
            if abs(vx) > ABSURD_FACTOR * max_vx or abs(omega) > ABSURD_FACTOR * max_omega:
                counters.cmd_vel_dropped_absurd += 1
                return
            if abs(vx) > max_vx or abs(omega) > max_omega:
                counters.cmd_vel_clamped += 1
            self.session.set_velocity(vx, omega)  # clamps to the limits
            counters.cmd_vel_applied += 1
            self._last_cmd_vel = self._monotonic()
        self._wake.set()  # the watchdog's deadline moved

    def on_dock(self) -> None:
        self.counters.dock_requests += 1
        with self.runner.lock:
            self.session.go_home()

    def on_undock(self) -> None:
        self.counters.undock_requests += 1
        with self.runner.lock:
            self.session.cancel_action()

    def on_reset_odometry(self) -> None:
        self.counters.odometry_resets += 1
        with self.runner.lock:
            self.options.maker.reset_odometry(self.session.pose)

    def on_emergency_stop(self, latch: bool) -> None:
        self.counters.estop_requests += 1
        with self.runner.lock:
            if latch:
                self.session.emergency_stop()
            else:
                self.session.release_stop()

    def _watchdog(self, now: float) -> float | None:
        """Stop the wheels if cmd_vel went quiet; returns when to look again (None: nothing to watch)."""
        last = self._last_cmd_vel
        if last is None:
            return None
        deadline = last + self.options.cmd_vel_timeout_s
        if now < deadline:
            return deadline
        with self.runner.lock:
            command = self.session.command
            # Only a teleop command is cmd_vel's: an action (docking) runs on its own.
            if command.mode == "teleop" and (command.vx_mps or command.omega_radps):
                self.session.set_velocity(0.0, 0.0)
                self.counters.watchdog_stops += 1
            self._last_cmd_vel = None
        return None

    # ---------------------------------------------------------------------------- publishing

    def state(self) -> BaseState:
        with self.runner.lock:
            return session_state(self.session, self._clock())

    def _run(self) -> None:
        try:
            while not self._stop.is_set():
                now = self._monotonic()
                watch = self._watchdog(now)
                self.pump.run(now, self.state, self.counters)
                wake = self.pump.next_due(now)
                if watch is not None:
                    wake = min(wake, watch)
                self._wake.wait(max(0.0, min(MAX_WAIT_S, wake - self._monotonic())))
                self._wake.clear()
        except Exception as exc:  # report it rather than die silently
            self.failure = f"{type(exc).__name__}: {exc}"
            log.exception("the ros2 bridge failed")
