# SPDX-License-Identifier: MIT
"""The simulated room: walls, cliff areas, the charging dock and its IR beacons (docs/simulator.md).

World frame: millimetres, x to the right, y up, angles anticlockwise from +x. `load_room(path)`
reads a JSON file; with no path it reads the packaged default, ctrlbus/data/sim-room.json.
"""

from __future__ import annotations

from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

from ctrlbus.kinematics import Pose, normalize_angle_deg, to_world
from ctrlbus.sim.config import ConfigReader, load_json_file, parse_json_text, unique_names
from ctrlbus.sim.geometry import Point, Segment, polyline_segments

__all__ = [
    "DEFAULT_ROOM_RESOURCE",
    "MAX_BEACONS",
    "MAX_SHAPES",
    "BeaconSpec",
    "CliffArea",
    "DockSpec",
    "Room",
    "WallShape",
    "default_room",
    "load_room",
    "room_from_dict",
]

MAX_BEACONS = 8  # one bit each in a GET_CHARGER_DATA probe byte
MAX_SHAPES = 256


@dataclass(frozen=True)
class WallShape:
    """A wall as a polyline; `closed` joins the last point to the first (a room outline, a box)."""

    points: tuple[Point, ...]
    closed: bool


@dataclass(frozen=True)
class CliffArea:
    """A polygon where the floor drops away (stairs)."""

    name: str
    points: tuple[Point, ...]


@dataclass(frozen=True)
class BeaconSpec:
    """An IR emitter on the dock: position and aim in the dock frame, a cone of `cone_deg` (full)."""

    name: str
    code: int
    x_mm: float
    y_mm: float
    yaw_deg: float
    cone_deg: float
    range_mm: float


@dataclass(frozen=True)
class DockSpec:
    """The charging dock.

    (x_mm, y_mm) is where the robot's charging contacts meet the dock and heading_deg the direction
    the dock faces (out into the room). A robot is docked when its contacts are within
    `contact_radius_mm` of that point and face the dock within `contact_angle_deg`.
    """

    x_mm: float
    y_mm: float
    heading_deg: float
    contact_radius_mm: float
    contact_angle_deg: float
    beacons: tuple[BeaconSpec, ...]

    @property
    def pose(self) -> Pose:
        return Pose(self.x_mm, self.y_mm, normalize_angle_deg(self.heading_deg))

    def beacon_pose(self, beacon: BeaconSpec) -> Pose:
        """Where a beacon is in the world and which way its cone points."""
        x, y = to_world(self.pose, beacon.x_mm, beacon.y_mm)
        return Pose(x, y, normalize_angle_deg(self.heading_deg + beacon.yaw_deg))


@dataclass(frozen=True)
class Room:
    name: str
    walls: tuple[WallShape, ...]
    wall_segments: tuple[Segment, ...]
    cliffs: tuple[CliffArea, ...]
    dock: DockSpec | None
    start_pose: Pose
    source: str = "<dict>"


DEFAULT_ROOM_RESOURCE = "sim-room.json"


def default_room() -> Room:
    """The packaged default room (ctrlbus/data/sim-room.json)."""
    text = (resources.files("ctrlbus") / "data" / DEFAULT_ROOM_RESOURCE).read_text(encoding="utf-8")
    source = f"<default {DEFAULT_ROOM_RESOURCE}>"
    return room_from_dict(parse_json_text(text, source), source)


def load_room(path: str | Path | None = None) -> Room:
    """Read a room file; None gives the packaged default. Raises SimConfigError."""
    if path is None:
        return default_room()
    data, source = load_json_file(path)
    return room_from_dict(data, source)


def room_from_dict(data: Any, source: str = "<dict>") -> Room:
    """Validate parsed JSON; every problem raises SimConfigError naming the key."""
    top = ConfigReader(data, "", source)
    name = top.string("name", "room")

    walls: list[WallShape] = []
    for reader in top.children("walls", max_count=MAX_SHAPES, required=True):
        walls.append(WallShape(reader.points("points", min_count=2), reader.boolean("closed", False)))
        reader.finish()
    if not walls:
        raise top.error("walls", "needs at least one wall")
    segments = tuple(segment for wall in walls for segment in polyline_segments(wall.points, wall.closed))

    cliff_readers = top.children("cliffs", max_count=MAX_SHAPES)
    cliffs: list[CliffArea] = []
    for index, reader in enumerate(cliff_readers):
        cliffs.append(CliffArea(reader.string("name", f"cliff{index}"), reader.points("points", min_count=3)))
        reader.finish()
    unique_names(cliff_readers, [cliff.name for cliff in cliffs])

    dock_reader = top.optional_child("dock")
    dock = None if dock_reader is None else _dock(dock_reader)

    pose_reader = top.child("start_pose")
    start_pose = Pose(
        pose_reader.number("x_mm"),
        pose_reader.number("y_mm"),
        normalize_angle_deg(pose_reader.number("theta_deg", 0.0, minimum=-360.0, maximum=360.0)),
    )
    pose_reader.finish()
    top.finish()
    return Room(name, tuple(walls), segments, tuple(cliffs), dock, start_pose, source)


def _dock(reader: ConfigReader) -> DockSpec:
    x_mm = reader.number("x_mm")
    y_mm = reader.number("y_mm")
    heading = reader.angle("heading_deg")
    contact_radius = reader.number("contact_radius_mm", 25.0, positive=True)
    contact_angle = reader.number("contact_angle_deg", 20.0, minimum=0.0, maximum=180.0)
    beacon_readers = reader.children("beacons", max_count=MAX_BEACONS)
    beacons: list[BeaconSpec] = []
    for index, beacon_reader in enumerate(beacon_readers):
        beacons.append(
            BeaconSpec(
                name=beacon_reader.string("name", f"beacon{index}"),
                code=beacon_reader.integer("code", 0, minimum=0, maximum=255),
                x_mm=beacon_reader.number("x_mm", 0.0),
                y_mm=beacon_reader.number("y_mm", 0.0),
                yaw_deg=beacon_reader.angle("yaw_deg", 0.0),
                cone_deg=beacon_reader.number("cone_deg", positive=True, maximum=360.0),
                range_mm=beacon_reader.number("range_mm", positive=True),
            )
        )
        beacon_reader.finish()
    unique_names(beacon_readers, [beacon.name for beacon in beacons])
    reader.finish()
    return DockSpec(x_mm, y_mm, heading, contact_radius, contact_angle, tuple(beacons))
