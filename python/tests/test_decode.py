# SPDX-License-Identifier: MIT
"""`ctrlbus decode` and the annotation engine behind it (ctrlbus.annotate).

The frames are written by hand (the reference's §6 examples, and a few more whose checksums were
worked out by hand), never produced by our encoder.
"""

from __future__ import annotations

import functools
import io
import json
import operator
import os
import pty
import random
import select
import struct
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

from ctrlbus.annotate import Annotation, Annotator, FrameNote, Rejection, format_annotation
from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.cli import main
from ctrlbus.cli.decode_cmd import decode_bytes, detect_format
from ctrlbus.frame import StreamDecoder

C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE

# The reference's example frames (control-bus.md §6), as request / answer pairs where the reference
# gives the answer, in one stream of unknown direction. Requests the reference does not list are
# marked; their checksums were computed by hand.
REFERENCE_STREAM = """
10 01 00 11                                     # SYNC, no filler
10 01 00 11                                     # its answer: the same bytes
10 03 01 AA 55 ED                               # ECHO AA 55
50 03 00 01 AA 55 AD                            # the same as a long frame
10 03 F8 10 01 FA                               # CONNECT_BASE v1
10 02 F8 30 DA                                  # GET_BASE_STATUS
50 03 00 02 50 03 02                            # status: 80 %, charging on cable
50 02 00 F8 30 9A                               # GET_BASE_STATUS, long
10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27   # SET_V vx 0.2 m/s, omega 0.5 rad/s
10 03 F8 60 63 E8                               # (ours) SEND_EVENT SYSTEM_UP_OK
50 01 00 02 53                                  # OK, empty
10 02 F8 50 BA                                  # (ours) POLL_BASE_CMD
50 03 00 02 FF 00 AE                            # nothing pending, SDP Mini form
10 03 F8 90 01 7A                               # (ours) HEALTH_GET_HEALTH
50 03 00 02 00 00 51                            # health: all well
10 02 F8 35 DF                                  # (ours) GET_AUXILIARY_ANCHOR
50 03 00 03 00 80 D0                            # ERROR 0x8000
50 03 00 03 20 00 70                            # ERROR 0x0020
"""


def run_decode(
    capsys: pytest.CaptureFixture[str], *args: str, stdin: bytes | None = None, monkeypatch: Any = None
) -> tuple[int, str, str]:
    if stdin is not None:
        monkeypatch.setattr("sys.stdin", io.TextIOWrapper(io.BytesIO(stdin)))
    code = main(["decode", *args])
    out, err = capsys.readouterr()
    return code, out, err


def frame_lines(out: str) -> list[str]:
    return [line for line in out.splitlines() if not line.startswith("#")]


def json_lines(out: str) -> list[dict[str, Any]]:
    return [json.loads(line) for line in out.splitlines()]


def write_hex(tmp_path: Path, text: str, name: str = "input.txt") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


# --- the reference examples --------------------------------------------------------------------


def test_reference_examples_print_names_values_and_pairs(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, err = run_decode(capsys, str(write_hex(tmp_path, REFERENCE_STREAM)), "--color", "never")
    assert (code, err) == (0, "")
    lines = frame_lines(out)
    expected = [
        ("@0 ", "std  SYNC: filler 0 bytes", "read as a request"),
        ("@4 ", "std  SYNC to SYNC @0: filler 0 bytes", "read as its answer"),
        ("@8 ", "std  ECHO: data 2 bytes: AA 55", "read as a request"),
        ("@14 ", "long ECHO: data 2 bytes: AA 55", ""),
        ("@21 ", "std  CTRL_BUS CONNECT_BASE: protocol_version 1", ""),
        ("@27 ", "std  CTRL_BUS GET_BASE_STATUS", ""),
        (
            "@32 ",
            "long OK to GET_BASE_STATUS @27: battery 80 %, power_status 0x03 (charging, DC connected)",
            "",
        ),
        ("@39 ", "long CTRL_BUS GET_BASE_STATUS", ""),
        ("@45 ", "std  CTRL_BUS SET_V_AND_GET_DEADRECKON: vx 0.200 m/s, vy 0.000 m/s, omega 0.500 rad/s", ""),
        ("@62 ", "std  CTRL_BUS SEND_EVENT: event 0x63 SYSTEM_UP_OK", ""),
        ("@68 ", "long OK to SEND_EVENT @62", ""),
        ("@73 ", "std  CTRL_BUS POLL_BASE_CMD", ""),
        ("@78 ", "long OK to POLL_BASE_CMD @73: command none, payload_size 2, pad 0", ""),
        ("@85 ", "std  CTRL_BUS HEALTH_GET_HEALTH", ""),
        ("@91 ", "long OK to HEALTH_GET_HEALTH @85: flags 0x00 (all well), error_count 0", ""),
        ("@98 ", "std  CTRL_BUS GET_AUXILIARY_ANCHOR", ""),
        ("@103 ", "long ERROR to GET_AUXILIARY_ANCHOR @98: error_code 0x8000 (not supported)", ""),
        ("@110 ", "long ERROR: error_code 0x0020 (request too long)", "answers bytes on the line"),
    ]
    assert len(lines) == len(expected), out
    for line, (offset, text, note) in zip(lines, expected, strict=True):
        assert line.startswith(offset), line
        assert text in line, f"{text!r} not in {line!r}"
        assert note in line, f"{note!r} not in {line!r}"
    assert "# 18 frames, 0 bytes discarded" in out


def test_reference_examples_as_json_carry_the_contract_fields(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_decode(capsys, str(write_hex(tmp_path, REFERENCE_STREAM)), "--json")
    assert code == 0
    records = json_lines(out)
    frames = [record for record in records if record["kind"] == "frame"]
    by_offset = {record["offset"]: record for record in frames}
    set_v = by_offset[45]
    assert (set_v["role"], set_v["name"], set_v["cmd"], set_v["request_code"], set_v["long"]) == (
        "request",
        "SET_V_AND_GET_DEADRECKON",
        0xF8,
        0x41,
        False,
    )
    assert set_v["fields"] == {"vx_mps_q16": 13107, "vy_mps_q16": 0, "omega_radps_q16": 32768}
    assert set_v["values"]["vx_mps"] == pytest.approx(0.2, abs=1e-4)
    assert set_v["values"]["omega_radps"] == 0.5
    assert set_v["hex"] == "10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27"
    status = by_offset[32]
    assert (status["role"], status["name"], status["to"], status["request_offset"]) == (
        "answer",
        "OK",
        "GET_BASE_STATUS",
        27,
    )
    assert status["fields"] == {"battery_percent": 80, "power_status": 3}
    poll = by_offset[78]
    assert poll["fields"] == {"command": None, "payload_size": 2, "pad": 0}
    line_fault = by_offset[110]
    assert (line_fault["name"], line_fault["to"], line_fault["fields"]) == (
        "ERROR",
        None,
        {"error_code": 0x20},
    )
    assert by_offset[4]["ambiguous"] and by_offset[4]["role"] == "answer"
    assert by_offset[0]["ambiguous"] and by_offset[0]["role"] == "request"
    summary = records[-1]
    assert summary == {
        "kind": "summary",
        "direction": None,
        "counters": {
            "frames": 18,
            "bytes_discarded": 0,
            "checksum_errors": 0,
            "oversize": 0,
            "timeouts": 0,
            "empty_frames": 0,
            "resyncs": 0,
        },
    }
    documented = {
        "kind",
        "direction",
        "offset",
        "size",
        "time",
        "long",
        "cmd",
        "cmd_name",
        "hex",
        "role",
        "ambiguous",
        "name",
        "request_code",
        "to",
        "request_offset",
        "fields",
        "values",
        "error",
        "error_message",
        "notes",
        "guess",
    }
    assert all(set(record) == documented for record in frames)


def test_other_answer_layouts_have_units_and_names() -> None:
    # CONNECT_BASE answer from "ref base", firmware 1.20, and a 17-byte deadreckon answer
    # (dx 1.0 mm, dy -1.0 mm, dtheta 0.5 deg, stall, 1234 ms), each after its request.
    stream = bytes.fromhex(
        "10 03 F8 10 01 FA"
        "50 1D 00 02 72 65 66 20 62 61 73 65 00 00 00 00 14 01 01 00 01 00 00 00 02 00 00 00 03 00 00 00 1F"
        "10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27"
        "50 12 00 02 00 00 01 00 00 00 FF FF 00 80 00 00 02 D2 04 00 00 15"
    )
    annotator = Annotator()
    entries = annotator.feed(stream) + annotator.finish()
    text = [format_annotation(entry) for entry in entries]
    assert "model 'ref base', firmware_version 0x0114 (1.20), hardware_version 1" in text[1]
    assert "serial 000000010000000200000003, firmware_version_suffix none" in text[1]
    assert (
        "dx 1.000 mm, dy -1.000 mm, dtheta 0.500 deg, status 0x02 (wheel stall), timestamp 1234 ms" in text[3]
    )


def test_a_binary_configuration_is_shown_as_its_tree() -> None:
    # GET_BASE_CONF_ADV and a blob {x: 1.5 (float32), type: sonar (dictionary id)}, then a blob
    # that is not a configuration (its root is not an object).
    stream = bytes.fromhex(
        "10 02 F8 21 CB  50 0C 00 02 50 02 0E 20 00 00 C0 3F 0B 31 15 F210 02 F8 21 CB  50 03 00 02 51 00 00"
    )
    annotator = Annotator()
    entries = annotator.feed(stream) + annotator.finish()
    good, bad = entries[1].to_json(), entries[3].to_json()
    assert good["fields"] == {"blob": "50 02 0E 20 00 00 C0 3F 0B 31 15"}
    assert good["values"]["config"] == {"x": 1.5, "type": {"dict": "sonar"}}
    assert 'config {"x": 1.5, "type": {"dict": "sonar"}}' in format_annotation(entries[1])
    assert bad["values"]["config"] is None and "root must be an object" in bad["values"]["config_error"]
    assert "not a configuration" in format_annotation(entries[3])


# --- directions and pairing --------------------------------------------------------------------


def test_direction_base_reads_every_frame_as_an_answer(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    answers = "10 01 00 11  50 03 00 02 50 03 02  50 03 00 03 00 80 D0"
    code, out, _ = run_decode(capsys, str(write_hex(tmp_path, answers)), "--direction", "base", "--json")
    assert code == 0
    frames = [record for record in json_lines(out) if record["kind"] == "frame"]
    assert [(f["direction"], f["role"], f["name"], f["ambiguous"]) for f in frames] == [
        ("base", "answer", "SYNC", False),
        ("base", "answer", "OK", False),
        ("base", "answer", "ERROR", False),
    ]
    assert frames[1]["error"] == "unpaired" and frames[1]["fields"] is None
    assert frames[2]["fields"] == {"error_code": 0x8000}


def test_direction_core_reads_sync_as_a_request_without_ambiguity(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_decode(
        capsys, str(write_hex(tmp_path, "10 01 00 11 10 01 00 11")), "--direction", "core"
    )
    assert code == 0
    lines = frame_lines(out)
    assert len(lines) == 2 and all("core→base" in line and "ambiguous" not in line for line in lines)
    assert all("got no answer" not in line for line in lines)  # no answers seen: nothing to expect


def test_pairing_in_a_capture_and_line_fault_errors_keep_the_request(tmp_path: Path) -> None:
    path = tmp_path / "pairs.pcap"
    with CaptureWriter.create(path) as capture:
        capture.write(C, bytes.fromhex("10 02 F8 30 DA"), 100.0)  # GET_BASE_STATUS
        capture.write(B, bytes.fromhex("50 03 00 03 10 00 40"), 100.001)  # ERROR 0x0010: a line fault
        capture.write(B, bytes.fromhex("50 03 00"), 100.002)  # the answer, in two chunks
        capture.write(B, bytes.fromhex("02 50 03 02"), 100.003)
        capture.write(B, bytes.fromhex("50 03 00 03 00 80 D0"), 100.004)  # a stray ERROR
        capture.write(C, bytes.fromhex("10 03 F8 30 00 DB"), 100.010)  # GET_BASE_STATUS + extra byte
        capture.write(B, bytes.fromhex("50 03 00 03 01 80 D1"), 100.011)  # ERROR 0x8001
    result = decode_bytes(path.read_bytes())
    entries, warnings = result.entries, result.warnings
    assert warnings == []
    frames = [entry for entry in entries if isinstance(entry, FrameNote)]
    summary = [(e.direction, e.role.value, e.name, e.to, e.request_offset, e.error) for e in frames]
    assert summary == [
        (C, "request", "GET_BASE_STATUS", None, None, None),
        (B, "answer", "ERROR", None, None, None),
        (B, "answer", "OK", "GET_BASE_STATUS", 0, None),
        (B, "answer", "ERROR", None, None, None),
        (C, "request", "GET_BASE_STATUS", None, None, "format"),
        (B, "answer", "ERROR", "GET_BASE_STATUS", 5, None),
    ]
    assert frames[2].time == pytest.approx(100.003) and frames[2].request_time == pytest.approx(100.0)
    assert "still waiting" in frames[1].notes[0]
    assert frames[3].notes == ("no request outstanding",)
    assert "1 argument bytes, expected 0" in (frames[4].error_message or "")


@pytest.mark.parametrize("code", [0x0030, 0x0090, 0x00D0, 0x00F0])
def test_the_references_combined_line_fault_codes_keep_the_request(tmp_path: Path, code: int) -> None:
    """Every ERROR code below 0x0100 is a line fault (protocol §11.6), not only the four plain ones."""
    error = bytes([0x50, 0x03, 0x00, 0x03, code & 0xFF, code >> 8])
    error += bytes([functools.reduce(operator.xor, error, 0)])
    path = tmp_path / "combined.pcap"
    with CaptureWriter.create(path) as capture:
        capture.write(C, bytes.fromhex("10 02 F8 30 DA"), 1.0)  # GET_BASE_STATUS
        capture.write(B, error, 1.001)
        capture.write(B, bytes.fromhex("50 03 00 02 50 03 02"), 1.002)
    frames = [e for e in decode_bytes(path.read_bytes()).entries if isinstance(e, FrameNote)]
    assert [(e.name, e.to) for e in frames] == [
        ("GET_BASE_STATUS", None),
        ("ERROR", None),
        ("OK", "GET_BASE_STATUS"),
    ]


def test_sync_answer_that_is_not_a_copy_is_flagged(tmp_path: Path) -> None:
    path = tmp_path / "sync.pcap"
    with CaptureWriter.create(path) as capture:
        capture.write(C, bytes.fromhex("10 03 00 55 55 13"), 1.0)
        capture.write(B, bytes.fromhex("10 01 00 11"), 1.1)
    entries = decode_bytes(path.read_bytes()).entries
    answer = entries[1]
    assert isinstance(answer, FrameNote) and answer.to == "SYNC"
    assert "not a copy of the request" in answer.notes


# --- rejections ------------------------------------------------------------------------------


def test_rejections_have_offsets_counts_and_reasons(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    stream = (
        "AA BB CC "  # garbage
        "10 02 F8 30 DA "  # GET_BASE_STATUS
        "10 02 F8 30 DB "  # checksum 0xDB, expected 0xDA
        "10 00 10 "  # LEN = 0 frame
        "10 02 F8 30 DA "
        "50 FF FF "  # a long header announcing 65539 + ... bytes: oversize with --max-frame 512
        "10 02 F8 30 DA"
    )
    code, out, _ = run_decode(capsys, str(write_hex(tmp_path, stream)), "--max-frame", "512", "--json")
    assert code == 0
    records = json_lines(out)
    rejected = [r for r in records if r["kind"] == "rejected"]
    assert [(r["offset"], r["size"], r["reason"]) for r in rejected] == [
        (0, 3, "garbage"),
        (8, 5, "checksum_error"),
        (13, 3, "empty_frame"),
        (21, 3, "oversize"),  # the flag, and the FF FF discarded (silently) after it
    ]
    assert rejected[0]["bytes"] == "AA BB CC"
    assert (rejected[1]["expected_checksum"], rejected[1]["found_checksum"]) == (0xDA, 0xDB)
    assert rejected[3]["declared_size"] == 3 + 0xFFFF + 1
    frames = [r for r in records if r["kind"] == "frame"]
    assert [f["offset"] for f in frames] == [3, 16, 24]
    assert records[-1]["counters"]["bytes_discarded"] == 14


def test_bytes_after_a_frame_inside_a_failed_span_are_rejected_silently() -> None:
    # 10 07 announces 10 bytes whose checksum (00) is wrong (expected BD); GET_BASE_STATUS inside
    # it is found by backtracking, and AA 00 00 after it, still inside the span, raise no event.
    annotator = Annotator()
    entries = annotator.feed(bytes.fromhex("10 07 10 02 F8 30 DA AA 00 00 10 02 F8 30 DA"))
    entries += annotator.finish()
    summary = [
        (entry.offset, entry.size, entry.reason.value if isinstance(entry, Rejection) else "frame")
        for entry in entries
    ]
    assert summary == [(0, 2, "checksum_error"), (2, 5, "frame"), (7, 3, "silent"), (10, 5, "frame")]
    failure = entries[0]
    assert isinstance(failure, Rejection)
    assert (failure.expected_checksum, failure.found_checksum) == (0xBD, 0x00)
    assert "discarded silently" in format_annotation(entries[2])


def test_rejections_in_text_name_expected_and_found(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_decode(capsys, str(write_hex(tmp_path, "AA BB 10 02 F8 30 DB")), "--color", "never")
    assert code == 0
    lines = frame_lines(out)
    assert lines[0] == "@0      rejected garbage: 2 bytes discarded  [AA BB]"
    assert lines[1] == (
        "@2      rejected checksum error: checksum 0xDB, expected 0xDA; 5 bytes discarded  [10 02 F8 30 DB]"
    )


def test_end_of_input_inside_a_false_start_still_shows_the_frames_behind_it(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # 50 10 02 announces a long frame of 0x0210 bytes that never comes; the real frame is behind it.
    code, out, _ = run_decode(capsys, str(write_hex(tmp_path, "50 10 02 F8 30 DA")), "--json")
    assert code == 0
    records = json_lines(out)
    assert [(r["kind"], r["offset"], r["size"]) for r in records[:2]] == [("rejected", 0, 1), ("frame", 1, 5)]
    assert records[0]["reason"] == "incomplete"
    # The counters are the decoder's, before that end-of-input flush (the contract has no flush).
    assert records[-1]["counters"]["frames"] == 0


def test_capture_timeout_uses_the_chunk_times(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = tmp_path / "slow.pcap"
    with CaptureWriter.create(path) as capture:
        capture.write(C, bytes.fromhex("10 02 F8"), 10.0)
        capture.write(C, bytes.fromhex("30 DA"), 10.5)  # 500 ms later: past the 100 ms default
        capture.write(C, bytes.fromhex("10 02 F8 30 DA"), 10.6)
    code, out, _ = run_decode(capsys, str(path), "--json")
    assert code == 0
    records = json_lines(out)
    # The timeout's gap runs to the next frame: the stale 10 02 F8 and the 30 DA after them.
    assert [(r["kind"], r.get("reason"), r["offset"], r["size"]) for r in records[:2]] == [
        ("rejected", "timeout", 0, 5),
        ("frame", None, 5, 5),
    ]
    assert records[0]["time"] == pytest.approx(10.5)
    _, text, _ = run_decode(capsys, str(path), "--color", "never")
    assert frame_lines(text)[0].startswith("  0.500000 core→base @0      rejected timeout")
    code, out, _ = run_decode(capsys, str(path), "--json", "--timeout-ms", "0")
    frames = [r for r in json_lines(out) if r["kind"] == "frame"]
    assert [f["offset"] for f in frames] == [0, 5]


def noisy_stream(seed: int) -> bytes:
    """Valid frames (hand-checked ones from this file) with random garbage, cuts and bit flips."""
    pieces = [bytes.fromhex(line.split("#")[0]) for line in REFERENCE_STREAM.strip().splitlines()]
    rng = random.Random(seed)
    out = bytearray()
    for _ in range(60):
        piece = bytearray(rng.choice(pieces))
        roll = rng.random()
        if roll < 0.15:
            piece[rng.randrange(len(piece))] ^= 1 << rng.randrange(8)
        elif roll < 0.25:
            del piece[rng.randrange(len(piece)) :]
        elif roll < 0.35:
            out += rng.randbytes(rng.randint(1, 12))
        out += piece
    return bytes(out)


@pytest.mark.parametrize("seed", range(8))
def test_every_byte_is_accounted_for_once_in_order(seed: int) -> None:
    data = noisy_stream(seed)
    rng = random.Random(seed)
    annotator = Annotator()
    entries: list[Annotation] = []
    at = 0
    while at < len(data):  # in random pieces: the result must not depend on them
        size = rng.randint(1, 40)
        entries += annotator.feed(data[at : at + size])
        at += size
    entries += annotator.finish()
    offset = 0
    for entry in sorted(entries, key=lambda item: item.offset):
        assert entry.offset == offset, (seed, entry)
        offset += entry.size
    assert offset == len(data)
    # The same bytes through a bare decoder, flushed at the end as finish() does.
    reference = StreamDecoder(timeout=1.0)
    expected = reference.feed(data)
    before_flush = reference.stats
    expected += reference.feed(b"", 0.0) + reference.feed(b"", 10.0)
    found = [(entry.offset, entry.frame.raw) for entry in entries if isinstance(entry, FrameNote)]
    assert found == [(frame.offset, frame.raw) for frame in expected]
    assert annotator.stats() == before_flush
    rejected = sum(entry.size for entry in entries if isinstance(entry, Rejection))
    assert rejected == reference.stats.bytes_discarded


# --- input formats, colour and errors ------------------------------------------------------------


def test_hex_text_forms_and_raw_bytes_decode_alike(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    raw = bytes.fromhex("10 02 F8 30 DA 50 03 00 02 50 03 02")
    forms = {
        "spaced.txt": "10 02 F8 30 DA\n50 03 00 02 50 03 02\n",
        "prefixed.txt": "0x10, 0x02, 0xF8, 0x30, 0xDA,\n0x50,0x03,0x00,0x02,0x50,0x03,0x02",
        "packed.txt": "1002f830da # a comment\n50030002500302",
    }
    outputs = set()
    for name, text in forms.items():
        code, out, _ = run_decode(capsys, str(write_hex(tmp_path, text, name)), "--color", "never")
        assert code == 0
        outputs.add(out)
    binary = tmp_path / "raw.bin"
    binary.write_bytes(raw)
    code, out, _ = run_decode(capsys, str(binary), "--color", "never")
    outputs.add(out)
    assert len(outputs) == 1
    assert "OK to GET_BASE_STATUS @0: battery 80 %" in out
    assert detect_format(raw) == "binary"


def test_stdin_is_read_with_a_dash(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = run_decode(capsys, "-", stdin=b"10 02 F8 30 DA", monkeypatch=monkeypatch)
    assert code == 0 and "GET_BASE_STATUS" in out


def test_colour_only_when_asked_or_on_a_terminal(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = str(write_hex(tmp_path, "10 02 F8 30 DB"))
    _, always, _ = run_decode(capsys, path, "--color", "always")
    _, auto, _ = run_decode(capsys, path)  # captured stdout is not a terminal
    _, never, _ = run_decode(capsys, path, "--color", "never")
    assert "\x1b[" in always
    assert "\x1b[" not in auto and auto == never


def test_colour_by_default_on_a_real_terminal(tmp_path: Path) -> None:
    path = str(write_hex(tmp_path, "10 02 F8 30 DA"))
    master, slave = pty.openpty()
    try:
        result = subprocess.run(
            [sys.executable, "-m", "ctrlbus", "decode", path],
            stdout=slave,
            stderr=subprocess.PIPE,
            timeout=60,
            check=False,
        )
        os.close(slave)
        slave = -1
        shown = b""
        while select.select([master], [], [], 0.5)[0]:
            try:
                chunk = os.read(master, 4096)
            except OSError:  # EIO: the terminal's other end is closed and drained
                break
            if not chunk:
                break
            shown += chunk
    finally:
        if slave >= 0:
            os.close(slave)
        os.close(master)
    assert result.returncode == 0, result.stderr
    assert b"GET_BASE_STATUS" in shown and b"\x1b[" in shown, shown


def test_empty_input_decodes_to_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code, out, _ = run_decode(capsys, str(write_hex(tmp_path, "")))
    assert code == 0 and frame_lines(out) == []


def _pcap_header(link_type: int = 147) -> bytes:
    return struct.pack("<IHHiIII", 0xA1B2C3D4, 2, 4, 0, 0, 65535, link_type)


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (b"hello world\n", "not hex text: 'hello' at line 1 column 1"),
        (b"10 02 F8 301", "'301' has an odd number of digits"),
        (b"\x0a\x0d\x0d\x0a" + bytes(20), "pcapng is not supported"),
        (_pcap_header(1), "link type 1 is not a ctrlbus capture"),
        (_pcap_header() + struct.pack("<IIII", 0, 0, 2, 2) + b"\x07\x10", "direction byte 7"),
        (_pcap_header()[:10], "too short for a pcap header"),
    ],
)
def test_bad_input_is_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], content: bytes, message: str
) -> None:
    path = tmp_path / "bad"
    path.write_bytes(content)
    code, out, err = run_decode(capsys, str(path))
    assert code == 2 and out == ""
    assert err.count("\n") == 1 and err.startswith("ctrlbus decode: error: ")
    assert message in err


def test_truncated_capture_is_decoded_with_a_warning(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "cut.pcap"
    with CaptureWriter.create(path) as capture:
        capture.write(C, bytes.fromhex("10 02 F8 30 DA"), 1.0)
        capture.write(C, bytes.fromhex("10 02 F8 30 DA"), 2.0)
    path.write_bytes(path.read_bytes()[:-3])
    code, out, err = run_decode(capsys, str(path))
    assert code == 0
    assert len(frame_lines(out)) == 1
    assert "the last record is cut short" in err


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["/nonexistent/input"], "cannot read /nonexistent/input: No such file or directory"),
        (["--timeout-ms", "soon"], "--timeout-ms wants a number"),
        (["--max-frame", "4"], "--max-frame must be 5..65539"),
        (["--format", "hex", "{binary}"], "is not text"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], options: list[str], message: str
) -> None:
    binary = tmp_path / "binary"
    binary.write_bytes(b"\xff\xfe\x10")
    options = [option.replace("{binary}", str(binary)) for option in options]
    if not any(not option.startswith("-") and "/" in option for option in options):
        options.append(str(write_hex(tmp_path, "10 02 F8 30 DA")))
    code, _, err = run_decode(capsys, *options)
    assert code == 2 and err.count("\n") == 1 and message in err


# --- a lone answer (issue 11) --------------------------------------------------------------------


def test_a_lone_ok_is_read_as_the_request_its_size_makes_unique(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from ctrlbus.messages import ConnectBaseAnswer, GetBaseConfAnswer, answer_frame

    connect = answer_frame(ConnectBaseAnswer("ref base", 0x005A, 1, (1, 2, 3), None), long=True)
    conf = answer_frame(GetBaseConfAnswer(0, 180 * 256, 0, 0, (), 0, ()), long=True)
    status = bytes.fromhex("50 03 00 02 50 03 02")  # 2 bytes: status, health or poll
    path = write_hex(tmp_path, (connect + conf + status).hex(" "))
    code, out, _ = run_decode(capsys, str(path), "--direction", "base", "--json")
    assert code == 0
    frames = [record for record in json_lines(out) if record["kind"] == "frame"]
    assert [(f["guess"], f["error"], f["to"]) for f in frames] == [
        ("CONNECT_BASE", "unpaired", None),
        ("GET_BASE_CONF", "unpaired", None),
        (None, "unpaired", None),
    ]
    assert frames[0]["fields"]["model"] == "ref base"
    assert frames[1]["values"]["base_radius_mm"] == 180.0
    assert frames[2]["fields"] is None
    code, out, _ = run_decode(capsys, str(path), "--direction", "base")
    lines = out.splitlines()
    assert "model 'ref base'" in lines[0] and "a guess: read as the answer to CONNECT_BASE" in lines[0]
    assert "the only request whose OK answer can be these 264 bytes" in lines[1]
    assert "[unpaired]" in lines[2]


def test_printable_ascii_in_a_payload_is_shown(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    from ctrlbus.frame import encode

    unread = encode(0x02, b"\x00\x01ref base\x00\x07", long=True)  # 12 bytes: no request fits
    echo = encode(0x01, b"hello world")
    code, out, _ = run_decode(capsys, "--direction", "base", str(write_hex(tmp_path, (unread + echo).hex())))
    assert code == 0
    first, second = out.splitlines()[:2]
    assert 'text "ref base"' in first
    assert 'text "hello world"' in second
