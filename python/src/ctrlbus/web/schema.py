# SPDX-License-Identifier: MIT
"""The dashboard snapshot schema (docs/dashboard.md), as a checker.

`check_snapshot(snapshot)` lists every way a snapshot departs from the schema, so the tests of
whatever produces snapshots (the Core emulator, the simulator adapter) can assert it is empty.
The schema is written once, here, as data; docs/dashboard.md explains each field.
"""

from __future__ import annotations

import math
from typing import Any

from ctrlbus.core.events import MAX_EVENTS  # the schema's limits are the Core's own
from ctrlbus.core.telemetry import BLOB_STATES, MAX_TRAIL_POINTS

__all__ = [
    "COMMAND_MODES",
    "CONNECTION_STATES",
    "MAX_EVENTS",
    "MAX_TRAIL_POINTS",
    "MOUNT",
    "POSE",
    "SCHEMA_VERSION",
    "SIM",
    "SNAPSHOT",
    "XY",
    "Spec",
    "check_snapshot",
]

SCHEMA_VERSION = 1

# A spec is one of: a type name ("num", "int", "bool", "str"), a type name with "?" (may be
# null), ("enum", values), ("list", item_spec), ("point",) for [x_mm, y_mm], ("map", value_spec)
# for an object with free text keys, or a dict of key -> spec where a key ending in "?" may be
# absent.
Spec = Any

POSE: Spec = {"x_mm": "num", "y_mm": "num", "theta_deg": "num"}
MOUNT: Spec = {"x_mm": "num", "y_mm": "num", "z_mm": "num", "angle_deg": "num"}
CONNECTION_STATES = ("connecting", "configuring", "connected", "disconnected")
COMMAND_MODES = ("idle", "teleop", "external", "go_home", "estop")

# The simulator's own picture (ctrlbus.sim.base.SimulatedBase.snapshot(): the world's snapshot,
# room and trail included, the time scale and the queued external commands), plus where the
# Core's dead-reckoned frame sits in the room, which only the program running both knows.
XY: Spec = {"x_mm": "num", "y_mm": "num"}
SIM: Spec = {
    "time_s": "num",
    "robot": {"model": "str", "radius_mm": "num", "wheel_track_mm": "num"},
    "pose": POSE,
    "odometry_pose": POSE,
    "wheels": {
        "commanded_mm_s": ("list", "num"),
        "speed_mm_s": ("list", "num"),
        "encoders_mm": ("list", "num"),
    },
    "distance_sensors": (
        "list",
        {
            "name": "str",
            "type": "str",
            **XY,
            "heading_deg": "num",
            "beam_deg": "num",
            "max_range_mm": "num",
            "hit_mm": "num?",
            "reading_mm": "num",
        },
    ),
    "bumpers": ("list", {"name": "str", "start_deg": "num", "end_deg": "num", "pressed": "bool"}),
    "cliff_sensors": ("list", {"name": "str", **XY, "triggered": "bool"}),
    "beacon_probes": (
        "list",
        {"name": "str", **XY, "heading_deg": "num", "fov_deg": "num", "beacon_bits": "int"},
    ),
    "battery": {
        "percent": "num",
        "charging": "bool",
        "dc_connected": "bool",
        "docked": "bool",
        "power_status": "int",
    },
    "motion": {"held_by": "str?", "stalled": "bool", "traction_lost": "bool"},
    "trail": ("list", ("point",)),
    "room": {
        "name": "str",
        "walls": ("list", {"points": ("list", ("point",)), "closed": "bool"}),
        "cliffs": ("list", {"name": "str", "points": ("list", ("point",))}),
        "dock": (
            "nullable",
            {
                **XY,
                "heading_deg": "num",
                "contact_radius_mm": "num",
                "beacons": (
                    "list",
                    {
                        "name": "str",
                        "code": "int",
                        **XY,
                        "heading_deg": "num",
                        "cone_deg": "num",
                        "range_mm": "num",
                    },
                ),
            },
        ),
    },
    "odometry_origin": POSE,
    "speed": "num",
    "pending_commands": ("list", "int"),
}

SNAPSHOT: Spec = {
    "schema": "int",
    "time_s": "num",
    "base": (
        "nullable",
        {
            "model": "str",
            "firmware_version": "str",
            "hardware_version": "int",
            "serial": "str",
            "shape": ("enum", ("circle", "square")),
            "radius_mm": "num",
            "config_source": ("enum", ("GET_BASE_CONF", "GET_BASE_CONF_ADV")),
            "views?": (
                "map",
                {"radius_mm": "num", "distance_sensors": "int", "bumpers": "int", "cliffs": "int"},
            ),
            "blob?": ("nullable", ("enum", BLOB_STATES)),
        },
    ),
    "limits": {"vx_mps": "num", "omega_radps": "num"},
    "pose": POSE,
    "trail": ("list", ("point",)),
    "command": {
        "vx_mps": "num",
        "omega_radps": "num",
        "estop": "bool",
        "mode": ("enum", COMMAND_MODES),
        "activity": "str?",
    },
    "motion": {"status": "int?", "stall": "bool", "traction_lost": "bool"},
    "battery": {
        "percent": "int?",
        "power_status": "int?",
        "charging": "bool",
        "dc_connected": "bool",
        "on_dock": "bool",
    },
    "sensors": ("list", {**MOUNT, "distance_mm": "num?"}),
    "bumper_bitmap": "int?",
    "bumpers": ("list", {**MOUNT, "bit": "int", "pressed": "bool"}),
    "cliffs": ("list", {"bit": "int", "triggered": "bool"}),
    "ignored_sensors?": (
        "list",
        {"slot": "int", "distance_mm": "num", "mount": ("nullable", MOUNT), "mount_source": "str?"},
    ),
    "warnings?": ("list", "str"),
    "charger": ("nullable", {"beacon_count": "int", "probe_count": "int", "probes": ("list", "int")}),
    "health": {
        "flags": "int?",
        "warning": "bool",
        "error": "bool",
        "fatal": "bool",
        "errors": ("list", {"code": "int", "message": "str"}),
    },
    "events": (
        "list",
        {"seq": "int", "t_s": "num", "direction": ("enum", ("core", "base")), "text": "str"},
    ),
    "link": {
        "connection": {
            "state": ("enum", CONNECTION_STATES),
            "port": "str",
            "since_s": "num",
            "connects": "int",
        },
        "requests": "int",
        "requests_per_s": "num",
        "latency_p50_ms": "num?",
        "latency_p99_ms": "num?",
        "errors_by_code": ("map", "int"),
        "checksum_failures": "int",
        "resyncs": "int",
        "timeouts": "int",
        "watchdog_trips": "int",
        "retries": "int",
        "lost_requests?": "int",
        "superseded?": "int",
        "line_faults_by_bit?": ("map", "int"),
    },
    "sim?": SIM,
}


def check_snapshot(snapshot: object) -> list[str]:
    """Every departure from the schema, as 'path: problem' lines; empty when it conforms."""
    problems: list[str] = []
    _check(snapshot, SNAPSHOT, "snapshot", problems)
    if not problems and isinstance(snapshot, dict):
        if snapshot["schema"] != SCHEMA_VERSION:
            problems.append(f"snapshot.schema: expected {SCHEMA_VERSION}, got {snapshot['schema']}")
        if len(snapshot["trail"]) > MAX_TRAIL_POINTS:
            problems.append(f"snapshot.trail: more than {MAX_TRAIL_POINTS} points")
        if len(snapshot["events"]) > MAX_EVENTS:
            problems.append(f"snapshot.events: more than {MAX_EVENTS} entries")
        sim = snapshot.get("sim")
        if isinstance(sim, dict) and len(sim["trail"]) > MAX_TRAIL_POINTS:
            problems.append(f"snapshot.sim.trail: more than {MAX_TRAIL_POINTS} points")
    return problems


def _check(value: object, spec: Spec, path: str, problems: list[str]) -> None:
    if isinstance(spec, str):
        _check_scalar(value, spec, path, problems)
    elif isinstance(spec, dict):
        if not isinstance(value, dict):
            problems.append(f"{path}: expected an object, got {_type_name(value)}")
            return
        expected = {key.rstrip("?") for key in spec}
        for key, item_spec in spec.items():
            name = key.rstrip("?")
            if name not in value:
                if not key.endswith("?"):
                    problems.append(f"{path}.{name}: missing")
                continue
            _check(value[name], item_spec, f"{path}.{name}", problems)
        for key in value:
            if key not in expected:
                problems.append(f"{path}.{key}: not in the schema")
    elif spec[0] == "nullable":
        if value is not None:
            _check(value, spec[1], path, problems)
    elif spec[0] == "enum":
        if value not in spec[1]:
            problems.append(f"{path}: {value!r} is not one of {', '.join(map(str, spec[1]))}")
    elif spec[0] == "list":
        if not isinstance(value, list):
            problems.append(f"{path}: expected a list, got {_type_name(value)}")
            return
        for index, item in enumerate(value):
            _check(item, spec[1], f"{path}[{index}]", problems)
    elif spec[0] == "map":
        if not isinstance(value, dict):
            problems.append(f"{path}: expected an object, got {_type_name(value)}")
            return
        for key, item in value.items():
            _check(item, spec[1], f"{path}.{key}", problems)
    elif spec[0] == "point":
        if not (isinstance(value, list) and len(value) == 2):
            problems.append(f"{path}: expected [x_mm, y_mm], got {value!r}")
            return
        _check_scalar(value[0], "num", f"{path}[0]", problems)
        _check_scalar(value[1], "num", f"{path}[1]", problems)
    else:  # pragma: no cover - a mistake in the spec above
        raise ValueError(f"bad spec at {path}: {spec!r}")


def _check_scalar(value: object, kind: str, path: str, problems: list[str]) -> None:
    if kind.endswith("?"):
        if value is None:
            return
        kind = kind[:-1]
    ok: bool
    if kind == "num":
        ok = isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)
    elif kind == "int":
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif kind == "bool":
        ok = isinstance(value, bool)
    elif kind == "str":
        ok = isinstance(value, str)
    else:  # pragma: no cover - a mistake in the spec above
        raise ValueError(f"bad scalar spec {kind!r} at {path}")
    if not ok:
        problems.append(f"{path}: expected {kind}{' or null' if value is None else ''}, got {value!r}"[:200])


def _type_name(value: object) -> str:
    return "null" if value is None else type(value).__name__
