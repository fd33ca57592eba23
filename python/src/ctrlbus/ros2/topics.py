# SPDX-License-Identifier: MIT
"""What the bridge publishes, made from what the Core knows: one function per ROS 2 topic.

`BaseState` is one moment of the Core's knowledge, read at once (under the runner's lock, or from
a capture's frames); `MessageMaker` turns it into ROS 2 messages (ctrlbus.ros2.msgs). It keeps the
little state the messages need across calls: the previous pose (odometry's twist) and the pose at
the last `reset_odometry`. It reads no clock and sends nothing: the bridge (live DDS) and the
recorder (rosbag2) both use it, so the bag holds the messages the live topics carry.

Conventions (REP 103, REP 105): x forward, y left, z up, metres, radians, anticlockwise; odometry in
the frame `odom` (where the Core started, or the last reset), the robot in `base_link`.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass, field
from typing import Any

from cyclonedds.idl import IdlStruct

from ctrlbus.core.geometry import BaseGeometry, Mount
from ctrlbus.core.telemetry import CommandState, HealthState
from ctrlbus.errors import UsageError
from ctrlbus.kinematics import Pose, relative_pose
from ctrlbus.ros2 import msgs
from ctrlbus.ros2.dds import DEFAULT_QOS, SENSOR_QOS, STATIC_QOS, TF_QOS, QosKind, dds_topic_name

__all__ = [
    "POSE_COVARIANCE",
    "TWIST_COVARIANCE",
    "BaseState",
    "BridgeCounters",
    "MessageMaker",
    "RangeSpec",
    "TopicNames",
    "TopicSpec",
]

# Odometry covariances (row-major 6x6: x, y, z, roll, pitch, yaw). Dead reckoning on a planar
# base: x, y and yaw get a variance, z, roll and pitch are not measured (a large variance, as
# REP 105 bases do so that a filter ignores them).
_UNMEASURED = 1e6


def _diagonal(*variances: float) -> tuple[float, ...]:
    return tuple(variances[row] if row == column else 0.0 for row in range(6) for column in range(6))


POSE_COVARIANCE = _diagonal(0.01, 0.01, _UNMEASURED, _UNMEASURED, _UNMEASURED, 0.05)  # m², rad²
TWIST_COVARIANCE = _diagonal(0.001, 0.001, _UNMEASURED, _UNMEASURED, _UNMEASURED, 0.01)  # (m/s)², (rad/s)²
# A cliff sensor has no mount in the base's configuration: its point goes on the rim, in front,
# spread over this arc in bit order (enough for a costmap to stop forward motion).
CLIFF_ARC_DEG = 90.0


@dataclass(frozen=True)
class RangeSpec:
    """What the configuration does not say about a distance sensor: its kind and limits."""

    radiation_type: int = msgs.RANGE_ULTRASOUND
    field_of_view_rad: float = math.radians(30.0)
    min_range_m: float = 0.02
    max_range_m: float = 2.5

    @classmethod
    def parse(cls, text: str) -> tuple[int, RangeSpec]:
        """`SLOT=sonar|ir:FOV_DEG:MIN_M:MAX_M` (the --range option)."""
        slot_text, _, rest = text.partition("=")
        parts = rest.split(":")
        try:
            slot = int(slot_text)
            kind = parts[0]
            fov, low, high = (float(part) for part in parts[1:])
        except ValueError:
            raise UsageError(f"--range wants SLOT=sonar|ir:FOV_DEG:MIN_M:MAX_M, got {text!r}") from None
        if kind not in ("sonar", "ir") or not 0 <= slot < 16:
            raise UsageError(f"--range wants a slot 0..15 and sonar or ir, got {text!r}")
        if not (0 < fov <= 180 and 0 <= low < high and math.isfinite(high)):
            raise UsageError(f"--range: field of view 0..180 degrees and 0 <= MIN < MAX, got {text!r}")
        radiation = msgs.RANGE_ULTRASOUND if kind == "sonar" else msgs.RANGE_INFRARED
        return slot, cls(radiation, math.radians(fov), low, high)


@dataclass(frozen=True)
class TopicSpec:
    name: str  # the ROS 2 name, relative to the namespace
    qos: QosKind


@dataclass(frozen=True)
class TopicNames:
    """The ROS 2 topics (relative names; the namespace is put in front of each)."""

    cmd_vel: str = "cmd_vel"
    odom: str = "odom"
    tf: str = "/tf"  # tf is global in ROS 2 (absolute unless remapped)
    tf_static: str = "/tf_static"
    battery_state: str = "battery_state"
    range_prefix: str = "range/"
    bumper_cloud: str = "bumper_cloud"
    diagnostics: str = "/diagnostics"
    dock: str = "dock"
    undock: str = "undock"
    reset_odometry: str = "reset_odometry"
    emergency_stop: str = "emergency_stop"

    def range(self, slot: int) -> str:
        return f"{self.range_prefix}sensor_{slot}"


@dataclass(frozen=True)
class BaseState:
    """One moment of what the Core knows (read at once); `stamp_s` is the ROS time (seconds)."""

    stamp_s: float
    connected: bool
    pose: Pose
    geometry: BaseGeometry | None
    battery_percent: int | None
    charging: bool
    dc_connected: bool
    on_dock: bool
    bumper_bitmap: int | None
    bumpers_pressed: tuple[bool, ...]
    cliffs_triggered: tuple[bool, ...]
    distances_mm: tuple[float, ...] | None
    health: HealthState
    command: CommandState
    serial: str
    link: dict[str, Any]


@dataclass
class BridgeCounters:
    """What the bridge did with its inputs (published in diagnostics)."""

    cmd_vel_received: int = 0
    cmd_vel_applied: int = 0
    cmd_vel_clamped: int = 0
    cmd_vel_dropped_nonfinite: int = 0
    cmd_vel_dropped_absurd: int = 0
    cmd_vel_not_ready: int = 0
    watchdog_stops: int = 0
    estop_requests: int = 0
    dock_requests: int = 0
    undock_requests: int = 0
    odometry_resets: int = 0

    def as_pairs(self) -> list[tuple[str, str]]:
        return [(name, str(value)) for name, value in vars(self).items()]


def quaternion_from_yaw(yaw_rad: float) -> msgs.Quaternion:
    return msgs.Quaternion(0.0, 0.0, math.sin(yaw_rad / 2), math.cos(yaw_rad / 2))


def _transform(
    header: msgs.Header, child: str, x: float, y: float, z: float, yaw: float
) -> msgs.TransformStamped:
    return msgs.TransformStamped(
        header, child, msgs.Transform(msgs.Vector3(x, y, z), quaternion_from_yaw(yaw))
    )


def _mount_point(mount: Mount) -> tuple[float, float, float]:
    return mount.x_mm / 1000.0, mount.y_mm / 1000.0, mount.z_mm / 1000.0


@dataclass
class MessageMaker:
    """Builds the messages of each topic from a BaseState (see the module)."""

    odom_frame: str = "odom"
    base_frame: str = "base_link"
    distro: str = "jazzy"
    default_range: RangeSpec = field(default_factory=RangeSpec)
    ranges: dict[int, RangeSpec] = field(default_factory=dict)
    hardware_id: str = "slamware-base"
    _origin: Pose = field(default_factory=lambda: Pose(0.0, 0.0, 0.0))
    _last_odom: tuple[float, Pose] | None = None

    @property
    def range_type(self) -> type[msgs.RangeHumble] | type[msgs.RangeJazzy]:
        return msgs.RangeHumble if self.distro == "humble" else msgs.RangeJazzy

    def range_frame(self, slot: int) -> str:
        return f"range_sensor_{slot}"

    def reset_odometry(self, pose: Pose) -> None:
        """From now on `pose` (the Core's) is the odom origin."""
        self._origin = pose
        self._last_odom = None

    def odom_pose(self, pose: Pose) -> tuple[float, float, float]:
        """The Core's pose in the odom frame: metres, metres, radians."""
        delta = relative_pose(self._origin, pose)
        return delta.dx_mm / 1000.0, delta.dy_mm / 1000.0, math.radians(delta.dtheta_deg)

    def odometry(self, state: BaseState) -> tuple[msgs.Odometry, msgs.TFMessage]:
        """nav_msgs/Odometry and the odom -> base_link transform. The twist is the motion since
        the previous call, in base_link (zero on the first)."""
        x, y, yaw = self.odom_pose(state.pose)
        vx = vy = omega = 0.0
        if self._last_odom is not None:
            last_time, last_pose = self._last_odom
            dt = state.stamp_s - last_time
            if dt > 0:
                moved = relative_pose(last_pose, state.pose)
                vx = moved.dx_mm / 1000.0 / dt
                vy = moved.dy_mm / 1000.0 / dt
                omega = math.radians(moved.dtheta_deg) / dt
        self._last_odom = (state.stamp_s, state.pose)
        header = msgs.Header(msgs.Time.from_seconds(state.stamp_s), self.odom_frame)
        odometry = msgs.Odometry(
            header,
            self.base_frame,
            msgs.PoseWithCovariance(
                msgs.Pose(msgs.Point(x, y, 0.0), quaternion_from_yaw(yaw)), list(POSE_COVARIANCE)
            ),
            msgs.TwistWithCovariance(
                msgs.Twist(msgs.Vector3(vx, vy, 0.0), msgs.Vector3(0.0, 0.0, omega)), list(TWIST_COVARIANCE)
            ),
        )
        tf = msgs.TFMessage([_transform(header, self.base_frame, x, y, 0.0, yaw)])
        return odometry, tf

    def static_transforms(self, geometry: BaseGeometry, stamp_s: float) -> msgs.TFMessage:
        """base_link -> each distance sensor's frame (its mount in the configuration)."""
        header = msgs.Header(msgs.Time.from_seconds(stamp_s), self.base_frame)
        return msgs.TFMessage(
            [
                _transform(
                    header,
                    self.range_frame(sensor.slot),
                    *_mount_point(sensor.mount),
                    math.radians(sensor.mount.angle_deg),
                )
                for sensor in geometry.sensors
            ]
        )

    def battery(self, state: BaseState) -> msgs.BatteryState:
        if state.charging:
            status = msgs.POWER_SUPPLY_STATUS_CHARGING
        elif state.battery_percent is not None and state.battery_percent >= 100 and state.dc_connected:
            status = msgs.POWER_SUPPLY_STATUS_FULL
        elif state.dc_connected or state.on_dock:
            status = msgs.POWER_SUPPLY_STATUS_NOT_CHARGING
        elif state.battery_percent is None:
            status = msgs.POWER_SUPPLY_STATUS_UNKNOWN
        else:
            status = msgs.POWER_SUPPLY_STATUS_DISCHARGING
        percentage = float("nan") if state.battery_percent is None else state.battery_percent / 100.0
        return msgs.BatteryState(
            header=msgs.Header(msgs.Time.from_seconds(state.stamp_s), self.base_frame),
            percentage=percentage,
            power_supply_status=status,
            present=state.battery_percent is not None,
            location="base",
            serial_number=state.serial,
        )

    def range_spec(self, slot: int) -> RangeSpec:
        return self.ranges.get(slot, self.default_range)

    def ranges_of(self, state: BaseState) -> list[tuple[int, msgs.RangeHumble | msgs.RangeJazzy]]:
        """One sensor_msgs/Range per configured distance sensor. REP 117: a reading of 0 (no
        echo, as the reference's sonar says it) or beyond max_range is +inf, below min_range -inf."""
        if state.geometry is None or state.distances_mm is None:
            return []
        out: list[tuple[int, msgs.RangeHumble | msgs.RangeJazzy]] = []
        for sensor in state.geometry.sensors:
            spec = self.range_spec(sensor.slot)
            metres = state.distances_mm[sensor.slot] / 1000.0
            if metres <= 0 or metres >= spec.max_range_m:
                value = math.inf
            elif metres < spec.min_range_m:
                value = -math.inf
            else:
                value = metres
            header = msgs.Header(msgs.Time.from_seconds(state.stamp_s), self.range_frame(sensor.slot))
            message = self.range_type(
                header=header,
                radiation_type=spec.radiation_type,
                field_of_view=spec.field_of_view_rad,
                min_range=spec.min_range_m,
                max_range=spec.max_range_m,
                range=value,
            )
            out.append((sensor.slot, message))
        return out

    def contact_points(self, state: BaseState) -> list[tuple[float, float, float]]:
        """The points of the pressed bumpers (at their mounts) and triggered cliffs (on the
        front rim), in base_link."""
        geometry = state.geometry
        if geometry is None:
            return []
        points = [
            _mount_point(bumper.mount)
            for bumper, pressed in zip(geometry.bumpers, state.bumpers_pressed, strict=False)
            if pressed
        ]
        count = len(geometry.cliff_bits)
        radius = geometry.radius_mm / 1000.0
        for index, triggered in enumerate(state.cliffs_triggered):
            if triggered:
                angle = 0.0 if count < 2 else math.radians(CLIFF_ARC_DEG * (0.5 - index / (count - 1)))
                points.append((radius * math.cos(angle), radius * math.sin(angle), 0.0))
        return points

    def bumper_cloud(self, state: BaseState) -> msgs.PointCloud2:
        """sensor_msgs/PointCloud2 (x, y, z float32) with a point per contact; empty when none,
        so that a costmap clears."""
        points = self.contact_points(state)
        data = b"".join(struct.pack("<fff", *point) for point in points)
        return msgs.PointCloud2(
            header=msgs.Header(msgs.Time.from_seconds(state.stamp_s), self.base_frame),
            height=1,
            width=len(points),
            fields=[
                msgs.PointField(name, offset, msgs.POINT_FIELD_FLOAT32, 1)
                for name, offset in (("x", 0), ("y", 4), ("z", 8))
            ],
            is_bigendian=False,
            point_step=12,
            row_step=12 * len(points),
            data=list(data),
            is_dense=True,
        )

    def diagnostics(self, state: BaseState, counters: BridgeCounters) -> msgs.DiagnosticArray:
        """The base's health list, the link's counters, the contacts' raw state and the bridge's
        own counters, one DiagnosticStatus each."""
        hw = state.serial or self.hardware_id
        health = state.health
        if not state.connected:
            health_level = msgs.DIAGNOSTIC_STALE
        elif health.fatal or health.error:
            health_level = msgs.DIAGNOSTIC_ERROR
        elif health.warning:
            health_level = msgs.DIAGNOSTIC_WARN
        else:
            health_level = msgs.DIAGNOSTIC_OK
        health_values = [msgs.KeyValue("flags", "" if health.flags is None else f"0x{health.flags:02X}")]
        health_values += [msgs.KeyValue(f"0x{error.code:08X}", error.message) for error in health.errors]
        link = state.link
        line_faults = sum(link.get("line_faults_by_bit", {}).values())
        link_pairs = [
            ("state", str(link.get("connection", {}).get("state", ""))),
            ("connects", str(link.get("connection", {}).get("connects", 0))),
            ("timeouts", str(link.get("timeouts", 0))),
            ("line_faults", str(line_faults)),
            ("lost_requests", str(link.get("lost_requests", 0))),
            ("retries", str(link.get("retries", 0))),
            ("superseded", str(link.get("superseded", 0))),
            ("watchdog_trips", str(link.get("watchdog_trips", 0))),
            ("watchdog_reported", str(link.get("watchdog_reported", 0))),
            ("checksum_failures", str(link.get("checksum_failures", 0))),
            ("latency_p99_ms", str(link.get("latency_p99_ms"))),
        ]
        link_level = msgs.DIAGNOSTIC_OK if state.connected else msgs.DIAGNOSTIC_ERROR
        contacts = [
            ("bitmap", "" if state.bumper_bitmap is None else f"0x{state.bumper_bitmap:08X}"),
            *((f"bumper_{i}", str(pressed).lower()) for i, pressed in enumerate(state.bumpers_pressed)),
            *((f"cliff_{i}", str(hit).lower()) for i, hit in enumerate(state.cliffs_triggered)),
        ]
        touching = any(state.bumpers_pressed) or any(state.cliffs_triggered)
        command = state.command
        bridge_pairs = [
            ("mode", command.mode),
            ("estop_latched", str(command.estop).lower()),
            ("vx_mps", f"{command.vx_mps:.3f}"),
            ("omega_radps", f"{command.omega_radps:.3f}"),
            *counters.as_pairs(),
        ]
        rejected = counters.cmd_vel_dropped_nonfinite + counters.cmd_vel_dropped_absurd
        statuses = [
            msgs.DiagnosticStatus(
                health_level,
                "ctrlbus: base health",
                _health_message(health, state.connected),
                hw,
                health_values,
            ),
            msgs.DiagnosticStatus(
                link_level,
                "ctrlbus: control bus link",
                str(link.get("connection", {}).get("state", "")),
                hw,
                [msgs.KeyValue(k, v) for k, v in link_pairs],
            ),
            msgs.DiagnosticStatus(
                msgs.DIAGNOSTIC_WARN if touching else msgs.DIAGNOSTIC_OK,
                "ctrlbus: bumpers and cliffs",
                "contact" if touching else "clear",
                hw,
                [msgs.KeyValue(k, v) for k, v in contacts],
            ),
            msgs.DiagnosticStatus(
                msgs.DIAGNOSTIC_WARN if rejected or command.estop else msgs.DIAGNOSTIC_OK,
                "ctrlbus: ros2 bridge",
                "emergency stop latched" if command.estop else command.mode,
                hw,
                [msgs.KeyValue(k, v) for k, v in bridge_pairs],
            ),
        ]
        return msgs.DiagnosticArray(msgs.Header(msgs.Time.from_seconds(state.stamp_s), ""), statuses)


def _health_message(health: HealthState, connected: bool) -> str:
    if not connected:
        return "base not connected"
    if health.flags is None:
        return "not read yet"
    if not health.errors:
        return "ok"
    return "; ".join(error.message for error in health.errors)


def topic_table(
    names: TopicNames, distro: str, sensor_slots: tuple[int, ...]
) -> dict[str, tuple[str, type[IdlStruct], QosKind]]:
    """key -> (ROS 2 name, message type, QoS) for every topic the bridge publishes."""
    range_type: type[IdlStruct] = msgs.RangeHumble if distro == "humble" else msgs.RangeJazzy
    table: dict[str, tuple[str, type[IdlStruct], QosKind]] = {
        "odom": (names.odom, msgs.Odometry, DEFAULT_QOS),
        "tf": (names.tf, msgs.TFMessage, TF_QOS),
        "tf_static": (names.tf_static, msgs.TFMessage, STATIC_QOS),
        "battery_state": (names.battery_state, msgs.BatteryState, DEFAULT_QOS),
        "bumper_cloud": (names.bumper_cloud, msgs.PointCloud2, SENSOR_QOS),
        "diagnostics": (names.diagnostics, msgs.DiagnosticArray, DEFAULT_QOS),
    }
    for slot in sensor_slots:
        table[f"range_{slot}"] = (names.range(slot), range_type, SENSOR_QOS)
    return table


def absolute_name(ros_name: str, namespace: str) -> str:
    """`/ns/odom` for `odom` in `ns`; an absolute name stays as it is."""
    return "/" + dds_topic_name(ros_name, "" if ros_name.startswith("/") else namespace)[len("rt/") :]
