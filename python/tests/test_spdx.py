# SPDX-License-Identifier: MIT
"""Every source file in the repository carries an SPDX license line (issue 12)."""

from __future__ import annotations

import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TAG = "SPDX-License-Identifier: MIT"
SOURCE_SUFFIXES = {
    ".c",
    ".h",
    ".ld",
    ".S",
    ".s",
    ".py",
    ".sh",
    ".lua",
    ".js",
    ".css",
    ".html",
    ".xml",
    ".toml",
    ".cmake",
    ".yml",
    ".yaml",
    ".ino",
    ".mmd",
    ".dot",
    ".msc",
}
SOURCE_NAMES = {"Makefile", "CMakeLists.txt", "Kconfig", "run"}


def _tracked_sources() -> list[Path]:
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    ).stdout.split()
    paths = [REPO / name for name in listed]
    return [p for p in paths if p.is_file() and (p.suffix in SOURCE_SUFFIXES or p.name in SOURCE_NAMES)]


def test_repository_has_a_license_file() -> None:
    assert "MIT License" in (REPO / "LICENSE").read_text()


def test_every_source_file_has_an_spdx_line() -> None:
    sources = _tracked_sources()
    assert len(sources) > 100, "git ls-files found too few sources: is this a checkout?"
    missing = [
        str(p.relative_to(REPO))
        for p in sources
        if TAG not in "".join(p.read_text().splitlines(keepends=True)[:5])
    ]
    assert not missing, f"source files without '{TAG}' in their first lines: {missing}"
