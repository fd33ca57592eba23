# SPDX-License-Identifier: MIT
"""QEMU for the tests: the one place a QEMU command line is made (qemu_command), the boards it runs
(the firmware's mps2-an385 and the boards of c/ports/), what the checker is given against an
emulated MCU, and waiting for QEMU's UART to accept a connection."""

from __future__ import annotations

import socket
import time
from pathlib import Path

from support.base_harness import REPO, Process

FIRMWARE_SOURCES = REPO / "c" / "ports"
FIRMWARE_BUILD = REPO / "build" / "ports" / "mps2_an385"
FIRMWARE_BASE = FIRMWARE_BUILD / "simbase-qemu.elf"
FIRMWARE_BASE_SDK2020 = FIRMWARE_BUILD / "simbase-sdk2020-qemu.elf"
FIRMWARE_ECHO = FIRMWARE_BUILD / "uart-echo-qemu.elf"
# The lock (support.base_harness.exclusive) of every build into build/ports: the firmware's and
# the other boards' share that directory and c/ports/Makefile.
BUILD_LOCK = "ports-build"


def build_firmware_command() -> list[str]:
    """The make command that builds the mps2-an385 images (the board's target of c/ports/Makefile)."""
    return ["make", "-C", str(FIRMWARE_SOURCES), f"O={FIRMWARE_BUILD.parent}", "mps2_an385"]


# board: the QEMU program and machine, and how an image is loaded (the image's path follows)
QEMU_BOARDS = {
    "mps2-an385": ["qemu-system-arm", "-M", "mps2-an385", "-kernel"],
    "uno": ["qemu-system-avr", "-M", "uno", "-bios"],
    "microbit": ["qemu-system-arm", "-M", "microbit", "-kernel"],
    "netduinoplus2": ["qemu-system-arm", "-M", "netduinoplus2", "-kernel"],
    "sifive_e": ["qemu-system-riscv32", "-M", "sifive_e", "-kernel"],
}
# What `ctrlbus check` is given against an emulated MCU: QEMU answers a byte at a time whenever
# the host runs it, so the checker's own inter-byte timeout is the images' (500 ms, c/ports/README.md)
# and the request timeout its answers are judged against twice that. Real-time smoke runs; the
# checker's verdicts themselves are tested in simulated time (test_checker.py).
EMULATOR_CHECKER_ARGS = ("--timeout-ms", "1000", "--interbyte-timeout-ms", "500")


def qemu_command(
    image: Path,
    uart_socket: Path | None = None,
    *,
    board: str = "mps2-an385",
    tcp_port: int | None = None,
    monitor: Path | None = None,
) -> list[str]:
    """QEMU running `image` on `board` (no display), with its first UART on a Unix socket or on a
    TCP server at 127.0.0.1:tcp_port (pyserial's socket:// URLs), both listened on by QEMU, and
    its monitor on a Unix socket if `monitor` is given. The one place a QEMU command line is made.

    nodelay=on: without it QEMU's byte-by-byte writes meet Nagle's algorithm and delayed ACKs,
    and every answer seems to take 40 ms.
    """
    if tcp_port is not None:
        uart = f"socket,id=uart0,host=127.0.0.1,port={tcp_port},server=on,wait=off,nodelay=on"
    else:
        assert uart_socket is not None, "a UART socket path or a TCP port"
        uart = f"socket,id=uart0,path={uart_socket},server=on,wait=off"
    return [
        *QEMU_BOARDS[board], str(image),
        "-display", "none",
        "-monitor", "none" if monitor is None else f"unix:{monitor},server=on,wait=off",
        "-nodefaults",
        "-chardev", uart,
        "-serial", "chardev:uart0",
    ]  # fmt: skip


def connect_tcp_when_listening(port: int, qemu: Process, limit_s: float = 10.0) -> None:
    """Wait until QEMU accepts on its UART port; the probe connection is closed again."""
    deadline = time.monotonic() + limit_s
    while True:
        try:
            socket.create_connection(("127.0.0.1", port), timeout=1).close()
            return
        except OSError:
            if time.monotonic() > deadline or qemu.popen.poll() is not None:
                raise AssertionError(f"QEMU never listened on {port}: {qemu.describe()}") from None
            time.sleep(0.05)
