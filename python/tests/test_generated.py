# SPDX-License-Identifier: MIT
"""The files generated from the protocol description (protocol/ctrlbus.json) are what the
generator writes now: it runs into a temporary folder and every file it writes must equal the
committed one. On a difference, run `make generate` and commit the result."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
GENERATOR = ROOT / "scripts" / "generate_protocol.py"
DESCRIPTION = ROOT / "protocol" / "ctrlbus.json"


def generate(repo: Path, *args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, str(GENERATOR), "--repo", str(repo), *args],
        capture_output=True,
        text=True,
        check=False,
    )


def written_files(folder: Path) -> list[Path]:
    return sorted(path for path in folder.rglob("*") if path.is_file())


def test_the_committed_files_are_what_the_description_generates(tmp_path: Path) -> None:
    run = generate(ROOT, "--out", str(tmp_path))
    assert run.returncode == 0, run.stderr
    files = written_files(tmp_path)
    assert len(files) >= 8  # C header, sources, Python, Lua and sigrok tables, protocol.md
    stale = [
        str(path.relative_to(tmp_path))
        for path in files
        if path.read_bytes() != (ROOT / path.relative_to(tmp_path)).read_bytes()
    ]
    assert stale == [], f"out of date: {', '.join(stale)}; run `make generate` and commit the result"


def copy_of_the_repository(tmp_path: Path) -> Path:
    """The description and every file the generator writes into, in a scratch tree."""
    scratch = tmp_path / "repo"
    out = tmp_path / "out"
    assert generate(ROOT, "--out", str(out)).returncode == 0
    for path in [DESCRIPTION, *(ROOT / p.relative_to(out) for p in written_files(out))]:
        target = scratch / path.relative_to(ROOT)
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(path, target)
    return scratch


def test_a_described_field_the_files_lack_is_reported_with_the_command(tmp_path: Path) -> None:
    scratch = copy_of_the_repository(tmp_path)
    description = json.loads((scratch / "protocol" / "ctrlbus.json").read_text(encoding="utf-8"))
    status = next(m for m in description["messages"] if m["name"] == "GET_BASE_STATUS")
    status["answer"]["fields"].append({"name": "charge_cycles", "type": "u16"})
    (scratch / "protocol" / "ctrlbus.json").write_text(json.dumps(description), encoding="utf-8")
    run = generate(scratch, "--check")
    assert run.returncode == 1
    assert "c/include/ctrlbus/messages.h is out of date: run `make generate`" in run.stderr
    assert generate(scratch).returncode == 0
    assert generate(scratch, "--check").returncode == 0
    assert "uint16_t charge_cycles;" in (scratch / "c/include/ctrlbus/messages.h").read_text(encoding="utf-8")


def test_a_description_breaking_its_rules_is_one_clear_line(tmp_path: Path) -> None:
    scratch = copy_of_the_repository(tmp_path)
    description = json.loads((scratch / "protocol" / "ctrlbus.json").read_text(encoding="utf-8"))
    conf = next(m for m in description["messages"] if m["name"] == "GET_BASE_CONF_ADV")
    conf["answer"]["fields"].append({"name": "after_the_blob", "type": "u8"})
    (scratch / "protocol" / "ctrlbus.json").write_text(json.dumps(description), encoding="utf-8")
    run = generate(scratch, "--check")
    assert run.returncode == 2
    assert run.stderr.strip() == "generate_protocol: GET_BASE_CONF_ADV: a bytes field must be the last one"
