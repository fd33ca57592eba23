# SPDX-License-Identifier: MIT
"""The ecosystem manifests and the one version number (issue 12), checked offline.

- One version: ctrlbus.h's CTRLBUS_VERSION_* is what the installed Python package reports, what
  library.json and c/idf_component.yml say, and the newest release in CHANGELOG.md (CMake reads
  the header itself: test_c_consumers.py checks what find_package and the headers report).
- Zephyr module (zephyr/): Kconfig parsed with kconfiglib (the library Zephyr's own tooling is
  built on), then zephyr/CMakeLists.txt run against stand-ins for Zephyr's CMake functions: which
  sources, include directories and switch definitions a Zephyr build would get. Every build-time
  switch of the library has its option.
- ESP-IDF component (c/): c/CMakeLists.txt run in script mode, as ESP-IDF's requirement scan does,
  against a stand-in idf_component_register; the manifest's fields.
No Zephyr or ESP-IDF tree is available offline, so neither is compiled here (README says so).
"""

from __future__ import annotations

import importlib.metadata
import json
import re
from pathlib import Path
from typing import Any

import kconfiglib  # type: ignore[import-untyped]
from support.packaging_support import REPO, header_version, run, tool

import ctrlbus

C_DIR = REPO / "c"
LIBRARY_SOURCES = sorted(str(p) for p in (C_DIR / "src").rglob("*.c"))
# Each Kconfig option CTRLBUS_<X> of zephyr/Kconfig sets the C macro CTRLBUS_CONFIG_<X>, except:
KCONFIG_TO_MACRO = {
    "CTRLBUS_CONFIG_HEADER": "CTRLBUS_CONFIG_HEADER",
}

# Stand-ins for the functions Zephyr and ESP-IDF give a module's CMakeLists.txt: each call is
# written to OUT as one "function argument" line per argument.
STAND_INS = """
function(record kind)
    foreach(value IN LISTS ARGN)
        file(APPEND "${OUT}" "${kind} ${value}\\n")
    endforeach()
endfunction()
function(zephyr_library_named name)
    record(library ${name})
endfunction()
function(zephyr_library_sources)
    record(source ${ARGN})
endfunction()
function(zephyr_include_directories)
    record(include ${ARGN})
endfunction()
function(zephyr_compile_definitions)
    record(define ${ARGN})
endfunction()
function(zephyr_library_compile_definitions)
    record(library_define ${ARGN})
endfunction()
function(idf_component_register)
    cmake_parse_arguments(ARG "" "" "SRCS;INCLUDE_DIRS;PRIV_INCLUDE_DIRS;REQUIRES;PRIV_REQUIRES" ${ARGN})
    if(ARG_UNPARSED_ARGUMENTS)
        message(FATAL_ERROR "idf_component_register: unknown arguments ${ARG_UNPARSED_ARGUMENTS}")
    endif()
    record(source ${ARG_SRCS})
    record(include ${ARG_INCLUDE_DIRS})
endfunction()
file(WRITE "${OUT}" "")
"""


def run_with_stand_ins(tmp_path: Path, cmakelists: Path, variables: dict[str, str]) -> dict[str, list[str]]:
    """What cmakelists asks of the build system, run in CMake's script mode with the stand-ins."""
    out = tmp_path / "calls.txt"
    script = tmp_path / "drive.cmake"
    settings = "".join(f'set({name} "{value}")\n' for name, value in variables.items())
    script.write_text(STAND_INS + settings + f'include("{cmakelists}")\n')
    run(tool("cmake"), f"-DOUT={out}", "-P", script)
    calls: dict[str, list[str]] = {}
    for line in out.read_text().splitlines():
        kind, _, value = line.partition(" ")
        calls.setdefault(kind, []).append(value)
    return calls


def yaml_scalar(text: str, key: str) -> str:
    """A top-level `key: value` of a simple YAML file (the manifests use no nesting for these)."""
    match = re.search(rf"^{key}:\s*\"?([^\"\n]*)\"?\s*$", text, re.M)
    assert match, f"no top-level {key!r}"
    return match.group(1).strip()


# ---- one version ---------------------------------------------------------------------------------


def test_the_python_package_reports_the_header_version() -> None:
    installed = importlib.metadata.version("ctrlbus")
    assert installed == header_version(), (
        f"the installed package says {installed}, ctrlbus.h says {header_version()}: run `make setup`"
    )
    assert ctrlbus.__version__ == header_version()


def test_manifests_and_changelog_carry_the_header_version() -> None:
    version = header_version()
    assert json.loads((REPO / "library.json").read_text())["version"] == version
    assert yaml_scalar((C_DIR / "idf_component.yml").read_text(), "version") == version
    releases = re.findall(r"^## (\d+\.\d+\.\d+)\b", (REPO / "CHANGELOG.md").read_text(), re.M)
    assert releases and releases[0] == version, f"newest CHANGELOG release {releases[:1]}, header {version}"
    # The Arduino manifest is filled in from the header when the zip is built (test_release.py).
    assert "version=@VERSION@" in (REPO / "packaging" / "arduino" / "library.properties.in").read_text()


def test_no_other_file_types_the_version() -> None:
    """The places that once typed it by hand now read it (issue 12: "typed by hand in 4 places")."""
    assert not re.search(r"^version\s*=", (REPO / "python" / "pyproject.toml").read_text(), re.M)
    assert not re.search(
        r"__version__\s*=\s*\"\d+\.\d+", (REPO / "python" / "src" / "ctrlbus" / "__init__.py").read_text()
    )
    assert not re.search(r"project\([^)]*VERSION +\d", (C_DIR / "CMakeLists.txt").read_text())


# ---- Zephyr --------------------------------------------------------------------------------------


def zephyr_kconfig(tmp_path: Path, **values: str) -> Any:
    """zephyr/Kconfig under a stand-in of Zephyr's tree (the one Zephyr symbol it uses), with
    CTRLBUS=y and the given values."""
    top = tmp_path / "Kconfig"
    top.write_text(
        'mainmenu "stand-in"\nconfig SIZE_OPTIMIZATIONS\n\tbool "size"\n'
        f'source "{REPO / "zephyr" / "Kconfig"}"\n'
    )
    kconfig = kconfiglib.Kconfig(str(top), warn_to_stderr=False)
    assert not kconfig.warnings, kconfig.warnings
    for name, value in {"CTRLBUS": "y", **values}.items():
        assert kconfig.syms[name].set_value(value), f"{name}={value} refused"
    return kconfig


def ctrlbus_options(kconfig: Any) -> dict[str, str]:
    return {name: sym.str_value for name, sym in kconfig.syms.items() if name.startswith("CTRLBUS_")}


def library_switches() -> set[str]:
    """The library's build-time switches: the #ifndef-defaulted CTRLBUS_CONFIG_* macros (their
    home is ctrlbus_config.h) and the CTRLBUS_CONFIG_HEADER hook."""
    found = {"CTRLBUS_CONFIG_HEADER"}
    for path in [*C_DIR.glob("include/ctrlbus/*.h"), *C_DIR.rglob("src/*.[ch]")]:
        found |= set(re.findall(r"^#ifndef (CTRLBUS_CONFIG_\w+)\s*$", path.read_text(), re.M))
    return {s for s in found if not s.endswith("_H")}


def test_module_yml_points_at_the_cmake_and_kconfig_files() -> None:
    text = (REPO / "zephyr" / "module.yml").read_text()
    assert yaml_scalar(text, "name") == "ctrlbus"
    assert re.search(r"^build:\n(?:  .*\n)*  cmake: zephyr$", text, re.M), text
    kconfig = re.search(r"^  kconfig: (\S+)$", text, re.M)
    assert kconfig and (REPO / kconfig.group(1)).is_file(), text
    assert (REPO / "zephyr" / "CMakeLists.txt").is_file()


def test_every_library_switch_has_a_kconfig_option(tmp_path: Path) -> None:
    mapped = {
        KCONFIG_TO_MACRO.get(n, n.replace("CTRLBUS_", "CTRLBUS_CONFIG_", 1))
        for n in ctrlbus_options(zephyr_kconfig(tmp_path))
    }
    missing = library_switches() - mapped
    assert not missing, f"switches of the C library without a zephyr/Kconfig option: {sorted(missing)}"
    assert "CTRLBUS_CONFIG_HEALTH" in library_switches()  # the scan itself works


def test_zephyr_build_with_the_defaults(tmp_path: Path) -> None:
    options = ctrlbus_options(zephyr_kconfig(tmp_path))
    assert options.pop("CTRLBUS_CONFIG_HEADER") == ""
    assert set(options.values()) == {"y"}, options
    calls = run_with_stand_ins(
        tmp_path,
        REPO / "zephyr" / "CMakeLists.txt",
        {"CONFIG_CTRLBUS": "y", **{f"CONFIG_{k}": v for k, v in options.items()}},
    )
    assert calls["library"] == ["ctrlbus"]
    assert sorted(calls["source"]) == LIBRARY_SOURCES
    assert [Path(p).resolve() for p in calls["include"]] == [C_DIR / "include"]
    switches = {n.replace("CTRLBUS_", "CTRLBUS_CONFIG_", 1) for n in options}
    assert set(calls["define"]) == {f"{s}=1" for s in switches}
    assert not calls.get("library_define")  # one decoder: nothing chooses its inside


def test_zephyr_options_turn_switches_off(tmp_path: Path) -> None:
    kconfig = zephyr_kconfig(
        tmp_path, SIZE_OPTIMIZATIONS="y", CTRLBUS_HEALTH="n", CTRLBUS_CONFIG_HEADER="board_ctrlbus.h"
    )
    options = ctrlbus_options(kconfig)
    variables = {f"CONFIG_{k}": v for k, v in options.items() if v != "n"}
    calls = run_with_stand_ins(
        tmp_path, REPO / "zephyr" / "CMakeLists.txt", {"CONFIG_CTRLBUS": "y", **variables}
    )
    assert "CTRLBUS_CONFIG_HEALTH=0" in calls["define"] and "CTRLBUS_CONFIG_LIMITS=1" in calls["define"]
    assert 'CTRLBUS_CONFIG_HEADER="board_ctrlbus.h"' in calls["define"]
    assert not calls.get("library_define")


def test_zephyr_builds_nothing_without_config_ctrlbus(tmp_path: Path) -> None:
    assert run_with_stand_ins(tmp_path, REPO / "zephyr" / "CMakeLists.txt", {}) == {}


# ---- ESP-IDF -------------------------------------------------------------------------------------


def test_esp_idf_component_registers_the_library(tmp_path: Path) -> None:
    calls = run_with_stand_ins(tmp_path, C_DIR / "CMakeLists.txt", {"ESP_PLATFORM": "1"})
    assert sorted(calls["source"]) == LIBRARY_SOURCES
    assert [(C_DIR / p).resolve() for p in calls["include"]] == [C_DIR / "include"]


def test_esp_idf_manifest_fields() -> None:
    text = (C_DIR / "idf_component.yml").read_text()
    assert yaml_scalar(text, "license") == "MIT"
    assert yaml_scalar(text, "description")
    assert re.search(r"^dependencies:\n  idf: \"[^\"]+\"$", text, re.M), text
    excluded = re.findall(r"^    - \"([^\"]+)\"$", text, re.M)
    assert excluded and not [p for p in excluded if p.startswith(("src", "include"))], excluded
