# SPDX-License-Identifier: MIT
"""Shared test settings: one hypothesis profile so the property tests stay fast on 2 cores, and the
markers that set apart the tests needing more than the Python package.

`make test` runs every test; a test whose tool is missing fails there (make test installs the
tools). A contributor with only the package and its test tools runs the rest with

    pytest -m "not external"

`external` is put on every test that carries one of the markers in EXTERNAL_MARKERS; a module
named in MODULE_MARKERS, or a test using a fixture in FIXTURE_MARKERS, gets its marker here, so a
new test in those modules is marked without anyone remembering to.
"""

from __future__ import annotations

import importlib.util
from pathlib import Path

import pytest
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

# marker -> what the tests need besides the package, its `web` extra and the `test` group.
EXTERNAL_MARKERS = {
    "c_build": "the C host build (make c-build: build/c)",
    "qemu": "the firmware images (make firmware, make ports) and QEMU",
    "tshark": "tshark (Wireshark) for the Lua dissector",
    "sigrok": "sigrok-cli for the PulseView decoder (tools/sigrok)",
    "browser": "Chromium and playwright for the dashboard in a browser",
    "bench": "the benchmark tools (make bench: the bench dependency group, valgrind, the C build)",
    "packaging": "PyPI (the floor setuptools is installed in a venv of its own) and twine",
    "setup": "scripts/setup.sh run in a scratch copy of the repository (a venv of its own)",
    "ros2": "the ros2 extra (cyclonedds, rosbags) and mcap-ros2-support (scripts/setup.sh full)",
}

MODULE_MARKERS = {
    "test_posix_base": ("c_build",),
    "test_firmware": ("qemu", "c_build"),
    "test_wireshark": ("tshark",),
    "test_wireshark_vs_decode": ("tshark",),
    "test_dashboard_browser": ("browser", "c_build", "qemu"),
    "test_bench_smoke": ("bench", "c_build"),
    "test_packaging": ("packaging",),
    "test_release": ("packaging", "c_build"),
    "test_manifests": ("packaging", "c_build"),
    "test_c_consumers": ("c_build",),
    "test_c_build_alone": ("c_build",),
    "test_minimal_base": ("c_build",),
    "test_mcu_ports": ("qemu",),
    "test_served_bases": ("qemu", "c_build"),
    "test_hostile_link": ("qemu", "c_build"),
    "test_sigrok": ("sigrok",),
    "test_setup": ("setup",),
    "test_ros2_bridge": ("ros2",),
    "test_ros2_record": ("ros2",),
    "test_ros2_loopback": ("ros2",),
    "test_ros2_cli": ("ros2",),
    "test_ros2_messages": ("ros2",),
}

FIXTURE_MARKERS = {
    "posix_base": ("c_build",),
}


# Modules that import a marker's tools at the top, so that they cannot even be collected without
# them: skipped at collection when the tools are missing and the run deselects their marker.
IMPORTS_AT_THE_TOP = {"ros2": ("cyclonedds", "rosbags", "mcap_ros2")}


def pytest_ignore_collect(collection_path: Path, config: pytest.Config) -> bool | None:
    markers = MODULE_MARKERS.get(collection_path.stem, ())
    expression = config.getoption("markexpr") or ""
    for marker in markers:
        modules = IMPORTS_AT_THE_TOP.get(marker, ())
        deselected = "not external" in expression or f"not {marker}" in expression
        if deselected and any(_missing(name) for name in modules):
            return True
    return None


def _missing(module: str) -> bool:
    try:
        return importlib.util.find_spec(module) is None
    except ValueError:  # a module set to None in sys.modules (hidden on purpose)
        return True


def pytest_configure(config: pytest.Config) -> None:
    for name, needs in EXTERNAL_MARKERS.items():
        config.addinivalue_line("markers", f"{name}: needs {needs}")
    config.addinivalue_line("markers", "external: needs more than the Python package (any marker above)")


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    for item in items:
        module = item.nodeid.split("::", 1)[0].rsplit("/", 1)[-1].removesuffix(".py")
        names = set(MODULE_MARKERS.get(module, ()))
        for fixture in getattr(item, "fixturenames", ()):
            names.update(FIXTURE_MARKERS.get(fixture, ()))
        names.update(mark.name for mark in item.iter_markers() if mark.name in EXTERNAL_MARKERS)
        for name in sorted(names):
            item.add_marker(name)
        if names:
            item.add_marker("external")
