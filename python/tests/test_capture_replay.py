# SPDX-License-Identifier: MIT
"""`ctrlbus capture` and `ctrlbus replay`, on captures made by our own Core emulator and simulated
base: a clean session and a noisy one (bit errors and garbage bursts injected on both lines), both
run in virtual time (ctrlbus.vtime), then decoded, replayed over TCP on 127.0.0.1 and captured
again.

`record_session` is also used by test_wireshark_vs_decode.py.
"""

from __future__ import annotations

import re
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import pytest
from base_harness import Process

from ctrlbus.annotate import Annotator, FrameNote, Rejection, RejectReason, Role
from ctrlbus.capture import CaptureReader, CaptureRecord, CaptureWriter, Direction, read_capture
from ctrlbus.cli import main
from ctrlbus.cli.decode_cmd import decode_bytes
from ctrlbus.cli.replay_cmd import replay_schedule
from ctrlbus.core import ConnectionState, CoreSession
from ctrlbus.faults import FaultFilter, fault_models
from ctrlbus.frame import StreamDecoder
from ctrlbus.messages import ConnectBaseAnswer, decode_answer
from ctrlbus.sim.server import SimSettings, build_simulated_stack
from ctrlbus.vtime import ByteFilter, VirtualBus

C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE
CTRLBUS = [sys.executable, "-m", "ctrlbus"]
EPOCH = 1_700_000_000.0  # capture times: the virtual clock's seconds after this
# ctrlbus.faults spec: bit errors both ways, garbage bursts (each with a false frame header) in
# front of 5 % of the Core's writes.
NOISE = "ber=3e-4,tx.burst=0.05:2-12,seed=9"  # a seed whose session shows every kind of rejection


class _Recorder:
    """A vtime byte filter that applies faults (if any) and records what goes onto the line."""

    def __init__(self, writer: CaptureWriter, direction: Direction, faults: ByteFilter | None) -> None:
        self.writer = writer
        self.direction = direction
        self.faults = faults

    def __call__(self, data: bytes, now: float) -> bytes:
        out = self.faults(data, now) if self.faults is not None else data
        if out:
            self.writer.write(self.direction, out, EPOCH + now)
        return out


def record_session(path: Path, *, seconds: float, noise: str | None = None) -> CoreSession:
    """Our Core emulator against the simulated base for `seconds` of virtual time, every chunk on
    either line recorded in a capture at `path` (after the faults of `noise`, if given)."""
    _, stack = build_simulated_stack(SimSettings(seed=1))
    core = CoreSession()
    to_base: ByteFilter | None = None
    to_core: ByteFilter | None = None
    if noise is not None:
        tx, rx = fault_models(noise)
        to_base, to_core = FaultFilter(tx), FaultFilter(rx)
    with CaptureWriter.create(path, flush=False) as writer:
        bus = VirtualBus(
            core,
            stack,
            to_base=_Recorder(writer, C, to_base),
            to_core=_Recorder(writer, B, to_core),
        )
        bus.run_for(seconds)
    return core


@pytest.fixture(scope="module")
def clean_capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("captures") / "clean.pcap"
    core = record_session(path, seconds=3.0)
    assert core.state is ConnectionState.CONNECTED
    return path


@pytest.fixture(scope="module")
def noisy_capture(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("captures") / "noisy.pcap"
    record_session(path, seconds=6.0, noise=NOISE)
    return path


def side_bytes(path: Path, direction: Direction) -> bytes:
    return b"".join(record.data for record in read_capture(path) if record.direction is direction)


# --- what the captures decode to ---------------------------------------------------------------


def test_clean_capture_decodes_to_a_sane_conversation(clean_capture: Path) -> None:
    decoded = decode_bytes(clean_capture.read_bytes(), name=str(clean_capture))
    assert decoded.warnings == []
    assert decoded.time_origin == pytest.approx(EPOCH, abs=0.01)
    entries = decoded.entries
    assert not [entry for entry in entries if isinstance(entry, Rejection)]
    frames = [entry for entry in entries if isinstance(entry, FrameNote)]
    assert all(frame.error is None for frame in frames)
    requests = [frame for frame in frames if frame.role is Role.REQUEST]
    answers = [frame for frame in frames if frame.role is Role.ANSWER]
    assert all(frame.direction is C for frame in requests) and all(frame.direction is B for frame in answers)
    # §11: connect, configuration (the sim's blob, then 0x20 for the second view), system up.
    assert [request.name for request in requests[:4]] == [
        "CONNECT_BASE",
        "GET_BASE_CONF_ADV",
        "GET_BASE_CONF",
        "SEND_EVENT",
    ]
    assert answers[0].to == "CONNECT_BASE" and answers[0].name == "OK"
    assert answers[0].message is not None and "'ctrlbus sim'" in str(decoded_text(answers[0]))
    assert (answers[1].name, answers[1].to) == ("OK", "GET_BASE_CONF_ADV")  # the sim serves a blob
    # Every request is answered, in turn: each answer names the request just before it.
    assert len(requests) - len(answers) in (0, 1)
    for request, answer in zip(requests, answers, strict=False):
        assert (answer.to, answer.request_offset) == (request.name, request.offset)
        assert answer.time is not None and request.time is not None and answer.time > request.time
    names = {request.name for request in requests}
    assert {"SET_V_AND_GET_DEADRECKON", "GET_BASE_SENSOR_DATA", "HEALTH_GET_HEALTH", "POLL_BASE_CMD"} <= names


def decoded_text(entry: FrameNote) -> str:
    from ctrlbus.annotate import format_annotation

    return format_annotation(entry)


def test_noisy_capture_shows_every_rejection_and_accounts_for_every_byte(noisy_capture: Path) -> None:
    records = read_capture(noisy_capture)
    decoded = decode_bytes(noisy_capture.read_bytes())
    entries = decoded.entries
    rejections = [entry for entry in entries if isinstance(entry, Rejection)]
    reasons = {rejection.reason for rejection in rejections}
    assert {RejectReason.CHECKSUM_ERROR, RejectReason.GARBAGE, RejectReason.TIMEOUT} <= reasons
    for rejection in rejections:
        if rejection.reason is RejectReason.CHECKSUM_ERROR:
            assert rejection.expected_checksum != rejection.found_checksum
    for direction in Direction:
        sent = b"".join(record.data for record in records if record.direction is direction)
        mine = sorted((entry for entry in entries if entry.direction is direction), key=lambda e: e.offset)
        offset = 0
        for entry in mine:
            assert entry.offset == offset
            if isinstance(entry, FrameNote):
                assert sent[offset : offset + entry.size] == entry.frame.raw
            else:
                assert sent[offset : offset + len(entry.preview)] == entry.preview
            offset += entry.size
        assert offset == len(sent)
        # The frames are exactly those a bare decoder (same timeout, same chunk times) finds.
        decoder = StreamDecoder(timeout=0.1)
        expected = []
        for record in records:
            if record.direction is direction:
                expected += decoder.feed(record.data, record.time)
        assert decoded.annotator.stats(direction) == decoder.stats
        found = [entry.frame for entry in mine if isinstance(entry, FrameNote)]
        assert found[: len(expected)] == expected
    # The base answered the damaged requests with line-fault errors; those answer no request.
    # The conversation goes on through the noise: the base is connected and answers are read.
    answered = [e for e in entries if isinstance(e, FrameNote) and e.to is not None and e.error is None]
    assert any(entry.to == "CONNECT_BASE" and entry.name == "OK" for entry in answered)
    assert len({entry.to for entry in answered}) >= 5
    faults = [
        entry
        for entry in entries
        if isinstance(entry, FrameNote)
        and entry.name == "ERROR"
        and entry.frame.payload in (b"\x40\x00", b"\x10\x00")
    ]
    assert faults and all(entry.to is None for entry in faults)


def test_decode_cli_on_the_noisy_capture(noisy_capture: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["decode", str(noisy_capture), "--direction", "base", "--color", "never"]) == 0
    out = capsys.readouterr().out
    lines = out.splitlines()
    assert all("base→core" in line for line in lines if not line.startswith("#"))
    assert re.search(r"^ +\d+\.\d{6} base→core @\d+ +rejected checksum error: checksum 0x", out, re.MULTILINE)
    assert re.search(
        r"^ +\d+\.\d{6} base→core @\d+ +long OK to SET_V_AND_GET_DEADRECKON @\d+: dx ", out, re.M
    )
    assert lines[-1].startswith("# base→core: ")


# --- replay timing -----------------------------------------------------------------------------


def _record(seconds: float, direction: Direction, data: bytes) -> CaptureRecord:
    return CaptureRecord(round(seconds * 1e9), direction, data, 0)


def test_replay_schedule_keeps_one_side_at_its_times_scaled() -> None:
    records = [
        _record(100.0, B, b"b0"),
        _record(100.5, C, b"c0"),
        _record(100.7, B, b"b1"),
        _record(101.5, C, b"c1"),
        _record(101.25, C, b"c2"),  # a clock step back: played right after the one before
        _record(103.5, C, b"c3"),
    ]
    assert replay_schedule(records, C, 1.0) == [(0.0, b"c0"), (1.0, b"c1"), (1.0, b"c2"), (3.0, b"c3")]
    assert replay_schedule(records, C, 2.0) == [(0.0, b"c0"), (0.5, b"c1"), (0.5, b"c2"), (1.5, b"c3")]
    assert replay_schedule(records, B, 0.0) == [(0.0, b"b0"), (0.0, b"b1")]


# --- round trips over TCP --------------------------------------------------------------------------


@pytest.fixture
def processes() -> Iterator[list[Process]]:
    started: list[Process] = []
    yield started
    for process in started:
        process.stop()


def start(processes: list[Process], log: Path, *args: str) -> Process:
    process = Process([*CTRLBUS, *args], log)
    processes.append(process)
    return process


def listening_port(process: Process) -> int:
    line = process.read_line()
    match = re.fullmatch(r"listen: 127\.0\.0\.1:(\d+)", line)
    assert match, f"unexpected first line {line!r} from {process.describe()}"
    return int(match.group(1))


def wait_for_bytes(path: Path, direction: Direction, size: int, limit_s: float = 10.0) -> bytes:
    """The bytes of `direction` in a capture being written, once there are `size` (or the limit)."""
    deadline = time.monotonic() + limit_s
    while True:
        with CaptureReader.open(path) as reader:
            data = b"".join(record.data for record in reader if record.direction is direction)
        if len(data) >= size or time.monotonic() > deadline:
            return data
        time.sleep(0.05)


@pytest.mark.parametrize("side", ["core", "base"])
def test_capture_replay_capture_gives_the_same_bytes(
    noisy_capture: Path, tmp_path: Path, processes: list[Process], side: str
) -> None:
    direction = C if side == "core" else B
    original = side_bytes(noisy_capture, direction)
    again = tmp_path / "again.pcap"
    capture = start(
        processes,
        tmp_path / "capture.log",
        "capture",
        "--port",
        "listen:127.0.0.1:0",
        "-o",
        str(again),
        "--direction",
        side,
    )
    port = listening_port(capture)
    replay = subprocess.run(
        [
            *CTRLBUS,
            "replay",
            str(noisy_capture),
            "--port",
            f"socket://127.0.0.1:{port}",
            "--direction",
            side,
            "--speed",
            "20",
            "--linger",
            "0",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert replay.returncode == 0, replay.stderr
    assert f"{len(original)} bytes in" in replay.stderr
    received = wait_for_bytes(again, direction, len(original))
    capture.popen.send_signal(signal.SIGINT)
    assert capture.wait_exit() == 0
    assert received == original
    assert side_bytes(again, direction) == original  # the finished file holds the same
    assert f"{len(original)} bytes in" in capture.log()


def test_replay_the_core_side_into_the_simulated_base(
    clean_capture: Path, tmp_path: Path, processes: list[Process]
) -> None:
    sim = start(processes, tmp_path / "sim.log", "sim", "--listen", "127.0.0.1:0")
    port = listening_port(sim)
    back = tmp_path / "back.pcap"
    replay = subprocess.run(
        [
            *CTRLBUS,
            "replay",
            str(clean_capture),
            "--port",
            f"socket://127.0.0.1:{port}",
            "--speed",
            "3",
            "--capture",
            str(back),
            "--linger",
            "0.5",
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert replay.returncode == 0, replay.stderr
    assert side_bytes(back, C) == side_bytes(clean_capture, C)
    frames = [entry for entry in decode_bytes(back.read_bytes()).entries if isinstance(entry, FrameNote)]
    requests = [frame for frame in frames if frame.role is Role.REQUEST]
    answers = [frame for frame in frames if frame.role is Role.ANSWER]
    # A live base answered each replayed request once, in order. Played open loop, faster than
    # recorded, a request may go out before the previous answer is back, so pair them by order here
    # (the annotator pairs with the one outstanding request, as a Core does).
    assert len(answers) == len(requests)
    for request, answer in zip(requests, answers, strict=True):
        assert request.name is not None
        message = decode_answer(request.name, answer.frame.cmd, answer.frame.payload)
        assert (request.name, message.NAME) == (request.name, "OK"), answer  # the sim serves a blob
    first = decode_answer("CONNECT_BASE", answers[0].frame.cmd, answers[0].frame.payload)
    assert isinstance(first, ConnectBaseAnswer) and first.model == "ctrlbus sim"


def test_an_annotator_fed_live_chunks_matches_the_file(clean_capture: Path) -> None:
    """The spy's way (chunk by chunk, with idle() between) gives the decode's frames."""
    annotator = Annotator(timeout=0.1)
    live = []
    for record in read_capture(clean_capture):
        live += annotator.feed(record.data, record.direction, record.time)
        live += annotator.idle(record.time)
    live += annotator.finish()
    offline = decode_bytes(clean_capture.read_bytes()).entries
    assert [(e.direction, e.offset, e.size) for e in live] == [
        (e.direction, e.offset, e.size) for e in offline
    ]


# --- errors --------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["replay", "{missing}", "--port", "loop://"], "cannot read"),
        (["replay", "{text}", "--port", "loop://"], "not a pcap capture file"),
        (["replay", "{capture}", "--port", "loop://", "--speed", "fast"], "--speed wants a number"),
        (["replay", "{capture}", "--port", "loop://", "--speed", "-1"], "--speed wants a finite number >= 0"),
        (["replay", "{capture}", "--port", "nosuchscheme://x"], "cannot open nosuchscheme://x"),
        (["replay", "{capture}", "--port", "listen:localhost"], "expected HOST:PORT"),
        (
            ["capture", "--port", "loop://", "-o", "/nonexistent/dir/x.pcap"],
            "cannot write /nonexistent/dir/x.pcap",
        ),
        (["capture", "--port", "/dev/nonexistent-tty", "-o", "{out}"], "cannot open /dev/nonexistent-tty"),
        (
            ["capture", "--port", "loop://", "-o", "{out}", "--duration", "0"],
            "--duration wants a finite number > 0",
        ),
    ],
)
def test_errors_are_one_line_and_exit_2(
    clean_capture: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str], args: list[str], message: str
) -> None:
    text = tmp_path / "text.txt"
    text.write_text("10 02 F8 30 DA\n", encoding="utf-8")
    values = {"missing": str(tmp_path / "missing.pcap"), "text": str(text), "capture": str(clean_capture)}
    values["out"] = str(tmp_path / "out.pcap")
    code = main([arg.format(**values) for arg in args])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and message in err, err


def test_capture_for_a_duration_from_a_loop_port(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "loop.pcap"
    assert (
        main(["capture", "--port", "loop://", "-o", str(out), "--duration", "0.2", "--direction", "base"])
        == 0
    )
    assert capsys.readouterr().out == "port: loop://\n"
    assert read_capture(out) == []  # nothing was sent on the loop
