# SPDX-License-Identifier: MIT
"""The Wireshark dissector on hostile captures: seconds and peak memory of tshark (issue 25).

    .venv/bin/python bench/hostile_captures.py [--out DIR]

Writes the captures of docs/reliability.md ("The Wireshark dissector under hostile input"): 1 MB
of false long headers (`50 FF FF` repeated: every third byte starts a candidate announcing 65,539
bytes), 2 MB of random bytes in both directions, and 1 MB of `10 00 FF` (a raised checksum error
every third byte), in records of 1..4096 bytes 1 ms apart, as a tap writes read chunks. Then it
runs tshark with tools/wireshark/ctrlbus.lua on each, and on a one-frame capture for tshark's own
footprint, and `ctrlbus decode` on each, and prints wall and CPU seconds and peak RSS per run.
python/tests/test_wireshark_hostile.py writes the first two (write_records) and holds tshark to
loose bounds; the figures themselves are measured here.
"""

from __future__ import annotations

import argparse
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
DISSECTOR = REPO / "tools" / "wireshark" / "ctrlbus.lua"
EPOCH = 1_700_000_000.0
# (name, bytes, the 3 bytes repeated, or None for random bytes): the captures the test reads
CAPTURES: list[tuple[str, int, bytes | None]] = [
    ("false-long-headers", 1_000_000, b"\x50\xff\xff"),
    ("random", 2_000_000, None),
]
# Measured here only: the most items a dissector must keep, a raised checksum error (and a silent
# run) every third byte.
WORST_CASE: tuple[str, int, bytes | None] = (
    "event-every-third-byte",
    1_000_000,
    b"\x10\x00\xff",
)


def write_records(path: Path, size: int, seed: int, pattern: bytes | None) -> None:
    """`size` bytes in records of 1..4096 bytes, 1 ms apart: `pattern` repeated, Core to base, or
    (None) random bytes in random directions."""
    from ctrlbus.capture import CaptureWriter, Direction

    rng = random.Random(seed)
    repeated = pattern * (size // len(pattern) + 2) if pattern else b""
    written = index = 0
    with CaptureWriter.create(path) as writer:
        while written < size:
            count = min(rng.randint(1, 4096), size - written)
            if pattern is not None:
                direction, data = (
                    Direction.CORE_TO_BASE,
                    repeated[written : written + count],
                )
            else:
                direction, data = rng.choice(list(Direction)), rng.randbytes(count)
            writer.write(direction, data, EPOCH + index * 0.001)
            written += count
            index += 1


def measure(command: list[str]) -> tuple[float, float, int]:
    """(wall seconds, CPU seconds, peak RSS in KB) of `command`, its output thrown away (CPU time
    says what the work costs on a busy machine, where wall time also counts waiting)."""
    started = time.monotonic()
    with open(os.devnull, "wb") as sink:
        process = subprocess.Popen(command, stdout=sink, stderr=subprocess.DEVNULL)
        _, status, usage = os.wait4(process.pid, 0)
    if os.waitstatus_to_exitcode(status) != 0:
        raise SystemExit(f"failed: {' '.join(command)}")
    return time.monotonic() - started, usage.ru_utime + usage.ru_stime, usage.ru_maxrss


def cost(command: list[str]) -> str:
    wall, cpu, peak = measure(command)
    return f"{wall:.2f} s wall, {cpu:.2f} s CPU, {peak / 1024:.0f} MB peak RSS"


def tshark_command(tshark: str, path: Path) -> list[str]:
    return [
        tshark, "-n", "-X", f"lua_script:{DISSECTOR}", "-r", str(path), "-T", "fields",
        "-e", "ctrlbus.stream.event", "-e", "ctrlbus.counters.frames",
    ]  # fmt: skip


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--out",
        type=Path,
        help="where to write the captures (default: a temporary folder)",
    )
    args = parser.parse_args()
    tshark = shutil.which("tshark")
    if tshark is None:
        raise SystemExit("tshark is not installed (scripts/setup.sh full installs it)")
    out = args.out or Path(tempfile.mkdtemp(prefix="hostile-captures-"))
    out.mkdir(parents=True, exist_ok=True)
    from ctrlbus.capture import CaptureWriter, Direction

    baseline = out / "one-frame.pcap"
    with CaptureWriter.create(baseline) as writer:
        writer.write(Direction.CORE_TO_BASE, bytes.fromhex("10 02 F8 30 DA"), EPOCH)
    print(f"tshark, one frame (its own footprint): {cost(tshark_command(tshark, baseline))}")
    for name, size, pattern in [*CAPTURES, WORST_CASE]:
        path = out / f"{name}.pcap"
        write_records(path, size, seed=25, pattern=pattern)
        print(f"tshark, {name} ({size:,} bytes): {cost(tshark_command(tshark, path))}")
        decode = [sys.executable, "-m", "ctrlbus", "decode", "--json", str(path)]
        print(f"ctrlbus decode, {name}: {cost(decode)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
