# SPDX-License-Identifier: MIT
"""The Core emulator: a stand-in for the SLAMWARE Core (the bus master).

- `CoreSession` (ctrlbus.core.session): the protocol as a sans-IO state machine, with telemetry,
  controls (velocity, emergency stop, go home), a snapshot for the dashboard and link statistics.
- `CoreRunner` (ctrlbus.core.runner): a thread that connects a session to a `Link` in real time.
- `ctrlbus.vtime`: runs a session against an in-process base in simulated time.
- `CoreConfig` / `PollRates` / `DockingConfig` (ctrlbus.core.config): its settings.

docs/core.md is the manual; docs/protocol.md §11 the behaviour it implements.
"""

from ctrlbus.core.config import CoreConfig, DockingConfig, PollRates, byte_time_for_baud
from ctrlbus.core.runner import CoreRunner
from ctrlbus.core.session import (
    BaseIdentity,
    CommandState,
    ConnectionState,
    CoreEvent,
    CoreSession,
    HealthError,
    HealthState,
)

__all__ = [
    "BaseIdentity",
    "CommandState",
    "ConnectionState",
    "CoreConfig",
    "CoreEvent",
    "CoreRunner",
    "CoreSession",
    "DockingConfig",
    "HealthError",
    "HealthState",
    "PollRates",
    "byte_time_for_baud",
]
