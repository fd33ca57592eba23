# SPDX-License-Identifier: MIT
"""`ctrlbus spy` between our Core emulator and the simulated base.

In process: Core runner ↔ in-process links ↔ Spy ↔ in-process links ↔ base runner, with both ends
recording what they wrote and read, so the test sees that every byte was forwarded unchanged. As a
program: `ctrlbus sim --listen` ↔ `ctrlbus spy --core listen: --base socket:// --capture` ↔ the Core
emulator, over TCP on 127.0.0.1; then the capture is decoded.
"""

from __future__ import annotations

import json
import os
import re
import select
import signal
import subprocess
import sys
import termios
import threading
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from support.base_harness import Process

from ctrlbus.annotate import Annotation, Annotator, FrameNote, Rejection, RejectReason, Role
from ctrlbus.base import BaseRunner
from ctrlbus.capture import Direction, read_capture
from ctrlbus.cli import main
from ctrlbus.cli.decode_cmd import decode_bytes
from ctrlbus.cli.spy_cmd import Chunk, Spy, fault_transforms
from ctrlbus.core import ConnectionState, CoreRunner, CoreSession
from ctrlbus.errors import LinkError
from ctrlbus.link import Link, link_pair
from ctrlbus.messages import Event, SendEvent
from ctrlbus.ports import open_link
from ctrlbus.sim.server import SimSettings, build_simulated_stack

C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE
CTRLBUS = [sys.executable, "-m", "ctrlbus"]
LIMIT_S = 15.0  # generous bounds for waits on a loaded machine; no test asserts a duration


class RecordingLink:
    """A Link that keeps a copy of everything written to and read from the link it wraps."""

    def __init__(self, inner: Link) -> None:
        self.inner = inner
        self.written = bytearray()
        self.read_bytes = bytearray()
        self._lock = threading.Lock()

    @property
    def name(self) -> str:
        return self.inner.name

    def read(self, timeout: float) -> bytes:
        data = self.inner.read(timeout)
        with self._lock:
            self.read_bytes += data
        return data

    def write(self, data: bytes) -> None:
        with self._lock:
            self.written += data
        self.inner.write(data)

    def close(self) -> None:
        self.inner.close()

    def wait_quiet(self, quiet_s: float = 0.3) -> None:
        """Wait until nothing has been written for `quiet_s` (at most LIMIT_S)."""
        size, since = -1, time.monotonic()

        def quiet() -> bool:
            nonlocal size, since
            if len(self.written) != size:
                size, since = len(self.written), time.monotonic()
            return time.monotonic() - since >= quiet_s

        wait_until(quiet)


def wait_until(condition: Callable[[], bool], limit_s: float = LIMIT_S) -> bool:
    deadline = time.monotonic() + limit_s
    while not condition():
        if time.monotonic() > deadline:
            return False
        time.sleep(0.02)
    return True


def annotate(chunks: list[Chunk]) -> list[Annotation]:
    annotator = Annotator(timeout=0.1)
    entries: list[Annotation] = []
    for chunk in chunks:
        entries += annotator.feed(chunk.data, chunk.direction, chunk.time)
    return entries + annotator.finish()


class Session:
    """Core runner ↔ spy ↔ simulated base, in process; the test drains the spy's chunks."""

    def __init__(self, fault: str | None = None) -> None:
        core_end, spy_core = link_pair(("core", "spy:core"))
        spy_base, base_end = link_pair(("spy:base", "base"))
        self.core_link = RecordingLink(core_end)
        self.base_link = RecordingLink(base_end)
        _, stack = build_simulated_stack(SimSettings(seed=1))
        self.base = BaseRunner(stack, self.base_link)
        self.session = CoreSession()
        self.core = CoreRunner(self.session, self.core_link)
        self.spy = Spy(spy_core, spy_base, transforms=fault_transforms(fault))
        self.chunks: list[Chunk] = []

    def run_until_connected_and(self, requests: int, *, still_connected: bool = True) -> None:
        """Run until the Core has written `requests` chunks and is connected (or, without
        `still_connected`, has been connected at least once)."""
        self.base.start()
        self.spy.start()
        self.core.start()

        def connected() -> bool:
            if still_connected:
                return self.session.state is ConnectionState.CONNECTED
            return self.session.identity is not None

        while not (connected() and self.chunks_from(C) >= requests):
            assert not self.spy.stop_event.is_set(), self.spy.failure
            got = self.spy.chunks(LIMIT_S)
            assert got, "the spy forwarded nothing"
            self.chunks += got

    def chunks_from(self, direction: Direction) -> int:
        return sum(1 for chunk in self.chunks if chunk.direction is direction)

    def stop(self) -> None:
        """Stop the Core on purpose (its CORE_DISCONNECT goes through), then the rest."""
        self.core.stop()
        self.base_link.wait_quiet()
        self.spy.stop()
        self.base.stop()
        self.chunks += self.spy.chunks(0.0)

    def forwarded(self, direction: Direction) -> bytes:
        return b"".join(chunk.data for chunk in self.chunks if chunk.direction is direction)


def test_spy_forwards_every_byte_unchanged_and_decodes_the_conversation() -> None:
    session = Session()
    try:
        session.run_until_connected_and(requests=30)
    finally:
        session.stop()
    # Closing the Core's end at the end ends the spy's reading there; nothing else went wrong.
    assert session.spy.failure is None or isinstance(session.spy.failure, LinkError)
    core, base = session.core_link, session.base_link
    assert bytes(base.read_bytes) == bytes(core.written) == session.forwarded(C)
    assert bytes(core.read_bytes) == bytes(base.written) == session.forwarded(B)
    assert all(chunk.data == chunk.original for chunk in session.chunks)
    entries = annotate(session.chunks)
    assert not [entry for entry in entries if isinstance(entry, Rejection)]
    frames = [entry for entry in entries if isinstance(entry, FrameNote)]
    assert frames[0].name == "CONNECT_BASE" and frames[0].direction is C
    assert (frames[1].name, frames[1].to, frames[1].direction) == ("OK", "CONNECT_BASE", B)
    answers = [frame for frame in frames if frame.role is Role.ANSWER]
    assert all(answer.to is not None and answer.error is None for answer in answers)
    assert frames[-2].message == SendEvent(Event.CORE_DISCONNECT)  # stopped on purpose


def test_spy_fault_changes_what_the_base_receives() -> None:
    # Garbage bursts (ctrlbus.faults) in front of a tenth of the Core's writes; the base's answers
    # pass untouched.
    session = Session(fault="tx.burst=0.1:3-8,seed=2")
    try:
        # The Core emulator may lose the connection over such damage and reconnect: fine here.
        session.run_until_connected_and(requests=30, still_connected=False)
    finally:
        session.stop()
    core, base = session.core_link, session.base_link
    assert bytes(base.read_bytes) == session.forwarded(C) != bytes(core.written)
    # rx untouched; a disconnected Core stops without CORE_DISCONNECT, so an answer may still be
    # on its way when its end closes: what it read is what the base wrote, up to there.
    assert bytes(base.written) == session.forwarded(B)
    assert bytes(base.written).startswith(bytes(core.read_bytes))
    assert b"".join(chunk.original for chunk in session.chunks if chunk.direction is C) == bytes(core.written)
    entries = annotate(session.chunks)
    rejected = [entry for entry in entries if isinstance(entry, Rejection) and entry.direction is C]
    assert {RejectReason.GARBAGE, RejectReason.OVERSIZE} & {entry.reason for entry in rejected}
    assert not [entry for entry in entries if isinstance(entry, Rejection) and entry.direction is B]
    # The base answered the damage with line-fault errors, which answer no request.
    line_faults = [
        entry
        for entry in entries
        if isinstance(entry, FrameNote)
        and entry.name == "ERROR"
        and entry.frame.payload in (b"\x10\x00", b"\x20\x00", b"\x40\x00")
    ]
    assert line_faults and all(entry.to is None for entry in line_faults)


# --- the program -------------------------------------------------------------------------------


@pytest.fixture
def processes() -> Iterator[list[Process]]:
    started: list[Process] = []
    yield started
    for process in started:
        process.stop()


def wait_for_line(path: Path, pattern: str, process: subprocess.Popen[bytes]) -> re.Match[str]:
    found: re.Match[str] | None = None

    def seen() -> bool:
        nonlocal found
        found = re.search(pattern, path.read_text(errors="replace"), re.MULTILINE)
        return found is not None or process.poll() is not None

    wait_until(seen)
    assert found is not None, f"no line matching {pattern!r} in {path.read_text(errors='replace')!r}"
    return found


def test_spy_program_between_sim_and_core_over_tcp_with_capture(
    tmp_path: Path, processes: list[Process]
) -> None:
    sim = Process([*CTRLBUS, "sim", "--listen", "127.0.0.1:0"], tmp_path / "sim.log")
    processes.append(sim)
    sim_port = re.fullmatch(r"listen: 127\.0\.0\.1:(\d+)", sim.read_line())
    assert sim_port, sim.describe()
    capture = tmp_path / "spy.pcap"
    out_path = tmp_path / "spy.out"
    with open(out_path, "wb") as out, open(tmp_path / "spy.err", "wb") as err:
        spy = subprocess.Popen(
            [
                *CTRLBUS,
                "spy",
                "--core",
                "listen:127.0.0.1:0",
                "--base",
                f"socket://127.0.0.1:{sim_port.group(1)}",
                "--capture",
                str(capture),
                "--json",
            ],
            stdout=out,
            stderr=err,
            stdin=subprocess.DEVNULL,
        )
    try:
        match = wait_for_line(out_path, r'"side": "core", "address": "listen: 127\.0\.0\.1:(\d+)"', spy)
        link = RecordingLink(open_link(f"socket://127.0.0.1:{match.group(1)}"))
        session = CoreSession()
        runner = CoreRunner(session, link)
        runner.start()
        try:
            assert wait_until(lambda: session.state is ConnectionState.CONNECTED and len(link.written) > 200)
        finally:
            runner.stop()
        spy.send_signal(signal.SIGINT)
        assert spy.wait(timeout=LIMIT_S) == 0, (tmp_path / "spy.err").read_text()
    finally:
        if spy.poll() is None:
            spy.kill()
            spy.wait()
    records: list[dict[str, Any]] = [json.loads(line) for line in out_path.read_text().splitlines()]
    assert [record["kind"] for record in records[:2]] == ["endpoint", "endpoint"]
    assert records[1] == {
        "kind": "endpoint",
        "side": "base",
        "address": f"port: socket://127.0.0.1:{sim_port.group(1)}",
    }
    assert [record["direction"] for record in records[-2:] if record["kind"] == "summary"] == ["core", "base"]
    shown = [record for record in records if record["kind"] == "frame"]
    assert shown[0]["name"] == "CONNECT_BASE" and shown[1]["to"] == "CONNECT_BASE"
    # The capture holds exactly what the Core sent and received, and decodes to the same frames.
    chunks = read_capture(capture)
    assert b"".join(r.data for r in chunks if r.direction is C) == bytes(link.written)
    assert b"".join(r.data for r in chunks if r.direction is B) == bytes(link.read_bytes)
    decoded = [e for e in decode_bytes(capture.read_bytes()).entries if isinstance(e, FrameNote)]
    assert [(e.direction, e.offset, e.name) for e in decoded] == [
        (C if r["direction"] == "core" else B, r["offset"], r["name"]) for r in shown
    ]
    assert [e for e in decoded if e.error is not None] == []
    assert [e for e in decoded if e.role is Role.ANSWER and e.to is None] == []


def test_spy_on_two_ptys_for_a_duration(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["spy", "--core", "pty", "--base", "pty", "--duration", "0.3", "--color", "never"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert re.fullmatch(r"core: pty: /dev/pts/\d+", out[0]) and re.fullmatch(
        r"base: pty: /dev/pts/\d+", out[1]
    )
    assert len(out) == 2  # nothing was said, so no summary


def test_spy_program_fault_over_two_ptys(capsys: pytest.CaptureFixture[str]) -> None:
    """--fault through the command: bytes written on the Core's pty arrive damaged on the base's
    pty, and the spy reports what it injected."""
    args = [
        "spy",
        "--core",
        "pty",
        "--base",
        "pty",
        "--duration",
        "3",
        "--json",
        "--fault",
        "tx.ber=0.1,seed=4",
    ]
    result: list[int] = []
    thread = threading.Thread(target=lambda: result.append(main(args)), daemon=True)
    thread.start()
    addresses: dict[str, str] = {}

    def endpoints_printed() -> bool:
        for line in capsys.readouterr().out.splitlines():
            record = json.loads(line)
            addresses[record["side"]] = record["address"].removeprefix("pty: ")
        return len(addresses) == 2

    assert wait_until(endpoints_printed)
    core_fd, base_fd = (os.open(addresses[side], os.O_RDWR | os.O_NOCTTY) for side in ("core", "base"))
    try:
        for fd in (core_fd, base_fd):
            tty.setraw(fd, termios.TCSANOW)
        sent = bytes(range(256))
        os.write(core_fd, sent)
        received = b""
        deadline = time.monotonic() + LIMIT_S
        while len(received) < len(sent) and time.monotonic() < deadline:
            ready, _, _ = select.select([base_fd], [], [], 0.1)
            if ready:
                received += os.read(base_fd, 4096)
    finally:
        os.close(core_fd)
        os.close(base_fd)
    thread.join(LIMIT_S)
    assert result == [0]
    assert len(received) == len(sent) and received != sent  # bits flipped, none lost
    records = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    (faults,) = [record for record in records if record["kind"] == "faults"]
    assert faults["direction"] == "core"
    assert faults["counters"]["bytes_in"] == len(sent) and faults["counters"]["bits_flipped"] > 0
    flipped = sum(bin(a ^ b).count("1") for a, b in zip(sent, received, strict=True))
    assert flipped == faults["counters"]["bits_flipped"]


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--core", "pty", "--base", "pty", "--fault", "ber=lots"], "ber"),
        (["--core", "pty", "--base", "pty", "--fault", "frobnicate=1"], "unknown fault 'frobnicate'"),
        (["--core", "listen:nowhere", "--base", "pty"], "expected HOST:PORT"),
        (["--core", "pty", "--base", "socket://127.0.0.1:1"], "cannot open socket://127.0.0.1:1"),
        (["--core", "pty", "--base", "pty", "--duration", "-2"], "--duration wants a finite number > 0"),
        (["--core", "pty", "--base", "pty", "--capture", "/nonexistent/dir/x.pcap"], "cannot write"),
        (["--core", "pty", "--base", "pty", "--timeout-ms", "x"], "--timeout-ms wants a number"),
    ],
)
def test_spy_errors_are_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert main(["spy", *args]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ctrlbus spy: error: ") and message in err, err
