# SPDX-License-Identifier: MIT
"""The Cortex-M3 firmware under QEMU's mps2-an385 board (c/ports/mps2_an385, behind c/ports/port.h).

The images are built here with c/ports/Makefile (make -C c/ports mps2_an385), so `make test`
always runs the current sources. QEMU's UART0 is a Unix socket in a fresh directory: no port to
collide with. Where the images are and what they are called is said here only (FIRMWARE_*).

Two images run: the board bring-up probe, uart-echo-qemu.elf (vector table and start-up, the UART0
RX interrupt (IRQ 0), the interrupt-to-main-loop ring and the TX path, proven by echoing bytes),
and simbase-qemu.elf, the C base stack serving the simulated base (the acceptance test of issue 3:
the firmware answers the Core's requests over the emulated UART, and its motor watchdog shows).
"""

from __future__ import annotations

import json
import random
import shutil
import socket
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from base_harness import REPO, FramePeer, Process, connect_unix

from ctrlbus.frame import Frame, encode

FIRMWARE_SOURCES = REPO / "c" / "ports"
FIRMWARE_BUILD = REPO / "build" / "ports" / "mps2_an385"
FIRMWARE_BASE = FIRMWARE_BUILD / "simbase-qemu.elf"
FIRMWARE_BASE_SDK2020 = FIRMWARE_BUILD / "simbase-sdk2020-qemu.elf"
FIRMWARE_ECHO = FIRMWARE_BUILD / "uart-echo-qemu.elf"


def build_firmware_command() -> list[str]:
    """The make command that builds the mps2-an385 images (the board's target of c/ports/Makefile)."""
    return ["make", "-C", str(FIRMWARE_SOURCES), f"O={FIRMWARE_BUILD.parent}", "mps2_an385"]


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


def qemu_command_tcp(kernel: Path, port: int) -> list[str]:
    """The same board with UART0 on a TCP server at 127.0.0.1:port, for pyserial's socket:// URLs.

    nodelay=on: without it QEMU's byte-by-byte writes meet Nagle's algorithm and delayed ACKs,
    and every answer seems to take 40 ms.
    """
    command = qemu_command(kernel, Path("unused"))
    command[command.index("-chardev") + 1] = (
        f"socket,id=uart0,host=127.0.0.1,port={port},server=on,wait=off,nodelay=on"
    )
    return command


@pytest.fixture(scope="module")
def firmware_images() -> Path:
    """Build every firmware image; fails with the compiler's output if the build fails."""
    for tool in ("arm-none-eabi-gcc", "qemu-system-arm"):
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is missing: scripts/setup.sh installs it")
    build = subprocess.run(
        build_firmware_command(),
        capture_output=True,
        text=True,
        timeout=600,
    )
    if build.returncode != 0:
        pytest.fail(f"firmware build failed:\n{build.stdout}\n{build.stderr}")
    return FIRMWARE_BUILD


def run_in_qemu(kernel: Path) -> Iterator[FramePeer]:
    """Run `kernel` in QEMU and yield the test's end of its UART0; always stops QEMU."""
    workdir = Path(tempfile.mkdtemp(prefix="ctrlbus-qemu-"))  # short: socket paths max 107 bytes
    uart_socket = workdir / "uart0.sock"
    qemu = Process(qemu_command(kernel, uart_socket), workdir / "qemu.log", False)
    sock = None
    try:
        sock = connect_unix(uart_socket, qemu)
        yield FramePeer.over_socket(sock, f"QEMU UART0 of {kernel.name}")
    finally:
        if sock is not None:
            sock.close()
        qemu.stop()
        shutil.rmtree(workdir, ignore_errors=True)


@pytest.fixture
def echo_uart(firmware_images: Path) -> Iterator[FramePeer]:
    """The bring-up probe running in QEMU, and the test's end of its UART0."""
    yield from run_in_qemu(FIRMWARE_ECHO)


@pytest.fixture
def base_uart(firmware_images: Path) -> Iterator[FramePeer]:
    """The ctrlbus base firmware running in QEMU, and the test's end of its UART0."""
    kernel = FIRMWARE_BASE
    if not kernel.exists():
        pytest.fail(f"{kernel} was not built: the Makefile says why ({' '.join(build_firmware_command())})")
    yield from run_in_qemu(kernel)


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


# --- the base firmware ---------------------------------------------------------------------------

CMD_SYNC, CMD_ECHO, CMD_OK, CMD_ERROR, CMD_CTRL_BUS = 0x00, 0x01, 0x02, 0x03, 0xF8
HEALTH_WARNING = 0x01
WATCHDOG_TRIPPED = 0x01038000  # docs/protocol.md §10.3


def ok_payload(answer: Frame, size: int) -> bytes:
    """The payload of an OK answer of `size` bytes in a long frame (the reference's way)."""
    assert answer.cmd == CMD_OK, f"expected OK, got CMD 0x{answer.cmd:02X} payload {answer.payload.hex(' ')}"
    assert len(answer.payload) == size, f"OK payload of {len(answer.payload)} bytes, expected {size}"
    assert answer.long
    return answer.payload


def set_velocity(vx_mps: float, omega_radps: float) -> bytes:
    return bytes((0x41,)) + struct.pack("<iii", round(vx_mps * 65536), 0, round(omega_radps * 65536))


def test_base_firmware_answers_the_core(base_uart: FramePeer) -> None:
    connect = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x10, 0x01))), 28)
    model, _firmware_version, hardware_version = struct.unpack_from("<12sHH", connect)
    assert model.rstrip(b"\0") == b"ctrlbus sim"
    assert hardware_version == 2  # the QEMU firmware (posix_base says 1)

    conf = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x20,))), 264)
    base_type, radius_q8, motor_type, sensor_num = struct.unpack_from("<BIBB", conf)
    assert (base_type, radius_q8, motor_type, sensor_num) == (0, 170 * 256, 0, 5)
    assert conf[135] == 2  # bumper_num

    # Drive forwards for a while (well within the watchdog): the deadreckon deltas add up.
    dx_total = 0.0
    for _ in range(6):
        dx, dy, dtheta, _status = struct.unpack(
            "<iiiB", ok_payload(base_uart.request(CMD_CTRL_BUS, set_velocity(0.2, 0.0)), 13)
        )
        dx_total += dx / 65536
        assert dy == 0 and dtheta == 0
        time.sleep(0.05)
    assert dx_total > 5.0, f"the simulated robot did not move: dx {dx_total:.2f} mm"
    ok_payload(base_uart.request(CMD_CTRL_BUS, set_velocity(0.0, 0.0)), 13)

    flags, error_count = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x90, 0x01))), 2)
    assert (flags, error_count) == (0, 0)

    # 300 bytes of ECHO: more than a standard frame holds, copied back verbatim as the long frame.
    echo = encode(CMD_ECHO, bytes(range(256)) + bytes(range(44)))
    base_uart.send(echo)
    assert base_uart.read_bytes(len(echo)) == echo

    # A corrupted SET_BASE_MOTOR is refused with ERROR 0x0040 and not executed. (First let the
    # robot come to rest: it brakes at its acceleration limit.)
    time.sleep(0.3)
    before = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x31,))), 9)
    corrupted = bytearray(encode(CMD_CTRL_BUS, bytes((0x40,)) + struct.pack("<iiii", 300, 300, 0, 0)))
    corrupted[-1] ^= 0x01
    base_uart.send(bytes(corrupted))
    answer = base_uart.read_frame()
    assert (answer.cmd, answer.payload) == (CMD_ERROR, struct.pack("<H", 0x0040))
    time.sleep(0.3)
    after = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x31,))), 9)
    assert after[:8] == before[:8], "the wheels moved on a corrupted request"


def test_base_firmware_watchdog_stops_the_wheels_and_tells_the_core(base_uart: FramePeer) -> None:
    ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x40,)) + struct.pack("<iiii", -150, -150, 0, 0)), 0)
    # SYNC only for 1.3 s: it does not feed the motor watchdog (1000 ms).
    deadline = time.monotonic() + 1.3
    while time.monotonic() < deadline:
        base_uart.send(bytes.fromhex("10 01 00 11"))
        assert base_uart.read_bytes(4) == bytes.fromhex("10 01 00 11")
        time.sleep(0.1)
    flags, error_count = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x90, 0x01))), 2)
    assert flags & HEALTH_WARNING and error_count >= 1
    codes = []
    for index in range(error_count):
        entry = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x90, 0x02, index))), 36)
        codes.append(struct.unpack_from("<I", entry)[0])
    assert WATCHDOG_TRIPPED in codes
    first = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x31,))), 9)
    time.sleep(0.3)
    second = ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x31,))), 9)
    left, right, _status = struct.unpack("<iiB", second)
    assert left < 0 and right < 0, "the wheels never moved before the watchdog stopped them"
    assert first[:8] == second[:8], "the wheels kept turning after the watchdog tripped"
    # The Core clears the warning.
    ok_payload(base_uart.request(CMD_CTRL_BUS, bytes((0x90, 0x03)) + struct.pack("<I", WATCHDOG_TRIPPED)), 0)


def test_base_firmware_loses_nothing_in_a_burst_longer_than_its_ring(base_uart: FramePeer) -> None:
    # 10 kB of ECHO requests in one write, ten times the stack's receive ring: every byte goes
    # through the UART interrupt into the ring while the main loop answers earlier requests.
    requests = b"".join(encode(CMD_ECHO, bytes((i % 256,)) * (i % 60)) for i in range(300))
    base_uart.send(requests)
    assert base_uart.read_bytes(len(requests)) == requests


@pytest.mark.parametrize(
    ("image", "profile"),
    [(FIRMWARE_BASE.name, "reference"), (FIRMWARE_BASE_SDK2020.name, "sdk2020")],
)
def test_conformance_checker_passes_against_the_firmware(
    firmware_images: Path, tmp_path: Path, image: str, profile: str
) -> None:
    """Issue 4's acceptance, and issue 11's: `ctrlbus check` passes against each QEMU firmware
    image over a real link, in its own profile (check 21 requires that profile's answer sizes;
    the sdk2020 image is the same sources built with -DCTRLBUS_DEFAULT_PROFILE)."""
    with socket.socket() as probe:  # a free port; QEMU binds it right after
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    qemu = Process(qemu_command_tcp(firmware_images / image, port), tmp_path / "qemu.log", False)
    try:
        connect_tcp_when_listening(port, qemu)
        report = tmp_path / "report.json"
        result = subprocess.run(
            [sys.executable, "-m", "ctrlbus", "check", "--port", f"socket://127.0.0.1:{port}",
             "--profile", profile, "--json", str(report)],
            capture_output=True, text=True, timeout=300,
        )  # fmt: skip
        assert result.returncode == 0, f"{result.stdout}\n{result.stderr}\n{qemu.describe()}"
        results = json.loads(report.read_text())
        summary = results["summary"]
        assert summary["fail"] == 0 and summary["pass"] >= 20, summary
        by_name = {entry["name"]: entry["status"] for entry in results["checks"]}
        assert by_name["profile"] == "pass", results["checks"]
    finally:
        qemu.stop()


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
