# SPDX-License-Identifier: MIT
"""The simulated robot's description: shape, drive, sensors, battery, noise (docs/simulator.md).

`load_base_description(path)` reads a JSON file; with no path it reads the packaged default,
ctrlbus/data/sim-base.json. All lengths are millimetres, in the robot frame (x forward, y left,
z up, origin at the centre of the wheel axle on the floor); angles are degrees, anticlockwise,
0..360 (0 = straight ahead).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any, NamedTuple

from ctrlbus.sim.config import ConfigReader, load_json_file, parse_json_text, unique_names

__all__ = [
    "DEFAULT_BASE_RESOURCE",
    "DISTANCE_SENSOR_TYPES",
    "MAX_BEACON_PROBES",
    "MAX_BUMPERS",
    "MAX_CLIFF_SENSORS",
    "MAX_DISTANCE_SENSORS",
    "MODEL_MAX_LENGTH",
    "NO_ECHO_CHOICES",
    "BaseDescription",
    "BatterySpec",
    "BeaconProbeSpec",
    "BumperSpec",
    "ChargingContactsSpec",
    "CliffSensorSpec",
    "DistanceSensorSpec",
    "Mount",
    "WheelSlipSpec",
    "base_description_from_dict",
    "default_base_description",
    "load_base_description",
]

# What the wire can carry: GET_BASE_CONF has 8 sensor and 8 bumper slots, the reference bumper
# bitmap keeps bits 2-5 for cliff sensors, and a GET_CHARGER_DATA probe byte has 8 beacon bits.
MAX_DISTANCE_SENSORS = 8
MAX_BUMPERS = 8
MAX_CLIFF_SENSORS = 4
MAX_BEACON_PROBES = 8
MODEL_MAX_LENGTH = 12

DISTANCE_SENSOR_TYPES = ("sonar", "ir")
NO_ECHO_CHOICES = ("zero", "max_range")


class Mount(NamedTuple):
    """Where a part sits on the robot: position (mm) and the direction it faces (deg, 0..360)."""

    x_mm: float
    y_mm: float
    z_mm: float
    yaw_deg: float


@dataclass(frozen=True)
class DistanceSensorSpec:
    """A sonar or IR range finder; `beam_deg` is the full cone angle (0 = a single ray)."""

    name: str
    kind: str
    mount: Mount
    max_range_mm: float
    beam_deg: float
    no_echo: str  # what it reports without an echo: "zero" (the reference's sonar) or "max_range"
    noise_stddev_mm: float

    @property
    def no_echo_reading_mm(self) -> float:
        return 0.0 if self.no_echo == "zero" else self.max_range_mm


@dataclass(frozen=True)
class BumperSpec:
    """A bumper covering the arc of the robot's rim from `start_deg` anticlockwise to `end_deg`."""

    name: str
    start_deg: float
    end_deg: float
    z_mm: float

    @property
    def middle_deg(self) -> float:
        span = (self.end_deg - self.start_deg) % 360.0 or 360.0
        return (self.start_deg + span / 2.0) % 360.0

    def mount(self, radius_mm: float) -> Mount:
        """The rim point in the middle of the arc, facing outwards (what GET_BASE_CONF reports)."""
        middle = math.radians(self.middle_deg)
        return Mount(radius_mm * math.cos(middle), radius_mm * math.sin(middle), self.z_mm, self.middle_deg)


@dataclass(frozen=True)
class CliffSensorSpec:
    """A downward-looking floor sensor; it triggers over a cliff area of the room."""

    name: str
    x_mm: float
    y_mm: float
    z_mm: float


@dataclass(frozen=True)
class BeaconProbeSpec:
    """An IR receiver for the dock's beacons; `fov_deg` is its full field of view."""

    name: str
    mount: Mount
    fov_deg: float


@dataclass(frozen=True)
class ChargingContactsSpec:
    """Where the charging contacts are and which way they face (they must face the dock)."""

    x_mm: float
    y_mm: float
    yaw_deg: float


@dataclass(frozen=True)
class BatterySpec:
    capacity_mah: float
    initial_percent: float
    idle_current_ma: float
    drive_current_ma_per_m_s: float  # extra draw per m/s of mean absolute wheel speed
    charge_current_ma: float


@dataclass(frozen=True)
class WheelSlipSpec:
    """How far the encoders' count strays from the ground the wheels really covered.

    `random_fraction` is the standard deviation of the error per metre of travel as a fraction
    (0.01: 10 mm per metre); the error grows with the square root of the distance, whatever the
    simulation step. The scale errors are systematic (a wheel slightly bigger than its nominal size).
    """

    random_fraction: float
    left_scale_error: float
    right_scale_error: float

    @property
    def is_zero(self) -> bool:
        return self.random_fraction == 0.0 and self.left_scale_error == 0.0 and self.right_scale_error == 0.0


@dataclass(frozen=True)
class BaseDescription:
    """Everything the simulator needs to know about the robot."""

    model: str
    radius_mm: float
    wheel_track_mm: float
    max_wheel_speed_mm_s: float
    max_wheel_accel_mm_s2: float
    distance_sensors: tuple[DistanceSensorSpec, ...]
    bumpers: tuple[BumperSpec, ...]
    cliff_sensors: tuple[CliffSensorSpec, ...]
    beacon_probes: tuple[BeaconProbeSpec, ...]
    charging_contacts: ChargingContactsSpec
    battery: BatterySpec
    wheel_slip: WheelSlipSpec
    seed: int
    source: str = "<dict>"

    def bumper_mounts(self) -> tuple[Mount, ...]:
        return tuple(bumper.mount(self.radius_mm) for bumper in self.bumpers)


DEFAULT_BASE_RESOURCE = "sim-base.json"


def default_base_description() -> BaseDescription:
    """The packaged default robot (ctrlbus/data/sim-base.json)."""
    text = (resources.files("ctrlbus") / "data" / DEFAULT_BASE_RESOURCE).read_text(encoding="utf-8")
    source = f"<default {DEFAULT_BASE_RESOURCE}>"
    return base_description_from_dict(parse_json_text(text, source), source)


def load_base_description(path: str | Path | None = None) -> BaseDescription:
    """Read a base description file; None gives the packaged default. Raises SimConfigError."""
    if path is None:
        return default_base_description()
    data, source = load_json_file(path)
    return base_description_from_dict(data, source)


def base_description_from_dict(data: Any, source: str = "<dict>") -> BaseDescription:
    """Validate parsed JSON; every problem raises SimConfigError naming the key."""
    top = ConfigReader(data, "", source)
    model = top.string("model", "ctrlbus sim")
    if len(model) > MODEL_MAX_LENGTH or not model.isascii():
        raise top.error("model", f"at most {MODEL_MAX_LENGTH} ASCII characters (CONNECT_BASE), got {model!r}")
    radius = top.number("radius_mm", positive=True)
    track = top.number("wheel_track_mm", positive=True, maximum=2.0 * radius)
    max_speed = top.number("max_wheel_speed_mm_s", 500.0, positive=True)
    max_accel = top.number("max_wheel_accel_mm_s2", 1000.0, positive=True)

    sensor_readers = top.children("distance_sensors", max_count=MAX_DISTANCE_SENSORS)
    sensors = tuple(_distance_sensor(reader, index, radius) for index, reader in enumerate(sensor_readers))
    unique_names(sensor_readers, [sensor.name for sensor in sensors])

    bumper_readers = top.children("bumpers", max_count=MAX_BUMPERS)
    bumpers = tuple(_bumper(reader, index) for index, reader in enumerate(bumper_readers))
    unique_names(bumper_readers, [bumper.name for bumper in bumpers])

    cliff_readers = top.children("cliff_sensors", max_count=MAX_CLIFF_SENSORS)
    cliffs = tuple(_cliff_sensor(reader, index, radius) for index, reader in enumerate(cliff_readers))
    unique_names(cliff_readers, [cliff.name for cliff in cliffs])

    probe_readers = top.children("beacon_probes", max_count=MAX_BEACON_PROBES)
    probes = tuple(_beacon_probe(reader, index, radius) for index, reader in enumerate(probe_readers))
    unique_names(probe_readers, [probe.name for probe in probes])

    contacts_reader = top.optional_child("charging_contacts")
    if contacts_reader is None:
        contacts = ChargingContactsSpec(radius, 0.0, 0.0)
    else:
        contacts = ChargingContactsSpec(
            contacts_reader.number("x_mm"), contacts_reader.number("y_mm"), contacts_reader.angle("yaw_deg")
        )
        _check_inside(contacts_reader, contacts.x_mm, contacts.y_mm, radius)
        contacts_reader.finish()

    description = BaseDescription(
        model=model,
        radius_mm=radius,
        wheel_track_mm=track,
        max_wheel_speed_mm_s=max_speed,
        max_wheel_accel_mm_s2=max_accel,
        distance_sensors=sensors,
        bumpers=bumpers,
        cliff_sensors=cliffs,
        beacon_probes=probes,
        charging_contacts=contacts,
        battery=_battery(top.optional_child("battery")),
        wheel_slip=_wheel_slip(top.optional_child("wheel_slip")),
        seed=top.integer("seed", 0, minimum=0),
        source=source,
    )
    top.finish()
    return description


def _check_inside(reader: ConfigReader, x_mm: float, y_mm: float, radius_mm: float) -> None:
    # Parts mounted outside the body would sense from beyond a wall the body touches.
    if math.hypot(x_mm, y_mm) > radius_mm + 1e-9:
        raise reader.error(
            "", f"position ({x_mm:g}, {y_mm:g}) mm lies outside the robot (radius_mm {radius_mm:g})"
        )


def _mount(reader: ConfigReader, radius_mm: float) -> Mount:
    mount = Mount(
        reader.number("x_mm"), reader.number("y_mm"), reader.number("z_mm", 0.0), reader.angle("yaw_deg")
    )
    _check_inside(reader, mount.x_mm, mount.y_mm, radius_mm)
    return mount


def _distance_sensor(reader: ConfigReader, index: int, radius_mm: float) -> DistanceSensorSpec:
    sensor = DistanceSensorSpec(
        name=reader.string("name", f"distance{index}"),
        kind=reader.string("type", "sonar", choices=DISTANCE_SENSOR_TYPES),
        mount=_mount(reader, radius_mm),
        max_range_mm=reader.number("max_range_mm", positive=True),
        beam_deg=reader.number("beam_deg", 0.0, minimum=0.0, maximum=180.0),
        no_echo=reader.string("no_echo", "zero", choices=NO_ECHO_CHOICES),
        noise_stddev_mm=reader.number("noise_stddev_mm", 0.0, minimum=0.0),
    )
    reader.finish()
    return sensor


def _bumper(reader: ConfigReader, index: int) -> BumperSpec:
    bumper = BumperSpec(
        name=reader.string("name", f"bumper{index}"),
        start_deg=reader.angle("start_deg"),
        end_deg=reader.angle("end_deg"),
        z_mm=reader.number("z_mm", 0.0),
    )
    if bumper.start_deg == bumper.end_deg:
        raise reader.error("end_deg", "the arc is empty (start_deg equals end_deg)")
    reader.finish()
    return bumper


def _cliff_sensor(reader: ConfigReader, index: int, radius_mm: float) -> CliffSensorSpec:
    cliff = CliffSensorSpec(
        name=reader.string("name", f"cliff{index}"),
        x_mm=reader.number("x_mm"),
        y_mm=reader.number("y_mm"),
        z_mm=reader.number("z_mm", 0.0),
    )
    _check_inside(reader, cliff.x_mm, cliff.y_mm, radius_mm)
    reader.finish()
    return cliff


def _beacon_probe(reader: ConfigReader, index: int, radius_mm: float) -> BeaconProbeSpec:
    probe = BeaconProbeSpec(
        name=reader.string("name", f"probe{index}"),
        mount=_mount(reader, radius_mm),
        fov_deg=reader.number("fov_deg", positive=True, maximum=360.0),
    )
    reader.finish()
    return probe


def _battery(reader: ConfigReader | None) -> BatterySpec:
    if reader is None:
        return BatterySpec(2600.0, 100.0, 100.0, 1000.0, 1300.0)
    battery = BatterySpec(
        capacity_mah=reader.number("capacity_mah", positive=True),
        initial_percent=reader.number("initial_percent", 100.0, minimum=0.0, maximum=100.0),
        idle_current_ma=reader.number("idle_current_ma", 0.0, minimum=0.0),
        drive_current_ma_per_m_s=reader.number("drive_current_ma_per_m_s", 0.0, minimum=0.0),
        charge_current_ma=reader.number("charge_current_ma", positive=True),
    )
    reader.finish()
    return battery


def _wheel_slip(reader: ConfigReader | None) -> WheelSlipSpec:
    if reader is None:
        return WheelSlipSpec(0.0, 0.0, 0.0)
    slip = WheelSlipSpec(
        random_fraction=reader.number("random_fraction", 0.0, minimum=0.0, maximum=1.0),
        left_scale_error=reader.number("left_scale_error", 0.0, minimum=-0.5, maximum=0.5),
        right_scale_error=reader.number("right_scale_error", 0.0, minimum=-0.5, maximum=0.5),
    )
    reader.finish()
    return slip
