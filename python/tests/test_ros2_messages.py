# SPDX-License-Identifier: MIT
"""The messages the bridge makes from one moment of the Core's knowledge (ctrlbus.ros2.topics),
without DDS: REP 117 ranges, battery status, contact points, frames, times and names."""

from __future__ import annotations

import math
import struct
from dataclasses import replace

import pytest
from ros2_support import Stores, get_typestore, same_value

from ctrlbus.core.geometry import BaseGeometry, Bumper, DistanceSensor, Mount
from ctrlbus.core.telemetry import CommandState, HealthError, HealthState
from ctrlbus.errors import UsageError
from ctrlbus.kinematics import Pose
from ctrlbus.ros2 import msgs
from ctrlbus.ros2.dds import dds_topic_name
from ctrlbus.ros2.pump import Rates
from ctrlbus.ros2.topics import BaseState, BridgeCounters, MessageMaker, RangeSpec

GEOMETRY = BaseGeometry(
    source="GET_BASE_CONF",
    shape="circle",
    radius_mm=170.0,
    sensors=(
        DistanceSensor(Mount(165.0, 0.0, 120.0, 0.0), 0),
        DistanceSensor(Mount(-160.0, 0.0, 120.0, 180.0), 5),
    ),
    bumpers=(Bumper(Mount(120.0, 120.0, 40.0, 45.0), 0), Bumper(Mount(120.0, -120.0, 40.0, 315.0), 1)),
    cliff_bits=(2, 3),
)


def state(**changes: object) -> BaseState:
    distances = [0.0] * 16
    distances[0], distances[5] = 1234.0, 0.0
    base = BaseState(
        stamp_s=1_700_000_000.25,
        connected=True,
        pose=Pose(1000.0, 500.0, 90.0),
        geometry=GEOMETRY,
        battery_percent=57,
        charging=False,
        dc_connected=False,
        on_dock=False,
        bumper_bitmap=0xFFFFFFFE,
        bumpers_pressed=(True, False),
        cliffs_triggered=(False, True),
        distances_mm=tuple(distances),
        health=HealthState(0x02, (HealthError(0x02020100, "battery critically low"),)),
        command=CommandState(0.2, 0.0, False, "teleop", None),
        serial="ABC",
        link={"connection": {"state": "connected", "connects": 1}, "timeouts": 3},
    )
    return replace(base, **changes)  # type: ignore[arg-type]


def test_ranges_follow_rep_117() -> None:
    maker = MessageMaker(ranges={5: RangeSpec(msgs.RANGE_INFRARED, math.radians(4), 0.05, 0.8)})
    (slot0, front), (slot5, back) = maker.ranges_of(state())
    assert (slot0, slot5) == (0, 5)
    assert front.range == pytest.approx(1.234) and front.header.frame_id == "range_sensor_0"
    assert math.isinf(back.range) and back.range > 0  # 0 = no echo
    assert back.radiation_type == msgs.RANGE_INFRARED and back.max_range == 0.8
    distances = [0.0] * 16
    distances[0], distances[5] = 10.0, 900.0
    near, far = (message.range for _, message in maker.ranges_of(state(distances_mm=tuple(distances))))
    assert near == -math.inf and far == math.inf
    assert maker.ranges_of(state(distances_mm=None)) == []


def test_humble_ranges_have_no_variance() -> None:
    (_, message), _ = MessageMaker(distro="humble").ranges_of(state())
    assert isinstance(message, msgs.RangeHumble)
    theirs = get_typestore(Stores.ROS2_HUMBLE).deserialize_cdr(message.serialize(), "sensor_msgs/msg/Range")
    sent = msgs.RangeHumble.deserialize(message.serialize())  # the float32 fields as they travel
    assert list(same_value(sent, theirs, "range")) == []
    with pytest.raises(Exception, match="deserialize"):
        get_typestore(Stores.ROS2_JAZZY).deserialize_cdr(message.serialize(), "sensor_msgs/msg/Range")


@pytest.mark.parametrize(
    ("changes", "status"),
    [
        ({}, msgs.POWER_SUPPLY_STATUS_DISCHARGING),
        ({"charging": True, "on_dock": True}, msgs.POWER_SUPPLY_STATUS_CHARGING),
        ({"on_dock": True}, msgs.POWER_SUPPLY_STATUS_NOT_CHARGING),
        ({"dc_connected": True, "battery_percent": 100}, msgs.POWER_SUPPLY_STATUS_FULL),
        ({"battery_percent": None}, msgs.POWER_SUPPLY_STATUS_UNKNOWN),
    ],
)
def test_battery_status(changes: dict[str, object], status: int) -> None:
    message = MessageMaker().battery(state(**changes))
    assert message.power_supply_status == status
    if changes.get("battery_percent", 57) is None:
        assert math.isnan(message.percentage) and not message.present
    else:
        assert message.percentage == pytest.approx(changes.get("battery_percent", 57) / 100)  # type: ignore[operator]


def test_contacts_become_points_in_base_link() -> None:
    cloud = MessageMaker().bumper_cloud(state())
    assert cloud.width == 2 and cloud.point_step == 12 and cloud.header.frame_id == "base_link"
    points = list(struct.iter_unpack("<fff", bytes(cloud.data)))
    assert points[0] == pytest.approx((0.12, 0.12, 0.04))  # the pressed bumper's mount
    # the second of two cliffs: on the rim, 45 degrees right of straight ahead
    assert points[1] == pytest.approx(
        (0.17 * math.cos(math.radians(-45)), 0.17 * math.sin(math.radians(-45)), 0.0)
    )
    empty = MessageMaker().bumper_cloud(
        state(bumpers_pressed=(False, False), cliffs_triggered=(False, False))
    )
    assert empty.width == 0 and empty.data == []


def test_odometry_is_relative_to_the_start_or_the_reset() -> None:
    maker = MessageMaker()
    first, tf = maker.odometry(state())
    assert first.pose.pose.position.x == pytest.approx(1.0) and first.pose.pose.position.y == pytest.approx(
        0.5
    )
    assert 2 * math.atan2(first.pose.pose.orientation.z, first.pose.pose.orientation.w) == pytest.approx(
        math.pi / 2
    )
    assert first.twist.twist.linear.x == 0.0  # nothing to compare with yet
    assert tf.transforms[0].child_frame_id == "base_link" and tf.transforms[0].header.frame_id == "odom"
    # 0.1 s later, 20 mm further along the heading (+y in the odom frame): 0.2 m/s forward
    later, _ = maker.odometry(state(stamp_s=1_700_000_000.35, pose=Pose(1000.0, 520.0, 90.0)))
    assert later.twist.twist.linear.x == pytest.approx(0.2) and later.twist.twist.linear.y == pytest.approx(
        0.0, abs=1e-9
    )
    maker.reset_odometry(Pose(1000.0, 520.0, 90.0))
    reset, _ = maker.odometry(state(pose=Pose(1000.0, 520.0, 90.0)))
    assert (reset.pose.pose.position.x, reset.pose.pose.position.y) == (0.0, 0.0)
    assert reset.pose.covariance[0] == 0.01 and reset.pose.covariance[35] == 0.05


def test_diagnostics_say_health_link_contacts_and_counters() -> None:
    counters = BridgeCounters(cmd_vel_dropped_nonfinite=2)
    array = MessageMaker().diagnostics(state(), counters)
    by_name = {status.name: status for status in array.status}
    health = by_name["ctrlbus: base health"]
    assert health.level == msgs.DIAGNOSTIC_ERROR and health.message == "battery critically low"
    assert {pair.key: pair.value for pair in health.values}["0x02020100"] == "battery critically low"
    link = {pair.key: pair.value for pair in by_name["ctrlbus: control bus link"].values}
    assert link["timeouts"] == "3"
    contacts = {pair.key: pair.value for pair in by_name["ctrlbus: bumpers and cliffs"].values}
    assert contacts == {
        "bitmap": "0xFFFFFFFE",
        "bumper_0": "true",
        "bumper_1": "false",
        "cliff_0": "false",
        "cliff_1": "true",
    }
    bridge = by_name["ctrlbus: ros2 bridge"]
    assert bridge.level == msgs.DIAGNOSTIC_WARN
    assert {pair.key: pair.value for pair in bridge.values}["cmd_vel_dropped_nonfinite"] == "2"
    stale = MessageMaker().diagnostics(state(connected=False), counters)
    assert stale.status[0].level == msgs.DIAGNOSTIC_STALE


def test_static_transforms_put_each_sensor_at_its_mount() -> None:
    static = MessageMaker().static_transforms(GEOMETRY, 5.0)
    back = static.transforms[1]
    assert back.child_frame_id == "range_sensor_5" and back.header.frame_id == "base_link"
    assert back.transform.translation.x == pytest.approx(-0.16)
    assert abs(back.transform.rotation.z) == pytest.approx(1.0)  # facing backwards


def test_times_and_names() -> None:
    assert msgs.Time.from_seconds(1.9999999999) == msgs.Time(2, 0)
    assert msgs.Time.from_seconds(3.25) == msgs.Time(3, 250_000_000)
    assert dds_topic_name("odom", "robot1") == "rt/robot1/odom"
    assert dds_topic_name("/tf", "") == "rt/tf"
    for bad in ("9odom", "od-om", ""):
        with pytest.raises(UsageError):
            dds_topic_name(bad)
    assert Rates.parse("odom=50, range=0") == Rates(odom=50.0, range=0.0)
    assert msgs.ros_type_name(msgs.Odometry) == "nav_msgs/msg/Odometry"
