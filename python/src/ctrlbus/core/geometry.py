# SPDX-License-Identifier: MIT
"""What the Core knows of the base's body: shape, size and where its sensors sit.

It comes from GET_BASE_CONF (0x20, fixed layout) or from the binary configuration tree of
GET_BASE_CONF_ADV (0x21, decoded by ctrlbus.binconf), which the Core prefers when the base serves
one. The tree is metres, radians and fractions, as the reference's own blob has them, and its
`robot_size` is the robot's DIAMETER (0.36 for the reference base whose GET_BASE_CONF says radius
180 mm); everything here is millimetres and degrees (0..360, as the 0x20 layout has them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

from ctrlbus import protocol_tables
from ctrlbus.binconf import JsonValue
from ctrlbus.messages import GetBaseConfAnswer, Position

__all__ = [
    "BUMPER_BITS",
    "NOT_DISTANCE_TYPES",
    "REFERENCE_CLIFF_BITS",
    "SENSOR_SLOTS",
    "SOURCE_CONF",
    "SOURCE_CONF_ADV",
    "BaseGeometry",
    "Bumper",
    "DistanceSensor",
    "Mount",
    "geometry_from_conf",
    "geometry_from_tree",
    "shared_bits",
]

SOURCE_CONF = "GET_BASE_CONF"
SOURCE_CONF_ADV = "GET_BASE_CONF_ADV"
BUMPER_BITS = 32
SENSOR_SLOTS = 16
# The reference puts its cliff sensors in the 4 bits after the bumpers (protocol §5.7): the
# description's bumper_bitmap groups (protocol/ctrlbus.json).
REFERENCE_CLIFF_BITS = len(protocol_tables.REFERENCE_CLIFFS_BITS)
# Configuration-tree sensor types that are not distance sensors.
NOT_DISTANCE_TYPES = frozenset({"bumper", "cliff"})


@dataclass(frozen=True)
class Mount:
    """Where a sensor sits on the robot: mm from the centre (x forward, y left, z up), and the
    direction it faces in degrees anticlockwise, 0..360."""

    x_mm: float
    y_mm: float
    z_mm: float
    angle_deg: float

    def as_dict(self) -> dict[str, float]:
        return {"x_mm": self.x_mm, "y_mm": self.y_mm, "z_mm": self.z_mm, "angle_deg": self.angle_deg}


@dataclass(frozen=True)
class DistanceSensor:
    mount: Mount
    slot: int  # index in GET_BASE_SENSOR_DATA's 16 distances


@dataclass(frozen=True)
class Bumper:
    mount: Mount
    bit: int  # bit in GET_BASE_BUMPER_DATA's active-low bitmap


@dataclass(frozen=True)
class BaseGeometry:
    source: str  # SOURCE_CONF or SOURCE_CONF_ADV
    shape: str  # "circle" or "square"
    radius_mm: float
    sensors: tuple[DistanceSensor, ...]
    bumpers: tuple[Bumper, ...]
    cliff_bits: tuple[int, ...]


def _mount_from_position(position: Position) -> Mount:
    return Mount(position.x_mm, position.y_mm, position.z_mm, position.angle_deg)


def geometry_from_conf(conf: GetBaseConfAnswer) -> BaseGeometry:
    """The geometry in a GET_BASE_CONF answer; cliffs are read where the reference puts them."""
    sensors = tuple(
        DistanceSensor(_mount_from_position(conf.sensors[slot]), slot) for slot in range(conf.sensor_num)
    )
    bumpers = tuple(Bumper(_mount_from_position(conf.bumpers[bit]), bit) for bit in range(conf.bumper_num))
    first_cliff = conf.bumper_num
    cliffs = tuple(range(first_cliff, min(BUMPER_BITS, first_cliff + REFERENCE_CLIFF_BITS)))
    return BaseGeometry(
        source=SOURCE_CONF,
        shape="square" if conf.base_type == 1 else "circle",
        radius_mm=conf.base_radius_mm,
        sensors=sensors,
        bumpers=bumpers,
        cliff_bits=cliffs,
    )


def _number(value: JsonValue) -> float | None:
    """A number of the tree: a float32 is a JSON number, an integer is {"u8"|"u16"|"s32": n}."""
    if isinstance(value, bool):
        return None
    if isinstance(value, int | float):
        return float(value) if math.isfinite(value) else None
    if isinstance(value, dict) and len(value) == 1:
        (tag, inner), *_ = value.items()
        if tag in ("u8", "u16", "s32") and isinstance(inner, int) and not isinstance(inner, bool):
            return float(inner)
    return None


def _name(value: JsonValue) -> str | None:
    """A string of the tree: plain text, or a dictionary id {"dict": "sonar"}."""
    if isinstance(value, str):
        return value
    if isinstance(value, dict) and len(value) == 1 and isinstance(value.get("dict"), str):
        text = value["dict"]
        assert isinstance(text, str)
        return text
    return None


def _mount_from_pose(pose: JsonValue) -> Mount:
    values = pose if isinstance(pose, dict) else {}

    def metres(key: str) -> float:
        number = _number(values.get(key))
        return 0.0 if number is None else number * 1000.0

    yaw = _number(values.get("yaw"))
    angle = 0.0 if yaw is None else math.degrees(yaw) % 360.0
    return Mount(metres("x"), metres("y"), metres("z"), angle)


def geometry_from_tree(tree: Mapping[str, JsonValue]) -> BaseGeometry | None:
    """The geometry in a decoded configuration tree, or None if it has no `base` object.

    `robot_size` is read as the diameter in metres, `sensors[]` entries by their `type`: bumpers and
    cliffs by name, anything else is a distance sensor. An entry's `id` is its slot (distance
    sensors) or bit in GET_BASE_BUMPER_DATA's bitmap (bumpers and cliffs alike: the reference's
    blob gives its cliffs ids 2-5, the bits protocol §5.7 puts them in). Distance sensors and
    bumpers without an id take their order; cliffs without one the free bits after the bumpers.
    """
    base = tree.get("base")
    if not isinstance(base, dict):
        return None
    diameter_m = _number(base.get("robot_size", None))
    entries = base.get("sensors")
    distance: list[DistanceSensor] = []
    bumper_entries: list[tuple[Mount, int | None]] = []
    cliff_entries: list[int | None] = []
    for entry in entries if isinstance(entries, list) else []:
        if not isinstance(entry, dict):
            continue
        kind = _name(entry.get("type")) or ""
        ident_number = _number(entry.get("id"))
        ident = int(ident_number) if ident_number is not None else None
        mount = _mount_from_pose(entry.get("installation_pose"))
        if kind == "bumper":
            bumper_entries.append((mount, ident))
        elif kind == "cliff":
            cliff_entries.append(ident)
        else:
            slot = ident if ident is not None and 0 <= ident < SENSOR_SLOTS else len(distance)
            if slot < SENSOR_SLOTS:
                distance.append(DistanceSensor(mount, slot))
    bumpers = tuple(
        Bumper(mount, ident if ident is not None and 0 <= ident < BUMPER_BITS else order)
        for order, (mount, ident) in enumerate(bumper_entries)
    )
    # A cliff sensor's id is its bit, as a bumper's is: the reference's own blob numbers its cliffs
    # 2-5, the bits its bitmap carries them in (protocol §5.7). One without a usable id takes the
    # next bit after the bumpers (and the cliffs with ids) that is still free.
    cliff_set = {ident for ident in cliff_entries if ident is not None and 0 <= ident < BUMPER_BITS}
    after_bumpers = 1 + max((bumper.bit for bumper in bumpers), default=-1)
    free = (bit for bit in range(after_bumpers, BUMPER_BITS) if bit not in cliff_set)
    for ident in cliff_entries:
        if ident is None or not 0 <= ident < BUMPER_BITS:
            bit = next(free, None)
            if bit is not None:
                cliff_set.add(bit)
    cliffs = tuple(sorted(cliff_set))
    return BaseGeometry(
        source=SOURCE_CONF_ADV,
        shape="circle",
        radius_mm=0.0 if diameter_m is None else diameter_m * 1000.0 / 2.0,
        sensors=tuple(distance),
        bumpers=bumpers,
        cliff_bits=cliffs,
    )


def shared_bits(geometry: BaseGeometry) -> tuple[int, ...]:
    """Bitmap bits that are both a bumper's and a cliff's: a blob that numbers its cliffs from 0
    (as ctrlbus's own example did before issue 23) instead of by their bits."""
    return tuple(sorted({bumper.bit for bumper in geometry.bumpers} & set(geometry.cliff_bits)))


# How far the two sources may differ before it counts as a disagreement: the blob's float metres
# against GET_BASE_CONF's Q8 millimetres round differently, by far less than this.
RADIUS_TOLERANCE_MM = 2.0
POSITION_TOLERANCE_MM = 5.0
ANGLE_TOLERANCE_DEG = 2.0


def _angle_apart(a_deg: float, b_deg: float) -> float:
    return abs((a_deg - b_deg + 180.0) % 360.0 - 180.0)


def _mount_text(mount: Mount) -> str:
    return f"({mount.x_mm:.0f}, {mount.y_mm:.0f}) mm {mount.angle_deg:.0f}°"


@dataclass(frozen=True)
class Disagreement:
    """One way the two configuration sources disagree. `kind`: radius, sensor_count,
    sensor_position or bumper_count; `missing_slots`: distance channels GET_BASE_CONF lists and
    the blob does not."""

    kind: str
    text: str
    missing_slots: tuple[int, ...] = ()

    def __str__(self) -> str:
        return self.text


def compare_geometries(adv: BaseGeometry, conf: BaseGeometry) -> list[Disagreement]:
    """Where the 0x21 blob's geometry (`adv`) and GET_BASE_CONF's (`conf`) disagree, one item
    each; empty when they agree. A Core reads only one of them, so each item is something that
    Core gets wrong (or misses) about the robot."""
    problems: list[Disagreement] = []
    if abs(adv.radius_mm - conf.radius_mm) > RADIUS_TOLERANCE_MM:
        problems.append(
            Disagreement(
                "radius",
                f"radius: the blob's robot_size/2 is {adv.radius_mm:.0f} mm, "
                f"GET_BASE_CONF says {conf.radius_mm:.0f} mm",
            )
        )
    adv_slots = {sensor.slot: sensor.mount for sensor in adv.sensors}
    conf_slots = {sensor.slot: sensor.mount for sensor in conf.sensors}
    if len(adv_slots) != len(conf_slots):
        missing = tuple(sorted(set(conf_slots) - set(adv_slots)))
        extra = f" (channels {', '.join(map(str, missing))} are missing from the blob)" if missing else ""
        problems.append(
            Disagreement(
                "sensor_count",
                f"distance sensors: the blob lists {len(adv_slots)}, GET_BASE_CONF {len(conf_slots)}{extra}",
                missing,
            )
        )
    for slot in sorted(set(adv_slots) & set(conf_slots)):
        a, c = adv_slots[slot], conf_slots[slot]
        if (
            math.hypot(a.x_mm - c.x_mm, a.y_mm - c.y_mm) > POSITION_TOLERANCE_MM
            or _angle_apart(a.angle_deg, c.angle_deg) > ANGLE_TOLERANCE_DEG
        ):
            problems.append(
                Disagreement(
                    "sensor_position",
                    f"distance sensor {slot}: the blob puts it at {_mount_text(a)}, "
                    f"GET_BASE_CONF at {_mount_text(c)}",
                )
            )
    if len(adv.bumpers) != len(conf.bumpers):
        problems.append(
            Disagreement(
                "bumper_count",
                f"bumpers: the blob lists {len(adv.bumpers)}, GET_BASE_CONF {len(conf.bumpers)}",
            )
        )
    return problems


def geometry_view(geometry: BaseGeometry) -> dict[str, float | int]:
    """A short summary of one source's geometry, for a status display."""
    return {
        "radius_mm": round(geometry.radius_mm, 1),
        "distance_sensors": len(geometry.sensors),
        "bumpers": len(geometry.bumpers),
        "cliffs": len(geometry.cliff_bits),
    }
