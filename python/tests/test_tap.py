# SPDX-License-Identifier: MIT
"""`ctrlbus capture --tap`: the passive two-line tap.

The bench is rebuilt in the test: our Core emulator and the simulated base talk through a splitter
(in process) that copies each direction to the other peer and to a pty of its own, as the two RX
pins of a pair of USB adapters hear the Core's and the base's TX lines. `ctrlbus capture --tap` (a
program) reads the two ptys; the test checks that it shows the conversation while it happens, with
answers paired, and that its capture holds every byte of both directions in time order and decodes
to what it showed.
"""

from __future__ import annotations

import itertools
import json
import os
import signal
import subprocess
import sys
import threading
import time
import tty
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from test_spy import LIMIT_S, wait_until

from ctrlbus.annotate import FrameNote, Role
from ctrlbus.base import BaseRunner
from ctrlbus.capture import Direction, read_capture
from ctrlbus.cli import main
from ctrlbus.cli.capture_cmd import Tap
from ctrlbus.cli.decode_cmd import decode_bytes
from ctrlbus.cli.spy_cmd import Chunk
from ctrlbus.core import ConnectionState, CoreRunner, CoreSession
from ctrlbus.errors import LinkError
from ctrlbus.frame import encode
from ctrlbus.link import Link, link_pair
from ctrlbus.messages import Cmd, Event, Request, Response
from ctrlbus.sim.server import SimSettings, build_simulated_stack
from ctrlbus.tap import TapMerger

C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE
CTRLBUS = [sys.executable, "-m", "ctrlbus"]


class Splitter:
    """The wire between a Core and a base, with a tap on each TX line: every byte a side sends
    goes to its peer and to that side's tap pty (the pty's master end; the tool opens the slave)."""

    def __init__(self, core: Link, base: Link) -> None:
        self.taps = {direction: os.openpty() for direction in Direction}
        for _, slave in self.taps.values():
            tty.setraw(slave)  # the tool's port is raw, as pyserial would set it
        self.sent = {direction: bytearray() for direction in Direction}
        self.stop_event = threading.Event()
        self.threads = [
            threading.Thread(target=self._copy, args=(core, base, C), daemon=True),
            threading.Thread(target=self._copy, args=(base, core, B), daemon=True),
        ]

    def tap_path(self, direction: Direction) -> str:
        return os.ttyname(self.taps[direction][1])

    def start(self) -> None:
        for thread in self.threads:
            thread.start()

    def _copy(self, source: Link, target: Link, direction: Direction) -> None:
        master = self.taps[direction][0]
        try:
            while not self.stop_event.is_set():
                data = source.read(0.05)
                if data:
                    self.sent[direction] += data
                    os.write(master, data)
                    target.write(data)
        except LinkError:
            return  # a side closed its end: the wire carries nothing more that way

    def stop(self) -> None:
        self.stop_event.set()
        for thread in self.threads:
            thread.join(LIMIT_S)
        for master, slave in self.taps.values():
            os.close(master)
            os.close(slave)


@pytest.fixture
def bench() -> Iterator[tuple[CoreSession, CoreRunner, BaseRunner, Splitter]]:
    core_end, wire_core = link_pair(("core", "wire:core"))
    wire_base, base_end = link_pair(("wire:base", "base"))
    _, stack = build_simulated_stack(SimSettings(seed=1))
    base = BaseRunner(stack, base_end)
    session = CoreSession()
    core = CoreRunner(session, core_end)
    splitter = Splitter(wire_core, wire_base)
    yield session, core, base, splitter
    core.stop()
    splitter.stop()
    base.stop()


def json_lines(path: Path) -> list[dict[str, Any]]:
    """The complete lines the tool has written so far (a line being written is left for later)."""
    lines = path.read_text().split("\n")[:-1]
    return [json.loads(line) for line in lines if line.strip()]


def test_tap_shows_the_conversation_live_and_captures_both_lines_in_time_order(
    tmp_path: Path, bench: tuple[CoreSession, CoreRunner, BaseRunner, Splitter]
) -> None:
    session, core, base, splitter = bench
    capture = tmp_path / "tap.pcap"
    out_path = tmp_path / "tap.out"
    args = [
        *CTRLBUS,
        "capture",
        "--tap",
        f"core={splitter.tap_path(C)}",
        "--tap",
        f"base={splitter.tap_path(B)}",
        "-o",
        str(capture),
        "--json",
    ]
    with open(out_path, "wb") as out, open(tmp_path / "tap.err", "wb") as err:
        tool = subprocess.Popen(args, stdout=out, stderr=err, stdin=subprocess.DEVNULL)
    try:
        assert wait_until(lambda: len(json_lines(out_path)) >= 2 or tool.poll() is not None)
        endpoints = json_lines(out_path)[:2]
        assert endpoints == [
            {"kind": "endpoint", "side": "core", "address": f"port: {splitter.tap_path(C)}"},
            {"kind": "endpoint", "side": "base", "address": f"port: {splitter.tap_path(B)}"},
        ]
        base.start()
        splitter.start()
        core.start()

        def answered(request: str) -> bool:
            return any(r.get("to") == request for r in json_lines(out_path))

        def disconnect_answered() -> bool:
            records = json_lines(out_path)
            events = [
                r["offset"]
                for r in records
                if r.get("name") == "SEND_EVENT" and r["fields"] == {"event": int(Event.CORE_DISCONNECT)}
            ]
            return bool(events) and any(r.get("request_offset") == events[-1] for r in records)

        # Live: the tool shows the handshake while the Core is still talking.
        assert wait_until(lambda: answered("CONNECT_BASE")), (tmp_path / "tap.err").read_text()
        assert wait_until(lambda: session.state is ConnectionState.CONNECTED and len(splitter.sent[C]) > 300)
        assert tool.poll() is None
        core.stop()  # on purpose: its CORE_DISCONNECT event goes through and is answered
        assert wait_until(lambda: disconnect_answered() or tool.poll() is not None)
        tool.send_signal(signal.SIGINT)
        assert tool.wait(timeout=LIMIT_S) == 0, (tmp_path / "tap.err").read_text()
    finally:
        if tool.poll() is None:
            tool.kill()
            tool.wait()
    records = json_lines(out_path)
    shown = [record for record in records if record["kind"] == "frame"]
    assert [record["kind"] for record in records if record["kind"] not in ("frame", "endpoint")] == [
        "summary",
        "summary",
    ]
    answers = [record for record in shown if record["role"] == "answer"]
    assert shown[0]["name"] == "CONNECT_BASE" and answers[0]["to"] == "CONNECT_BASE"
    assert answers and all(record["to"] is not None and record["error"] is None for record in answers)

    # The capture: every byte of each line, one merged file whose records go forward in time.
    chunks = read_capture(capture)
    for direction in Direction:
        assert b"".join(r.data for r in chunks if r.direction is direction) == bytes(splitter.sent[direction])
    assert {r.direction for r in chunks} == {C, B}
    assert all(a.time_ns <= b.time_ns for a, b in itertools.pairwise(chunks))
    # ... and decodes (`ctrlbus decode`) to exactly the frames and pairs shown live.
    decoded = [e for e in decode_bytes(capture.read_bytes()).entries if isinstance(e, FrameNote)]
    assert [(e.direction, e.offset, e.name, e.to) for e in decoded] == [
        (C if r["direction"] == "core" else B, r["offset"], r["name"], r["to"]) for r in shown
    ]
    assert [e for e in decoded if e.role is Role.ANSWER and e.to is None] == []


class _ScriptedLine:
    """A tapped line that delivers one chunk, after `delay_s`, then nothing; counts writes."""

    def __init__(self, name: str, chunk: bytes, delay_s: float) -> None:
        self._name = name
        self._chunk: bytes | None = chunk
        self._ready_at = time.monotonic() + delay_s
        self.writes = 0

    @property
    def name(self) -> str:
        return self._name

    def read(self, timeout: float) -> bytes:
        time.sleep(min(timeout, 0.01))
        if self._chunk is not None and time.monotonic() >= self._ready_at:
            chunk, self._chunk = self._chunk, None
            return chunk
        return b""

    def write(self, data: bytes) -> None:
        self.writes += 1

    def close(self) -> None:
        pass


def test_tap_hands_on_chunks_in_read_time_order_and_writes_nothing() -> None:
    # The Core's line delivers first, but the clock says the base's chunk was read earlier (as when
    # one reading thread is scheduled late): the tap must hand the base's chunk on first.
    core = _ScriptedLine("core", b"\x10\x01\x00\x11", delay_s=0.0)
    base = _ScriptedLine("base", b"\x10\x01\x02\x13", delay_s=0.1)
    origin = time.time()
    read_times = {"spy-core-to-base": origin + 0.2, "spy-base-to-core": origin + 0.1}

    def clock() -> float:
        return read_times.get(threading.current_thread().name, time.time())

    tap = Tap(core, base, merge_window=0.5, clock=clock)
    tap.start()
    got: list[Chunk] = []
    try:
        while len(got) < 2:
            more = tap.chunks(LIMIT_S)
            assert more, "the tap handed on nothing"
            got += more
    finally:
        tap.stop()
    assert [(chunk.direction, chunk.time) for chunk in got] == [(B, origin + 0.1), (C, origin + 0.2)]
    assert core.writes == base.writes == 0


REQUEST_1 = encode(Cmd.CTRL_BUS, bytes([Request.GET_BASE_STATUS]))
REQUEST_2 = encode(Cmd.CTRL_BUS, bytes([Request.GET_BASE_MOTOR_DATA]))
ANSWER_1 = encode(Response.OK, bytes([80, 0]), long=True)
ANSWER_2 = encode(Response.OK, bytes(8), long=True)


def merged(merger: TapMerger, chunks: list[tuple[Direction, bytes, float]]) -> list[tuple[Direction, bytes]]:
    for direction, data, time_s in chunks:
        merger.add(direction, data, time_s)
    pieces = merger.release(None)
    assert [piece.time for piece in pieces] == sorted(piece.time for piece in pieces)
    return [(piece.direction, piece.data) for piece in pieces]


def test_merger_puts_a_late_read_answer_before_the_next_request() -> None:
    # Both answers came in one late read of the base's line, after the second request was read.
    chunks = [(C, REQUEST_1, 1.000), (C, REQUEST_2, 1.002), (B, ANSWER_1 + ANSWER_2, 1.010)]
    assert merged(TapMerger(), chunks) == [(C, REQUEST_1), (B, ANSWER_1), (C, REQUEST_2), (B, ANSWER_2)]
    # Without the protocol's order (no skew allowed), read times alone get it wrong.
    assert merged(TapMerger(skew=0.0), chunks)[1] == (C, REQUEST_2)


def test_merger_puts_a_request_read_late_before_its_answer() -> None:
    chunks = [(B, ANSWER_1, 1.001), (C, REQUEST_1, 1.004)]
    assert merged(TapMerger(), chunks) == [(C, REQUEST_1), (B, ANSWER_1)]


def test_merger_lets_an_unanswered_request_go_after_the_core_gave_up() -> None:
    # REQUEST_1 got no answer; after the answer limit the Core sends REQUEST_2, whose answer is
    # read just after it: it answers REQUEST_2 and must not go before it.
    merger = TapMerger(answer_limit=0.2)
    assert merged(merger, [(C, REQUEST_1, 1.0)]) == [(C, REQUEST_1)]
    assert merged(merger, [(C, REQUEST_2, 1.3), (B, ANSWER_2, 1.29)]) == [(C, REQUEST_2), (B, ANSWER_2)]


def test_merger_holds_what_is_newer_than_until_and_cuts_partial_frames() -> None:
    merger = TapMerger()
    merger.add(C, REQUEST_1 + REQUEST_2[:3], 1.0)
    merger.add(C, REQUEST_2[3:], 2.0)
    assert [piece.data for piece in merger.release(1.5)] == [REQUEST_1, REQUEST_2[:3]]
    assert merger.held == 1 and merger.oldest == 2.0
    (rest,) = merger.release(None)
    assert (rest.data, rest.ends_frame) == (REQUEST_2[3:], True)


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--tap", "core=pty"], "base=ENDPOINT is missing"),
        (["--tap", "core=pty", "--tap", "core=pty"], "--tap core= given twice"),
        (["--tap", "robot=pty", "--tap", "base=pty"], "--tap wants core=ENDPOINT or base=ENDPOINT"),
        (["--tap", "core=pty", "--tap", "base=socket://127.0.0.1:1"], "cannot open socket://127.0.0.1:1"),
    ],
)
def test_tap_errors_are_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    assert main(["capture", *args, "-o", str(tmp_path / "x.pcap")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("ctrlbus capture: error: ") and message in err, err


def test_tap_and_port_exclude_each_other(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exited:
        main(["capture", "--port", "pty", "--tap", "core=pty", "-o", str(tmp_path / "x.pcap")])
    assert exited.value.code == 2
    assert "not allowed with argument" in capsys.readouterr().err
