# SPDX-License-Identifier: MIT
"""Plane geometry for the simulated world: points, wall segments, rays, polygons, arcs (mm, degrees)."""

from __future__ import annotations

import itertools
import math

__all__ = [
    "Point",
    "Segment",
    "angle_between_deg",
    "angle_in_arc",
    "closest_point_on_segment",
    "distance_to_segment",
    "line_of_sight",
    "nearest_hit",
    "point_in_polygon",
    "polyline_segments",
    "ray_hit_distance",
]

Point = tuple[float, float]
Segment = tuple[Point, Point]

# Rays parallel to a wall (cross product below this) never hit it; they graze along it.
_PARALLEL_EPS = 1e-12


def closest_point_on_segment(point: Point, segment: Segment) -> Point:
    """The point of `segment` nearest to `point`."""
    (ax, ay), (bx, by) = segment
    ex = bx - ax
    ey = by - ay
    length_sq = ex * ex + ey * ey
    if length_sq == 0.0:
        return ax, ay
    t = ((point[0] - ax) * ex + (point[1] - ay) * ey) / length_sq
    t = min(1.0, max(0.0, t))
    return ax + t * ex, ay + t * ey


def distance_to_segment(point: Point, segment: Segment) -> float:
    cx, cy = closest_point_on_segment(point, segment)
    return math.hypot(point[0] - cx, point[1] - cy)


def ray_hit_distance(origin: Point, heading_deg: float, segment: Segment) -> float | None:
    """How far along the ray from `origin` towards `heading_deg` it meets `segment`; None if never."""
    dx = math.cos(math.radians(heading_deg))
    dy = math.sin(math.radians(heading_deg))
    (ax, ay), (bx, by) = segment
    ex = bx - ax
    ey = by - ay
    denom = dx * ey - dy * ex
    if abs(denom) < _PARALLEL_EPS:
        return None
    ox = ax - origin[0]
    oy = ay - origin[1]
    along_ray = (ox * ey - oy * ex) / denom
    along_segment = (ox * dy - oy * dx) / denom
    if along_ray < 0.0 or along_segment < 0.0 or along_segment > 1.0:
        return None
    return along_ray


def nearest_hit(origin: Point, heading_deg: float, segments: tuple[Segment, ...]) -> float | None:
    """Distance to the first of `segments` the ray meets, or None."""
    best: float | None = None
    for segment in segments:
        hit = ray_hit_distance(origin, heading_deg, segment)
        if hit is not None and (best is None or hit < best):
            best = hit
    return best


def line_of_sight(a: Point, b: Point, segments: tuple[Segment, ...], *, margin_mm: float = 1e-6) -> bool:
    """True when no segment crosses the open line from `a` to `b`.

    A wall within `margin_mm` of either end does not block: an emitter mounted on a wall must
    still see into the room.
    """
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    if length <= 2.0 * margin_mm:
        return True
    heading = math.degrees(math.atan2(b[1] - a[1], b[0] - a[0]))
    for segment in segments:
        hit = ray_hit_distance(a, heading, segment)
        if hit is not None and margin_mm < hit < length - margin_mm:
            return False
    return True


def point_in_polygon(point: Point, polygon: tuple[Point, ...]) -> bool:
    """Even-odd rule; points exactly on an edge may fall either way."""
    x, y = point
    inside = False
    count = len(polygon)
    for index in range(count):
        x1, y1 = polygon[index]
        x2, y2 = polygon[(index + 1) % count]
        if (y1 > y) != (y2 > y):
            crossing_x = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x < crossing_x:
                inside = not inside
    return inside


def polyline_segments(points: tuple[Point, ...], closed: bool) -> tuple[Segment, ...]:
    """The segments joining consecutive points (and the last to the first when `closed`)."""
    pairs = list(itertools.pairwise(points))
    if closed and len(points) > 2:
        pairs.append((points[-1], points[0]))
    return tuple(pairs)


def angle_in_arc(angle_deg: float, start_deg: float, end_deg: float) -> bool:
    """Whether `angle_deg` lies on the arc running anticlockwise from `start_deg` to `end_deg`."""
    span = (end_deg - start_deg) % 360.0
    if span == 0.0 and end_deg != start_deg:
        return True  # a full circle, e.g. 0 to 360
    return (angle_deg - start_deg) % 360.0 <= span


def angle_between_deg(a_deg: float, b_deg: float) -> float:
    """The unsigned angle between two directions, in [0, 180]."""
    difference = abs(a_deg - b_deg) % 360.0
    return 360.0 - difference if difference > 180.0 else difference
