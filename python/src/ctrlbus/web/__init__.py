# SPDX-License-Identifier: MIT
"""The browser dashboard: an optional layer over the Core emulator (the core never imports it).

- `ctrlbus.web.source`: the `DashboardSource` protocol, and `CoreSource`, a Core session under
  its runner's lock.
- `ctrlbus.web.snapshot`: a Core session's state as the dashboard's JSON snapshot.
- `ctrlbus.web.schema`: the snapshot schema (docs/dashboard.md) as a checker.
- `ctrlbus.web.control`: strict parsing of the page's control messages.
- `ctrlbus.web.options`: address, token and rate, validated before anything starts.
- `ctrlbus.web.server`: the aiohttp server (needs the `web` extra), in its own thread.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from ctrlbus.errors import UsageError

if TYPE_CHECKING:
    from ctrlbus.web.options import DashboardOptions
    from ctrlbus.web.server import DashboardServer
    from ctrlbus.web.source import DashboardSource

__all__ = [
    "start_dashboard",
]


def start_dashboard(source: DashboardSource, options: DashboardOptions) -> DashboardServer:
    """Start serving the dashboard for `source`; UsageError if the web extra is missing."""
    try:
        from ctrlbus.web import server
    except ModuleNotFoundError as exc:
        if exc.name != "aiohttp":
            raise
        raise UsageError("the dashboard needs the web extra: pip install 'ctrlbus[web]'") from None
    return server.start_dashboard(source, options)
