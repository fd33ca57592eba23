"""The Cortex-M3 firmware (c/firmware/) under QEMU's mps2-an385 board.

The firmware is built here with its own Makefile (make -C c/firmware), so `make test` always runs
the current sources. QEMU's UART0 is a Unix socket in a fresh directory: no port to collide with.

What runs now is the board bring-up probe, uart-echo.elf: vector table and start-up, the UART0
RX interrupt (IRQ 0), the interrupt-to-main-loop ring and the TX path, proven by echoing bytes.
"""

from __future__ import annotations

import random
import shutil
import subprocess
import tempfile
from collections.abc import Iterator
from pathlib import Path

import pytest
from base_harness import REPO, FramePeer, Process, connect_unix

FIRMWARE_SOURCES = REPO / "c" / "firmware"
FIRMWARE_BUILD = REPO / "build" / "firmware"


def qemu_command(kernel: Path, uart_socket: Path) -> list[str]:
    """QEMU with the firmware and UART0 on a Unix socket it listens on (no display, no monitor)."""
    return [
        "qemu-system-arm",
        "-M", "mps2-an385",
        "-display", "none",
        "-monitor", "none",
        "-nodefaults",
        "-kernel", str(kernel),
        "-chardev", f"socket,id=uart0,path={uart_socket},server=on,wait=off",
        "-serial", "chardev:uart0",
    ]  # fmt: skip


@pytest.fixture(scope="module")
def firmware_images() -> Path:
    """Build every firmware image; fails with the compiler's output if the build fails."""
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is missing: scripts/setup.sh installs it")
    build = subprocess.run(
        ["make", "-C", str(FIRMWARE_SOURCES), f"O={FIRMWARE_BUILD}"],
        capture_output=True,
        text=True,
        timeout=600,
    )
    if build.returncode != 0:
        pytest.fail(f"firmware build failed:\n{build.stdout}\n{build.stderr}")
    return FIRMWARE_BUILD


@pytest.fixture
def echo_uart(firmware_images: Path) -> Iterator[FramePeer]:
    """The bring-up probe running in QEMU, and the test's end of its UART0."""
    workdir = Path(tempfile.mkdtemp(prefix="ctrlbus-qemu-"))  # short: socket paths max 107 bytes
    uart_socket = workdir / "uart0.sock"
    qemu = Process(qemu_command(firmware_images / "uart-echo.elf", uart_socket), workdir / "qemu.log", False)
    sock = None
    try:
        sock = connect_unix(uart_socket, qemu)
        yield FramePeer.over_socket(sock, "QEMU UART0")
    finally:
        if sock is not None:
            sock.close()
        qemu.stop()
        shutil.rmtree(workdir, ignore_errors=True)


def test_echo_probe_returns_every_byte_value(echo_uart: FramePeer) -> None:
    data = bytes(range(256))
    echo_uart.send(data)
    assert echo_uart.read_bytes(len(data)) == data


def test_echo_probe_loses_nothing_in_a_burst_longer_than_its_ring(echo_uart: FramePeer) -> None:
    # 16 times the probe's 256-byte ring, in one write: the UART holds one byte at a time, so
    # every byte goes through the RX interrupt while the main loop is still sending earlier ones.
    data = random.Random(3).randbytes(4096)
    echo_uart.send(data)
    assert echo_uart.read_bytes(len(data)) == data
