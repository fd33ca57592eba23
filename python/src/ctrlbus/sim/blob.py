# SPDX-License-Identifier: MIT
"""The binary configuration (GET_BASE_CONF_ADV blob) the simulated base serves by default.

It is made from the base description, so that it describes the same robot GET_BASE_CONF does
(protocol §12.4 [conf-agree]): `robot_size` is the diameter in metres, each distance sensor is
listed with its GET_BASE_SENSOR_DATA channel as `id` (a sonar by its dictionary type, an IR range
finder with the plain string type "ir", for which the dictionary has no id), each bumper and cliff
sensor with its bit in GET_BASE_BUMPER_DATA's bitmap as `id` (bumpers first, cliffs after them,
as the simulated base sets them and as the reference numbers its own). Poses are metres and
radians. Unlike the reference's blob it lists every distance sensor, so a Core that reads only
the blob sees them all.
"""

from __future__ import annotations

import math

from ctrlbus import binconf
from ctrlbus.binconf import JsonValue
from ctrlbus.errors import UsageError
from ctrlbus.sim.description import BaseDescription, Mount

__all__ = ["MAX_BLOB_BYTES", "blob_from_description", "tree_from_description"]

MAX_BLOB_BYTES = 507  # the reference's answer buffer (protocol §3): a longer blob is never sent


def _metres(value_mm: float) -> float:
    return value_mm / 1000.0


def _pose(mount: Mount) -> JsonValue:
    return {
        "x": _metres(mount.x_mm),
        "y": _metres(mount.y_mm),
        "z": _metres(mount.z_mm),
        "yaw": math.remainder(math.radians(mount.yaw_deg), math.tau),
    }


def _entry(kind: str, ident: int, mount: Mount) -> JsonValue:
    # Dictionary types travel as one byte; "ir" has no dictionary id, so it goes as a string.
    kind_value: JsonValue = {"dict": kind} if kind in binconf.DICTIONARY_IDS else kind
    return {"type": kind_value, "id": {"u8": ident}, "installation_pose": _pose(mount)}


def tree_from_description(base: BaseDescription) -> dict[str, JsonValue]:
    """The configuration tree of the simulated robot `base` (binconf's JSON form)."""
    sensors: list[JsonValue] = [
        _entry(sensor.kind, channel, sensor.mount) for channel, sensor in enumerate(base.distance_sensors)
    ]
    bumpers = base.bumper_mounts()
    sensors += [_entry("bumper", bit, mount) for bit, mount in enumerate(bumpers)]
    sensors += [
        _entry("cliff", len(bumpers) + index, Mount(cliff.x_mm, cliff.y_mm, cliff.z_mm, 0.0))
        for index, cliff in enumerate(base.cliff_sensors)
    ]
    return {
        "base": {
            "model_name": base.model,
            "robot_size": _metres(2 * base.radius_mm),
            "wheel_span": _metres(base.wheel_track_mm),
            "sensors": sensors,
        }
    }


def blob_from_description(base: BaseDescription) -> bytes:
    """The encoded blob of tree_from_description(base); UsageError if it would not fit an answer."""
    blob = binconf.encode(tree_from_description(base))
    if len(blob) > MAX_BLOB_BYTES:
        raise UsageError(
            f"the binary configuration made from the base description is {len(blob)} bytes, more than "
            f"the {MAX_BLOB_BYTES} an answer holds: serve a smaller one (--binary-config FILE) or none "
            "(--no-binary-config)"
        )
    return blob
