# SPDX-License-Identifier: MIT
"""The sigrok protocol decoder tools/sigrok/ctrlbus, run by sigrok-cli on logic-level recordings,
against `ctrlbus decode` on the same bytes.

A capture of our Core emulator talking to the simulated base gets a few bit errors and is then
drawn as the two UART lines a logic analyser would see (115200 8N1, sampled at 1 MHz): the Core's
TX on channel 0 (the uart decoder's RX: what the base receives), the base's TX on channel 1.
sigrok-cli decodes the recording with `uart` and our decoder stacked on it; `ctrlbus decode` reads a
capture with the same bytes at the same times. Every frame (name, pairing, fields with units) and
every reported failure (garbage, checksum errors with both checksums, ...) must match, in order, on
each line. The same comparison over every frame vector (vectors/frames.json) covers the messages a
short conversation does not use.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
from test_spy import Session

from ctrlbus.annotate import format_fields
from ctrlbus.capture import CaptureWriter, Direction, read_capture
from ctrlbus.frame import StreamDecoder
from ctrlbus.messages import Cmd, GetBaseConfAdvAnswer, from_fields

SIGROK_CLI = shutil.which("sigrok-cli")
CTRLBUS = [sys.executable, "-m", "ctrlbus"]
ROOT = Path(__file__).resolve().parents[2]
DECODERS = ROOT / "tools" / "sigrok"
FRAME_VECTORS = json.loads((ROOT / "vectors" / "frames.json").read_text(encoding="utf-8"))["frames"]
C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE
SAMPLERATE = 1_000_000
BAUD = 115200
BIT_S = 1 / BAUD
# Gaps in the drawn recording: within a burst of exchanges at most BURST_GAP_S, between bursts
# PAUSE_S; the inter-byte timeout both decoders use lies well between, so that both see the same
# timeouts although one is fed whole chunks and the other single bytes.
BURST_GAP_S = 0.002
PAUSE_S = 0.08
TIMEOUT_MS = 40
LIMIT_S = 15.0


@pytest.fixture(autouse=True)
def _sigrok_cli_is_installed() -> None:
    """scripts/setup.sh installs sigrok-cli, so its absence is a broken set-up, not a skip."""
    if SIGROK_CLI is None:
        pytest.fail("sigrok-cli is not installed: scripts/setup.sh installs it (apt-get install sigrok-cli)")


# --- making the recording ----------------------------------------------------------------------


@dataclass
class Record:
    direction: Direction
    data: bytes
    time: float


def record_a_conversation() -> list[Record]:
    """Our Core emulator and the simulated base through the spy (tests/test_spy.py): connection,
    a few polling rounds, and the disconnect when the Core is stopped."""
    session = Session()
    try:
        session.run_until_connected_and(requests=30)
    finally:
        session.stop()
    return [Record(chunk.direction, chunk.data, chunk.time) for chunk in session.chunks if chunk.data]


def flip_bits(records: list[Record], flips: list[tuple[Direction, int, int]]) -> list[Record]:
    """The records with bit `mask` flipped in byte `offset` of `direction`'s stream."""
    out = []
    fed = dict.fromkeys(Direction, 0)
    for record in records:
        data = bytearray(record.data)
        start = fed[record.direction]
        for direction, offset, mask in flips:
            if direction is record.direction and start <= offset < start + len(data):
                data[offset - start] ^= mask
        fed[record.direction] += len(data)
        out.append(Record(record.direction, bytes(data), record.time))
    return out


def redraw_times(records: list[Record]) -> list[Record]:
    """One record after the other on the wire (no overlap, so both decoders see the same order),
    each starting when its bytes start: the gaps within a burst shrunk to at most BURST_GAP_S, the
    pauses between bursts set to PAUSE_S."""
    out: list[Record] = []
    wire_free = 0.001
    previous = records[0].time
    for record in records:
        gap = record.time - previous
        previous = record.time
        start = wire_free + (min(gap, BURST_GAP_S) if gap < 0.02 else PAUSE_S)
        out.append(Record(record.direction, record.data, start))
        wire_free = start + len(record.data) * 10 * BIT_S
    return out


def draw_lines(records: list[Record]) -> bytes:
    """A 2-channel logic recording, one byte per sample: bit 0 the Core's TX line, bit 1 the
    base's; idle high, 8N1, LSB first."""
    end = records[-1].time + len(records[-1].data) * 10 * BIT_S + 0.001
    samples = bytearray(b"\x03") * round(end * SAMPLERATE)
    for record in records:
        line = 1 if record.direction is C else 2
        for index, byte in enumerate(record.data):
            start = record.time + index * 10 * BIT_S
            bits = [0, *((byte >> bit) & 1 for bit in range(8)), 1]
            for position, bit in enumerate(bits):
                first = round((start + position * BIT_S) * SAMPLERATE)
                last = round((start + (position + 1) * BIT_S) * SAMPLERATE)
                samples[first:last] = bytes([3 if bit else 3 & ~line]) * (last - first)
    return bytes(samples)


def write_capture(path: Path, records: list[Record]) -> None:
    with CaptureWriter.create(path) as writer:
        for record in records:
            writer.write(record.direction, record.data, 1_700_000_000.0 + record.time)


# --- the two decoders ----------------------------------------------------------------------------


def sigrok_annotations(logic: Path) -> dict[Direction, list[str]]:
    """What our decoder says per line, in order: its request/answer and error rows."""
    assert SIGROK_CLI is not None
    result = subprocess.run(
        [
            SIGROK_CLI,
            "-I",
            f"binary:numchannels=2:samplerate={SAMPLERATE}",
            "-i",
            str(logic),
            "-P",
            f"uart:baudrate={BAUD}:rx=0:tx=1,ctrlbus:timeout_ms={TIMEOUT_MS}",
            "-A",
            "ctrlbus=core-msg:core-err:base-msg:base-err",
            "--protocol-decoder-jsontrace",
        ],
        capture_output=True,
        text=True,
        env={**os.environ, "SIGROKDECODE_DIR": str(DECODERS)},
        timeout=120,
        check=False,
    )
    assert result.returncode == 0 and "Traceback" not in result.stderr, result.stderr
    # One trace event a line. sigrok-cli 0.7 does not escape the quotes that printable-text runs
    # bring into an annotation, so a line is read by its shape, the name (the text) last.
    rows = {"Core requests": C, "Core errors": C, "Base answers": B, "Base errors": B}
    out: dict[Direction, list[str]] = {C: [], B: []}
    events = [line for line in result.stdout.splitlines() if line.startswith('{"ph"')]
    assert events, result.stdout
    for line in events:
        event = re.fullmatch(
            r'\{"ph": "(?P<ph>[BE])", .*"tid": "(?P<tid>[^"]+)", "name": "(?P<name>.*)"\},?', line
        )
        assert event is not None, f"unexpected trace line {line!r}"
        if event["ph"] == "B":
            name = event["name"]
            out[rows[event["tid"]]].append(error_kind(name) if event["tid"].endswith("errors") else name)
    return out


def error_kind(text: str) -> str:
    """The decoder event of a sigrok error annotation (with both checksums for a checksum error)."""
    checksum = re.fullmatch(r"checksum error: checksum (0x..), expected (0x..)", text)
    if checksum:
        return f"checksum_error {checksum.group(1)} {checksum.group(2)}"
    for kind in ("garbage", "oversize", "timeout", "empty frame"):
        if text.startswith(kind):
            return kind.replace(" ", "_")
    raise AssertionError(f"unexpected error annotation {text!r}")


def frame_text(record: dict[str, Any]) -> str:
    """A frame as our decoder writes it, made from a `ctrlbus decode --json` frame record."""
    payload = bytes.fromhex(record["hex"])[(3 if record["long"] else 2) + 1 : -1]
    label: str
    if record["role"] == "request":
        label = record["name"]
        if record["name"] is None:
            if record["cmd"] != Cmd.CTRL_BUS:
                label = f"0x{record['cmd']:02X}"
            else:
                label = f"CTRL_BUS 0x{payload[0]:02X}" if payload else "CTRL_BUS"
        answered = None
    else:
        label = (record["name"] or f"0x{record['cmd']:02X}") + (f" to {record['to']}" if record["to"] else "")
        if record["guess"]:  # an OK read by its size alone: both decoders say it is a guess
            label += f" (a guess: to {record['guess']})"
        answered = record["to"] or record.get("guess") or "SYNC"  # SYNC: answers that need no request
    text = ""
    if record["fields"] is not None:
        message = from_fields(record["name"], record["fields"], to=answered)
        text = format_fields(message)
        if isinstance(message, GetBaseConfAdvAnswer):
            # Our decoder shows the blob; the configuration tree inside is left to `ctrlbus decode`.
            text = re.split(r", (?:config |not a configuration)", text)[0]
    error = f" [{record['error']}]" if record["error"] else ""
    return label + (f": {text}" if text else "") + error


def decode_annotations(capture: Path) -> dict[Direction, list[str]]:
    """What `ctrlbus decode --json` says per line, in the same words (failures raised as events
    only: silent discards and the end-of-input flush are not events)."""
    result = subprocess.run(
        [*CTRLBUS, "decode", "--json", "--timeout-ms", str(TIMEOUT_MS), str(capture)],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert result.returncode == 0, result.stderr
    out: dict[Direction, list[str]] = {C: [], B: []}
    for line in result.stdout.splitlines():
        record = json.loads(line)
        if record["kind"] not in ("frame", "rejected"):
            continue
        direction = C if record["direction"] == "core" else B
        if record["kind"] == "frame":
            out[direction].append(frame_text(record))
        elif record["reason"] == "checksum_error":
            out[direction].append(
                f"checksum_error 0x{record['found_checksum']:02X} 0x{record['expected_checksum']:02X}"
            )
        elif record["reason"] not in ("silent", "incomplete"):
            out[direction].append(record["reason"])
    return out


def assert_same(sigrok: dict[Direction, list[str]], ours: dict[Direction, list[str]]) -> None:
    for direction in Direction:
        for index, (theirs, mine) in enumerate(zip(sigrok[direction], ours[direction], strict=False)):
            assert theirs == mine, f"{direction.name} item {index}: sigrok {theirs!r} != decode {mine!r}"
        assert len(sigrok[direction]) == len(ours[direction]), direction.name


# --- the tests ------------------------------------------------------------------------------------


def test_sigrok_decoder_matches_ctrlbus_decode_on_a_noisy_recording(tmp_path: Path) -> None:
    clean = record_a_conversation()
    core_frames, base_frames = (
        StreamDecoder().feed(b"".join(r.data for r in clean if r.direction is side)) for side in (C, B)
    )
    # Bit errors: in a request's payload, in an answer's payload (checksum errors), and in a
    # request's flag byte (its bytes become garbage).
    flips = [
        (C, core_frames[6].offset + 3, 0x04),
        (B, base_frames[8].offset + 4, 0x10),
        (C, core_frames[12].offset, 0x01),
    ]
    damaged = redraw_times(flip_bits(clean, flips))
    capture_path = tmp_path / "noisy.pcap"
    write_capture(capture_path, damaged)
    logic = tmp_path / "noisy.bin"
    logic.write_bytes(draw_lines(damaged))
    assert [(r.direction, r.data) for r in read_capture(tmp_path / "noisy.pcap")] == [
        (r.direction, r.data) for r in damaged
    ]

    ours = decode_annotations(capture_path)
    sigrok = sigrok_annotations(logic)
    assert_same(sigrok, ours)
    # The recording holds what the test is about.
    assert sum(item.startswith("checksum_error") for item in sigrok[C]) >= 1
    assert sum(item.startswith("checksum_error") for item in sigrok[B]) >= 1
    assert "garbage" in sigrok[C]
    assert any(item.startswith("OK to CONNECT_BASE: model ") for item in sigrok[B])
    assert any(re.match(r"SET_V_AND_GET_DEADRECKON: vx -?\d+\.\d{3} m/s", item) for item in sigrok[C])
    assert any(item.endswith("[unpaired]") for item in sigrok[B])  # the answer to a damaged request


def test_sigrok_decoder_matches_ctrlbus_decode_on_every_frame_vector(tmp_path: Path) -> None:
    """Each request vector, and each answer vector after a request of the kind it answers."""
    requests = {
        v["message"]["name"]: bytes.fromhex(v["hex"])
        for v in reversed(FRAME_VECTORS)
        if v.get("message", {}).get("kind") == "request"
    }
    records: list[Record] = []
    for vector in FRAME_VECTORS:
        message = vector.get("message")
        if message is None:
            continue
        frame = bytes.fromhex(vector["hex"])
        if message["kind"] == "request":
            records.append(Record(C, frame, 0.0))
        else:
            records += [Record(C, requests[message["to"]], 0.0), Record(B, frame, 0.0)]
    # An unknown request code and an OK with no request, for the fallbacks.
    unknown = bytes([0x10, 0x02, 0xF8, 0x77, 0x10 ^ 0x02 ^ 0xF8 ^ 0x77])
    records += [Record(C, unknown, 0.0), Record(B, bytes.fromhex("50 01 00 02 53"), 0.0)]
    drawn = redraw_times(records)
    capture_path = tmp_path / "vectors.pcap"
    write_capture(capture_path, drawn)
    logic = tmp_path / "vectors.bin"
    logic.write_bytes(draw_lines(drawn))
    ours = decode_annotations(capture_path)
    sigrok = sigrok_annotations(logic)
    assert_same(sigrok, ours)
    assert len(sigrok[C]) == len([r for r in records if r.direction is C])
    # Every vector decodes; only the two fallbacks at the end carry an error.
    assert [
        item for item in sigrok[C] + sigrok[B] if re.search(r" \[(format|unsupported|unpaired)\]$", item)
    ] == [
        "CTRL_BUS 0x77 [unsupported]",
        "OK [unpaired]",
    ]
