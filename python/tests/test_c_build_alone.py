# SPDX-License-Identifier: MIT
"""`make c-build` and `make arduino` on a machine that has only what they claim to need (issue 28).

Each runs with a PATH holding nothing but those tools: `make c-build` with a C compiler (and its
assembler, linker and archiver), CMake, make and a shell; `make arduino` with python3, make and a
shell. No set-up can run there (no apt, no pip, no venv: scripts/setup.sh would fail at its first
tool), and no Ninja, so CMake's default generator builds. The build directory and the zip go to a
temporary directory, never to the checkout's build/.
"""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

from packaging_support import REPO, header_version

C_BUILD_TOOLS = ("bash", "sh", "make", "cmake", "cc", "gcc", "as", "ld", "ar", "ranlib")
ARDUINO_TOOLS = ("bash", "sh", "make", "python3")


def path_with_only(tools: tuple[str, ...], directory: Path) -> str:
    directory.mkdir()
    for name in tools:
        # python3: the interpreter this venv was made from, without the venv's packages (a
        # `python3` on the PATH may be a version manager's shim, which needs more tools).
        found = str(Path(sys.base_prefix) / "bin" / "python3") if name == "python3" else shutil.which(name)
        assert found and Path(found).is_file(), f"{name} is not installed"
        (directory / name).symlink_to(found)
    return str(directory)


def make(target: str, path: str, *variables: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        ["make", "-C", str(REPO), target, *variables],
        env={"PATH": path, "HOME": os.environ.get("HOME", "/tmp")},
        capture_output=True, text=True, timeout=900,
    )  # fmt: skip


def test_make_c_build_needs_only_a_compiler_cmake_and_make(tmp_path: Path) -> None:
    path = path_with_only(C_BUILD_TOOLS, tmp_path / "bin")
    result = make("c-build", path, f"BUILD={tmp_path / 'build'}", "JOBS=2")
    assert result.returncode == 0, result.stdout + result.stderr
    assert "setup" not in result.stdout + result.stderr
    for program in ("examples/minimal_base/minimal_base", "examples/posix_base/posix_base", "libctrlbus.a"):
        assert (tmp_path / "build" / "c" / program).is_file(), program
    assert (tmp_path / "build" / "c" / "Makefile").is_file(), "not CMake's default generator"


def test_make_arduino_needs_only_python3(tmp_path: Path) -> None:
    path = path_with_only(ARDUINO_TOOLS, tmp_path / "bin")
    # VENV names a directory that does not exist: the system's python3 runs the script.
    result = make("arduino", path, f"DIST={tmp_path / 'dist'}", f"VENV={tmp_path / 'no-venv'}")
    assert result.returncode == 0, result.stdout + result.stderr
    archive = tmp_path / "dist" / f"ctrlbus-{header_version()}-arduino.zip"
    with zipfile.ZipFile(archive) as opened:
        assert "ctrlbus/src/ctrlbus/base.h" in opened.namelist()
