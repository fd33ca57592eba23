# SPDX-License-Identifier: MIT
"""Control messages from the dashboard page: strict parsing into typed commands.

The page sends small JSON objects over the WebSocket. Anything that is not exactly one of the
known shapes (unknown type or key, wrong type, non-finite number, duplicate key, too long) is
rejected with a `ControlMessageError` naming the problem; the server answers it with an error
reply and carries on.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from typing import Any

from ctrlbus.errors import UsageError
from ctrlbus.messages import ExternalCommand as MessagesExternalCommand

__all__ = [
    "EXTERNAL_COMMANDS",
    "EXTERNAL_COMMAND_BUTTONS",
    "EXTERNAL_COMMAND_NAMES",
    "MAX_ID_CHARS",
    "MAX_MESSAGE_CHARS",
    "MESSAGE_TYPES",
    "ControlMessage",
    "ControlMessageError",
    "EmergencyStop",
    "ExternalCommand",
    "GoHome",
    "MessageId",
    "ReleaseStop",
    "Velocity",
    "clamp_velocity",
    "parse_control_message",
]

# Longer than any valid message by a wide margin, short enough that parsing cost is trivial.
MAX_MESSAGE_CHARS = 1024
MAX_ID_CHARS = 64

# External command codes a base may offer through POLL_BASE_CMD (reference section 5, 0x50).
EXTERNAL_COMMANDS: dict[str, int] = {command.name: command.value for command in MessagesExternalCommand}
EXTERNAL_COMMAND_NAMES: dict[int, str] = {code: name for name, code in EXTERNAL_COMMANDS.items()}

# The ones the page offers as buttons, in button order: those the Core acts on, plus the sweep
# and health ones so that the POLL/ANS flow of a command the Core only logs is visible too.
EXTERNAL_COMMAND_BUTTONS: tuple[str, ...] = (
    "MOVE_FORWARD",
    "MOVE_BACKWARD",
    "TURN_LEFT",
    "TURN_RIGHT",
    "GO_HOME",
    "CANCEL_ACTION",
    "START_SWEEP",
    "STOP_SWEEP",
    "SPOT_SWEEP",
    "GET_HEALTH",
)


class ControlMessageError(UsageError):
    """A control message from the page that is not one of the accepted shapes."""


MessageId = int | str | None


@dataclass(frozen=True)
class Velocity:
    vx_mps: float
    omega_radps: float
    message_id: MessageId = None


@dataclass(frozen=True)
class EmergencyStop:
    message_id: MessageId = None


@dataclass(frozen=True)
class ReleaseStop:
    message_id: MessageId = None


@dataclass(frozen=True)
class GoHome:
    message_id: MessageId = None


@dataclass(frozen=True)
class ExternalCommand:
    code: int
    message_id: MessageId = None

    @property
    def name(self) -> str:
        return EXTERNAL_COMMAND_NAMES[self.code]


ControlMessage = Velocity | EmergencyStop | ReleaseStop | GoHome | ExternalCommand

# Keys each message type may carry besides "type" and the optional "id".
_FIELDS: dict[str, frozenset[str]] = {
    "velocity": frozenset({"vx_mps", "omega_radps"}),
    "estop": frozenset(),
    "release": frozenset(),
    "go_home": frozenset(),
    "external_command": frozenset({"code"}),
}
MESSAGE_TYPES: tuple[str, ...] = tuple(_FIELDS)


def parse_control_message(text: str) -> ControlMessage:
    """Read one control message; ControlMessageError says what is wrong with it."""
    if len(text) > MAX_MESSAGE_CHARS:
        raise ControlMessageError(f"message too long ({len(text)} characters, limit {MAX_MESSAGE_CHARS})")
    try:
        value = json.loads(text, object_pairs_hook=_no_duplicate_keys, parse_constant=_reject_constant)
    except ControlMessageError:
        raise
    except (ValueError, RecursionError) as exc:
        raise ControlMessageError(f"not valid JSON: {_short(exc)}") from None
    if not isinstance(value, dict):
        raise ControlMessageError(f"expected a JSON object, got {type(value).__name__}")
    kind = value.get("type")
    if not isinstance(kind, str):
        raise ControlMessageError('missing or non-text "type"')
    allowed = _FIELDS.get(kind)
    if allowed is None:
        raise ControlMessageError(f"unknown message type {_clip(kind)!r}; known: {', '.join(MESSAGE_TYPES)}")
    given = set(value) - {"type", "id"}
    unknown = given - allowed
    if unknown:
        raise ControlMessageError(f"{kind}: unknown key(s) {', '.join(sorted(_clip(k) for k in unknown))}")
    missing = allowed - given
    if missing:
        raise ControlMessageError(f"{kind}: missing key(s) {', '.join(sorted(missing))}")
    message_id = _message_id(value.get("id"))
    if kind == "velocity":
        return Velocity(
            _finite_number(value, "vx_mps", kind), _finite_number(value, "omega_radps", kind), message_id
        )
    if kind == "estop":
        return EmergencyStop(message_id)
    if kind == "release":
        return ReleaseStop(message_id)
    if kind == "go_home":
        return GoHome(message_id)
    code = value["code"]
    if isinstance(code, bool) or not isinstance(code, int):
        raise ControlMessageError(f"external_command: code must be an integer, got {type(code).__name__}")
    if code not in EXTERNAL_COMMAND_NAMES:
        raise ControlMessageError(f"external_command: unknown command code {code}")
    return ExternalCommand(code, message_id)


def clamp_velocity(vx_mps: float, omega_radps: float, limits: tuple[float, float]) -> tuple[float, float]:
    """Clamp each component to the symmetric limit; a non-finite or negative limit means zero."""
    max_vx, max_omega = (limit if math.isfinite(limit) and limit > 0 else 0.0 for limit in limits)
    return min(max(vx_mps, -max_vx), max_vx), min(max(omega_radps, -max_omega), max_omega)


def _finite_number(value: dict[str, Any], key: str, kind: str) -> float:
    number = value[key]
    if isinstance(number, bool) or not isinstance(number, int | float):
        raise ControlMessageError(f"{kind}: {key} must be a number, got {type(number).__name__}")
    result = float(number) if not isinstance(number, int) or abs(number) < 2**63 else math.inf
    if not math.isfinite(result):
        raise ControlMessageError(f"{kind}: {key} must be finite")
    return result


def _message_id(raw: object) -> MessageId:
    if raw is None:
        return None
    if isinstance(raw, bool):
        raise ControlMessageError("id must be an integer or text")
    if isinstance(raw, int):
        if not 0 <= raw < 2**53:
            raise ControlMessageError("id out of range")
        return raw
    if isinstance(raw, str):
        if len(raw) > MAX_ID_CHARS:
            raise ControlMessageError(f"id longer than {MAX_ID_CHARS} characters")
        return raw
    raise ControlMessageError("id must be an integer or text")


def _no_duplicate_keys(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    result: dict[str, Any] = {}
    for key, item in pairs:
        if key in result:
            raise ControlMessageError(f"duplicate key {_clip(key)!r}")
        result[key] = item
    return result


def _reject_constant(name: str) -> Any:
    raise ControlMessageError(f"{name} is not a number JSON allows")


def _clip(text: str, limit: int = 40) -> str:
    return text if len(text) <= limit else text[:limit] + "..."


def _short(exc: BaseException) -> str:
    return _clip(str(exc).splitlines()[0] if str(exc) else type(exc).__name__, 80)
