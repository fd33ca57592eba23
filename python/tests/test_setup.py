# SPDX-License-Identifier: MIT
"""`make demo` is light: on a machine without QEMU, the cross compilers, clang, tshark or Chromium
it sets up only the venv and serves the dashboard, installing nothing from apt.

The test runs `make demo` in a scratch copy of the repository (so it makes a venv of its own) with
two stubs first on PATH: `dpkg-query`, which says that only python3-venv is installed (the machine
has nothing else), and `apt-get`, which fails the run if anything tries to install.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import time
import urllib.request
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
URL_LINE = re.compile(r"dashboard at (http://\S+)")
SETUP_LIMIT_S = 240  # a fresh venv: pip installs the package and aiohttp (from its cache, mostly)

DPKG_QUERY_STUB = """#!/bin/sh
# A machine with python3-venv and nothing else of ours: every other package reads as missing.
for last; do :; done
if [ "$last" = python3-venv ]; then printf 'install ok installed'; exit 0; fi
exit 1
"""

APT_GET_STUB = """#!/bin/sh
echo "apt-get called: $*" >> "$APT_LOG"
echo "apt-get must not run for the light demo: $*" >&2
exit 1
"""


def scratch_copy(target: Path) -> None:
    """The repository's files as a fresh clone has them, plus the uncommitted changes."""
    listed = subprocess.run(
        ["git", "ls-files", "--cached", "--others", "--exclude-standard", "-z"],
        cwd=REPO,
        capture_output=True,
        check=True,
    ).stdout.decode()
    for name in filter(None, listed.split("\0")):
        source = REPO / name
        if not source.exists() or source.is_dir():
            continue
        destination = target / name
        destination.parent.mkdir(parents=True, exist_ok=True)
        shutil.copy2(source, destination, follow_symlinks=False)


def test_make_demo_sets_up_only_the_venv_and_serves_the_dashboard(tmp_path: Path) -> None:
    repo = tmp_path / "repo"
    scratch_copy(repo)
    stubs = tmp_path / "stubs"
    stubs.mkdir()
    for name, text in (("dpkg-query", DPKG_QUERY_STUB), ("apt-get", APT_GET_STUB)):
        (stubs / name).write_text(text)
        (stubs / name).chmod(0o755)
    apt_log = tmp_path / "apt.log"
    env = {**os.environ, "PATH": f"{stubs}{os.pathsep}{os.environ['PATH']}", "APT_LOG": str(apt_log)}
    env.pop("MAKEFLAGS", None)
    process = subprocess.Popen(
        ["make", "--no-print-directory", "demo", "DEMO_ARGS=--http 127.0.0.1:0"],
        cwd=repo,
        env=env,
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        text=True,
        start_new_session=True,
    )
    shown: list[str] = []
    try:
        assert process.stdout is not None
        deadline = time.monotonic() + SETUP_LIMIT_S
        url = None
        for line in process.stdout:
            shown.append(line)
            match = URL_LINE.search(line)
            if match:
                url = match.group(1)
                break
            assert time.monotonic() < deadline, "make demo took too long:\n" + "".join(shown)
        assert url, "make demo ended without a dashboard:\n" + "".join(shown)
        with urllib.request.urlopen(url, timeout=10) as response:
            assert response.status == 200 and b"<html" in response.read().lower()
        api = url.split("?")[0].rstrip("/") + "/api/snapshot"
        with urllib.request.urlopen(api, timeout=10) as response:
            assert "link" in json.load(response)["data"]
    finally:
        os.killpg(process.pid, signal.SIGINT)
        try:
            process.wait(30)
        except subprocess.TimeoutExpired:
            os.killpg(process.pid, signal.SIGKILL)
            process.wait(10)
    assert not apt_log.exists(), apt_log.read_text()
    text = "".join(shown)
    assert "installing apt packages" not in text, text
    # Only the venv was made; nothing was built.
    assert (repo / ".venv" / "bin" / "python").exists()
    assert not (repo / ".venv310").exists() and not (repo / "build").exists()


def demo_base(demo_args: str) -> str:
    """The base `make demo DEMO_ARGS=...` sets up for (the Makefile's DEMO_BASE)."""
    rule = "print-demo-base: ; @echo [$(DEMO_BASE)]"
    proc = subprocess.run(
        ["make", "-s", "--no-print-directory", "--eval", rule, "print-demo-base", f"DEMO_ARGS={demo_args}"],
        cwd=REPO,
        capture_output=True,
        text=True,
        check=True,
    )
    return proc.stdout.strip().strip("[]")


def test_make_demo_sets_up_what_the_chosen_base_needs() -> None:
    # "" and sim: scripts/setup.sh demo (the venv); c: + the C toolchain; qemu: + QEMU and the firmware's
    assert demo_base("") == ""
    assert demo_base("--speed 2 --base sim") == "sim"
    assert demo_base("--base c") == "c"
    assert demo_base("--http 127.0.0.1:0 --base=qemu") == "qemu"
    makefile = (REPO / "Makefile").read_text(encoding="utf-8")
    assert '""|sim) scripts/setup.sh demo' in makefile
    assert "c) scripts/setup.sh c &&" in makefile and "qemu) scripts/setup.sh qemu &&" in makefile
