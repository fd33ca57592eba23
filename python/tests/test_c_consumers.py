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
from packaging_support import REPO, header_version, run, tool

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


# --- as a firmware team meets it (issue 28) ------------------------------------------------------


def test_config_header_set_as_a_normal_variable_applies_on_the_first_configure(tmp_path: Path) -> None:
    """set(CTRLBUS_CONFIG_HEADER ...) before add_subdirectory, one configure: the switch is off in
    the library's objects (the consumer checks it at run time, and CTRLBUS_CONFIG_CHECK() links)."""
    output = configure_and_build(
        tmp_path, CONSUMER, f"-DCTRLBUS_CHECKOUT={REPO}", "-DCONSUMER_CONFIG_HEADER=ON", NO_PYTHON
    )
    run(tmp_path / "consumer")
    assert f"ctrlbus: build-time switches from {CONSUMER / 'consumer_config.h'}" in output, output
    assert "CTRLBUS_CONFIG_HEADER" not in (tmp_path / "CMakeCache.txt").read_text(), output
    assert_consumer_only(tmp_path)


def test_config_mismatch_between_library_and_firmware_fails_the_link(
    tmp_path: Path, installed_prefix: Path
) -> None:
    """The library installed with the default switches; a firmware compiled with one off."""
    result = subprocess.run(
        [tool("cc"), "-std=c99", "-DCTRLBUS_CONFIG_HEALTH=0", f"-I{installed_prefix / 'include'}",
         str(CONSUMER / "main.c"), "-o", str(tmp_path / "consumer"),
         str(installed_prefix / "lib" / "libctrlbus.a")],
        capture_output=True, text=True, timeout=120,
    )  # fmt: skip
    expected = "undefined reference to `ctrlbus_config_h0_"
    assert result.returncode != 0 and expected in result.stderr, result.stderr


def readme_fetchcontent_recipe() -> str:
    """The README's FetchContent block, as a user copies it."""
    readme = (REPO / "README.md").read_text()
    blocks = re.findall(r"```cmake\n(.*?)```", readme, re.S)
    recipes = [block for block in blocks if "FetchContent_Declare(ctrlbus" in block]
    assert len(recipes) == 1, blocks
    return str(recipes[0])


def test_readme_fetchcontent_recipe_as_written(tmp_path: Path) -> None:
    """The README's text verbatim but for the repository's address: a clone of this checkout's
    HEAD, tagged as the release procedure tags it (make release-tag). GIT_SHALLOW needs a tag."""
    recipe = readme_fetchcontent_recipe()
    assert re.search(rf"GIT_TAG +v{re.escape(header_version())}\n", recipe), recipe
    assert re.search(r"GIT_SHALLOW +TRUE\n", recipe), recipe
    published = "https://github.com/ctrlbus/ctrlbus.git"
    assert recipe.count(published) == 1, recipe
    clone = tmp_path / "ctrlbus.git"
    run("git", "clone", "--quiet", f"file://{REPO}", clone)
    env = {
        **os.environ, "GIT_AUTHOR_NAME": "release", "GIT_AUTHOR_EMAIL": "release@example.invalid",
        "GIT_COMMITTER_NAME": "release", "GIT_COMMITTER_EMAIL": "release@example.invalid",
    }  # fmt: skip
    run("make", "-C", clone, "release-tag", "PY=python3", env=env)
    recipe_file = tmp_path / "recipe.cmake"
    recipe_file.write_text(recipe.replace(published, f"file://{clone}"))
    build = tmp_path / "build"
    configure_and_build(
        build, CONSUMER, "-DCONSUMER_GETS_CTRLBUS=fetchcontent",
        f"-DCONSUMER_FETCHCONTENT_RECIPE={recipe_file}",
        f"-DCONSUMER_EXPECT_VERSION={header_version()}", NO_PYTHON,
    )  # fmt: skip
    source = build / "_deps" / "ctrlbus-src"
    assert run("git", "-C", source, "rev-list", "--count", "HEAD").strip() == "1", "not a shallow clone"
    run(build / "consumer")
    assert_consumer_only(build)


def test_consumer_library_wrapping_ctrlbus_installs_and_exports(tmp_path: Path) -> None:
    """A team's own library linking ctrlbus::ctrlbus, installed with install(EXPORT), then used by
    another of their projects through find_package(acme)."""
    prefix = tmp_path / "prefix"
    configure_and_build(tmp_path / "acme", CONSUMER / "wrapper", f"-DCTRLBUS_CHECKOUT={REPO}", NO_PYTHON)
    run(tool("cmake"), "--install", tmp_path / "acme", "--prefix", prefix)
    assert (prefix / "lib" / "cmake" / "ctrlbus" / "ctrlbusConfig.cmake").exists()
    configure_and_build(
        tmp_path / "user", CONSUMER, "-DCONSUMER_GETS_CTRLBUS=acme", f"-DCMAKE_PREFIX_PATH={prefix}",
        f"-DCONSUMER_EXPECT_VERSION={header_version()}", NO_PYTHON,
    )  # fmt: skip
    run(tmp_path / "user" / "consumer")


@pytest.mark.parametrize("standard", ["c++11", "c++17"])
def test_headers_compile_as_cxx_before_cxx20(tmp_path: Path, installed_prefix: Path, standard: str) -> None:
    """Every public header from C++ (no designated initializers before C++20), linked and run."""
    program = tmp_path / "cxx_consumer"
    run(
        tool("c++"), f"-std={standard}", "-Wall", "-Wextra", "-Wpedantic", "-Werror",
        f"-I{installed_prefix / 'include'}", CONSUMER / "cxx_main.cpp", "-o", program,
        installed_prefix / "lib" / "libctrlbus.a",
    )  # fmt: skip
    run(program)


def test_vectors_dir_stays_out_of_a_consumers_cache(tmp_path: Path) -> None:
    configure_and_build(tmp_path, CONSUMER, f"-DCTRLBUS_CHECKOUT={REPO}", NO_PYTHON)
    cache = (tmp_path / "CMakeCache.txt").read_text()
    assert "CTRLBUS_VECTORS_DIR" not in cache and "CTRLBUS_CONFIG_HEADER:FILEPATH=" in cache
