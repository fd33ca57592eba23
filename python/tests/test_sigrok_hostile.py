# SPDX-License-Identifier: MIT
"""The sigrok decoder on recordings a black-box campaign found it wrong on (issue 25, rows 2, 11).

Row 2: a recording that ends while a candidate is open (`50 FF 00` announces 259 bytes), with
three GET_BASE_STATUS behind it and then idle line: the inter-byte timeout must fire on the idle
time (uart reports idle periods with their sample numbers), so the candidate fails and the three
requests behind it show, as `ctrlbus decode` shows them at the end of its input. Row 11: an OK
answer to a request of unknown kind is read by its size only as a guess, and says so.
"""

from __future__ import annotations

from pathlib import Path

from test_sigrok import (
    BIT_S,
    SAMPLERATE,
    TIMEOUT_MS,
    Record,
    decode_annotations,
    draw_lines,
    sigrok_annotations,
    write_capture,
)

from ctrlbus.capture import Direction

C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE
GET_BASE_STATUS = bytes.fromhex("10 02 F8 30 DA")


def test_a_candidate_open_at_the_end_times_out_on_the_idle_line(tmp_path: Path) -> None:
    records = [Record(C, bytes.fromhex("50 FF 00"), 0.001)]
    start = 0.001 + 3 * 10 * BIT_S
    for _ in range(3):
        start += 0.002
        records.append(Record(C, GET_BASE_STATUS, start))
        start += len(GET_BASE_STATUS) * 10 * BIT_S
    logic = tmp_path / "open.bin"
    idle_s = 0.050  # longer than the timeout (TIMEOUT_MS), then the recording ends
    assert idle_s * 1000 > TIMEOUT_MS
    logic.write_bytes(draw_lines(records) + b"\x03" * round(idle_s * SAMPLERATE))
    capture = tmp_path / "open.pcap"
    write_capture(capture, records)

    sigrok = sigrok_annotations(logic)
    ours = decode_annotations(capture)  # its end-of-input flush ("incomplete") is left out
    assert sigrok[C] == ["timeout", *ours[C]]
    assert ours[C] == ["GET_BASE_STATUS"] * 3


def test_an_ok_to_a_request_of_unknown_kind_is_a_named_guess(tmp_path: Path) -> None:
    unknown = bytes([0x10, 0x02, 0xF8, 0x77, 0x10 ^ 0x02 ^ 0xF8 ^ 0x77])
    connect_answer = bytes.fromhex(  # 28 bytes: only CONNECT_BASE's OK answer is that long
        "50 1D 00 02 72 65 66 20 62 61 73 65 00 00 00 00 14 01 01 00 01 00 00 00 02 00 00 00 03 00 00 00 1F"
    )
    records = [Record(C, unknown, 0.001), Record(B, connect_answer, 0.005)]
    logic = tmp_path / "guess.bin"
    logic.write_bytes(draw_lines(records))
    capture = tmp_path / "guess.pcap"
    write_capture(capture, records)

    sigrok = sigrok_annotations(logic)
    assert sigrok == decode_annotations(capture)
    assert sigrok[B] == [
        "OK (a guess: to CONNECT_BASE): model 'ref base', firmware_version 0x0114 (1.20),"
        " hardware_version 1, serial 000000010000000200000003, firmware_version_suffix none [unpaired]"
    ]
