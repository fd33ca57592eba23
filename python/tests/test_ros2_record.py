# SPDX-License-Identifier: MIT
"""`ctrlbus record --rosbag` and `ctrlbus ros2 --rosbag`: rosbag2 (MCAP, CDR) files, read back by
two readers other than the writer's own types: rosbags (which also wrote the bag's container) and
the mcap library with its ROS 2 support (mcap_ros2: its own CDR decoder, driven by the message
definitions stored in the file). Every message decodes the same in both, field by field, and the
bags hold what the live topics carried.
"""

from __future__ import annotations

import math
from collections import defaultdict
from pathlib import Path
from typing import Any

import pytest
from ros2_support import (
    ConnectionExtRosbag2,
    DecoderFactory,
    Node,
    Reader,
    Stores,
    get_typestore,
    make_reader,
    same_value,
    sim_port,
    start_bridge,
    start_sim,
    twist,
    unique_domain,
    wait_for,
)
from test_capture_replay import _Recorder

from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.cli import main
from ctrlbus.core import ConnectionState, CoreSession
from ctrlbus.ros2 import msgs
from ctrlbus.sim.server import SimSettings, build_simulated_stack
from ctrlbus.vtime import VirtualBus

TYPES: dict[str, type[Any]] = {
    "nav_msgs/msg/Odometry": msgs.Odometry,
    "tf2_msgs/msg/TFMessage": msgs.TFMessage,
    "sensor_msgs/msg/BatteryState": msgs.BatteryState,
    "sensor_msgs/msg/PointCloud2": msgs.PointCloud2,
    "diagnostic_msgs/msg/DiagnosticArray": msgs.DiagnosticArray,
}


def read_bag(path: Path, distro: str = "jazzy") -> dict[str, list[tuple[int, Any]]]:
    """topic -> [(log time ns, our decoded message)], after checking that rosbags and mcap_ros2
    decode every message to the same fields as our types do."""
    store = get_typestore(Stores.ROS2_JAZZY if distro == "jazzy" else Stores.ROS2_HUMBLE)
    types = dict(
        TYPES, **{"sensor_msgs/msg/Range": msgs.RangeJazzy if distro == "jazzy" else msgs.RangeHumble}
    )
    ours: dict[str, list[tuple[int, Any]]] = defaultdict(list)
    with Reader(path) as reader:
        exts = {connection.topic: connection.ext for connection in reader.connections}
        qos = {
            topic: ext.offered_qos_profiles
            for topic, ext in exts.items()
            if isinstance(ext, ConnectionExtRosbag2)
        }
        for connection, stamp, raw in reader.messages():
            message = types[connection.msgtype].deserialize(raw)
            theirs = store.deserialize_cdr(raw, connection.msgtype)
            assert list(same_value(message, theirs, f"rosbags {connection.topic}")) == []
            ours[connection.topic].append((stamp, message))
    assert qos["/tf_static"][0].durability.name == "TRANSIENT_LOCAL"
    assert qos["/odom"][0].reliability.name == "RELIABLE"
    (mcap_file,) = path.glob("*.mcap")
    seen: dict[str, int] = defaultdict(int)
    with mcap_file.open("rb") as stream:
        for _, channel, record, decoded in make_reader(
            stream, decoder_factories=[DecoderFactory()]
        ).iter_decoded_messages():
            topic = channel.topic
            stamp, message = ours[topic][seen[topic]]
            assert record.log_time == stamp
            assert list(same_value(message, decoded, f"mcap {topic}")) == []
            seen[topic] += 1
    assert seen == {topic: len(messages) for topic, messages in ours.items()}
    return ours


def test_a_capture_becomes_a_rosbag_that_two_readers_agree_on(tmp_path: Path) -> None:
    capture = tmp_path / "drive.pcap"
    _, stack = build_simulated_stack(SimSettings(seed=1))
    core = CoreSession()
    with CaptureWriter.create(capture, flush=False) as writer:
        bus = VirtualBus(
            core,
            stack,
            to_base=_Recorder(writer, Direction.CORE_TO_BASE, None),
            to_core=_Recorder(writer, Direction.BASE_TO_CORE, None),
        )
        assert bus.run_until(lambda: core.state is ConnectionState.CONNECTED, 5.0)
        bus.run_for(1.0)
        core.set_velocity(0.2, 0.5)
        bus.run_for(2.0)
        core.set_velocity(0.0, 0.0)
        bus.run_for(1.0)
    assert core.pose.x_mm > 100
    bag = tmp_path / "drive-bag"
    assert main(["record", "--rosbag", str(bag), "--capture", str(capture)]) == 0
    topics = read_bag(bag)
    assert {
        "/odom",
        "/tf",
        "/tf_static",
        "/battery_state",
        "/bumper_cloud",
        "/diagnostics",
        "/range/sensor_0",
    } <= set(topics)
    # the bag's odometry ends where the Core's own pose does (the same answers, applied the same way)
    _, last = topics["/odom"][-1]
    assert last.pose.pose.position.x == pytest.approx(core.pose.x_mm / 1000, abs=1e-9)
    assert last.pose.pose.position.y == pytest.approx(core.pose.y_mm / 1000, abs=1e-9)
    assert math.degrees(
        2 * math.atan2(last.pose.pose.orientation.z, last.pose.pose.orientation.w)
    ) == pytest.approx((core.pose.theta_deg + 180) % 360 - 180, abs=1e-6)
    # odometry at 20 Hz of capture time, stamped with it
    stamps = [stamp for stamp, _ in topics["/odom"]]
    assert 60 <= len(stamps) <= 100
    assert stamps == sorted(stamps)
    battery = topics["/battery_state"][-1][1]
    assert core.battery_percent is not None
    assert battery.percentage == pytest.approx(core.battery_percent / 100)


def test_the_live_bridge_records_what_it_publishes(tmp_path: Path) -> None:
    sim = start_sim(seed=1)
    domain = unique_domain()
    node = Node(domain)
    odom = node.subscribe("rt/odom", msgs.Odometry)
    bag = tmp_path / "live-bag"
    bridge = start_bridge(sim_port(sim), domain, tmp_path, "--rosbag", str(bag))
    try:
        wait_for("odometry", lambda: odom)

        def driving() -> bool:
            node.publish("rt/cmd_vel", twist(0.2, 0.0))
            return len(odom) > 0 and odom[-1].pose.pose.position.x > 0.05

        wait_for("driven 5 cm", driving)
        bridge.stop()  # SIGTERM: the bridge closes the bag
        assert bridge.popen.returncode == 0, bridge.describe()
    finally:
        bridge.stop()
        sim.close()
    recorded = {message.header.stamp.nanoseconds: message for _, message in read_bag(bag)["/odom"]}
    live = [message for message in odom if message.header.stamp.nanoseconds in recorded]
    assert len(live) >= len(odom) - 2  # the last ones may be published after the bag closed, or lost
    for message in live:
        assert list(same_value(message, recorded[message.header.stamp.nanoseconds], "bag vs live")) == []
    assert any(message.pose.pose.position.x > 0.05 for message in recorded.values())
