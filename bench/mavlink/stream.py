# SPDX-License-Identifier: MIT
"""MAVLink v2 streams for the peer side: the synthetic Core<->base session, message for message.

Each request and answer of bench/session.py becomes one message of our dialect carrying the same
values (a velocity command, a deadreckon report, a poll request, ...), encoded by pymavlink's
generated Python encoder: the Core side as system 1 component 1, the base as system 1 component 2,
each with its own sequence counter. The stream is then cut or repeated to the requested size.
"""

from __future__ import annotations

from collections.abc import Iterator
from types import ModuleType
from typing import Any

from session import REQUEST_CODES, SYNTHETIC_PERIOD_S, Capture, SessionMessage, core_session, tile

CORE_COMPONENT = 1
BASE_COMPONENT = 2


def _message(dialect: Any, mav: Any, message: SessionMessage) -> Any:
    f = message.fields
    if message.direction == "request":
        if message.name == "SET_V_AND_GET_DEADRECKON":
            return mav.base_velocity_command_encode(f["vx_mps_q16"], f["vy_mps_q16"], f["omega_radps_q16"])
        code = REQUEST_CODES[message.name]
        return mav.base_request_encode(code[0], code[1] if len(code) > 1 else 0)
    if message.name == "SET_V_AND_GET_DEADRECKON":
        return mav.base_deadreckon_encode(f["dx_mm_q16"], f["dy_mm_q16"], f["dtheta_deg_q16"], f["status"])
    if message.name == "GET_BASE_BUMPER_DATA":
        return mav.base_bumpers_encode(f["bitmap"])
    if message.name == "GET_BASE_SENSOR_DATA":
        return mav.base_distance_sensors_encode(list(f["distances_mm_q16"]))  # type: ignore[arg-type]
    if message.name == "POLL_BASE_CMD":
        return mav.base_pending_command_encode(255)
    if message.name == "GET_BASE_STATUS":
        return mav.base_power_encode(f["battery_percent"], f["power_status"])
    if message.name == "HEALTH_GET_HEALTH":
        return mav.base_health_encode(f["flags"], f["error_count"])
    raise ValueError(f"no MAVLink message for {message.direction} {message.name}")


def session_messages(dialect: ModuleType, seconds: float, seed: int = 1) -> Iterator[bytes]:
    """The synthetic session as MAVLink v2 frames, in order."""
    core = dialect.MAVLink(None, srcSystem=1, srcComponent=CORE_COMPONENT)
    base = dialect.MAVLink(None, srcSystem=1, srcComponent=BASE_COMPONENT)
    for message in core_session(seconds, seed):
        mav = core if message.direction == "request" else base
        packed: bytes = _message(dialect, mav, message).pack(mav)
        mav.seq = (mav.seq + 1) % 256
        yield packed


def mavlink_capture(dialect: ModuleType, target_bytes: int, seed: int = 1) -> Capture:
    """A MAVLink stream of about target_bytes (whole messages) with the session's message mix."""
    seconds = SYNTHETIC_PERIOD_S
    frames = list(session_messages(dialect, seconds, seed))
    period_bytes = sum(len(f) for f in frames)
    if period_bytes > target_bytes:
        seconds = max(1.0, seconds * target_bytes / period_bytes + 1.0)
        frames = list(session_messages(dialect, seconds, seed))
    data, count = tile(frames, target_bytes)
    return Capture(data, count, f"MAVLink v2 messages of the synthetic session, seed {seed}")


MAVLINK_V2_STX = 0xFD
MAVLINK_V2_OVERHEAD = 12  # 10-byte header and 2-byte CRC (our streams are not signed)


def split_mavlink(data: bytes) -> list[bytes]:
    """Cut a clean, unsigned MAVLink v2 stream into its frames, by their length fields."""
    frames: list[bytes] = []
    pos = 0
    while pos < len(data):
        if data[pos] != MAVLINK_V2_STX or pos + 1 >= len(data):
            raise ValueError(f"byte {pos} of the MAVLink stream does not start a v2 frame")
        size = MAVLINK_V2_OVERHEAD + data[pos + 1]
        if pos + size > len(data):
            raise ValueError(f"the MAVLink stream ends inside a frame at byte {pos}")
        frames.append(data[pos : pos + size])
        pos += size
    return frames
