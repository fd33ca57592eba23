# SPDX-License-Identifier: MIT
"""The minimal base on the emulated MCUs of c/ports/: each board's image runs under QEMU with its
UART on TCP, and `ctrlbus check` passes against it.

The images are built here with c/ports/Makefile (make -C c/ports), so `make test` always runs the
current sources; QEMU runs the `minimal_base-qemu.elf` image of each board (c/ports/README.md says
how it differs from the chip's), and on the 32-bit boards also `simbase-qemu.elf`, the simulated
base. The Cortex-M0+ image is built and sized only: QEMU has no Cortex-M0+ board.

The Uno's chip image (receive interrupt, idle sleep), which QEMU cannot run, runs under simavr
(c/ports/uno/simavr_uno.c, its USART on a pty) and passes the checker too. On both Uno images the
checker run also measures the stack (the port paints the free RAM; QEMU's monitor, or simavr's
dump of the data memory at the end, gives it afterwards), and issue 13's footprint goal is
asserted for each: at least half of the 32 KB of flash and of the 2 KB of RAM free, the RAM
counting the static data and the deepest stack.
"""

from __future__ import annotations

import itertools
import json
import re
import shutil
import socket
import subprocess
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TypeVar

import pytest
from support.base_harness import REPO, Process, exclusive
from support.checker_runs import TIMED
from support.qemu import BUILD_LOCK, EMULATOR_CHECKER_ARGS, connect_tcp_when_listening, qemu_command
from test_dashboard_browser import free_port
from test_minimal_base import assert_checker_passes

PORTS_SOURCES = REPO / "c" / "ports"
PORTS_BUILD = REPO / "build" / "ports"

BOARDS = ("uno", "microbit", "netduinoplus2", "sifive_e")  # mps2-an385 runs in test_firmware.py
TOOLS = ("avr-gcc", "arm-none-eabi-gcc", "riscv64-unknown-elf-gcc", "qemu-system-avr", "qemu-system-arm",
         "qemu-system-riscv32")  # fmt: skip
# Every emulated board gets EMULATOR_CHECKER_ARGS (test_firmware.py). On the Uno it matters most:
# QEMU's AVR USART holds one byte and takes the next from the host only after the firmware read
# it, one turn of QEMU's event loop per byte, so the checker's 4 KB oversize frame takes 0.1 s on
# an idle host and up to 1 s on a loaded one (on the wire at 115200 baud, 0.36 s anyway); a 1 s
# request timeout lets the checker wait 5 s for the next answer.
# The Uno's 64-byte frame buffer (c/ports/Makefile) refuses the checker's SYNC and ECHO frames of
# 258 to 512 bytes as oversize: warnings, and the only ones.
CHECKER_WARNED = {"uno": frozenset({"sync", "echo"})}
SMALL_BUFFER_WARNING = "refused as oversize (0x0020)"
ATMEGA328P_FLASH, ATMEGA328P_RAM = 32 * 1024, 2 * 1024
# Issue 13's goal for the Uno's minimal base: at least half of the flash and of the RAM free.
FLASH_GOAL, RAM_GOAL = ATMEGA328P_FLASH // 2, ATMEGA328P_RAM // 2
AVR_DATA_SPACE = 0x800000  # where QEMU's AVR model maps the data memory (RAM at +0x100)
AVR_RAM_END = 0x8FF  # ATmega328P's last RAM address
STACK_PAINT = 0xC5  # what c/ports/uno/port.c paints the free RAM with before main()


@pytest.fixture(scope="module")
def port_images() -> Path:
    """Build every port image; fails with the compiler's output if the build fails."""
    for tool in TOOLS:
        if shutil.which(tool) is None:
            pytest.fail(f"{tool} is missing: scripts/setup.sh installs it")
    with exclusive(BUILD_LOCK):
        build = subprocess.run(
            ["make", "-C", str(PORTS_SOURCES), f"O={PORTS_BUILD}"],
            capture_output=True,
            text=True,
            timeout=600,
        )
    if build.returncode != 0:
        pytest.fail(f"port build failed:\n{build.stdout}\n{build.stderr}")
    return PORTS_BUILD


# The Uno's minimal base runs in the uno_stack fixture (its checker run also measures the stack).
RUNS = [(board, "minimal_base") for board in sorted(BOARDS) if board != "uno"] + [
    (board, "simbase") for board in ("microbit", "netduinoplus2", "sifive_e")
]

Measured = TypeVar("Measured")


def run_checker(
    board: str, image: Path, tmp_path: Path, measure: Callable[[Path, Process], Measured] | None = None
) -> Measured | None:
    """Run `image` under QEMU and require `ctrlbus check` to pass against it; then, while QEMU
    still runs, `measure(monitor socket, qemu)` if given, and return what it returns."""
    port = free_port()
    monitor = Path(tempfile.mkdtemp(prefix="ctrlbus-mon-")) / "monitor.sock"  # short: max 107 bytes
    command = qemu_command(image, board=board, tcp_port=port, monitor=monitor)
    qemu = Process(command, tmp_path / "qemu.log", False)
    try:
        connect_tcp_when_listening(port, qemu)
        url, report = f"socket://127.0.0.1:{port}", tmp_path / "report.json"
        warned = CHECKER_WARNED.get(board, frozenset())
        assert_checker_passes(url, report, qemu.describe, EMULATOR_CHECKER_ARGS, warned)
        assert_only_small_buffer_warnings(report)
        return None if measure is None else measure(monitor, qemu)
    finally:
        qemu.stop()
        shutil.rmtree(monitor.parent, ignore_errors=True)


def assert_only_small_buffer_warnings(report: Path) -> None:
    """Every warning of the checker's report is the small frame buffer's (CHECKER_WARNED), but
    those of the checks that judge answer times (a slow moment of the host)."""
    checks = json.loads(report.read_text())["checks"]
    findings = [f for check in checks if check["name"] not in TIMED for f in check["findings"]]
    for finding in findings:
        assert finding["status"] != "warn" or SMALL_BUFFER_WARNING in finding["text"], finding["text"]


# The 32-bit boards' binutils: where the stack instance is (nm) and where its drop count is in it
# (the DWARF that -g leaves in the image).
ARM_BINUTILS, RISCV_BINUTILS = "arm-none-eabi-", "riscv64-unknown-elf-"
BINUTILS = {"microbit": ARM_BINUTILS, "netduinoplus2": ARM_BINUTILS, "sifive_e": RISCV_BINUTILS}
# The stack instance in each application: minimal_base.c's `base`, and simbase_main.c's `glue`,
# whose first member is its ctrlbus_base_t.
BASE_SYMBOLS = {"minimal_base": "base", "simbase": "glue"}


def member_offset(objdump: str, image: Path, member: str, previous: str) -> int:
    """The offset of `member` in the struct where it follows `previous`, from the image's DWARF."""
    dwarf = subprocess.run([objdump, "--dwarf=info", str(image)], capture_output=True, text=True, check=True)
    members: list[tuple[str, int]] = []
    name = None
    for line in dwarf.stdout.splitlines():
        if "(DW_TAG_member)" in line:
            name = None
        elif "DW_AT_name" in line:
            name = line.split()[-1]
        elif "DW_AT_data_member_location" in line and name is not None:
            members.append((name, int(line.split()[-1])))
    offsets = [offset for (before, _), (name, offset) in itertools.pairwise(members)
               if (before, name) == (previous, member)]  # fmt: skip
    assert offsets, f"no member {member} after {previous} in the DWARF of {image}"
    return offsets[0]


def rx_dropped(board: str, application: str, image: Path, monitor: Path, qemu: Process) -> int:
    """The stack's count of received bytes that found its ring full (ctrlbus_base_t.rx_dropped),
    read from the running image through QEMU's monitor."""
    tools = BINUTILS[board]
    symbols = subprocess.run([f"{tools}nm", str(image)], capture_output=True, text=True, check=True).stdout
    wanted = BASE_SYMBOLS[application]
    address = next(int(line.split()[0], 16) for line in symbols.splitlines() if line.split()[-1] == wanted)
    address += member_offset(f"{tools}objdump", image, "rx_dropped", "rx_tail")
    (count,) = read_memory_and_quit(monitor, f"xp /1xw 0x{address:x}", qemu)
    return count


def run_checker_counting_drops(board: str, application: str, image: Path, tmp_path: Path) -> int:
    """run_checker() on `image`, then the stack's drop count (rx_dropped) after the checker run."""

    def measure(monitor: Path, qemu: Process) -> int:
        return rx_dropped(board, application, image, monitor, qemu)

    dropped = run_checker(board, image, tmp_path, measure)
    assert dropped is not None
    return dropped


@pytest.mark.parametrize(("board", "application"), RUNS)
def test_checker_passes_on(board: str, application: str, port_images: Path, tmp_path: Path) -> None:
    """...and no received byte was dropped meanwhile: the ports take a byte from the UART only when
    the application has room (port.h), which holds QEMU back when the host starves the guest."""
    image = port_images / board / f"{application}-qemu.elf"
    dropped = run_checker_counting_drops(board, application, image, tmp_path)
    assert dropped == 0, f"the stack's receive ring dropped {dropped} bytes during the checker run"


@pytest.mark.parametrize("board", sorted(BINUTILS))
def test_a_ring_smaller_than_the_uart_loses_nothing(board: str, port_images: Path, tmp_path: Path) -> None:
    """The minimal base with an 8-byte receive ring (c/ports/Makefile: minimal_base-smallring-qemu)
    passes the checker and drops nothing: every frame above 7 bytes, and the SiFive UART's 8-byte
    FIFO, overfill that ring, so a receive path that took bytes without asking port_uart_room()
    would drop some of every large frame (it did: 334 bytes in ten 512-byte SYNCs on the SiFive
    image, 92 on the micro:bit one), whatever the host's load."""
    image = port_images / board / "minimal_base-smallring-qemu.elf"
    dropped = run_checker_counting_drops(board, "minimal_base", image, tmp_path)
    assert dropped == 0, f"the 8-byte receive ring dropped {dropped} bytes during the checker run"


@pytest.fixture(scope="module")
def uno_stack(port_images: Path, tmp_path_factory: pytest.TempPathFactory) -> int:
    """The checker passes on the Uno's QEMU image; returns how deep its stack went meanwhile (B)."""
    image = port_images / "uno" / "minimal_base-qemu.elf"

    def measure(monitor: Path, qemu: Process) -> int:
        return avr_stack_high_water(monitor, image, qemu)

    stack = run_checker("uno", image, tmp_path_factory.mktemp("uno"), measure)
    assert stack is not None
    return stack


def test_checker_passes_on_the_uno(uno_stack: int) -> None:
    assert 0 < uno_stack < ATMEGA328P_RAM, f"stack high-water mark {uno_stack} B"


def avr_free_ram_start(image: Path) -> int:
    """The data-memory address where the image's free RAM (painted at start-up) begins: _end."""
    symbols = subprocess.run(["avr-nm", str(image)], capture_output=True, text=True, check=True).stdout
    end = next(int(line.split()[0], 16) for line in symbols.splitlines() if line.endswith(" _end"))
    return end - AVR_DATA_SPACE


def painted_depth(free_ram: Sequence[int]) -> int:
    """How deep the stack has been (B), from the free RAM as it is now: the stack grows down from
    its end, so it reached the lowest byte that no longer holds the paint."""
    untouched = next((index for index, value in enumerate(free_ram) if value != STACK_PAINT), len(free_ram))
    return len(free_ram) - untouched


def read_memory_and_quit(monitor: Path, command: str, qemu: Process) -> list[int]:
    """The values a memory command of QEMU's monitor (`xp /NxF ADDRESS`) prints; QEMU quits after
    it, which closes the monitor's connection and ends the output."""
    with socket.socket(socket.AF_UNIX) as sock:
        sock.connect(str(monitor))
        sock.sendall(f"{command}\nquit\n".encode())
        output = b""
        deadline = time.monotonic() + 10
        while chunk := sock.recv(65536):
            output += chunk
            assert time.monotonic() < deadline, f"QEMU's monitor did not finish: {qemu.describe()}"
    return [int(value, 16) for line in re.findall(rb"^[0-9a-f]{16}: (.*)$", output, re.M)
            for value in line.decode().split()]  # fmt: skip


def avr_stack_high_water(monitor: Path, image: Path, qemu: Process) -> int:
    """How deep the stack of the running AVR image has been, in bytes: the painted free RAM above
    .bss, read through QEMU's monitor."""
    start = avr_free_ram_start(image)
    count = AVR_RAM_END + 1 - start
    ram = read_memory_and_quit(monitor, f"xp /{count}xb 0x{AVR_DATA_SPACE + start:x}", qemu)
    assert len(ram) == count, f"read {len(ram)} of {count} RAM bytes from the monitor"
    return painted_depth(ram)


@pytest.fixture(scope="module")
def uno_chip_stack(port_images: Path, tmp_path_factory: pytest.TempPathFactory) -> int:
    """The checker passes on the Uno's chip image (receive interrupt, idle sleep: what QEMU cannot
    run) under simavr, with USART0 on a pty; returns how deep its stack went meanwhile (B), read
    from simavr's dump of the data memory when it stops."""
    with exclusive(BUILD_LOCK):
        build = subprocess.run(
            ["make", "-C", str(PORTS_SOURCES), f"O={PORTS_BUILD}", "simavr"],
            capture_output=True,
            text=True,
            timeout=300,
        )
    if build.returncode != 0:
        pytest.fail(
            f"simavr bench build failed (scripts/setup.sh installs libsimavr-dev):\n"
            f"{build.stdout}\n{build.stderr}"
        )
    image = port_images / "uno" / "minimal_base.elf"
    work = tmp_path_factory.mktemp("uno-chip")
    dump = work / "data-memory.bin"
    simavr = Process(
        [str(PORTS_BUILD / "uno" / "simavr_uno"), str(image), "--ram-dump", str(dump)], work / "simavr.log"
    )
    try:
        line = simavr.read_line()
        assert line.startswith("uart0 /dev/"), f"unexpected first line {line!r} from {simavr.describe()}"
        report = work / "report.json"
        assert_checker_passes(
            line.split(" ", 1)[1], report, simavr.describe, EMULATOR_CHECKER_ARGS, CHECKER_WARNED["uno"]
        )
        assert_only_small_buffer_warnings(report)
    finally:
        simavr.stop()
    assert simavr.popen.returncode == 0, simavr.describe()
    memory = dump.read_bytes()
    assert len(memory) == AVR_RAM_END + 1, f"{len(memory)} bytes dumped: {simavr.describe()}"
    return painted_depth(memory[avr_free_ram_start(image) :])


def test_checker_passes_on_the_uno_chip_image(uno_chip_stack: int) -> None:
    assert 0 < uno_chip_stack < ATMEGA328P_RAM, f"stack high-water mark {uno_chip_stack} B"


def sections(size_tool: str, image: Path) -> tuple[int, int, int]:
    """.text, .data and .bss of an image, as the binutils `size` tool counts them."""
    output = subprocess.run([size_tool, str(image)], capture_output=True, text=True, check=True).stdout
    text, data, bss = (int(field) for field in output.splitlines()[1].split()[:3])
    return text, data, bss


def avr_interrupt_frame(image: Path) -> int:
    """The most stack one interrupt handler of the image takes (B): its pushed registers and the
    2-byte return address. The handlers call nothing (checked: otherwise this would not be all of
    it) and do not re-enable interrupts, so they do not nest: this comes on top of the main loop's
    deepest stack once. An image without handlers gives 0."""
    objdump = ["avr-objdump", "-d", str(image)]
    listing = subprocess.run(objdump, capture_output=True, text=True, check=True).stdout
    deepest = 0
    for function in re.split(r"\n(?=[0-9a-f]+ <)", listing):
        name = re.match(r"[0-9a-f]+ <(__vector_\d+)>:", function)
        if name is None:
            continue
        instructions = re.findall(r"^\s+[0-9a-f]+:\t(?:[0-9a-f]{2} )+\s*\t(\w+)", function, re.M)
        calls = {"call", "rcall", "icall", "eicall"} & set(instructions)
        assert not calls, f"{name[1]} of {image.name} calls {sorted(calls)}: it needs more than its pushes"
        deepest = max(deepest, instructions.count("push") + 2)
    return deepest


# image: the fixture that measured its stack (the chip image under simavr, the QEMU one under QEMU)
MEASURED_UNDER = {"minimal_base.elf": "uno_chip_stack", "minimal_base-qemu.elf": "uno_stack"}


@pytest.mark.parametrize("image", sorted(MEASURED_UNDER))
def test_atmega328p_footprint_goal(image: str, port_images: Path, request: pytest.FixtureRequest) -> None:
    """Flash: .text + .data. RAM: .data + .bss + the stack's measured high-water mark + one
    interrupt frame (the chip image's handlers may have struck elsewhere than at the deepest
    point of the main loop; the QEMU image has none)."""
    uno_stack: int = request.getfixturevalue(MEASURED_UNDER[image])
    path = port_images / "uno" / image
    text, data, bss = sections("avr-size", path)
    interrupt = avr_interrupt_frame(path)
    flash, ram = text + data, data + bss + uno_stack + interrupt
    figures = (
        f"{image}: flash {flash} B of {ATMEGA328P_FLASH} ({ATMEGA328P_FLASH - flash} free); RAM {ram} B of "
        f"{ATMEGA328P_RAM} ({ATMEGA328P_RAM - ram} free) = .data {data} + .bss {bss} + stack {uno_stack} "
        f"(measured after a checker run) + interrupt {interrupt}"
    )
    assert flash <= FLASH_GOAL, f"less than half of the flash free: {figures}"
    assert ram <= RAM_GOAL, f"less than half of the RAM free: {figures}"


def test_cortex_m0plus_image_is_built(port_images: Path) -> None:
    image = port_images / "cortex-m0plus" / "minimal_base.elf"
    text, _data, _bss = sections("arm-none-eabi-size", image)
    assert text > 0
    attributes = subprocess.run(
        ["arm-none-eabi-readelf", "-A", str(image)], capture_output=True, text=True, check=True
    ).stdout
    assert "Tag_CPU_arch: v6S-M" in attributes, attributes  # ARMv6-M, Cortex-M0+'s architecture
