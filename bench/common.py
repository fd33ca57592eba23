# SPDX-License-Identifier: MIT
"""Shared plumbing of the benchmarks: paths, running commands, machine facts, result records."""

from __future__ import annotations

import os
import platform
import shlex
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
BENCH_DIR = REPO / "bench"
BUILD_DIR = REPO / "build" / "bench"
C_INCLUDE = REPO / "c" / "include"
C_SRC = REPO / "c" / "src"
PYTHON_SRC = REPO / "python" / "src"

# Result statuses: "measured" carries figures, "pending" names what it waits for, "failed" says why.
MEASURED = "measured"
PENDING = "pending"
FAILED = "failed"

# Sizes of the streams each benchmark uses, full run and smoke run.
FULL = "full"
SMOKE = "smoke"


class BenchError(RuntimeError):
    """A benchmark could not run (a tool failed or a result was not sane)."""


@dataclass
class BenchContext:
    """What every benchmark gets: the run mode and where to put its files."""

    mode: str
    work_dir: Path
    commands: list[str] = field(default_factory=list)

    @property
    def smoke(self) -> bool:
        return self.mode == SMOKE


def ensure_ctrlbus_importable() -> None:
    """Let the benchmarks import the in-tree ctrlbus package even outside the venv's editable install."""
    src = str(PYTHON_SRC)
    if src not in sys.path:
        sys.path.insert(0, src)


def run_command(ctx: BenchContext | None, argv: list[str], *, cwd: Path | None = None) -> str:
    """Run a tool, record its exact command line in the context, and return its stdout.

    A failure raises BenchError carrying the tool's stderr, so a broken benchmark says why.
    """
    if ctx is not None:
        ctx.commands.append(shlex.join(argv))
    proc = subprocess.run(argv, cwd=cwd or REPO, capture_output=True, text=True, check=False)
    if proc.returncode != 0:
        tail = (proc.stderr or proc.stdout).strip().splitlines()[-15:]
        raise BenchError(f"command failed ({proc.returncode}): {shlex.join(argv)}\n" + "\n".join(tail))
    return proc.stdout


def _first_line(argv: list[str]) -> str:
    try:
        proc = subprocess.run(argv, capture_output=True, text=True, check=False, timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        return "unavailable"
    text = (proc.stdout or proc.stderr).strip()
    return text.splitlines()[0] if text else "unavailable"


def _cpu_model() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown"


def machine_facts() -> dict[str, Any]:
    """Facts about the machine and tools that a reader needs to compare figures across runs."""
    import importlib.metadata as metadata

    def version_of(dist: str) -> str:
        try:
            return metadata.version(dist)
        except metadata.PackageNotFoundError:
            return "not installed"

    return {
        "cpu": _cpu_model(),
        "cores": os.cpu_count(),
        "os": platform.platform(),
        "python": platform.python_version(),
        "gcc": _first_line(["gcc", "--version"]),
        "valgrind": _first_line(["valgrind", "--version"]),
        "pymavlink": version_of("pymavlink"),
        "fastcrc": version_of("fastcrc"),
    }


def git_revision() -> dict[str, Any]:
    """The commit the figures were measured on, and whether the tree had uncommitted changes."""

    def git(*args: str) -> str:
        proc = subprocess.run(["git", *args], cwd=REPO, capture_output=True, text=True, check=False)
        return proc.stdout.strip() if proc.returncode == 0 else ""

    commit = git("rev-parse", "HEAD")
    dirty = bool(git("status", "--porcelain", "--untracked-files=no"))
    return {"commit": commit or "unknown", "dirty": dirty}


def stop_process(process: subprocess.Popen[bytes]) -> None:
    """Stop a program the benchmark started: SIGTERM, then SIGKILL after 5 s."""
    if process.poll() is None:
        process.terminate()
        try:
            process.wait(timeout=5)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait(timeout=5)
    if process.stdout is not None:
        process.stdout.close()
