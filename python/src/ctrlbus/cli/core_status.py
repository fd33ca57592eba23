# SPDX-License-Identifier: MIT
"""What `ctrlbus core` shows: a one-screen status, a one-line status, and a JSON status object.

All three are built from a session's dashboard snapshot (ctrlbus.web.snapshot, docs/dashboard.md)
and link statistics, so they show the same numbers the dashboard does. docs/core.md documents the
JSON object's fields. They read the session without a lock: a caller whose session a runner drives
holds `CoreRunner.lock` (ctrlbus.cli.core_cmd does).
"""

from __future__ import annotations

from typing import Any

from ctrlbus.core.session import CoreSession
from ctrlbus.web.snapshot import dashboard_snapshot

__all__ = [
    "BLOB_NOTES",
    "SCREEN_EVENTS",
    "SCREEN_HOME_CLEAR",
    "json_status",
    "render_screen",
    "status_line",
]

# ANSI: cursor home, then clear to the end of the screen (redraw in place without scrolling).
SCREEN_HOME_CLEAR = "\x1b[H\x1b[J"
SCREEN_EVENTS = 8
# What the base line adds about the 0x21 blob (dashboard `base.blob`); "not supported" is the
# base's ordinary ERROR 0x8000, an expected fallback, never counted among the errors.
BLOB_NOTES = {
    "not_supported": "; 0x21 not supported: fallback, not an error",
    "unusable": "; the 0x21 blob is unusable",
    "pending": "; the 0x21 blob did not arrive intact yet, asked again while polling",
}


def json_status(session: CoreSession, since_seq: int = 0) -> dict[str, Any]:
    """One JSON status object (docs/core.md); `events` holds those with seq > since_seq."""
    snap = dashboard_snapshot(session)
    stats = session.link_stats()
    link = snap["link"]
    connection = link["connection"]
    return {
        "t_s": snap["time_s"],
        "state": connection["state"],
        "port": connection["port"],
        "since_s": connection["since_s"],
        "connects": connection["connects"],
        "reason": stats["reason"],
        "base": snap["base"],
        "pose": snap["pose"],
        "command": snap["command"],
        "battery": snap["battery"],
        "motion_status": snap["motion"]["status"],
        "bumper_bitmap": snap["bumper_bitmap"],
        "bumpers_pressed": [bumper["pressed"] for bumper in snap["bumpers"]],
        "cliffs_triggered": [cliff["triggered"] for cliff in snap["cliffs"]],
        "distances_mm": [sensor["distance_mm"] for sensor in snap["sensors"]],
        "ignored_sensors": snap["ignored_sensors"],
        "warnings": snap["warnings"],
        "charger_probes": None if snap["charger"] is None else snap["charger"]["probes"],
        "health": {"flags": snap["health"]["flags"], "errors": snap["health"]["errors"]},
        "link": {
            "requests": link["requests"],
            "requests_per_s": link["requests_per_s"],
            "latency_p50_ms": link["latency_p50_ms"],
            "latency_p99_ms": link["latency_p99_ms"],
            "timeouts": link["timeouts"],
            "retries": link["retries"],
            "checksum_failures": link["checksum_failures"],
            "resyncs": link["resyncs"],
            "errors_by_code": link["errors_by_code"],
            "watchdog_trips": link["watchdog_trips"],
            "disconnects": stats["disconnects"],
            "lost_requests": stats["lost_requests"],
            "superseded": stats["superseded"],
            "line_faults_by_bit": stats["line_faults_by_bit"],
        },
        "events": [event for event in snap["events"] if event["seq"] > since_seq],
    }


def _number(value: float | None, digits: int = 1, unit: str = "") -> str:
    return "-" if value is None else f"{value:.{digits}f}{unit}"


def _yes(flag: bool) -> str:
    return "yes" if flag else "no"


def status_line(session: CoreSession) -> str:
    """A one-line summary, for output that is not a terminal."""
    snap = dashboard_snapshot(session)
    link = snap["link"]
    pose = snap["pose"]
    battery = snap["battery"]["percent"]
    command = snap["command"]
    return (
        f"{snap['time_s']:8.2f} s {link['connection']['state']:<12} "
        f"pose {pose['x_mm']:.1f} {pose['y_mm']:.1f} mm {pose['theta_deg']:.1f}°  "
        f"cmd {command['vx_mps']:.2f} m/s {command['omega_radps']:.2f} rad/s {command['mode']}  "
        f"battery {_number(battery, 0, ' %')}  "
        f"{link['requests_per_s']:.1f} req/s p50 {_number(link['latency_p50_ms'], 1, ' ms')} "
        f"timeouts {link['timeouts']} retries {link['retries']}"
    )


def render_screen(session: CoreSession, note: str | None = None) -> str:
    """The whole status as lines of text (no ANSI codes); `note` (e.g. the dashboard's address)
    goes on the second line, since the redraw clears anything printed before."""
    snap = dashboard_snapshot(session)
    stats = session.link_stats()
    link = snap["link"]
    connection = link["connection"]
    lines = [
        f"ctrlbus core  {connection['port']}  {connection['state']} since {connection['since_s']:.1f} s  "
        f"(connects {connection['connects']}, disconnects {stats['disconnects']})"
        + (f"  [{stats['reason']}]" if stats["reason"] and connection["state"] != "connected" else ""),
    ]
    if note:
        lines.append(note)
    base = snap["base"]
    if base is None:
        lines.append("base      -")
    else:
        lines.append(
            f"base      {base['model']!r} firmware {base['firmware_version']} "
            f"hardware {base['hardware_version']} serial {base['serial']}  "
            f"{base['shape']} r {base['radius_mm']:.0f} mm ({base['config_source']}"
            f"{BLOB_NOTES.get(base['blob'], '')})"
        )
        for source, view in base["views"].items():
            lines.append(
                f"  {source:<17} r {view['radius_mm']:.0f} mm, {view['distance_sensors']} distance sensors, "
                f"{view['bumpers']} bumpers, {view['cliffs']} cliffs"
            )
    pose = snap["pose"]
    command = snap["command"]
    lines.append(f"pose      x {pose['x_mm']:9.1f} mm  y {pose['y_mm']:9.1f} mm  θ {pose['theta_deg']:7.2f}°")
    activity = f"  {command['activity']}" if command["activity"] else ""
    lines.append(
        f"command   vx {command['vx_mps']:5.2f} m/s  ω {command['omega_radps']:5.2f} rad/s  "
        f"{command['mode']}{'  ESTOP' if command['estop'] else ''}{activity}"
    )
    battery = snap["battery"]
    motion = snap["motion"]
    lines.append(
        f"battery   {_number(battery['percent'], 0, ' %')}  charging {_yes(battery['charging'])}  "
        f"dc {_yes(battery['dc_connected'])}  dock {_yes(battery['on_dock'])}    "
        f"motion stall {_yes(motion['stall'])} traction lost {_yes(motion['traction_lost'])}"
    )
    bitmap = snap["bumper_bitmap"]
    pressed = [str(index) for index, bumper in enumerate(snap["bumpers"]) if bumper["pressed"]]
    cliffs = [str(cliff["bit"]) for cliff in snap["cliffs"] if cliff["triggered"]]
    lines.append(
        f"bumpers   {'-' if bitmap is None else f'0x{bitmap:08X}'}  pressed {', '.join(pressed) or 'none'}  "
        f"cliff bits {', '.join(cliffs) or 'none'}"
    )
    distances = [_number(sensor["distance_mm"], 0) for sensor in snap["sensors"]]
    lines.append(f"sensors   {' '.join(distances) or '-'} mm")
    ignored = [f"{item['slot']}: {_number(item['distance_mm'], 0)}" for item in snap["ignored_sensors"]]
    if ignored:
        lines.append(f"ignored   {', '.join(ignored)} mm (channel: reading; a real Core ignores them)")
    for warning in snap["warnings"]:
        lines.append(f"WARNING   {warning}")
    charger = snap["charger"]
    probes = "-" if charger is None else " ".join(f"0x{probe:02X}" for probe in charger["probes"])
    lines.append(f"charger   probes {probes}")
    health = snap["health"]
    flags = health["flags"]
    lines.append(
        f"health    flags {'-' if flags is None else f'0x{flags:02X}'}  "
        + (
            "; ".join(f"0x{error['code']:08X} {error['message']}" for error in health["errors"])
            or "no errors"
        )
    )
    errors = ", ".join(f"{code}: {count}" for code, count in link["errors_by_code"].items()) or "none"
    lines.append(
        f"link      {link['requests']} requests, {link['requests_per_s']:.1f}/s  latency p50 "
        f"{_number(link['latency_p50_ms'], 2, ' ms')} p99 {_number(link['latency_p99_ms'], 2, ' ms')}  "
        f"timeouts {link['timeouts']} retries {link['retries']}  "
        f"lost {stats['lost_requests']} superseded {stats['superseded']}"
    )
    lines.append(
        f"          checksum failures {link['checksum_failures']} resyncs {link['resyncs']} "
        f"watchdog trips {link['watchdog_trips']} (reported by the base {stats['watchdog_reported']})"
        f"  errors {errors}"
    )
    lines.append("events")
    for event in snap["events"][-SCREEN_EVENTS:]:
        lines.append(f"  {event['t_s']:8.2f} {event['direction']:<4} {event['text']}")
    return "\n".join(lines)
