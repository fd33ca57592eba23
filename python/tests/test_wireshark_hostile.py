# SPDX-License-Identifier: MIT
"""The Wireshark dissector on hostile captures (issue 25, row 1): linear time, bounded memory.

Two captures a black-box campaign used against tools/wireshark/ctrlbus.lua: 1 MB of false long
headers (`50 FF FF` repeated: every third byte starts a candidate announcing 65,539 bytes), and
2 MB of random bytes in both directions. Before the fix a 92 KB capture of the first kind took
168 s and 1.8 GB. tshark must now read each in a small fraction of a minute and a few hundred MB
(docs/reliability.md has the measured figures; the bounds here are loose on purpose, so that a
loaded machine cannot fail the test, while the old quadratic decoder cannot pass it), and show the
same frames, events and counters as `ctrlbus decode` on the same file.
"""

from __future__ import annotations

import importlib.util
import os
import resource
import subprocess
import time
from pathlib import Path
from typing import Any

import pytest
from test_wireshark_vs_decode import DISSECTOR, TSHARK, close_out, decode_view, dissector_view

from ctrlbus.capture import Direction

# The captures come from the benchmark that measures tshark on them (docs/reliability.md).
_SPEC = importlib.util.spec_from_file_location(
    "hostile_captures", Path(__file__).resolve().parents[2] / "bench" / "hostile_captures.py"
)
assert _SPEC is not None and _SPEC.loader is not None
hostile_captures = importlib.util.module_from_spec(_SPEC)
_SPEC.loader.exec_module(hostile_captures)
CPU_LIMIT_S = 60  # the old dissector needs hours on the 1 MB capture; the new one about a second
RSS_LIMIT_KB = 500 * 1024  # tshark itself takes about 160 MB here; the old dissector took GBs


@pytest.fixture(autouse=True)
def _tshark_is_installed() -> None:
    if TSHARK is None:
        pytest.fail("tshark is not installed: scripts/setup.sh installs it (apt-get install tshark)")


def tshark_cost(path: Path) -> tuple[float, int]:
    """(seconds, peak RSS in KB) of tshark reading `path` with the dissector and printing fields;
    its CPU time is capped so that a quadratic decoder fails the test instead of hanging it."""
    assert TSHARK is not None

    def limit_cpu() -> None:
        resource.setrlimit(resource.RLIMIT_CPU, (CPU_LIMIT_S, CPU_LIMIT_S))

    command = [
        TSHARK, "-n", "-X", f"lua_script:{DISSECTOR}", "-r", str(path), "-T", "fields",
        "-e", "ctrlbus.stream.event", "-e", "ctrlbus.counters.frames",
    ]  # fmt: skip
    started = time.monotonic()
    with open(os.devnull, "wb") as sink:
        process = subprocess.Popen(command, stdout=sink, stderr=subprocess.PIPE, preexec_fn=limit_cpu)
        assert process.stderr is not None
        errors = process.stderr.read()
        _, status, usage = os.wait4(process.pid, 0)
    process.returncode = os.waitstatus_to_exitcode(status)
    elapsed = time.monotonic() - started
    assert process.returncode == 0, (process.returncode, errors.decode(errors="replace")[-2000:])
    assert b"Lua: Error" not in errors, errors.decode(errors="replace")
    return elapsed, usage.ru_maxrss


@pytest.mark.parametrize(("name", "size", "pattern"), hostile_captures.CAPTURES)
def test_hostile_capture_is_read_in_linear_time_and_bounded_memory(
    tmp_path: Path, name: str, size: int, pattern: bytes | None
) -> None:
    path = tmp_path / f"{name}.pcap"
    hostile_captures.write_records(path, size, seed=25, pattern=pattern)
    close_out(path)
    elapsed, peak_kb = tshark_cost(path)
    assert elapsed < CPU_LIMIT_S and peak_kb < RSS_LIMIT_KB, (elapsed, peak_kb)
    # the same frames, events and counters as `ctrlbus decode`
    seen_frames, seen_events, seen_counters = dissector_view(path)
    frames, events, counters = decode_view(path)
    assert [without_unknown_name(frame) for frame in seen_frames] == [
        without_unknown_name(frame) for frame in frames
    ]
    assert (seen_events, seen_counters) == (events, counters)
    assert counters[int(Direction.CORE_TO_BASE)]["resyncs"] > size // 1000  # it was hostile
    if pattern is None:
        assert len(frames) > 10  # random bytes make a few valid frames, all found by both


def without_unknown_name(frame: tuple[Any, ...]) -> tuple[Any, ...]:
    """A frame of dissector_view / decode_view with the name left out where the message is not
    known: `ctrlbus decode` gives no name (null), the dissector describes it (`0xBA`, "unknown
    command 0x81") so that its Info column says something."""
    direction, offset, kind, name, to, error, fields = frame
    return direction, offset, kind, None if error == "unsupported" else name, to, error, fields
