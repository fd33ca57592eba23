# SPDX-License-Identifier: MIT
"""Cyclone DDS set-up for the bridge: the ROS 2 names, the QoS a ROS 2 node expects, the
loopback-only configuration that tests and examples use, and the check that the extra is there.

`require_cyclonedds()` is the one place that says the `ros2` extra is missing; everything that
needs cyclonedds calls it before importing it, so `ctrlbus ros2` without the extra is one line and
exit code 2, and the rest of ctrlbus never notices.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING
from xml.sax.saxutils import escape

from ctrlbus.errors import UsageError

if TYPE_CHECKING:
    from cyclonedds.core import Qos

__all__ = [
    "DISTROS",
    "LOOPBACK_CONFIG",
    "MissingExtraError",
    "QosKind",
    "dds_config",
    "dds_topic_name",
    "qos_for",
    "require_cyclonedds",
    "tracing_config",
]

# DDS kept on this machine: only the loopback interface, no multicast, the one peer 127.0.0.1
# (unicast discovery, participant indices so that several processes find each other).
LOOPBACK_CONFIG = (
    '<CycloneDDS><Domain><General><Interfaces><NetworkInterface name="lo"/></Interfaces>'
    '<AllowMulticast>false</AllowMulticast></General><Discovery><Peers><Peer address="127.0.0.1"/>'
    "</Peers><ParticipantIndex>auto</ParticipantIndex><MaxAutoParticipantIndex>60</MaxAutoParticipantIndex>"
    "</Discovery></Domain></CycloneDDS>"
)

DISTROS = ("humble", "jazzy")


def tracing_config(path: str) -> str:
    """A configuration that writes Cyclone's discovery and configuration trace to `path` (it
    names every address a participant sends to: how the tests check that DDS stays on lo)."""
    return (
        "<CycloneDDS><Domain><Tracing><Category>discovery,config</Category>"
        f"<OutputFile>{escape(path)}</OutputFile></Tracing></Domain></CycloneDDS>"
    )


def dds_config(*, loopback: bool, trace: str | None, environment_uri: str | None) -> str | None:
    """The configuration the bridge gives its domain, or None to leave it to CYCLONEDDS_URI.

    `loopback` uses LOOPBACK_CONFIG alone, never merged with CYCLONEDDS_URI: Cyclone merges
    interface lists, so another configuration's interfaces would be added to lo. A trace is
    merged in (it names no interface); without `loopback` it comes after CYCLONEDDS_URI's."""
    base = LOOPBACK_CONFIG if loopback else environment_uri
    if trace is None:
        return base if loopback else None
    return f"{base},{tracing_config(trace)}" if base else tracing_config(trace)


MAX_DOMAIN_ID = 232  # ROS 2's limit (DDS allows up to 232 with the default port mapping)


class MissingExtraError(UsageError):
    """cyclonedds (the `ros2` extra) is not installed."""


def require_cyclonedds(what: str = "ctrlbus ros2") -> None:
    """Raise MissingExtraError naming the extra when cyclonedds cannot be imported."""
    try:
        import cyclonedds  # noqa: F401
    except ImportError:
        raise MissingExtraError(
            f"{what} needs the ros2 extra (Cyclone DDS): pip install 'ctrlbus[ros2]'"
        ) from None


def dds_topic_name(ros_name: str, namespace: str = "") -> str:
    """The DDS topic of a ROS 2 topic: `rt/` + the absolute name (`odom` in `/robot1` is
    `rt/robot1/odom`). UsageError for a name ROS 2 would refuse."""
    parts = [part for part in f"{namespace}/{ros_name}".split("/") if part]
    if not parts:
        raise UsageError(f"empty ROS 2 topic name {ros_name!r}")
    for part in parts:
        if not (part[0].isalpha() or part[0] == "_") or not all(c.isalnum() or c == "_" for c in part):
            raise UsageError(
                f"bad ROS 2 name {ros_name!r} (namespace {namespace!r}): each part is letters, digits "
                "and _, not starting with a digit"
            )
    return "rt/" + "/".join(parts)


def check_domain(domain_id: int) -> int:
    if not 0 <= domain_id <= MAX_DOMAIN_ID:
        raise UsageError(f"--domain wants 0..{MAX_DOMAIN_ID} (ROS_DOMAIN_ID), got {domain_id}")
    return domain_id


@dataclass(frozen=True)
class QosKind:
    """One of the QoS profiles of REP 2003 / rclcpp that the topics use."""

    reliable: bool
    transient_local: bool
    depth: int


# rclcpp's defaults: reliable, volatile, keep last 10; sensor data: best effort, keep last 5;
# /tf_static: reliable, transient local, keep last 1 (tf2_ros StaticTransformBroadcaster).
DEFAULT_QOS = QosKind(reliable=True, transient_local=False, depth=10)
SENSOR_QOS = QosKind(reliable=False, transient_local=False, depth=5)
TF_QOS = QosKind(reliable=True, transient_local=False, depth=100)
STATIC_QOS = QosKind(reliable=True, transient_local=True, depth=1)


def qos_for(kind: QosKind) -> Qos:
    """The cyclonedds Qos of `kind` (needs the extra)."""
    from cyclonedds.core import Policy, Qos
    from cyclonedds.util import duration

    reliability = (
        Policy.Reliability.Reliable(duration(milliseconds=100))
        if kind.reliable
        else Policy.Reliability.BestEffort
    )
    durability = Policy.Durability.TransientLocal if kind.transient_local else Policy.Durability.Volatile
    return Qos(reliability, durability, Policy.History.KeepLast(kind.depth))
