# SPDX-License-Identifier: MIT
"""What a benchmark module hands back to bench/run.py, which turns it into the run's `Outcome`.

The benchmark modules (exchange.py, footprint.py, endtoend.py) cannot import run.py (it is the
script that imports them), so they return this, with the same fields as `run.Outcome`.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

PARTIAL = "partial"  # as in run.py: part of it measured, the rest pending


@dataclass
class Findings:
    status: str
    figures: dict[str, Any] = field(default_factory=dict)
    rows: list[list[str]] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)
