# SPDX-License-Identifier: MIT
"""The C library as other projects consume it (issue 12): c/tests/consumers/ is a tiny project
that links ctrlbus::ctrlbus and checks an encode/decode round trip and the headers' version. It is
configured, built and run here through each way of getting the library: add_subdirectory,
FetchContent (from this checkout's git repository: what is committed at HEAD), find_package after
`cmake --install` to a temporary prefix, pkg-config (plain cc, no CMake), and a Cortex-M0+ cross
build with the toolchain file shipped in c/cmake/.

Beyond "it links", each way checks what a consumer must not get: ctrlbus's tests in their ctest,
-Werror on their compiler, a need for Python, POSIX examples in a cross build.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
from pathlib import Path

import pytest
from support.packaging_support import REPO, header_version, run, tool

CONSUMER = REPO / "c" / "tests" / "consumers"
TOOLCHAIN_M0PLUS = REPO / "c" / "cmake" / "cortex-m0plus.cmake"
# A consumer that asks for Python would fail to configure with this (find_package REQUIRED).
NO_PYTHON = "-DCMAKE_DISABLE_FIND_PACKAGE_Python3=ON"
# newlib's stubs stand in for a board's start-up code, so a Cortex-M0+ program links.
M0PLUS_LINK = "-DCMAKE_EXE_LINKER_FLAGS=--specs=nano.specs --specs=nosys.specs"


def configure_and_build(build: Path, source: Path, *options: str) -> str:
    output = run(
        tool("cmake"), "-S", source, "-B", build, "-G", "Ninja", "-DCMAKE_BUILD_TYPE=Release",
        "-DCMAKE_EXPORT_COMPILE_COMMANDS=ON", *options,
    )  # fmt: skip
    run(tool("cmake"), "--build", build, "-j", "2")
    return output


def built_targets(build: Path) -> set[str]:
    """The file names of the programs and libraries a ninja build directory links."""
    lines = run(tool("ninja"), "-C", build, "-t", "targets", "all").splitlines()
    return {line.split(":")[0].rsplit("/", 1)[-1] for line in lines if "_LINKER__" in line}


def assert_consumer_only(build: Path) -> None:
    """Nothing of ctrlbus's own but the library: no tests in ctest, no -Werror anywhere."""
    listed = run(tool("ctest"), "--test-dir", build, "-N")
    assert re.search(r"Total Tests: 1\b", listed) and "consumer" in listed, listed
    commands = json.loads((build / "compile_commands.json").read_text())
    assert commands, "no compile commands recorded"
    for command in commands:
        assert "-Werror" not in command["command"], command
    assert built_targets(build) <= {"consumer", "libctrlbus.a"}, built_targets(build)


@pytest.fixture(scope="module")
def installed_prefix(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """c/ configured as a packager would (top level, Release, no tests or examples), installed."""
    work = tmp_path_factory.mktemp("install")
    build, prefix = work / "build", work / "prefix"
    configure_and_build(
        build, REPO / "c", "-DCTRLBUS_BUILD_TESTS=OFF", "-DCTRLBUS_BUILD_EXAMPLES=OFF", NO_PYTHON
    )
    run(tool("cmake"), "--install", build, "--prefix", prefix)
    return prefix


def test_add_subdirectory_builds_the_library_alone(tmp_path: Path) -> None:
    configure_and_build(
        tmp_path,
        CONSUMER,
        f"-DCTRLBUS_CHECKOUT={REPO}",
        f"-DCONSUMER_EXPECT_VERSION={header_version()}",
        NO_PYTHON,
    )
    run(tmp_path / "consumer")
    assert_consumer_only(tmp_path)


def test_fetchcontent_from_the_local_checkout(tmp_path: Path) -> None:
    configure_and_build(
        tmp_path / "build", CONSUMER, "-DCONSUMER_GETS_CTRLBUS=fetchcontent", f"-DCTRLBUS_GIT_URL={REPO}",
        f"-DCONSUMER_EXPECT_VERSION={header_version()}", NO_PYTHON,
    )  # fmt: skip
    assert (tmp_path / "build" / "_deps" / "ctrlbus-src" / "c" / "CMakeLists.txt").exists()
    run(tmp_path / "build" / "consumer")
    assert_consumer_only(tmp_path / "build")


def test_install_tree_has_the_library_headers_and_package_files(installed_prefix: Path) -> None:
    files = {p.relative_to(installed_prefix).as_posix() for p in installed_prefix.rglob("*") if p.is_file()}
    headers = {f"include/ctrlbus/{h.name}" for h in (REPO / "c" / "include" / "ctrlbus").glob("*.h")}
    assert headers and headers <= files, sorted(files)
    for expected in (
        "lib/libctrlbus.a", "lib/pkgconfig/ctrlbus.pc", "lib/cmake/ctrlbus/ctrlbusConfig.cmake",
        "lib/cmake/ctrlbus/ctrlbusConfigVersion.cmake", "lib/cmake/ctrlbus/ctrlbusTargets.cmake",
    ):  # fmt: skip
        assert expected in files, sorted(files)
    # Nothing of ours but the library: no test programs or examples installed.
    assert not [f for f in files if f.startswith("bin/")], sorted(files)


def test_find_package_after_install(tmp_path: Path, installed_prefix: Path) -> None:
    output = configure_and_build(
        tmp_path, CONSUMER, "-DCONSUMER_GETS_CTRLBUS=find_package", f"-DCMAKE_PREFIX_PATH={installed_prefix}",
        f"-DCONSUMER_EXPECT_VERSION={header_version()}", NO_PYTHON,
    )  # fmt: skip
    assert f"found ctrlbus {header_version()} in {installed_prefix}" in output, output
    run(tmp_path / "consumer")
    assert_consumer_only(tmp_path)


def test_find_package_refuses_another_minor_version(tmp_path: Path, installed_prefix: Path) -> None:
    major, minor, _ = header_version().split(".")
    result = subprocess.run(
        [tool("cmake"), "-S", str(CONSUMER), "-B", str(tmp_path), "-G", "Ninja",
         "-DCONSUMER_GETS_CTRLBUS=find_package", f"-DCMAKE_PREFIX_PATH={installed_prefix}",
         f"-DCONSUMER_EXPECT_VERSION={major}.{int(minor) + 1}.0"],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    assert result.returncode != 0 and f"ctrlbusConfig.cmake, version: {header_version()}" in result.stderr, (
        result.stderr
    )


def test_pkg_config_with_plain_cc(tmp_path: Path, installed_prefix: Path) -> None:
    env = {**os.environ, "PKG_CONFIG_PATH": str(installed_prefix / "lib" / "pkgconfig")}
    assert run(tool("pkg-config"), "--modversion", "ctrlbus", env=env).strip() == header_version()
    flags = run(tool("pkg-config"), "--cflags", "--libs", "ctrlbus", env=env).split()
    major, minor, patch = header_version().split(".")
    expect = [
        f"-DCONSUMER_EXPECT_VERSION_{n}={v}"
        for n, v in zip(("MAJOR", "MINOR", "PATCH"), (major, minor, patch), strict=True)
    ]
    program = tmp_path / "consumer"
    run(tool("cc"), "-std=c99", "-Wall", "-Wextra", *expect, CONSUMER / "main.c", "-o", program, *flags)
    run(program)


def test_cortex_m0plus_configures_c_alone_to_the_library(tmp_path: Path) -> None:
    """Configuring c/ itself with the toolchain file and no options: the library only, no Python."""
    tool("arm-none-eabi-gcc")
    configure_and_build(tmp_path, REPO / "c", f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN_M0PLUS}", NO_PYTHON)
    assert built_targets(tmp_path) == {"libctrlbus.a"}, built_targets(tmp_path)
    attributes = run(tool("arm-none-eabi-readelf"), "-A", tmp_path / "libctrlbus.a")
    assert "Tag_CPU_arch: v6S-M" in attributes, attributes  # ARMv6-M: Cortex-M0/M0+


def test_cortex_m0plus_consumer_links(tmp_path: Path) -> None:
    configure_and_build(
        tmp_path, CONSUMER, f"-DCMAKE_TOOLCHAIN_FILE={TOOLCHAIN_M0PLUS}", f"-DCTRLBUS_CHECKOUT={REPO}",
        f"-DCONSUMER_EXPECT_VERSION={header_version()}", M0PLUS_LINK, NO_PYTHON,
        "-DCMAKE_BUILD_TYPE=MinSizeRel",
    )  # fmt: skip
    header = run(tool("arm-none-eabi-readelf"), "-h", "-A", tmp_path / "consumer")
    assert "Machine:                           ARM" in header and "Tag_CPU_arch: v6S-M" in header, header
    sizes = run(tool("arm-none-eabi-size"), tmp_path / "consumer").splitlines()[1].split()
    assert int(sizes[0]) > 0, sizes
