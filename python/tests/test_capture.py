# SPDX-License-Identifier: MIT
"""Capture files: the exact pcap bytes, reading every pcap variant, damage and live growth."""

from __future__ import annotations

import io
import struct
from pathlib import Path

import pytest

from ctrlbus.capture import (
    MAX_CHUNK,
    CaptureReader,
    CaptureRecord,
    CaptureWriter,
    Direction,
    looks_like_capture,
    read_capture,
)
from ctrlbus.errors import CaptureError, CtrlbusError

# Global header: magic (microseconds, little-endian), version 2.4, zone 0, sigfigs 0,
# snaplen 65535, link type 147.
HEADER_HEX = "D4 C3 B2 A1 02 00 04 00 00 00 00 00 00 00 00 00 FF FF 00 00 93 00 00 00"


def hexbytes(text: str) -> bytes:
    return bytes.fromhex(text)


def records_of(data: bytes, *, strict: bool = False) -> list[CaptureRecord]:
    return list(CaptureReader(io.BytesIO(data), strict=strict))


def test_writer_produces_the_documented_bytes() -> None:
    stream = io.BytesIO()
    writer = CaptureWriter(stream)
    writer.write(Direction.CORE_TO_BASE, hexbytes("10 02 F8 30 DA"), 1.5)
    writer.write(Direction.BASE_TO_CORE, hexbytes("50 03"), 2.000001)
    writer.write(Direction.BASE_TO_CORE, b"", 3.0)  # nothing to record
    expected = hexbytes(
        HEADER_HEX
        + " 01 00 00 00  20 A1 07 00  06 00 00 00  06 00 00 00  00 10 02 F8 30 DA"
        + " 02 00 00 00  01 00 00 00  03 00 00 00  03 00 00 00  01 50 03"
    )
    assert stream.getvalue() == expected


def test_written_records_read_back(tmp_path: Path) -> None:
    path = tmp_path / "c.pcap"
    chunks = [
        (Direction.CORE_TO_BASE, hexbytes("10 01 00 11"), 1_700_000_000.25),
        (Direction.BASE_TO_CORE, hexbytes("10 01"), 1_700_000_000.251),
        (Direction.BASE_TO_CORE, hexbytes("00 11"), 1_700_000_000.252),
    ]
    with CaptureWriter.create(path) as writer:
        for direction, data, time in chunks:
            writer.write(direction, data, time)
    records = read_capture(path)
    assert [(r.direction, r.data) for r in records] == [(d, data) for d, data, _ in chunks]
    assert [r.time_ns for r in records] == [
        1_700_000_000_250_000_000,
        1_700_000_000_251_000_000,
        1_700_000_000_252_000_000,
    ]
    assert records[0].time == pytest.approx(1_700_000_000.25)
    assert records[1].offset == 24 + 16 + 5
    assert looks_like_capture(path.read_bytes())


def test_a_long_chunk_becomes_several_records() -> None:
    stream = io.BytesIO()
    data = bytes(range(256)) * 300  # 76 800 bytes
    CaptureWriter(stream).write(1, data, 7.0)
    records = records_of(stream.getvalue())
    assert [len(r.data) for r in records] == [MAX_CHUNK, len(data) - MAX_CHUNK]
    assert b"".join(r.data for r in records) == data
    assert {r.time_ns for r in records} == {7_000_000_000}


def test_big_endian_nanosecond_files_are_read() -> None:
    data = hexbytes(
        "A1 B2 3C 4D 00 02 00 04 00 00 00 00 00 00 00 00 00 04 00 00 00 00 00 93"
        + " 00 00 00 05  00 00 00 07  00 00 00 03  00 00 00 03  01 AA BB"
        + " 00 00 00 06  3B 9A C9 FF  00 00 00 01  00 00 00 01  00"
    )
    records = records_of(data)
    assert records == [
        CaptureRecord(5_000_000_007, Direction.BASE_TO_CORE, hexbytes("AA BB"), 24),
        CaptureRecord(6_999_999_999, Direction.CORE_TO_BASE, b"", 43),
    ]


def test_little_endian_nanosecond_and_big_endian_microsecond_files_are_read() -> None:
    le_ns = hexbytes(
        "4D 3C B2 A1 02 00 04 00 00 00 00 00 00 00 00 00 FF FF 00 00 93 00 00 00"
        + " 01 00 00 00  02 00 00 00  02 00 00 00  02 00 00 00  00 42"
    )
    assert records_of(le_ns)[0].time_ns == 1_000_000_002
    be_us = hexbytes(
        "A1 B2 C3 D4 00 02 00 04 00 00 00 00 00 00 00 00 00 00 FF FF 00 00 00 93"
        + " 00 00 00 01  00 00 00 02  00 00 00 02  00 00 00 02  01 42"
    )
    assert records_of(be_us)[0] == CaptureRecord(1_000_002_000, Direction.BASE_TO_CORE, b"\x42", 24)


@pytest.mark.parametrize(
    ("data", "words"),
    [
        (b"", "too short"),
        (hexbytes("D4 C3 B2 A1 02 00"), "too short"),
        (b"10 02 F8 30 DA\n" * 3, "not a pcap"),
        (hexbytes("0A 0D 0D 0A") + bytes(40), "pcapng"),
        (hexbytes(HEADER_HEX)[:20] + hexbytes("01 00 00 00"), "link type 1 is not"),
        (hexbytes("D4 C3 B2 A1 01 00 00 00") + hexbytes(HEADER_HEX)[8:], "version 1.0"),
    ],
)
def test_bad_headers_are_refused(data: bytes, words: str) -> None:
    with pytest.raises(CaptureError, match=words):
        CaptureReader(io.BytesIO(data))


@pytest.mark.parametrize(
    ("record", "words"),
    [
        ("00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00", "empty"),
        ("00 00 00 00 00 00 00 00 02 00 00 00 02 00 00 00 02 10", "direction byte 2"),
        ("00 00 00 00 00 00 00 00 02 00 00 00 09 00 00 00 00 10", "2 of the chunk's 9 bytes"),
        ("00 00 00 00 00 00 00 00 00 00 00 7F 00 00 00 7F", "claims 2130706432 bytes"),
    ],
)
def test_damaged_records_name_their_offset(record: str, words: str) -> None:
    good = "00 00 00 00 00 00 00 00 01 00 00 00 01 00 00 00 00"
    data = hexbytes(HEADER_HEX + " " + good + " " + record)
    reader = CaptureReader(io.BytesIO(data))
    records = iter(reader)
    assert next(records).data == b""
    with pytest.raises(CaptureError, match=words) as caught:
        next(records)
    assert "offset 41" in str(caught.value)


def test_truncated_final_record_is_reported_or_refused() -> None:
    stream = io.BytesIO()
    writer = CaptureWriter(stream)
    writer.write(0, b"\x10\x01\x00\x11", 1.0)
    writer.write(1, b"\x10\x01\x00\x11", 2.0)
    cut = stream.getvalue()[:-2]
    reader = CaptureReader(io.BytesIO(cut))
    assert [r.data for r in reader] == [b"\x10\x01\x00\x11"]
    assert reader.truncated_tail == 16 + 5 - 2
    with pytest.raises(CaptureError, match="cut short"):
        records_of(cut, strict=True)
    header_only = stream.getvalue()[:24]
    assert records_of(header_only, strict=True) == []


def test_a_growing_live_capture_is_followed(tmp_path: Path) -> None:
    path = tmp_path / "live.pcap"
    writer = CaptureWriter.create(path)
    writer.write(Direction.CORE_TO_BASE, b"\x10\x02\xf8\x30\xda", 10.0)
    with CaptureReader.open(path) as reader:
        assert [r.data for r in reader] == [b"\x10\x02\xf8\x30\xda"]
        # a record half written by someone else: the reader waits for the rest
        with open(path, "ab") as raw:
            raw.write(struct.pack("<IIII", 11, 0, 3, 3) + b"\x01")
        assert list(reader) == []
        assert reader.truncated_tail == 17
        with open(path, "ab") as raw:
            raw.write(b"\x50\x01")
        assert [(r.direction, r.data, r.time_ns) for r in reader] == [
            (Direction.BASE_TO_CORE, b"\x50\x01", 11_000_000_000)
        ]
        assert reader.truncated_tail == 0
    writer.close()


def test_writer_refuses_bad_arguments() -> None:
    writer = CaptureWriter(io.BytesIO())
    with pytest.raises(CaptureError, match="direction"):
        writer.write(2, b"x", 1.0)
    with pytest.raises(CaptureError, match="time"):
        writer.write(0, b"x", -1.0)
    with pytest.raises(CaptureError, match="time"):
        writer.write(0, b"x", float("nan"))
    writer.close()
    with pytest.raises(CaptureError, match="closed"):
        writer.write(0, b"x", 1.0)
    assert issubclass(CaptureError, CtrlbusError)


def test_looks_like_capture() -> None:
    assert looks_like_capture(hexbytes(HEADER_HEX))
    assert looks_like_capture(hexbytes("A1 B2 3C 4D"))
    assert not looks_like_capture(b"50 03 00 02")
    assert not looks_like_capture(b"\xd4\xc3")
