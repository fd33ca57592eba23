# SPDX-License-Identifier: MIT
"""The three shipped bases, each started as its users start it and reached over its real link:

- posix_base (the C stack on the host) over TCP,
- `ctrlbus sim` (the Python stack) over TCP,
- the QEMU firmware (the C stack on a Cortex-M3) over QEMU's UART0 (a Unix socket).

Not a test module itself: test_hostile_link.py and test_served_bases.py import it. Every process
is stopped when the `ServedBase` is closed (the fixtures do it at teardown).
"""

from __future__ import annotations

import re
import shutil
import socket
import subprocess
import sys
import tempfile
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import pytest
from base_harness import REPO, FramePeer, Process, connect_tcp, connect_unix
from test_firmware import FIRMWARE_BASE, build_firmware_command, qemu_command

POSIX_BASE = REPO / "build" / "c" / "examples" / "posix_base" / "posix_base"
FIRMWARE_IMAGE = FIRMWARE_BASE
SIM = [sys.executable, "-m", "ctrlbus", "sim"]

BASE_NAMES = ("posix_base", "ctrlbus-sim", "firmware")
TCP_BASE_NAMES = ("posix_base", "ctrlbus-sim")  # those with options and a reconnectable link


@dataclass
class ServedBase:
    """A running base and the test's connection(s) to it."""

    name: str
    process: Process
    workdir: Path
    port: int | None = None  # TCP bases
    uart_socket: Path | None = None  # the firmware
    sockets: list[socket.socket] = field(default_factory=list)

    def connect(self) -> FramePeer:
        """A new connection to the base's link (a second TCP connection replaces the first)."""
        if self.port is not None:
            sock = connect_tcp("127.0.0.1", self.port)
        else:
            assert self.uart_socket is not None
            sock = connect_unix(self.uart_socket, self.process)
        self.sockets.append(sock)
        return FramePeer.over_socket(sock, f"{self.name} link")

    def close(self) -> None:
        for sock in self.sockets:
            sock.close()
        self.process.stop()
        shutil.rmtree(self.workdir, ignore_errors=True)


def _listening_port(process: Process) -> int:
    line = process.read_line()
    match = re.fullmatch(r"listen: 127\.0\.0\.1:(\d+)", line)
    assert match, f"unexpected first line {line!r} from {process.describe()}"
    return int(match.group(1))


def build_firmware() -> None:
    """Build the firmware images with their own Makefile; fails the test with the build's output."""
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is missing: scripts/setup.sh installs it")
    build = subprocess.run(build_firmware_command(), capture_output=True, text=True, timeout=600)
    if build.returncode != 0 or not FIRMWARE_IMAGE.exists():
        pytest.fail(f"firmware build failed:\n{build.stdout}\n{build.stderr}")


def start_base(name: str, *options: str) -> ServedBase:
    """Start base `name` (one of BASE_NAMES) with extra command-line options (TCP bases only)."""
    workdir = Path(tempfile.mkdtemp(prefix="ctrlbus-served-"))  # short: socket paths max 107 bytes
    log = workdir / "stderr.log"
    if name == "posix_base":
        if not POSIX_BASE.exists():
            pytest.fail(f"{POSIX_BASE} is missing: build it with `make c-build`")
        process = Process([str(POSIX_BASE), "--listen", "127.0.0.1:0", *options], log)
        served = ServedBase(name, process, workdir)
        served.port = _listening_port(process)
        return served
    if name == "ctrlbus-sim":
        process = Process([*SIM, "--listen", "127.0.0.1:0", *options], log)
        served = ServedBase(name, process, workdir)
        served.port = _listening_port(process)
        return served
    assert name == "firmware" and not options, "the firmware has no command line"
    uart_socket = workdir / "uart0.sock"
    process = Process(qemu_command(FIRMWARE_IMAGE, uart_socket), log, stdout_pipe=False)
    served = ServedBase(name, process, workdir)
    served.uart_socket = uart_socket
    return served


StartBase = Callable[..., ServedBase]
