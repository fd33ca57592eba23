# SPDX-License-Identifier: MIT
"""Helpers for the ROS 2 bridge's tests: DDS kept on loopback, the simulated base, the bridge as
a process, and a stand-in ROS 2 node written with Cyclone DDS directly.

Every participant here and in the bridge processes gets the loopback-only configuration (lo, no
multicast, the one peer 127.0.0.1): CYCLONEDDS_URI is set when this module is imported, before
any participant exists, and inherited by the processes; each test uses its own domain id.

Not a test module itself; the test_ros2_*.py modules import it, and import the third-party names
they need from here (the ros2 extra, mcap_ros2): without them those modules are not collected
under `-m "not external"` (conftest.py) and fail in `make test`, which installs them.
"""

from __future__ import annotations

import fcntl
import math
import os
import sys
import tempfile
import time
from collections.abc import Callable, Iterator
from dataclasses import fields, is_dataclass
from pathlib import Path
from typing import Any, TypeVar

from ctrlbus.ros2.dds import LOOPBACK_CONFIG

os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG  # before any participant exists

from cyclonedds.builtin import BuiltinDataReader, BuiltinTopicDcpsPublication, BuiltinTopicDcpsSubscription
from cyclonedds.core import Listener
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory
from rosbags.interfaces import ConnectionExtRosbag2
from rosbags.rosbag2 import Reader
from rosbags.typesys import Stores, get_typestore

from ctrlbus.ros2 import msgs
from ctrlbus.ros2.dds import DEFAULT_QOS, SENSOR_QOS, STATIC_QOS, TF_QOS, QosKind, dds_config, qos_for
from ctrlbus.sim.server import SimServer, SimSettings
from support.base_harness import Process

# re-exported for the test modules (see above)
__all__ = [
    "BuiltinDataReader",
    "BuiltinTopicDcpsPublication",
    "BuiltinTopicDcpsSubscription",
    "ConnectionExtRosbag2",
    "DecoderFactory",
    "Reader",
    "Stores",
    "get_typestore",
    "make_reader",
]

WAIT_S = 20.0  # generous: discovery and a busy 2-core machine
T = TypeVar("T")
DOMAIN_IDS = 101  # 1..101: their ports stay below Linux's ephemeral range, as ROS 2 advises
_held_domains: list[int] = []  # lock files of the domain ids this process took, open until it ends


def unique_domain() -> int:
    """A DDS domain id no other test process on this machine holds, nor this one before: each id
    is taken with an exclusive lock on a file of its own, held until the process ends, so that
    parallel workers and runs never meet on a domain (a shared one mixes their topics)."""
    start = os.getpid() % DOMAIN_IDS
    for step in range(DOMAIN_IDS):
        domain = 1 + (start + step) % DOMAIN_IDS
        lock = os.open(
            os.path.join(tempfile.gettempdir(), f"ctrlbus-dds-domain-{domain}.lock"),
            os.O_CREAT | os.O_RDWR,
            0o600,
        )
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(lock)
            continue
        _held_domains.append(lock)
        return domain
    raise RuntimeError(f"every DDS domain id 1..{DOMAIN_IDS} is held by other test processes")


def wait_for(what: str, check: Callable[[], T | None], limit_s: float = WAIT_S) -> T:
    """Poll `check` until it gives a true value; fails naming `what` after limit_s."""
    deadline = time.monotonic() + limit_s
    while True:
        value = check()
        if value:
            return value
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {limit_s} s")
        time.sleep(0.01)


def start_sim(**settings: Any) -> SimServer:
    return SimServer.open(SimSettings(**settings), listen="127.0.0.1:0").start()


def sim_port(server: SimServer) -> int:
    return int(server.address.rsplit(":", 1)[1])


def start_bridge(port: int, domain: int, workdir: Path, *extra: str) -> Process:
    """`ctrlbus ros2` against the simulated base on `port`; returns once it says it bridges."""
    process = Process(
        [
            sys.executable,
            "-m",
            "ctrlbus",
            "ros2",
            "--port",
            f"socket://127.0.0.1:{port}",
            "--domain",
            str(domain),
            "--loopback",
            *extra,
        ],
        workdir / f"bridge-{domain}.log",
    )
    line = process.read_line(WAIT_S)
    assert line.startswith("ctrlbus ros2: bridging"), process.describe()
    return process


class Node:
    """A stand-in for a ROS 2 node: readers that keep every sample, writers to publish."""

    def __init__(self, domain: int, trace: Path | None = None) -> None:
        config = dds_config(loopback=True, trace=None if trace is None else str(trace), environment_uri=None)
        self._domain = Domain(domain, config)
        self.participant = DomainParticipant(domain)
        self.samples: dict[str, list[Any]] = {}
        self._readers: list[DataReader[Any]] = []
        self._writers: dict[str, DataWriter[Any]] = {}

    def subscribe(self, dds_name: str, kind: type[IdlStruct], qos: QosKind = DEFAULT_QOS) -> list[Any]:
        received: list[Any] = self.samples.setdefault(dds_name, [])

        def on_data(reader: DataReader[Any]) -> None:
            received.extend(sample for sample in reader.take(N=100) if isinstance(sample, kind))

        topic = Topic(self.participant, dds_name, kind, qos=qos_for(qos))
        self._readers.append(
            DataReader(
                self.participant,
                topic,
                qos=qos_for(qos),
                listener=Listener(on_data_available=on_data),  # type: ignore[no-untyped-call]
            )
        )
        return received

    def publish(self, dds_name: str, message: IdlStruct, qos: QosKind = DEFAULT_QOS) -> None:
        writer = self._writers.get(dds_name)
        if writer is None:
            topic = Topic(self.participant, dds_name, type(message), qos=qos_for(qos))
            writer = self._writers[dds_name] = DataWriter(self.participant, topic, qos=qos_for(qos))
            # A sample written before discovery has matched the bridge's reader is lost (volatile
            # durability), so the first publish on a topic waits until discovery has matched it.
            new_writer = writer
            wait_for(f"the bridge's reader of {dds_name}", lambda: new_writer.get_matched_subscriptions())
        writer.write(message)

    def subscribe_all(self, distro: str = "jazzy") -> None:
        """Every topic the bridge publishes with the default names and one sonar slot range."""
        range_type = msgs.RangeJazzy if distro == "jazzy" else msgs.RangeHumble
        self.subscribe("rt/odom", msgs.Odometry)
        self.subscribe("rt/tf", msgs.TFMessage, TF_QOS)
        self.subscribe("rt/tf_static", msgs.TFMessage, STATIC_QOS)
        self.subscribe("rt/battery_state", msgs.BatteryState)
        self.subscribe("rt/range/sensor_0", range_type, SENSOR_QOS)
        self.subscribe("rt/bumper_cloud", msgs.PointCloud2, SENSOR_QOS)
        self.subscribe("rt/diagnostics", msgs.DiagnosticArray)


def twist(vx: float, omega: float) -> msgs.Twist:
    return msgs.Twist(msgs.Vector3(vx, 0.0, 0.0), msgs.Vector3(0.0, 0.0, omega))


def yaw_of(q: msgs.Quaternion) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def diagnostic_values(array: msgs.DiagnosticArray, name: str) -> dict[str, str]:
    for status in array.status:
        if status.name == name:
            return {pair.key: pair.value for pair in status.values}
    raise AssertionError(f"no diagnostic status {name!r} in {[s.name for s in array.status]}")


def same_value(ours: Any, theirs: Any, path: str) -> Iterator[str]:
    """Where `ours` (a ctrlbus.ros2.msgs object) and `theirs` (rosbags' or mcap's) differ, field
    by field; nothing when they are equal. Floats compare exactly (the same bytes), NaN = NaN."""
    if is_dataclass(ours):
        for item in fields(ours):
            yield from same_value(getattr(ours, item.name), getattr(theirs, item.name), f"{path}.{item.name}")
        return
    if isinstance(ours, list):
        their_list = list(theirs)
        if len(ours) != len(their_list):
            yield f"{path}: {len(ours)} items, theirs {len(their_list)}"
            return
        for index, (a, b) in enumerate(zip(ours, their_list, strict=True)):
            yield from same_value(a, b, f"{path}[{index}]")
        return
    if isinstance(ours, float):
        b = float(theirs)
        if not (ours == b or (math.isnan(ours) and math.isnan(b))):
            yield f"{path}: {ours!r} != {b!r}"
        return
    if isinstance(ours, bool) or isinstance(theirs, bool):
        if bool(ours) != bool(theirs):
            yield f"{path}: {ours!r} != {theirs!r}"
        return
    if ours != theirs:
        yield f"{path}: {ours!r} != {theirs!r}"
