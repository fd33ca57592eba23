# SPDX-License-Identifier: MIT
"""Shared test settings: the Hypothesis profiles, and the markers that set apart the tests needing
more than the Python package, the slow ones and those that run on Python 3.10 too.

Hypothesis profiles, chosen by HYPOTHESIS_PROFILE, else by CI=true (`ci`), else `dev`:

- `ci` (make test, make test-stress): the example counts the tests ask for (@settings), 60 where
  they ask for none;
- `dev` (make check, a plain `pytest`): a tenth of those counts, at least 10 each: the inner loop.

`slow` marks soaks and long end-to-end runs (SLOW_MODULES below, or @pytest.mark.slow): `make
check` leaves them out. `py310` marks the tests that `make test` runs again on Python 3.10
(PY310_MODULES below; README.md says why those).

`make test` runs every test; a test whose tool is missing fails there (make test installs the
tools). A contributor with only the package and its test tools runs the rest with

    pytest -m "not external"

`external` is put on every test that carries one of the markers in EXTERNAL_MARKERS; a module
named in MODULE_MARKERS, or a test using a fixture in FIXTURE_MARKERS, gets its marker here, so a
new test in those modules is marked without anyone remembering to.
"""

from __future__ import annotations

import importlib.util
import os
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# No per-example deadline: the machine is small and shared, and a deadline would turn a slow moment
# into a flaky failure.
settings.register_profile("ci", max_examples=60, deadline=None, suppress_health_check=[HealthCheck.too_slow])
settings.register_profile("dev", parent=settings.get_profile("ci"), max_examples=10)
PROFILE = os.environ.get("HYPOTHESIS_PROFILE") or ("ci" if os.environ.get("CI") == "true" else "dev")
settings.load_profile(PROFILE)
DEV_SHARE = 10  # under `dev`, a test's own example count is divided by this (at least 10 remain)

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

# The modules whose tests run again on Python 3.10 (a name ends the prefix: test_core matches
# test_core_cli and the test_core_* modules of core/): every module imported, the packaging and
# the CLI, the typed core, what uses compat.StrEnum (frames, faults, quirks, the checker) and the
# ROS 2 bridge (ROS 2 Humble's Python is 3.10).
PY310_MODULES = (
    "test_imports", "test_package_face", "test_packaging", "test_setup", "test_cli", "test_sim_cli",
    "test_core", "test_frame", "test_messages", "test_faults", "test_quirks", "test_checker",
    "test_ros2",
)  # fmt: skip

# Soaks and long end-to-end runs (a minute or more of a core on this machine).
SLOW_MODULES: tuple[str, ...] = ()


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
    config.addinivalue_line("markers", "slow: a soak or long end-to-end run: make check leaves it out")
    config.addinivalue_line("markers", "py310: runs on Python 3.10 too (PY310_MODULES)")


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
        if module.startswith(PY310_MODULES):
            item.add_marker("py310")
        if module in SLOW_MODULES:
            item.add_marker("slow")
        if PROFILE == "dev":
            _fewer_examples(item)


def _fewer_examples(item: pytest.Item) -> None:
    """Under `dev`, a property test's own example count divided by DEV_SHARE (at least 10).
    Hypothesis keeps a test's @settings on the test function; `ci` leaves them as written."""
    test = getattr(item, "obj", None)
    own = getattr(test, "_hypothesis_internal_use_settings", None)
    if own is not None and getattr(test, "is_hypothesis_test", False):
        fewer = max(10, own.max_examples // DEV_SHARE)
        test._hypothesis_internal_use_settings = settings(own, max_examples=fewer)  # type: ignore[union-attr]
