# SPDX-License-Identifier: MIT
"""The topics on their schedule: which messages are due when, handed to the sinks.

`TopicPump` knows the rates (odometry and tf together, ranges, the bumper cloud, battery,
diagnostics; /tf_static whenever the geometry is new) and, when something is due, asks the
caller's BaseState once and hands each message to every sink: the DDS writers
(ctrlbus.ros2.bridge) and the rosbag2 writer (ctrlbus.ros2.rosbag). Time is passed in: the live
bridge passes its clock, a capture's conversion the capture's times.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Protocol

from cyclonedds.idl import IdlStruct

from ctrlbus.errors import UsageError
from ctrlbus.ros2.dds import QosKind
from ctrlbus.ros2.topics import (
    BaseState,
    BridgeCounters,
    MessageMaker,
    TopicNames,
    absolute_name,
    topic_table,
)

__all__ = ["Rates", "Sink", "TopicPump"]


@dataclass(frozen=True)
class Rates:
    """Publishing rates in Hz (0 = off)."""

    odom: float = 20.0  # odom and tf
    range: float = 10.0
    bumper: float = 10.0
    battery: float = 1.0
    diagnostics: float = 1.0

    @classmethod
    def parse(cls, text: str) -> Rates:
        """`odom=50,range=5` (the --rates option); UsageError naming a bad entry."""
        values: dict[str, float] = {}
        for item in filter(None, (part.strip() for part in text.split(","))):
            name, _, number = item.partition("=")
            if name not in cls.__dataclass_fields__:
                raise UsageError(
                    f"--rates: unknown topic {name!r} (names: {', '.join(cls.__dataclass_fields__)})"
                )
            try:
                hz = float(number)
            except ValueError:
                raise UsageError(f"--rates: {item!r} is not NAME=HZ") from None
            if not (math.isfinite(hz) and 0 <= hz <= 1000):
                raise UsageError(f"--rates: {name} wants 0..1000 Hz, got {number}")
            values[name] = hz
        return cls(**values)


class Sink(Protocol):
    def publish(self, ros_name: str, message: IdlStruct, qos: QosKind, stamp_ns: int) -> None:
        """Send or store one message of the topic `ros_name` (absolute)."""


class TopicPump:
    """Publishes what is due (see the module)."""

    def __init__(
        self,
        maker: MessageMaker,
        rates: Rates,
        sinks: Sequence[Sink],
        *,
        names: TopicNames | None = None,
        namespace: str = "",
    ) -> None:
        self.maker = maker
        self.rates = rates
        self.sinks = list(sinks)
        self.names = names if names is not None else TopicNames()
        self.namespace = namespace
        self._periods = {
            key: 1.0 / hz
            for key, hz in (
                ("odom", rates.odom),
                ("range", rates.range),
                ("bumper", rates.bumper),
                ("battery", rates.battery),
                ("diagnostics", rates.diagnostics),
            )
            if hz > 0
        }
        self._next: dict[str, float] = {}
        self._static_geometry: object = None
        self._tables: dict[tuple[int, ...], dict[str, tuple[str, type[IdlStruct], QosKind]]] = {}
        self.published = 0

    def topics(self, sensor_slots: tuple[int, ...] = ()) -> dict[str, tuple[str, type[IdlStruct], QosKind]]:
        """key -> (absolute ROS 2 name, type, QoS); made once per set of sensor slots."""
        table = self._tables.get(sensor_slots)
        if table is None:
            made = topic_table(self.names, self.maker.distro, sensor_slots)
            table = {
                key: (absolute_name(name, self.namespace), kind, qos)
                for key, (name, kind, qos) in made.items()
            }
            self._tables[sensor_slots] = table
        return table

    def next_due(self, now: float) -> float:
        """When something is next due (now, before the first run)."""
        if not self._next:
            return now
        return min(self._next.values())

    def run(self, now: float, read_state: Callable[[], BaseState], counters: BridgeCounters) -> int:
        """Publish what is due at `now`; returns how many messages went out."""
        due = [key for key in self._periods if self._next.get(key, now) <= now]
        if not due:
            return 0
        for key in due:
            period = self._periods[key]
            following = self._next.get(key, now) + period
            self._next[key] = following if following > now else now + period  # late: no burst
        state = read_state()
        slots = () if state.geometry is None else tuple(sensor.slot for sensor in state.geometry.sensors)
        table = self.topics(slots)
        sent = 0

        def send(key: str, message: IdlStruct) -> None:
            nonlocal sent
            name, _, qos = table[key]
            stamp_ns = round(state.stamp_s * 1e9)
            for sink in self.sinks:
                sink.publish(name, message, qos, stamp_ns)
            sent += 1

        if state.geometry is not None and state.geometry is not self._static_geometry:
            self._static_geometry = state.geometry
            send("tf_static", self.maker.static_transforms(state.geometry, state.stamp_s))
        if "odom" in due:
            odometry, tf = self.maker.odometry(state)
            send("odom", odometry)
            send("tf", tf)
        if "range" in due:
            for slot, message in self.maker.ranges_of(state):
                send(f"range_{slot}", message)
        if "bumper" in due and state.geometry is not None:
            send("bumper_cloud", self.maker.bumper_cloud(state))
        if "battery" in due:
            send("battery_state", self.maker.battery(state))
        if "diagnostics" in due:
            send("diagnostics", self.maker.diagnostics(state, counters))
        self.published += sent
        return sent
