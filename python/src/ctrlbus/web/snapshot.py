# SPDX-License-Identifier: MIT
"""The dashboard's JSON snapshot of a Core session (docs/dashboard.md, schema version 1).

`dashboard_snapshot(session)` reads the session's telemetry model, command, event log and link
statistics and lays them out as the page expects. It takes no lock: the caller holds the lock of
the runner that drives the session (ctrlbus.web.source.CoreSource does). The Core knows nothing
of this layout; the CLI's status views (ctrlbus.cli.core_status) are made from it too, so they
show the same numbers.
"""

from __future__ import annotations

from typing import Any

from ctrlbus.core.geometry import geometry_view
from ctrlbus.core.session import CoreSession
from ctrlbus.web.schema import SCHEMA_VERSION

__all__ = [
    "SCHEMA_LINK_KEYS",
    "dashboard_snapshot",
    "ignored_readings",
    "ignored_warning",
]

# The part of CoreSession.link_stats() the schema's `link` object holds.
SCHEMA_LINK_KEYS = (
    "connection",
    "requests",
    "requests_per_s",
    "latency_p50_ms",
    "latency_p99_ms",
    "errors_by_code",
    "checksum_failures",
    "resyncs",
    "timeouts",
    "watchdog_trips",
    "retries",
    "lost_requests",
    "superseded",
    "line_faults_by_bit",
)


def ignored_readings(session: CoreSession) -> list[dict[str, Any]]:
    """The distance channels that report a reading (non-zero) but are no distance sensor of the
    configuration in use: a real Core has no position for them and ignores them (protocol §12.4
    [conf-sensor-list]; the reference's sonars through its blob). Each: `slot`, `distance_mm`, and
    the mount the other configuration gives it (`mount`, `mount_source`), if it gives one."""
    telemetry = session.telemetry
    geometry = telemetry.geometry
    distances = telemetry.distances_mm
    if geometry is None or distances is None:
        return []
    used = {sensor.slot for sensor in geometry.sensors}
    others = {
        sensor.slot: (source, sensor.mount)
        for source, view in telemetry.views.items()
        if view is not geometry
        for sensor in view.sensors
    }
    ignored = []
    for slot, reading in enumerate(distances):
        if slot in used or reading == 0:
            continue
        source, mount = others.get(slot, (None, None))
        ignored.append(
            {
                "slot": slot,
                "distance_mm": reading,
                "mount": None if mount is None else mount.as_dict(),
                "mount_source": source,
            }
        )
    return ignored


def ignored_warning(ignored: list[dict[str, Any]], config_source: str | None) -> str:
    """The one warning about readings a real Core would ignore."""
    slots = ", ".join(str(item["slot"]) for item in ignored)
    return (
        f"distance channels {slots} report readings, but the configuration the Core uses "
        f"({config_source}) lists no sensor there: a real Core ignores them (add them to it)"
    )


def dashboard_snapshot(session: CoreSession) -> dict[str, Any]:
    """The whole state of `session` as plain JSON values, in the dashboard's schema."""
    telemetry = session.telemetry
    identity = telemetry.identity
    geometry = telemetry.geometry
    base: dict[str, Any] | None = None
    if identity is not None and telemetry.configured:
        base = {
            "model": identity.model,
            "firmware_version": identity.firmware_version,
            "hardware_version": identity.hardware_version,
            "serial": identity.serial,
            "shape": "circle" if geometry is None else geometry.shape,
            "radius_mm": 0.0 if geometry is None else geometry.radius_mm,
            "config_source": telemetry.config_source or "GET_BASE_CONF",
            "views": {source: geometry_view(view) for source, view in telemetry.views.items()},
            "blob": telemetry.blob_status,
        }
    max_vx, max_omega = session.limits()
    command = session.command
    distances = telemetry.distances_mm
    sensors = []
    bumpers = []
    cliffs = []
    ignored: list[dict[str, Any]] = []
    if geometry is not None:
        for sensor in geometry.sensors:
            reading = None if distances is None else distances[sensor.slot]
            sensors.append({**sensor.mount.as_dict(), "distance_mm": reading})
        for bumper in geometry.bumpers:
            pressed = telemetry.pressed(bumper.bit)
            bumpers.append({**bumper.mount.as_dict(), "bit": bumper.bit, "pressed": pressed})
        for bit in geometry.cliff_bits:
            cliffs.append({"bit": bit, "triggered": telemetry.pressed(bit)})
    ignored = ignored_readings(session)
    charger = telemetry.charger
    health = telemetry.health
    link = session.link_stats()
    pose = telemetry.pose
    return {
        "schema": SCHEMA_VERSION,
        "time_s": round(session.time_s, 4),
        "base": base,
        "limits": {"vx_mps": max_vx, "omega_radps": max_omega},
        "pose": {
            "x_mm": round(pose.x_mm, 3),
            "y_mm": round(pose.y_mm, 3),
            "theta_deg": round(pose.theta_deg, 4),
        },
        "trail": [[round(x, 1), round(y, 1)] for x, y in telemetry.trail],
        "command": {
            "vx_mps": command.vx_mps,
            "omega_radps": command.omega_radps,
            "estop": command.estop,
            "mode": command.mode,
            "activity": command.activity,
        },
        "motion": {
            "status": telemetry.motion_status,
            "stall": telemetry.stall,
            "traction_lost": telemetry.traction_lost,
        },
        "battery": {
            "percent": telemetry.battery_percent,
            "power_status": telemetry.power_status,
            "charging": telemetry.charging,
            "dc_connected": telemetry.dc_connected,
            "on_dock": telemetry.on_dock,
        },
        "sensors": sensors,
        "bumper_bitmap": telemetry.bumper_bitmap,
        "bumpers": bumpers,
        "cliffs": cliffs,
        "ignored_sensors": ignored,
        "warnings": [ignored_warning(ignored, telemetry.config_source)] if ignored else [],
        "charger": None
        if charger is None
        else {
            "beacon_count": charger.beacon_count,
            "probe_count": charger.probe_count,
            "probes": list(charger.probes),
        },
        "health": {
            "flags": health.flags,
            "warning": health.warning,
            "error": health.error,
            "fatal": health.fatal,
            "errors": [{"code": error.code, "message": error.message} for error in health.errors],
        },
        "events": [
            {"seq": event.seq, "t_s": event.t_s, "direction": event.direction, "text": event.text}
            for event in session.events()
        ],
        "link": {key: link[key] for key in SCHEMA_LINK_KEYS},
    }
