# SPDX-License-Identifier: MIT
"""The ROS 2 messages the bridge speaks, as Cyclone DDS types with ROS 2's DDS type names.

Written from the public ROS 2 message definitions (.msg files of common_interfaces, rcl_interfaces
and geometry2): the same fields in the same order with the same types, so the CDR bytes are the
ones a ROS 2 node sends and expects. rosidl maps `pkg/msg/Type` to the DDS type
`pkg::msg::dds_::Type_`, an empty message gets one uint8 member, `byte` is an octet, `float64`
a double; the topic of ROS name `/x` is DDS `rt/x`.

One difference between the ROS 2 releases matters here: Jazzy added `float32 variance` to
sensor_msgs/Range (Humble has none), so there are two Range types and the bridge's `--distro`
picks one. Every other type below is the same in Humble and Jazzy.

Needs the `ros2` extra (cyclonedds); nothing else in ctrlbus imports this module.
"""

# No `from __future__ import annotations`: cyclonedds reads the annotations as types.
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from cyclonedds.idl import IdlStruct
from cyclonedds.idl.types import float32, float64, int32, uint8, uint32

if TYPE_CHECKING:  # for mypy an IDL sequence or array is the list it holds at run time
    array = list
    sequence = list
else:
    from cyclonedds.idl.types import array, sequence

__all__ = [
    "BatteryState",
    "Bool",
    "DiagnosticArray",
    "DiagnosticStatus",
    "Empty",
    "Header",
    "KeyValue",
    "Odometry",
    "Point",
    "PointCloud2",
    "PointField",
    "Pose",
    "PoseWithCovariance",
    "Quaternion",
    "RangeHumble",
    "RangeJazzy",
    "TFMessage",
    "Time",
    "Transform",
    "TransformStamped",
    "Twist",
    "TwistStamped",
    "TwistWithCovariance",
    "Vector3",
]

# The names ROS 2 tools show (`ros2 topic info`), for the record and the docs.
ROS_TYPE_NAMES: dict[str, str] = {}


def _ros_name(dds_name: str) -> str:
    package, _, rest = dds_name.partition("::msg::dds_::")
    return f"{package}/msg/{rest.rstrip('_')}"


# ------------------------------------------------------------------ builtin_interfaces, std_msgs


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: int32 = 0
    nanosec: uint32 = 0

    @classmethod
    def from_seconds(cls, seconds: float) -> "Time":
        whole = int(seconds // 1)
        nanosec = round((seconds - whole) * 1e9)
        if nanosec >= 1_000_000_000:
            whole, nanosec = whole + 1, nanosec - 1_000_000_000
        return cls(whole, nanosec)

    @property
    def seconds(self) -> float:
        return self.sec + self.nanosec * 1e-9

    @property
    def nanoseconds(self) -> int:
        return self.sec * 1_000_000_000 + self.nanosec


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Empty(IdlStruct, typename="std_msgs::msg::dds_::Empty_"):
    structure_needs_at_least_one_member: uint8 = 0


@dataclass
class Bool(IdlStruct, typename="std_msgs::msg::dds_::Bool_"):
    data: bool = False


# ------------------------------------------------------------------------------ geometry_msgs


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: float64 = 0.0
    y: float64 = 0.0
    z: float64 = 0.0
    w: float64 = 1.0


@dataclass
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::PoseWithCovariance_"):
    pose: Pose = field(default_factory=Pose)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)  # type: ignore[type-arg,valid-type]


@dataclass
class Twist(IdlStruct, typename="geometry_msgs::msg::dds_::Twist_"):
    linear: Vector3 = field(default_factory=Vector3)
    angular: Vector3 = field(default_factory=Vector3)


@dataclass
class TwistStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TwistStamped_"):
    header: Header = field(default_factory=Header)
    twist: Twist = field(default_factory=Twist)


@dataclass
class TwistWithCovariance(IdlStruct, typename="geometry_msgs::msg::dds_::TwistWithCovariance_"):
    twist: Twist = field(default_factory=Twist)
    covariance: array[float64, 36] = field(default_factory=lambda: [0.0] * 36)  # type: ignore[type-arg,valid-type]


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


# ------------------------------------------------------------------ nav_msgs, tf2_msgs


@dataclass
class Odometry(IdlStruct, typename="nav_msgs::msg::dds_::Odometry_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    pose: PoseWithCovariance = field(default_factory=PoseWithCovariance)
    twist: TwistWithCovariance = field(default_factory=TwistWithCovariance)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: sequence[TransformStamped] = field(default_factory=list)


# -------------------------------------------------------------------------------- sensor_msgs

# sensor_msgs/BatteryState's power_supply_status constants
POWER_SUPPLY_STATUS_UNKNOWN = 0
POWER_SUPPLY_STATUS_CHARGING = 1
POWER_SUPPLY_STATUS_DISCHARGING = 2
POWER_SUPPLY_STATUS_NOT_CHARGING = 3
POWER_SUPPLY_STATUS_FULL = 4
POWER_SUPPLY_HEALTH_UNKNOWN = 0
POWER_SUPPLY_HEALTH_GOOD = 1
POWER_SUPPLY_TECHNOLOGY_UNKNOWN = 0


@dataclass
class BatteryState(IdlStruct, typename="sensor_msgs::msg::dds_::BatteryState_"):
    header: Header = field(default_factory=Header)
    voltage: float32 = float("nan")
    temperature: float32 = float("nan")
    current: float32 = float("nan")
    charge: float32 = float("nan")
    capacity: float32 = float("nan")
    design_capacity: float32 = float("nan")
    percentage: float32 = float("nan")
    power_supply_status: uint8 = POWER_SUPPLY_STATUS_UNKNOWN
    power_supply_health: uint8 = POWER_SUPPLY_HEALTH_UNKNOWN
    power_supply_technology: uint8 = POWER_SUPPLY_TECHNOLOGY_UNKNOWN
    present: bool = True
    cell_voltage: sequence[float32] = field(default_factory=list)
    cell_temperature: sequence[float32] = field(default_factory=list)
    location: str = ""
    serial_number: str = ""


# sensor_msgs/Range's radiation_type constants
RANGE_ULTRASOUND = 0
RANGE_INFRARED = 1


@dataclass
class RangeHumble(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
    """sensor_msgs/Range up to Iron (Humble)."""

    header: Header = field(default_factory=Header)
    radiation_type: uint8 = RANGE_ULTRASOUND
    field_of_view: float32 = 0.0
    min_range: float32 = 0.0
    max_range: float32 = 0.0
    range: float32 = 0.0


@dataclass
class RangeJazzy(IdlStruct, typename="sensor_msgs::msg::dds_::Range_"):
    """sensor_msgs/Range from Jazzy on: `variance` added at the end."""

    header: Header = field(default_factory=Header)
    radiation_type: uint8 = RANGE_ULTRASOUND
    field_of_view: float32 = 0.0
    min_range: float32 = 0.0
    max_range: float32 = 0.0
    range: float32 = 0.0
    variance: float32 = 0.0


# sensor_msgs/PointField's datatype constants (FLOAT32 is the one used here)
POINT_FIELD_FLOAT32 = 7


@dataclass
class PointField(IdlStruct, typename="sensor_msgs::msg::dds_::PointField_"):
    name: str = ""
    offset: uint32 = 0
    datatype: uint8 = 0
    count: uint32 = 0


@dataclass
class PointCloud2(IdlStruct, typename="sensor_msgs::msg::dds_::PointCloud2_"):
    header: Header = field(default_factory=Header)
    height: uint32 = 0
    width: uint32 = 0
    fields: sequence[PointField] = field(default_factory=list)
    is_bigendian: bool = False
    point_step: uint32 = 0
    row_step: uint32 = 0
    data: sequence[uint8] = field(default_factory=list)
    is_dense: bool = False


# ---------------------------------------------------------------------------- diagnostic_msgs

DIAGNOSTIC_OK = 0
DIAGNOSTIC_WARN = 1
DIAGNOSTIC_ERROR = 2
DIAGNOSTIC_STALE = 3


@dataclass
class KeyValue(IdlStruct, typename="diagnostic_msgs::msg::dds_::KeyValue_"):
    key: str = ""
    value: str = ""


@dataclass
class DiagnosticStatus(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticStatus_"):
    level: uint8 = DIAGNOSTIC_OK  # `byte` in the .msg: an octet on the wire
    name: str = ""
    message: str = ""
    hardware_id: str = ""
    values: sequence[KeyValue] = field(default_factory=list)


@dataclass
class DiagnosticArray(IdlStruct, typename="diagnostic_msgs::msg::dds_::DiagnosticArray_"):
    header: Header = field(default_factory=Header)
    status: sequence[DiagnosticStatus] = field(default_factory=list)


for _type in (
    Empty,
    Bool,
    Twist,
    TwistStamped,
    Odometry,
    TFMessage,
    BatteryState,
    RangeJazzy,
    PointCloud2,
    DiagnosticArray,
):
    ROS_TYPE_NAMES[_type.__idl_typename__] = _ros_name(_type.__idl_typename__)


def ros_type_name(message_type: type[IdlStruct]) -> str:
    """`nav_msgs/msg/Odometry` for the DDS type `nav_msgs::msg::dds_::Odometry_`."""
    return _ros_name(message_type.__idl_typename__)
