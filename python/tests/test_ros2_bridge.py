# SPDX-License-Identifier: MIT
"""`ctrlbus ros2` against the simulated base, checked by a stand-in ROS 2 node (docs/ros2.md).

The bridge runs as its own process (as users run it); the simulated base runs in this process so
that its world is the truth the topics are checked against; the node is Cyclone DDS used directly.
DDS stays on loopback (ros2_support). Every message the node receives is also decoded by rosbags,
an independent implementation of the ROS 2 message definitions and CDR, and compared field by field.
"""

from __future__ import annotations

import math
import signal
import time
from pathlib import Path

import pytest
from support.ros2_support import (
    BuiltinDataReader,
    BuiltinTopicDcpsPublication,
    BuiltinTopicDcpsSubscription,
    Node,
    Stores,
    diagnostic_values,
    get_typestore,
    same_value,
    sim_port,
    start_bridge,
    start_sim,
    twist,
    unique_domain,
    wait_for,
    yaw_of,
)

from ctrlbus.kinematics import relative_pose
from ctrlbus.ros2 import msgs
from ctrlbus.ros2.dds import SENSOR_QOS
from ctrlbus.ros2.msgs import ros_type_name

CMD_VEL_TIMEOUT_S = 0.5
SET_V_PERIOD_S = 0.05  # the Core's default 20 Hz


def check_with_rosbags(node: Node, distro: str) -> int:
    """Every sample the node holds, decoded again by rosbags and compared; returns the count."""
    store = get_typestore(Stores.ROS2_JAZZY if distro == "jazzy" else Stores.ROS2_HUMBLE)
    checked = 0
    for topic, samples in node.samples.items():
        for sample in samples:
            theirs = store.deserialize_cdr(sample.serialize(), ros_type_name(type(sample)))
            differences = list(same_value(sample, theirs, topic))
            assert differences == [], differences
            checked += 1
    return checked


@pytest.fixture
def sim():  # type: ignore[no-untyped-def]
    server = start_sim(seed=1)
    yield server
    server.close()


def test_cmd_vel_drives_the_base_and_the_topics_tell_the_truth(sim, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    world = sim.sim.world
    start = world.odometry_pose
    domain = unique_domain()
    node = Node(domain)
    node.subscribe_all()
    bridge = start_bridge(sim_port(sim), domain, tmp_path)
    try:
        odom = node.samples["rt/odom"]
        wait_for("odometry", lambda: odom)
        diagnostics = node.samples["rt/diagnostics"]
        wait_for(
            "connected",
            lambda: (
                diagnostics
                and diagnostic_values(diagnostics[-1], "ctrlbus: control bus link")["state"] == "connected"
            ),
        )

        # drive: a command every 0.1 s for 1.5 s, then silence
        end = time.monotonic() + 1.5
        while time.monotonic() < end:
            last_command = time.monotonic()
            node.publish("rt/cmd_vel", twist(0.2, 0.4))
            time.sleep(0.1)  # the publishing rate of a planner, not a synchronisation
        moved = relative_pose(start, world.odometry_pose)
        assert moved.dx_mm > 50 and moved.dtheta_deg > 5, moved

        # the command watchdog: the wheels are told to stop with no further command
        wait_for("the watchdog's stop", lambda: world.commanded_wheel_speeds == (0.0, 0.0))
        stopped_after = time.monotonic() - last_command
        assert stopped_after >= CMD_VEL_TIMEOUT_S - 0.01  # not before the timeout (bench/ measures the bound)
        wait_for("standing still", lambda: world.wheel_speeds == (0.0, 0.0))

        # odometry and tf match the simulator's odometry once both have seen the stop
        def settled() -> bool:
            truth = relative_pose(start, world.odometry_pose)
            message = odom[-1]
            pose = message.pose.pose
            return (
                message.twist.twist.linear.x == 0.0
                and abs(pose.position.x - truth.dx_mm / 1000) < 0.002
                and abs(pose.position.y - truth.dy_mm / 1000) < 0.002
                and abs(math.degrees(yaw_of(pose.orientation)) - truth.dtheta_deg) < 0.2
            )

        wait_for("odometry equal to the simulator's", settled)
        last = odom[-1]
        assert (last.header.frame_id, last.child_frame_id) == ("odom", "base_link")
        tf = wait_for(
            "tf",
            lambda: [m for m in node.samples["rt/tf"] if m.transforms[0].header.stamp == last.header.stamp],
        )
        transform = tf[0].transforms[0]
        assert (transform.header.frame_id, transform.child_frame_id) == ("odom", "base_link")
        assert transform.transform.translation.x == last.pose.pose.position.x

        # battery, ranges and static transforms against the world and the base's description
        battery = wait_for("battery", lambda: node.samples["rt/battery_state"])[-1]
        assert abs(battery.percentage - world.battery_percent / 100) < 0.011
        assert battery.power_supply_status == msgs.POWER_SUPPLY_STATUS_DISCHARGING
        ranges = node.samples["rt/range/sensor_0"]
        wait_for(
            "a range after the stop", lambda: ranges and ranges[-1].header.stamp.seconds > time.time() - 0.5
        )
        hit = world.distance_hits_mm()[0]
        reading = ranges[-1].range
        if hit is None or hit >= 2500:
            assert math.isinf(reading)
        else:
            assert abs(reading - hit / 1000) < 0.05, (reading, hit)
        static = wait_for("tf_static", lambda: node.samples["rt/tf_static"])[-1]
        sensor0 = world.base.distance_sensors[0]
        frame = next(t for t in static.transforms if t.child_frame_id == "range_sensor_0")
        assert frame.header.frame_id == "base_link"
        assert abs(frame.transform.translation.x - sensor0.mount.x_mm / 1000) < 1e-3

        # diagnostics: health, link and the watchdog's stop counted
        array = wait_for(
            "the watchdog's stop in diagnostics",
            lambda: (
                int(diagnostic_values(diagnostics[-1], "ctrlbus: ros2 bridge")["watchdog_stops"]) == 1
                and diagnostics[-1]
            ),
        )
        assert int(diagnostic_values(array, "ctrlbus: control bus link")["lost_requests"]) == 0
        assert diagnostic_values(array, "ctrlbus: bumpers and cliffs")["bumper_0"] == "false"

        # the discovery data show the ROS 2 topic and type names
        seen: set[tuple[str, str]] = set()
        builtin = BuiltinDataReader(node.participant, BuiltinTopicDcpsPublication)
        wanted = {
            ("rt/odom", "nav_msgs::msg::dds_::Odometry_"),
            ("rt/tf", "tf2_msgs::msg::dds_::TFMessage_"),
            ("rt/battery_state", "sensor_msgs::msg::dds_::BatteryState_"),
            ("rt/range/sensor_0", "sensor_msgs::msg::dds_::Range_"),
            ("rt/bumper_cloud", "sensor_msgs::msg::dds_::PointCloud2_"),
            ("rt/diagnostics", "diagnostic_msgs::msg::dds_::DiagnosticArray_"),
        }

        def publications() -> bool:
            seen.update((p.topic_name, p.type_name) for p in builtin.take(N=200) if hasattr(p, "topic_name"))
            return wanted <= seen

        wait_for(f"discovery of {wanted}", publications)
        subscriptions = BuiltinDataReader(node.participant, BuiltinTopicDcpsSubscription)
        subs: set[tuple[str, str]] = set()

        def subscribed() -> bool:
            subs.update(
                (s.topic_name, s.type_name) for s in subscriptions.take(N=200) if hasattr(s, "topic_name")
            )
            return ("rt/cmd_vel", "geometry_msgs::msg::dds_::Twist_") in subs

        wait_for(
            "the bridge's cmd_vel subscription",
            subscribed,
        )

        # every message, decoded again by rosbags, field by field
        assert check_with_rosbags(node, "jazzy") > 50
    finally:
        bridge.stop()


def test_bad_cmd_vel_never_reaches_the_base_and_is_counted(sim, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    world = sim.sim.world
    domain = unique_domain()
    node = Node(domain)
    diagnostics = node.subscribe("rt/diagnostics", msgs.DiagnosticArray)
    bridge = start_bridge(sim_port(sim), domain, tmp_path, "--rates", "diagnostics=10")
    try:
        wait_for(
            "connected",
            lambda: (
                diagnostics
                and diagnostic_values(diagnostics[-1], "ctrlbus: control bus link")["state"] == "connected"
            ),
        )
        bad = [
            twist(math.nan, 0.0),
            twist(0.1, math.inf),
            twist(-math.inf, 0.0),
            twist(100.0, 0.0),
            twist(0.0, -1e9),
        ]
        for message in bad:
            node.publish("rt/cmd_vel", message)

        def counted() -> dict[str, str] | None:
            values = diagnostic_values(diagnostics[-1], "ctrlbus: ros2 bridge")
            return values if int(values["cmd_vel_received"]) >= len(bad) else None

        values = wait_for("the bad commands counted", counted)
        assert int(values["cmd_vel_dropped_nonfinite"]) == 3
        assert int(values["cmd_vel_dropped_absurd"]) == 2
        assert values["cmd_vel_applied"] == "0"
        assert world.commanded_wheel_speeds == (0.0, 0.0)

        # over the limit but plausible: clamped to the Core's 0.5 m/s
        node.publish("rt/cmd_vel", twist(2.0, 0.0))
        left, right = wait_for(
            "the clamped command",
            lambda: world.commanded_wheel_speeds if world.commanded_wheel_speeds != (0.0, 0.0) else None,
        )
        assert left == right and 0 < left <= 500.0 + 1e-6

        def clamp_counted() -> dict[str, str] | None:
            values = diagnostic_values(diagnostics[-1], "ctrlbus: ros2 bridge")
            return values if values["cmd_vel_clamped"] == "1" else None

        values = wait_for(
            "the clamp counted",
            clamp_counted,
        )
        assert values["cmd_vel_applied"] == "1"
    finally:
        bridge.stop()


def test_killed_bridge_leaves_the_stop_to_the_base_watchdog(sim, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    world = sim.sim.world
    domain = unique_domain()
    node = Node(domain)
    odom = node.subscribe("rt/odom", msgs.Odometry)
    bridge = start_bridge(sim_port(sim), domain, tmp_path, "--cmd-vel-timeout", "30")
    try:
        wait_for("odometry", lambda: odom)

        def driving() -> bool:
            node.publish("rt/cmd_vel", twist(0.1, 0.0))
            return bool(world.commanded_wheel_speeds != (0.0, 0.0))

        wait_for("the wheels driven", driving)
        bridge.popen.send_signal(signal.SIGKILL)
        bridge.popen.wait(10)
        # nobody polls any more: the base's own motor watchdog (1 s) stops the wheels
        wait_for("the base watchdog's stop", lambda: world.commanded_wheel_speeds == (0.0, 0.0))
    finally:
        bridge.stop()


def test_namespace_stamped_humble_and_the_commands(sim, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    world = sim.sim.world
    domain = unique_domain()
    node = Node(domain)
    odom = node.subscribe("rt/robot1/odom", msgs.Odometry)
    ranges = node.subscribe("rt/robot1/range/sensor_0", msgs.RangeHumble, SENSOR_QOS)
    diagnostics = node.subscribe("rt/diagnostics", msgs.DiagnosticArray)
    bridge = start_bridge(
        sim_port(sim), domain, tmp_path, "--namespace", "robot1", "--stamped", "--distro", "humble"
    )
    try:
        wait_for("odometry", lambda: odom)
        wait_for("a Humble range", lambda: ranges)

        def stamped(vx: float) -> msgs.TwistStamped:
            return msgs.TwistStamped(
                msgs.Header(msgs.Time.from_seconds(time.time()), "base_link"), twist(vx, 0.0)
            )

        def driving() -> bool:
            node.publish("rt/robot1/cmd_vel", stamped(0.15))
            return bool(world.commanded_wheel_speeds != (0.0, 0.0))

        wait_for("driven by TwistStamped", driving)

        # the emergency stop latches: commands are ignored until it is released
        node.publish("rt/robot1/emergency_stop", msgs.Bool(True))
        wait_for("the emergency stop", lambda: world.commanded_wheel_speeds == (0.0, 0.0))
        node.publish("rt/robot1/cmd_vel", stamped(0.15))
        wait_for(
            "the ignored command seen",
            lambda: (
                diagnostics
                and diagnostic_values(diagnostics[-1], "ctrlbus: ros2 bridge")["estop_latched"] == "true"
            ),
        )
        assert world.commanded_wheel_speeds == (0.0, 0.0)
        node.publish("rt/robot1/emergency_stop", msgs.Bool(False))
        wait_for("released and driven 2 cm", lambda: driving() and odom[-1].pose.pose.position.x > 0.02)
        node.publish("rt/robot1/cmd_vel", stamped(0.0))
        wait_for("stopped", lambda: world.wheel_speeds == (0.0, 0.0))

        # The Core's pose takes the last of the motion from the next dead-reckoning answer, after
        # the wheels stopped: the reset is asked for once odom has stood still for a while.
        def odom_at_rest() -> bool:
            recent = [(m.pose.pose.position.x, m.pose.pose.position.y) for m in odom[-5:]]
            return len(recent) == 5 and len(set(recent)) == 1

        odom_count = len(odom)
        wait_for("odometry at rest", lambda: len(odom) >= odom_count + 5 and odom_at_rest())

        # reset_odometry: the odom frame starts again where the robot is
        node.publish("rt/robot1/reset_odometry", msgs.Empty())
        wait_for(
            "odometry reset",
            lambda: abs(odom[-1].pose.pose.position.x) < 1e-6 and abs(odom[-1].pose.pose.position.y) < 1e-6,
        )

        # dock: the Core's GO_HOME starts; undock cancels it
        def mode() -> str:
            return diagnostic_values(diagnostics[-1], "ctrlbus: ros2 bridge")["mode"]

        node.publish("rt/robot1/dock", msgs.Empty())
        wait_for("docking", lambda: mode() == "go_home")
        node.publish("rt/robot1/undock", msgs.Empty())
        wait_for("docking cancelled", lambda: mode() == "idle")
        counters = diagnostic_values(diagnostics[-1], "ctrlbus: ros2 bridge")
        assert (counters["dock_requests"], counters["undock_requests"]) == ("1", "1")

        assert check_with_rosbags(node, "humble") > 10
    finally:
        bridge.stop()
