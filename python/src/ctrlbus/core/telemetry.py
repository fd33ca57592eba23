# SPDX-License-Identifier: MIT
"""What the Core knows about the base, as typed values: the telemetry model.

`BaseTelemetry` holds the last answer of each kind (identity, configuration views, odometry,
status, sensors, charger, health); the session fills it in as answers come and never reads it
back for protocol decisions beyond what §11 needs (bumpers for docking, the geometry). The
derived flags (stall, on dock, pressed bumpers, ...) are read here once, with the bit names from
ctrlbus.constants. `LinkTelemetry` is the link's side: the connection and its statistics.

Plain data, no lock: whoever drives the session from one thread and reads it from another
guards both (ctrlbus.core.runner does).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field
from typing import Any

from ctrlbus.compat import StrEnum
from ctrlbus.constants import (
    HEALTH_ERROR,
    HEALTH_FATAL,
    HEALTH_WARNING,
    LINE_FAULT_BIT_NAMES,
    MOTION_STALL,
    MOTION_TRACTION_LOST,
    POWER_CHARGING,
    POWER_DC_CONNECTED,
    POWER_ON_DOCK,
)
from ctrlbus.core.geometry import SOURCE_CONF_ADV, BaseGeometry
from ctrlbus.core.stats import LinkStats
from ctrlbus.frame import DecoderStats
from ctrlbus.kinematics import DeadreckonDelta, Pose, integrate_pose
from ctrlbus.messages import ConnectBaseAnswer, GetChargerDataAnswer

__all__ = [
    "BLOB_NOT_SUPPORTED",
    "BLOB_PENDING",
    "BLOB_STATES",
    "BLOB_UNUSABLE",
    "BLOB_USED",
    "MAX_TRAIL_POINTS",
    "TRAIL_STEP_MM",
    "BaseIdentity",
    "BaseTelemetry",
    "CommandState",
    "ConnectionState",
    "HealthError",
    "HealthState",
    "LinkTelemetry",
]

MAX_TRAIL_POINTS = 2000
TRAIL_STEP_MM = 10.0
# What became of the GET_BASE_CONF_ADV blob (§11.2): in use; the base has none (ERROR 0x8000, an
# expected fallback to GET_BASE_CONF, not a fault); refused otherwise or does not decode; or not
# yet received intact on a noisy line (asked again while polling).
BLOB_USED = "used"
BLOB_NOT_SUPPORTED = "not_supported"
BLOB_UNUSABLE = "unusable"
BLOB_PENDING = "pending"
BLOB_STATES = (BLOB_USED, BLOB_NOT_SUPPORTED, BLOB_UNUSABLE, BLOB_PENDING)


class ConnectionState(StrEnum):
    CONNECTING = "connecting"  # looking for the base, before the first connection
    CONFIGURING = "configuring"  # connected, reading the configuration
    CONNECTED = "connected"  # polling
    DISCONNECTED = "disconnected"  # lost (reconnecting), stopped, or the link failed


@dataclass(frozen=True)
class BaseIdentity:
    """The base as CONNECT_BASE describes it."""

    model: str
    firmware_version: str  # "major.minor"
    hardware_version: int
    serial: str  # 24 hex digits
    firmware_version_suffix: str | None

    @classmethod
    def from_answer(cls, answer: ConnectBaseAnswer) -> BaseIdentity:
        serial = "".join(f"{word:08X}" for word in answer.serial)
        return cls(
            answer.model,
            answer.firmware_version_text,
            answer.hardware_version,
            serial,
            answer.firmware_version_suffix,
        )


@dataclass(frozen=True)
class HealthError:
    code: int
    message: str

    @property
    def level(self) -> int:
        return self.code >> 24


@dataclass(frozen=True)
class HealthState:
    flags: int | None
    errors: tuple[HealthError, ...]

    @property
    def warning(self) -> bool:
        return self.flags is not None and bool(self.flags & HEALTH_WARNING)

    @property
    def error(self) -> bool:
        return self.flags is not None and bool(self.flags & HEALTH_ERROR)

    @property
    def fatal(self) -> bool:
        return self.flags is not None and bool(self.flags & HEALTH_FATAL)


@dataclass(frozen=True)
class CommandState:
    vx_mps: float
    omega_radps: float
    estop: bool
    mode: str  # idle | teleop | external | go_home | estop
    activity: str | None


def _bit_set(value: int | None, bit: int) -> bool:
    return value is not None and bool(value & bit)


@dataclass
class BaseTelemetry:
    """The last known state of the base (None: not heard yet)."""

    identity: BaseIdentity | None = None
    configured: bool = False  # the configuration step is done (with or without a geometry)
    geometry: BaseGeometry | None = None  # the one in use
    config_source: str | None = None
    # §11.2: each source's geometry, where known (the Core uses the blob's when it has one).
    views: dict[str, BaseGeometry] = field(default_factory=dict)
    # What became of the 0x21 blob (None: not asked yet): one of BLOB_STATES.
    blob_status: str | None = None
    pose: Pose = field(default_factory=lambda: Pose(0.0, 0.0, 0.0))
    trail: deque[tuple[float, float]] = field(
        default_factory=lambda: deque([(0.0, 0.0)], maxlen=MAX_TRAIL_POINTS)
    )
    deadreckon_timestamp_ms: int | None = None
    motion_status: int | None = None
    motor_totals_mm: tuple[int, int] | None = None
    battery_percent: int | None = None
    power_status: int | None = None
    bumper_bitmap: int | None = None
    distances_mm: tuple[float, ...] | None = None
    charger: GetChargerDataAnswer | None = None
    health: HealthState = field(default_factory=lambda: HealthState(None, ()))

    def use_geometry(self, geometry: BaseGeometry | None) -> None:
        """The configuration step chose `geometry` (None: the base gave none)."""
        self.views = {} if geometry is None else {geometry.source: geometry}
        if geometry is not None and geometry.source == SOURCE_CONF_ADV:
            self.blob_status = BLOB_USED
        self.geometry = geometry
        self.config_source = None if geometry is None else geometry.source
        self.configured = True

    def move(self, delta: DeadreckonDelta) -> None:
        """Integrate one deadreckon delta into the pose; the trail keeps a point every few mm."""
        self.pose = integrate_pose(self.pose, delta)
        last_x, last_y = self.trail[-1]
        if math.hypot(self.pose.x_mm - last_x, self.pose.y_mm - last_y) >= TRAIL_STEP_MM:
            self.trail.append((self.pose.x_mm, self.pose.y_mm))

    def pressed(self, bit: int) -> bool:
        """Bit `bit` of the last bumper bitmap says pressed (a bumper) or triggered (a cliff
        sensor): the bitmap is active low. False before the first GET_BASE_BUMPER_DATA."""
        return self.bumper_bitmap is not None and not self.bumper_bitmap >> bit & 1

    @property
    def bumpers_pressed(self) -> tuple[bool, ...]:
        """One flag per configured bumper (the bitmap is active low)."""
        if self.bumper_bitmap is None or self.geometry is None:
            return ()
        return tuple(self.pressed(bumper.bit) for bumper in self.geometry.bumpers)

    @property
    def cliffs_triggered(self) -> tuple[bool, ...]:
        """One flag per configured cliff bit (False before the first bumper data)."""
        if self.geometry is None:
            return ()
        return tuple(self.pressed(bit) for bit in self.geometry.cliff_bits)

    @property
    def charger_probes(self) -> tuple[int, ...] | None:
        return None if self.charger is None else self.charger.probes

    @property
    def stall(self) -> bool:
        return _bit_set(self.motion_status, MOTION_STALL)

    @property
    def traction_lost(self) -> bool:
        return _bit_set(self.motion_status, MOTION_TRACTION_LOST)

    @property
    def charging(self) -> bool:
        return _bit_set(self.power_status, POWER_CHARGING)

    @property
    def dc_connected(self) -> bool:
        return _bit_set(self.power_status, POWER_DC_CONNECTED)

    @property
    def on_dock(self) -> bool:
        return _bit_set(self.power_status, POWER_ON_DOCK)


@dataclass(frozen=True)
class LinkTelemetry:
    """The connection and the link's counters at one moment (`stats` and `decoder` as they were
    when it was made; `as_dict` reads them at once)."""

    state: ConnectionState
    port: str
    since_s: float  # when the state was entered, in session seconds
    reason: str | None  # why the connection is down (or "stopped")
    requests_per_s: float
    stats: LinkStats
    decoder: DecoderStats

    def as_dict(self) -> dict[str, Any]:
        """As plain values: the dashboard snapshot's `link` part (docs/dashboard.md) and more."""
        stats = self.stats
        decoder = self.decoder
        p50, p99 = stats.latency_percentiles_ms()
        return {
            "connection": {
                "state": self.state.value,
                "port": self.port,
                "since_s": round(self.since_s, 4),
                "connects": stats.connects,
            },
            "requests": stats.requests,
            "requests_per_s": round(self.requests_per_s, 3),
            "latency_p50_ms": None if p50 is None else round(p50, 3),
            "latency_p99_ms": None if p99 is None else round(p99, 3),
            "errors_by_code": {
                f"0x{code:04X}": count for code, count in sorted(stats.errors_by_code.items())
            },
            "checksum_failures": decoder.checksum_errors,
            "resyncs": decoder.resyncs,
            "timeouts": stats.timeouts,
            "watchdog_trips": stats.watchdog_trips,
            "retries": stats.retries,
            "lost_requests": stats.lost_requests,
            "superseded": stats.superseded,
            "line_faults_by_bit": {
                f"0x{bit:02X}": stats.line_fault_bits[bit] for bit in LINE_FAULT_BIT_NAMES
            },
            # Beyond the dashboard schema:
            "requests_tracked": stats.tracked_requests,
            "requests_answered": stats.answered_requests,
            "abandoned_at_disconnect": stats.abandoned_at_disconnect,
            "answers": stats.answers,
            "connect_attempts": stats.connect_attempts,
            "disconnects": stats.disconnects,
            "reason": self.reason,
            "invalid_answers": stats.invalid_answers,
            "malformed_answers": stats.malformed_answers,
            "stray_answers": stats.stray_answers,
            "not_synced_reports": stats.not_synced_reports,
            "flushed_frames": stats.flushed_frames,
            "damaged_config_answers": stats.damaged_config_answers,
            "conf_adv_not_supported": stats.unsupported_conf_adv,
            "watchdog_reported": stats.watchdog_reported,
            "latency_samples": stats.latency_samples,
            "decoder": {
                "frames": decoder.frames,
                "bytes_discarded": decoder.bytes_discarded,
                "checksum_errors": decoder.checksum_errors,
                "oversize": decoder.oversize,
                "timeouts": decoder.timeouts,
                "empty_frames": decoder.empty_frames,
                "resyncs": decoder.resyncs,
            },
        }
