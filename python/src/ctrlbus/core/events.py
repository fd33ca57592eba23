# SPDX-License-Identifier: MIT
"""The Core's event log: what it did and what the base said, in words, oldest first.

A bounded list (the last MAX_EVENTS); each event has a sequence number so that a reader can ask
for what came after the last one it saw. Times are the session's (seconds since its start).
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass

from ctrlbus.messages import (
    ConnectBase,
    Event,
    ExternalCommand,
    HealthGetError,
    RequestMessage,
    SendEvent,
    Sync,
)

__all__ = [
    "MAX_EVENTS",
    "CoreEvent",
    "EventLog",
    "command_name",
    "describe_request",
]

MAX_EVENTS = 200


@dataclass(frozen=True)
class CoreEvent:
    seq: int
    t_s: float
    direction: str  # "core" or "base"
    text: str


class EventLog:
    """The last `limit` events, numbered from 1."""

    def __init__(self, limit: int = MAX_EVENTS) -> None:
        self._events: deque[CoreEvent] = deque(maxlen=limit)
        self._seq = 0

    def add(self, t_s: float, direction: str, text: str) -> CoreEvent:
        self._seq += 1
        event = CoreEvent(self._seq, round(t_s, 4), direction, text)
        self._events.append(event)
        return event

    def since(self, seq: int = 0) -> list[CoreEvent]:
        """The kept events with seq > `seq`, oldest first."""
        # One copy first (a single C-level step): the filter then never walks a deque in change.
        return [event for event in list(self._events) if event.seq > seq]

    def __len__(self) -> int:
        return len(self._events)


def command_name(code: int) -> str:
    """How the event log names an external command the base offers."""
    try:
        return ExternalCommand(code).name
    except ValueError:
        return "unknown command"


def _event_name(code: int) -> str:
    try:
        return Event(code).name
    except ValueError:
        return f"0x{code:02X}"


def describe_request(message: RequestMessage) -> str:
    """How the event log names a request."""
    if isinstance(message, ConnectBase):
        return f"CONNECT_BASE v{message.protocol_version}"
    if isinstance(message, SendEvent):
        return f"SEND_EVENT {_event_name(message.event)}"
    if isinstance(message, Sync):
        return f"SYNC flush ({len(message.filler) + 5} bytes)"
    if isinstance(message, HealthGetError):
        return f"HEALTH_GET_ERROR #{message.index}"
    return message.NAME
