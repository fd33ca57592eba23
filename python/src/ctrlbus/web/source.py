# SPDX-License-Identifier: MIT
"""What the dashboard needs from the program it shows: the `DashboardSource` protocol.

Every method is called from the dashboard's own thread, so an implementation must be thread-safe
and quick: it may take a lock for a moment, never wait for the link. `CoreSource` is the Core
emulator's: its session is sans-IO and lock-free, so it takes the lock of the runner that drives
the session around each call. The snapshot's schema is in docs/dashboard.md;
`ctrlbus.web.schema.check_snapshot` checks a snapshot against it.
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from typing import Any, Protocol, runtime_checkable

from ctrlbus.core.runner import CoreRunner
from ctrlbus.core.session import CoreSession
from ctrlbus.web.snapshot import dashboard_snapshot

__all__ = [
    "CoreSource",
    "DashboardSource",
    "ExternalCommandSink",
    "accepts_external_commands",
]


@runtime_checkable
class DashboardSource(Protocol):
    """The view and the controls of a Core session, as the dashboard uses them."""

    def snapshot(self) -> dict[str, Any]:
        """The whole state as plain JSON values (schema: docs/dashboard.md)."""
        ...

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        """Command a body velocity, sent to the base as SET_V_AND_GET_DEADRECKON.

        Ignored (velocity stays zero) while the emergency stop is latched.
        """
        ...

    def emergency_stop(self) -> None:
        """Command zero velocity, cancel any action, and latch until `release_stop`."""
        ...

    def release_stop(self) -> None:
        """Unlatch the emergency stop; the velocity stays zero until commanded again."""
        ...

    def go_home(self) -> None:
        """Start docking on the charger using its beacons."""
        ...

    def limits(self) -> tuple[float, float]:
        """(max |vx| in m/s, max |omega| in rad/s) from the base's configuration."""
        ...


@runtime_checkable
class ExternalCommandSink(Protocol):
    """Optional: a source whose base is our simulator can queue a base-side external command.

    The command is then offered to the Core through POLL_BASE_CMD as a real base would offer it.
    A source without a simulator either lacks the method or raises from it.
    """

    def queue_external_command(self, code: int) -> None: ...


def accepts_external_commands(source: object) -> bool:
    """Whether the page should show the external-command buttons for this source."""
    return isinstance(source, ExternalCommandSink)


class CoreSource:
    """A Core session as a `DashboardSource`: each call holds `lock`, the lock of the thread that
    drives the session (`CoreRunner.lock`; `for_runner` takes both from a runner)."""

    def __init__(self, session: CoreSession, lock: AbstractContextManager[Any]) -> None:
        self.session = session
        self.lock = lock

    @classmethod
    def for_runner(cls, runner: CoreRunner) -> CoreSource:
        return cls(runner.session, runner.lock)

    def snapshot(self) -> dict[str, Any]:
        with self.lock:
            return dashboard_snapshot(self.session)

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        with self.lock:
            self.session.set_velocity(vx_mps, omega_radps)

    def emergency_stop(self) -> None:
        with self.lock:
            self.session.emergency_stop()

    def release_stop(self) -> None:
        with self.lock:
            self.session.release_stop()

    def go_home(self) -> None:
        with self.lock:
            self.session.go_home()

    def limits(self) -> tuple[float, float]:
        with self.lock:
            return self.session.limits()
