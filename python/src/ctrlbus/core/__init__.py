# SPDX-License-Identifier: MIT
"""The Core emulator: a stand-in for the SLAMWARE Core (the bus master).

- `CoreSession` (ctrlbus.core.session): the protocol as a sans-IO state machine (no lock), with
  controls (velocity, emergency stop, go home, drive, turn) and actions (actions, docking). Its
  parts: protocol (the §11 steps), exchange (the request in flight), schedule, health, readings,
  motion and journal (time, event log, change topics).
- `BaseTelemetry` / `LinkTelemetry` (ctrlbus.core.telemetry): what the session knows about the base
  and the link, as typed values; `EventLog` (ctrlbus.core.events): what it did, in words.
- `CoreRunner` (ctrlbus.core.runner): a thread that connects a session to a `Link` in real time,
  and the lock that other threads take to use the session meanwhile.
- `ctrlbus.vtime`: runs a session against an in-process base in simulated time.
- `CoreConfig` / `PollRates` / `DockingConfig` (ctrlbus.core.config): its settings.

docs/core.md is the manual; docs/protocol.md §11 the behaviour it implements.
"""

from ctrlbus.core.config import CoreConfig, DockingConfig, PollRates, byte_time_for_baud
from ctrlbus.core.events import CoreEvent, EventLog
from ctrlbus.core.runner import CoreRunner
from ctrlbus.core.session import CoreSession
from ctrlbus.core.telemetry import (
    BaseIdentity,
    BaseTelemetry,
    CommandState,
    ConnectionState,
    HealthError,
    HealthState,
    LinkTelemetry,
)

__all__ = [
    "BaseIdentity",
    "BaseTelemetry",
    "CommandState",
    "ConnectionState",
    "CoreConfig",
    "CoreEvent",
    "CoreRunner",
    "CoreSession",
    "DockingConfig",
    "EventLog",
    "HealthError",
    "HealthState",
    "LinkTelemetry",
    "PollRates",
    "byte_time_for_baud",
]
