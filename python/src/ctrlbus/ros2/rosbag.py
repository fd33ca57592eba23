# SPDX-License-Identifier: MIT
"""rosbag2 recording: the bridge's topics written as a bag (MCAP storage, CDR) that `ros2 bag
play` and Foxglove open.

`RosbagSink` is a sink of ctrlbus.ros2.pump: the same messages the live topics carry, serialized
by the same types (ctrlbus.ros2.msgs), with each topic's QoS in the bag's metadata so that a
player offers /tf_static transient-local again. The bag is a directory (metadata.yaml and one
.mcap file), written by the rosbags library (its rosbag2 format version 8, as Jazzy writes).
"""

from __future__ import annotations

from pathlib import Path
from types import TracebackType

from cyclonedds.idl import IdlStruct
from rosbags.interfaces import (
    Connection,
    Qos,
    QosDurability,
    QosHistory,
    QosLiveliness,
    QosReliability,
    QosTime,
)
from rosbags.rosbag2 import StoragePlugin, Writer, WriterError
from rosbags.typesys import Stores, get_typestore

from ctrlbus.errors import UsageError
from ctrlbus.ros2.dds import QosKind
from ctrlbus.ros2.msgs import ros_type_name

__all__ = ["RosbagSink"]

_NO_TIME = QosTime(0, 0)
_STORES = {"humble": Stores.ROS2_HUMBLE, "jazzy": Stores.ROS2_JAZZY}


def _bag_qos(kind: QosKind) -> Qos:
    return Qos(
        history=QosHistory.KEEP_LAST,
        depth=kind.depth,
        reliability=QosReliability.RELIABLE if kind.reliable else QosReliability.BEST_EFFORT,
        durability=QosDurability.TRANSIENT_LOCAL if kind.transient_local else QosDurability.VOLATILE,
        deadline=_NO_TIME,
        lifespan=_NO_TIME,
        liveliness=QosLiveliness.AUTOMATIC,
        liveliness_lease_duration=_NO_TIME,
        avoid_ros_namespace_conventions=False,
    )


class RosbagSink:
    """Writes every published message into a new rosbag2 directory `path` (MCAP, CDR)."""

    def __init__(self, path: str | Path, *, distro: str = "jazzy") -> None:
        self.path = Path(path)
        self._typestore = get_typestore(_STORES[distro])
        try:
            self._writer = Writer(self.path, version=8, storage_plugin=StoragePlugin.MCAP)
            self._writer.open()
        except (WriterError, OSError) as exc:
            raise UsageError(f"cannot write the rosbag {self.path}: {exc}") from None
        self._connections: dict[str, Connection] = {}
        self.messages = 0

    def publish(self, ros_name: str, message: IdlStruct, qos: QosKind, stamp_ns: int) -> None:
        connection = self._connections.get(ros_name)
        if connection is None:
            connection = self._writer.add_connection(
                ros_name,
                ros_type_name(type(message)),
                typestore=self._typestore,
                offered_qos_profiles=[_bag_qos(qos)],
            )
            self._connections[ros_name] = connection
        self._writer.write(connection, stamp_ns, message.serialize())
        self.messages += 1

    def close(self) -> None:
        self._writer.close()

    def __enter__(self) -> RosbagSink:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
