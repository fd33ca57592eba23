# SPDX-License-Identifier: MIT
"""The package as PyPI and pip see it: it builds with the oldest setuptools pyproject.toml allows,
its metadata is complete (twine check --strict, then field by field), and the wheel carries the
licence, the data files and the `ctrlbus` command."""

from __future__ import annotations

import email.message
import email.parser
import re
import shutil
import subprocess
import sys
import tarfile
import zipfile
from pathlib import Path

import pytest

PYTHON_DIR = Path(__file__).resolve().parent.parent
REPO = PYTHON_DIR.parent
PYPROJECT = (PYTHON_DIR / "pyproject.toml").read_text(encoding="utf-8")
SUPPORTED = ("3.10", "3.11", "3.12", "3.13")


def setuptools_floor() -> str:
    match = re.search(r'^requires = \["setuptools>=([0-9.]+)"\]$', PYPROJECT, re.MULTILINE)
    assert match, "pyproject.toml: [build-system] requires should be exactly one setuptools>=FLOOR"
    return match.group(1)


def floor_python() -> Path:
    """A venv holding exactly the floor setuptools (kept in build/ and reused)."""
    floor = setuptools_floor()
    venv = REPO / "build" / f"setuptools-{floor}-{sys.version_info.major}.{sys.version_info.minor}"
    python = venv / "bin" / "python"
    stamp = venv / ".installed"
    if not stamp.exists():
        shutil.rmtree(venv, ignore_errors=True)
        subprocess.run([sys.executable, "-m", "venv", "--without-pip", str(venv)], check=True)
        subprocess.run(
            [sys.executable, "-m", "pip", "--python", str(python), "install", "-q", f"setuptools=={floor}"],
            check=True,
        )
        stamp.touch()
    version = subprocess.run(
        [str(python), "-c", "import setuptools; print(setuptools.__version__)"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    assert version == floor, f"the floor venv holds setuptools {version}, not {floor}"
    return python


@pytest.fixture(scope="module")
def dist(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """sdist and wheel built from a copy of python/ by the floor setuptools, without isolation."""
    work = tmp_path_factory.mktemp("packaging")
    source = work / "python"
    ignore = shutil.ignore_patterns("__pycache__", "*.egg-info", "build", "dist")
    source.mkdir()
    for name in ("pyproject.toml", "README.md", "LICENSE"):
        shutil.copyfile(PYTHON_DIR / name, source / name)  # follows the LICENSE link to the root's
    shutil.copytree(PYTHON_DIR / "src", source / "src", ignore=ignore)
    out = work / "dist"
    for hook in ("build_sdist", "build_wheel"):  # one process each: setuptools keeps state
        script = f"from setuptools import build_meta; build_meta.{hook}({str(out)!r})"
        proc = subprocess.run(
            [str(floor_python()), "-c", script], cwd=source, capture_output=True, text=True, check=False
        )
        assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    return out


def only(directory: Path, pattern: str) -> Path:
    found = sorted(directory.glob(pattern))
    assert len(found) == 1, f"{pattern}: {found}"
    return found[0]


def wheel_metadata(wheel: Path) -> email.message.Message:
    with zipfile.ZipFile(wheel) as archive:
        name = next(n for n in archive.namelist() if n.endswith(".dist-info/METADATA"))
        return email.parser.Parser().parsestr(archive.read(name).decode("utf-8"))


def test_twine_check_passes_strictly(dist: Path) -> None:
    files = [str(only(dist, "*.whl")), str(only(dist, "*.tar.gz"))]
    command = [sys.executable, "-m", "twine", "check", "--strict", *files]
    proc = subprocess.run(command, capture_output=True, text=True, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr


def test_the_metadata_is_complete(dist: Path) -> None:
    meta = wheel_metadata(only(dist, "*.whl"))
    assert meta["Name"] == "ctrlbus" and meta["Version"] and meta["Summary"]
    assert meta["License-Expression"] == "MIT"
    assert meta.get_all("License-File") == ["LICENSE"]
    assert meta["Requires-Python"] == ">=3.10"
    assert meta["Description-Content-Type"] == "text/markdown"
    assert "ctrlbus demo" in meta.get_payload()  # the README is the long description
    urls = dict(url.split(", ", 1) for url in meta.get_all("Project-URL") or [])
    assert {"Homepage", "Documentation", "Repository", "Issues"} <= urls.keys()
    assert "slamware" in (meta["Keywords"] or "").split(",")
    classifiers = meta.get_all("Classifier") or []
    for version in SUPPORTED:
        assert f"Programming Language :: Python :: {version}" in classifiers
    assert "Typing :: Typed" in classifiers
    # Users choose the dashboard and the ROS 2 bridge; the contributors' tools are dependency groups.
    assert meta.get_all("Provides-Extra") == ["web", "ros2"]
    requirements = meta.get_all("Requires-Dist") or []
    assert all(
        "extra ==" not in dep or 'extra == "web"' in dep or 'extra == "ros2"' in dep for dep in requirements
    )
    assert any(dep.startswith("cyclonedds") and 'extra == "ros2"' in dep for dep in requirements)


def test_the_wheel_carries_the_licence_data_and_command(dist: Path) -> None:
    with zipfile.ZipFile(only(dist, "*.whl")) as archive:
        names = archive.namelist()
        licence = next(n for n in names if n.endswith(".dist-info/licenses/LICENSE"))
        assert archive.read(licence) == (REPO / "LICENSE").read_bytes()
        entry_points = archive.read(next(n for n in names if n.endswith(".dist-info/entry_points.txt")))
    assert "ctrlbus = ctrlbus.cli:main" in entry_points.decode()
    for needed in ("ctrlbus/py.typed", "ctrlbus/data/sim-base.json", "ctrlbus/data/sim-room.json"):
        assert needed in names
    assert any(name.startswith("ctrlbus/web/") and name.endswith(".html") for name in names)


def test_the_sdist_carries_readme_and_licence(dist: Path) -> None:
    with tarfile.open(only(dist, "*.tar.gz")) as archive:
        names = {name.split("/", 1)[1] for name in archive.getnames() if "/" in name}
    assert {"LICENSE", "README.md", "pyproject.toml", "src/ctrlbus/__init__.py"} <= names
    # what a wheel built from the sdist (pip install ctrlbus-X.tar.gz) needs besides the code
    assert {
        "src/ctrlbus/py.typed",
        "src/ctrlbus/data/sim-base.json",
        "src/ctrlbus/web/static/index.html",
    } <= names


def test_the_tools_target_the_oldest_supported_python() -> None:
    assert 'requires-python = ">=3.10"' in PYPROJECT
    assert 'python_version = "3.10"' in PYPROJECT  # mypy
    assert 'target-version = "py310"' in PYPROJECT  # ruff
