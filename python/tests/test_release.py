# SPDX-License-Identifier: MIT
"""`make release` (issue 12): the artefacts it puts in DIST, and that each works as its users
would use it.

- PlatformIO package (`pio pkg pack` on library.json): exactly the library, its manifest, licence,
  README and CHANGELOG (no tests, fuzzers, firmware or Python); its sources compile on their own.
- Arduino zip: the library layout (library.properties with the header's version, the header a
  sketch includes at the top of src/, every example in its own folder); the library and the
  MinimalBase sketch compile and link for an ATmega328P (an Uno) against a stand-in of the Arduino
  core, within the Uno's flash and RAM.
- Python wheel and sdist: the header's version; the wheel installed into a clean venv runs
  `ctrlbus check` against `ctrlbus sim` (both from that venv) and passes.
- Source tarball (git archive of HEAD): builds the consumer project of test_c_consumers.py.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest
from support.base_harness import Process
from support.packaging_support import REPO, header_version, run, tool

ARDUINO_STAND_IN = REPO / "c" / "tests" / "consumers" / "arduino"
UNO_FLASH, UNO_RAM = 32256, 2048  # ATmega328P: flash less the boot loader, SRAM


@pytest.fixture(scope="module")
def dist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    directory = tmp_path_factory.mktemp("dist")
    run(tool("make"), "--no-print-directory", "-C", REPO, "release", f"DIST={directory}", timeout=600)
    return directory


def artefact(dist: Path, name: str) -> Path:
    path = dist / name.format(version=header_version())
    assert path.is_file(), f"make release made no {path.name}: {sorted(p.name for p in dist.iterdir())}"
    return path


def files_under(directory: Path) -> set[str]:
    return {p.relative_to(REPO).as_posix() for p in directory.rglob("*") if p.is_file()}


def test_release_makes_the_five_artefacts(dist: Path) -> None:
    v = header_version()
    assert sorted(p.name for p in dist.iterdir()) == sorted(
        [f"ctrlbus-{v}-arduino.zip", f"ctrlbus-platformio-{v}.tar.gz", f"ctrlbus-{v}-py3-none-any.whl",
         f"ctrlbus-{v}.tar.gz", f"ctrlbus-{v}-source.tar.gz"]
    )  # fmt: skip


def test_platformio_package_holds_the_library_only(dist: Path, tmp_path: Path) -> None:
    with tarfile.open(artefact(dist, "ctrlbus-platformio-{version}.tar.gz")) as archive:
        names = {m.name for m in archive.getmembers() if m.isfile()}
        archive.extractall(tmp_path, filter="data")
    expected = {"library.json", "LICENSE", "README.md", "CHANGELOG.md"}
    for directory in ("c/include", "c/src", "c/examples/minimal_base", "c/ports"):
        if (REPO / directory).is_dir():  # the last two arrive with the front-door example
            expected |= files_under(REPO / directory)
    assert names == expected, f"extra: {sorted(names - expected)}, missing: {sorted(expected - names)}"
    assert json.loads((tmp_path / "library.json").read_text())["version"] == header_version()
    # What PlatformIO compiles (build.srcDir with build.includeDir) needs nothing else.
    for source in sorted((tmp_path / "c" / "src").rglob("*.c")):
        run(
            tool("cc"),
            "-std=c99",
            "-Wall",
            "-Wextra",
            "-I",
            tmp_path / "c" / "include",
            "-c",
            source,
            "-o",
            tmp_path / "o.o",
        )


def test_arduino_zip_layout(dist: Path) -> None:
    with zipfile.ZipFile(artefact(dist, "ctrlbus-{version}-arduino.zip")) as archive:
        names = set(archive.namelist())
        properties = archive.read("ctrlbus/library.properties").decode()
    assert all(n.startswith("ctrlbus/") for n in names), sorted(names)
    fields = dict(
        line.split("=", 1) for line in properties.splitlines() if "=" in line and not line.startswith("#")
    )
    assert fields["name"] == "ctrlbus" and fields["version"] == header_version(), fields
    for required in ("author", "maintainer", "sentence", "paragraph", "category", "url", "architectures"):
        assert fields.get(required), f"library.properties has no {required}"
    assert f"ctrlbus/src/{fields['includes']}" in names  # the header a sketch includes, at the top of src/
    headers = {f"ctrlbus/src/ctrlbus/{h.name}" for h in (REPO / "c" / "include" / "ctrlbus").glob("*.h")}
    sources = {
        f"ctrlbus/src/{p.relative_to(REPO / 'c' / 'src').as_posix()}"
        for p in (REPO / "c" / "src").rglob("*")
        if p.is_file()
    }
    assert headers | sources <= names, sorted((headers | sources) - names)
    sketches = [n for n in names if n.endswith(".ino")]
    assert sketches and all(re.fullmatch(r"ctrlbus/examples/(\w+)/\1\.ino", s) for s in sketches), sketches
    assert {"ctrlbus/LICENSE", "ctrlbus/library.properties"} <= names
    assert not [n for n in names if "/tests/" in n or "/fuzz/" in n or "/firmware/" in n], sorted(names)


def test_arduino_library_and_sketch_build_for_an_uno(dist: Path, tmp_path: Path) -> None:
    with zipfile.ZipFile(artefact(dist, "ctrlbus-{version}-arduino.zip")) as archive:
        archive.extractall(tmp_path)
    library = tmp_path / "ctrlbus"
    flags = ["-mmcu=atmega328p", "-Os", "-ffunction-sections", "-fdata-sections", "-Wall", "-Wextra"]
    objects = []
    for source in sorted((library / "src").rglob("*.c")):  # as the Arduino builder compiles a library
        objects.append(tmp_path / f"{source.stem}.o")
        run(tool("avr-gcc"), *flags, "-std=gnu11", "-I", library / "src", "-c", source, "-o", objects[-1])
    core = tmp_path / "core.o"
    run(tool("avr-g++"), *flags, "-std=gnu++11", "-c", ARDUINO_STAND_IN / "Arduino.cpp", "-o", core)
    for sketch in sorted((library / "examples").glob("*/*.ino")):
        # The Arduino builder's preprocessing: the core's header first, then the sketch as C++.
        source = tmp_path / f"{sketch.stem}.cpp"
        source.write_text(f'#include <Arduino.h>\n#line 1 "{sketch.name}"\n{sketch.read_text()}')
        warnings = run(
            tool("avr-g++"), *flags, "-std=gnu++11", "-fno-exceptions", "-I", ARDUINO_STAND_IN,
            "-I", library / "src", "-c", source, "-o", tmp_path / f"{sketch.stem}.o",
        )  # fmt: skip
        assert "warning" not in warnings, warnings
        elf = tmp_path / f"{sketch.stem}.elf"
        run(
            tool("avr-g++"),
            *flags,
            "-Wl,--gc-sections",
            tmp_path / f"{sketch.stem}.o",
            core,
            *objects,
            "-o",
            elf,
        )
        text, data, bss = map(int, run(tool("avr-size"), elf).splitlines()[1].split()[:3])
        assert text + data <= UNO_FLASH and data + bss <= UNO_RAM, (sketch.name, text, data, bss)


def test_python_sdist_and_wheel_carry_the_version(dist: Path) -> None:
    v = header_version()
    with tarfile.open(artefact(dist, "ctrlbus-{version}.tar.gz")) as sdist:
        names = set(sdist.getnames())
        pkg_info = sdist.extractfile(f"ctrlbus-{v}/PKG-INFO")
        assert pkg_info and f"\nVersion: {v}\n" in pkg_info.read().decode()
    assert {
        f"ctrlbus-{v}/setup.py",
        f"ctrlbus-{v}/pyproject.toml",
        f"ctrlbus-{v}/src/ctrlbus/cli/__init__.py",
    } <= names
    with zipfile.ZipFile(artefact(dist, "ctrlbus-{version}-py3-none-any.whl")) as wheel:
        metadata = wheel.read(f"ctrlbus-{v}.dist-info/METADATA").decode()
        assert f"\nVersion: {v}\n" in metadata
        assert any(n.startswith("ctrlbus/data/") and n.endswith(".json") for n in wheel.namelist())


def test_source_tarball_builds_the_consumer(dist: Path, tmp_path: Path) -> None:
    v = header_version()
    with tarfile.open(artefact(dist, "ctrlbus-{version}-source.tar.gz")) as archive:
        names = set(archive.getnames())
        archive.extractall(tmp_path, filter="data")
    for path in (
        "LICENSE",
        "CHANGELOG.md",
        "library.json",
        "zephyr/module.yml",
        "c/CMakeLists.txt",
        "python/pyproject.toml",
    ):
        assert f"ctrlbus-{v}/{path}" in names, path
    assert not [
        n for n in names if n.startswith((f"ctrlbus-{v}/build/", f"ctrlbus-{v}/dist/", f"ctrlbus-{v}/.venv/"))
    ]
    build = tmp_path / "build"
    run(
        tool("cmake"), "-S", REPO / "c" / "tests" / "consumers", "-B", build, "-G", "Ninja",
        f"-DCTRLBUS_CHECKOUT={tmp_path / f'ctrlbus-{v}'}", f"-DCONSUMER_EXPECT_VERSION={v}",
    )  # fmt: skip
    run(tool("cmake"), "--build", build)
    run(build / "consumer")


def test_wheel_in_a_clean_venv_checks_the_simulated_base(dist: Path, tmp_path: Path) -> None:
    venv = tmp_path / "venv"
    run(sys.executable, "-m", "venv", venv)
    env = {k: v for k, v in os.environ.items() if k not in ("VIRTUAL_ENV", "PYTHONPATH")}
    run(
        venv / "bin" / "python",
        "-m",
        "pip",
        "install",
        "-q",
        artefact(dist, "ctrlbus-{version}-py3-none-any.whl"),
        env=env,
    )
    where = run(
        venv / "bin" / "python",
        "-c",
        "import ctrlbus; print(ctrlbus.__file__, ctrlbus.__version__)",
        cwd=tmp_path,
        env=env,
    )
    assert where.startswith(str(venv)) and where.split()[1] == header_version(), where
    assert run(venv / "bin" / "ctrlbus", "--version", env=env).strip() == f"ctrlbus {header_version()}"

    sim = Process([str(venv / "bin" / "ctrlbus"), "sim", "--listen", "127.0.0.1:0"], tmp_path / "sim.log")
    try:
        line = sim.read_line()
        match = re.fullmatch(r"listen: 127\.0\.0\.1:(\d+)", line)
        assert match, f"unexpected first line {line!r} from {sim.describe()}"
        report = tmp_path / "report.json"
        result = subprocess.run(
            [str(venv / "bin" / "ctrlbus"), "check", "--port", f"socket://127.0.0.1:{match.group(1)}",
             "--json", str(report)],
            capture_output=True, text=True, timeout=300, cwd=tmp_path, env=env,
        )  # fmt: skip
        assert result.returncode == 0, f"{result.stdout}\n{result.stderr}\n{sim.describe()}"
        summary = json.loads(report.read_text())["summary"]
        assert summary["fail"] == 0 and summary["pass"] >= 18, summary
    finally:
        sim.stop()
