# SPDX-License-Identifier: MIT
"""Shared test settings: one hypothesis profile so the property tests stay fast on 2 cores."""

from __future__ import annotations

from hypothesis import HealthCheck, settings

# Moderate example counts and no per-example deadline: the machine is small and shared, and a
# deadline would turn a slow moment into a flaky failure. Tests that need more examples say so.
settings.register_profile(
    "ctrlbus",
    max_examples=60,
    deadline=None,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("ctrlbus")
