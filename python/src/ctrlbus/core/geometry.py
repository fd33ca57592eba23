# SPDX-License-Identifier: MIT
"""What the Core knows of the base's body: shape, size and where its sensors sit.

It comes from GET_BASE_CONF (0x20, fixed layout) or from the binary configuration tree of
GET_BASE_CONF_ADV (0x21, decoded by ctrlbus.binconf), which the Core prefers when the base serves
one. The tree is metres and radians; everything here is millimetres and degrees (0..360, as the
0x20 layout has them).
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass

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
]

SOURCE_CONF = "GET_BASE_CONF"
SOURCE_CONF_ADV = "GET_BASE_CONF_ADV"
BUMPER_BITS = 32
SENSOR_SLOTS = 16
# The reference puts its cliff sensors in the 4 bits after the bumpers (protocol §5.7).
REFERENCE_CLIFF_BITS = 4
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

    `robot_size` is read as the radius in metres, `sensors[]` entries by their `type`: bumpers and
    cliffs by name, anything else is a distance sensor. An entry's `id` is its slot (distance
    sensors) or bit (bumpers); cliff ids count from the bit after the last bumper, as the
    reference lays its bitmap out. Entries without an id take their order.
    """
    base = tree.get("base")
    if not isinstance(base, dict):
        return None
    radius_m = _number(base.get("robot_size", None))
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
    first_cliff = len(bumpers)
    cliffs = tuple(
        sorted(
            {
                first_cliff + (ident if ident is not None and ident >= 0 else order)
                for order, ident in enumerate(cliff_entries)
            }
            & set(range(BUMPER_BITS))
        )
    )
    return BaseGeometry(
        source=SOURCE_CONF_ADV,
        shape="circle",
        radius_mm=0.0 if radius_m is None else radius_m * 1000.0,
        sensors=tuple(distance),
        bumpers=bumpers,
        cliff_bits=cliffs,
    )
