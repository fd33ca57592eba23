# SPDX-License-Identifier: MIT
"""Settings of the Core emulator: polling rates, timeouts, limits and the actions' parameters.

Defaults are those of docs/protocol.md §11; every value can be changed, and each is checked when
the settings are built so that a bad value is refused before anything starts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields, replace

from ctrlbus.errors import UsageError
from ctrlbus.frame import MAX_FRAME
from ctrlbus.link import DEFAULT_BAUD

__all__ = [
    "BITS_PER_BYTE",
    "CoreConfig",
    "DockingConfig",
    "PollRates",
    "byte_time_for_baud",
]

# One UART character at 8N1 is 10 bits: start, 8 data, stop.
BITS_PER_BYTE = 10


def byte_time_for_baud(baud: int) -> float:
    """Seconds one byte takes on an 8N1 line at `baud` (86.8 µs at 115200)."""
    if baud <= 0:
        raise UsageError(f"baud rate must be positive, got {baud}")
    return BITS_PER_BYTE / baud


def _check_number(owner: str, name: str, value: float, *, low: float, allow_low: bool = True) -> None:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise UsageError(f"{owner}.{name} must be a finite number, got {value!r}")
    if value < low or (value == low and not allow_low):
        relation = "at least" if allow_low else "more than"
        raise UsageError(f"{owner}.{name} must be {relation} {low:g}, got {value!r}")


@dataclass(frozen=True)
class PollRates:
    """Polling rates in Hz (§11.4); 0 switches a request off.

    `charger_hz` applies only while the Core is docking (GO_HOME); GET_BASE_STATUS is then polled at
    that rate too, so that the Core sees the on-dock bit promptly.
    """

    set_v_hz: float = 20.0
    bumper_hz: float = 10.0
    sensor_hz: float = 10.0
    status_hz: float = 1.0
    motor_hz: float = 1.0
    poll_cmd_hz: float = 5.0
    health_hz: float = 1.0
    charger_hz: float = 10.0

    def __post_init__(self) -> None:
        for item in fields(self):
            _check_number("rates", item.name, getattr(self, item.name), low=0.0)
            if getattr(self, item.name) > 1000.0:
                raise UsageError(f"rates.{item.name} must be at most 1000 Hz, got {getattr(self, item.name)}")

    @classmethod
    def names(cls) -> tuple[str, ...]:
        """The names `parse` accepts: set_v, bumper, sensor, status, motor, poll_cmd, health, charger."""
        return tuple(item.name.removesuffix("_hz") for item in fields(cls))

    @classmethod
    def parse(cls, text: str) -> PollRates:
        """Rates from text like "set_v=50,status=2" (the others keep their defaults)."""
        known = cls.names()
        values: dict[str, float] = {}
        for part in text.split(","):
            part = part.strip()
            if not part:
                continue
            name, sep, number = part.partition("=")
            name = name.strip().removesuffix("_hz")
            if not sep or name not in known:
                raise UsageError(f"bad rate {part!r}: expected NAME=HZ with NAME one of {', '.join(known)}")
            try:
                value = float(number)
            except ValueError:
                raise UsageError(f"bad rate {part!r}: {number.strip()!r} is not a number") from None
            if f"{name}_hz" in values:
                raise UsageError(f"rate {name!r} given twice")
            values[f"{name}_hz"] = value
        return replace(cls(), **values)


@dataclass(frozen=True)
class DockingConfig:
    """The beacon-following GO_HOME controller (ctrlbus.core.docking)."""

    search_radps: float = 0.8  # turning while looking for the main beacon
    sweep_radps: float = 0.3  # turning while measuring where the main beacon's edges are
    approach_mps: float = 0.12  # driving towards the dock
    aligned_deg: float = 0.5  # close enough to the measured direction of the beacon
    timeout_s: float = 120.0  # give up after this long
    max_search_turns: float = 2.0  # full turns without seeing the main beacon before giving up

    def __post_init__(self) -> None:
        for item in fields(self):
            _check_number("docking", item.name, getattr(self, item.name), low=0.0, allow_low=False)


@dataclass(frozen=True)
class CoreConfig:
    """Everything the Core session needs to know besides the bytes and the time."""

    rates: PollRates = field(default_factory=PollRates)
    request_timeout_s: float = 0.2  # §11.6: answer complete within 200 ms of the request's last byte
    retries: int = 2  # §11.6: after 1 + retries silent attempts in a row the base is disconnected
    line_fault_attempts: int = 16  # §11.6: failed attempts in a row (no answer at all) before it is lost
    read_both_configs: bool = True  # §11.2: after a usable 0x21 blob, ask 0x20 too (to show both views)
    # §11.2 [core-config-retry]: attempts at the blob (and at 0x20 as a second view) while
    # connecting; then the Core goes on with what it has and asks again while polling.
    config_attempts: int = 2
    config_retry_s: float = 2.0  # first wait before asking again while polling (doubling, up to 4 s)
    connect_interval_s: float = 0.5  # §11.1: CONNECT_BASE every 500 ms until answered
    flush_sync: bool = True  # §11.1: a 512-byte SYNC after each unanswered CONNECT_BASE
    decoder_timeout_s: float = 0.1  # §7.6: host-side inter-byte timeout
    # §11.6: the largest answer accepted. A false 0x50 header in noise claims up to 64 KiB; a cap
    # near the largest real answer makes most of them fail at once instead of holding the line.
    max_frame: int = 4096
    transport_error_grace_s: float = 0.05  # §11.6: wait this long for the answer after ERROR 0x0020/0x0040
    byte_time_s: float = BITS_PER_BYTE / DEFAULT_BAUD  # when a request's last byte has left
    long_frames: bool = False  # §6.3: False = `reference` profile, True = `sdk2020`
    watchdog_s: float = 1.0  # §9.1: a gap longer than this between CTRL_BUS requests trips it
    max_vx_mps: float = 0.5  # limits() once the base is configured
    max_omega_radps: float = 2.0
    move_distance_m: float = 0.3  # MOVE_FORWARD / MOVE_BACKWARD
    move_speed_mps: float = 0.2
    turn_angle_deg: float = 90.0  # TURN_LEFT / TURN_RIGHT
    turn_rate_radps: float = 1.0
    docking: DockingConfig = field(default_factory=DockingConfig)

    def __post_init__(self) -> None:
        if not isinstance(self.rates, PollRates):
            raise UsageError("CoreConfig.rates must be a PollRates")
        if not isinstance(self.docking, DockingConfig):
            raise UsageError("CoreConfig.docking must be a DockingConfig")
        if isinstance(self.retries, bool) or not isinstance(self.retries, int) or not 0 <= self.retries <= 10:
            raise UsageError(f"CoreConfig.retries must be an integer 0..10, got {self.retries!r}")
        attempts = self.line_fault_attempts
        if isinstance(attempts, bool) or not isinstance(attempts, int) or not 1 <= attempts <= 1000:
            raise UsageError(f"CoreConfig.line_fault_attempts must be an integer 1..1000, got {attempts!r}")
        if (
            isinstance(self.config_attempts, bool)
            or not isinstance(self.config_attempts, int)
            or not 1 <= self.config_attempts <= 100
        ):
            raise UsageError(
                f"CoreConfig.config_attempts must be an integer 1..100, got {self.config_attempts!r}"
            )
        positive = (
            "request_timeout_s",
            "config_retry_s",
            "connect_interval_s",
            "watchdog_s",
            "max_vx_mps",
            "max_omega_radps",
            "move_distance_m",
            "move_speed_mps",
            "turn_angle_deg",
            "turn_rate_radps",
        )
        for name in positive:
            _check_number("CoreConfig", name, getattr(self, name), low=0.0, allow_low=False)
        _check_number("CoreConfig", "decoder_timeout_s", self.decoder_timeout_s, low=0.0)
        _check_number("CoreConfig", "transport_error_grace_s", self.transport_error_grace_s, low=0.0)
        if not isinstance(self.max_frame, int) or not 5 <= self.max_frame <= MAX_FRAME:
            raise UsageError(f"CoreConfig.max_frame must be a whole number from 5 to {MAX_FRAME}")
        _check_number("CoreConfig", "byte_time_s", self.byte_time_s, low=0.0)
