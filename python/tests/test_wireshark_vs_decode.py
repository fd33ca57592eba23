# SPDX-License-Identifier: MIT
"""The Wireshark dissector and `ctrlbus decode` say the same about the same capture.

tshark runs tools/wireshark/ctrlbus.lua over a capture and prints its tree (PDML); `ctrlbus
decode --json` prints its annotations. For every frame, both must give the same direction, stream
offset, kind (request / answer), message name, the request an answer answers, the message error
class and every message field with the same value (field names are the contract's, on both
sides); every decoder event must be at the same offset with the same kind (and the same expected
and found checksum); and the decoder counters at the end of each direction must agree.

Two captures: a hand-written conversation (the reference's example frames with garbage, a split
frame, a checksum error, an empty frame and a stray answer), and a noisy session of our Core
emulator and simulated base (test_capture_replay.record_session). Skipped without tshark.
"""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Any

import pytest
from test_capture_replay import EPOCH, NOISE, record_session

from ctrlbus.capture import CaptureWriter, Direction, read_capture

TSHARK = shutil.which("tshark")
ROOT = Path(__file__).resolve().parents[2]
DISSECTOR = ROOT / "tools" / "wireshark" / "ctrlbus.lua"
TIMEOUT_MS = 100  # the same inter-byte timeout on both sides


@pytest.fixture(autouse=True)
def _tshark_is_installed() -> None:
    """scripts/setup.sh installs tshark, so its absence is a broken set-up, not a reason to skip."""
    if TSHARK is None:
        pytest.fail("tshark is not installed: scripts/setup.sh installs it (apt-get install tshark)")


C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE
SYNC = bytes.fromhex("10 01 00 11")

# (direction, hex as read): one record each, 10 ms apart; checksums from the reference or by hand.
CONVERSATION: list[tuple[Direction, str]] = [
    (C, "10 03 F8 10 01 FA"),  # CONNECT_BASE v1
    (B, "50 1D 00 02 72 65 66 20 62 61 73 65 00 00 00 00 14 01 01 00 01 00 00 00 02 00 00 00 03 00 00 00 1F"),
    (C, "AA BB 10 02"),  # garbage, then GET_BASE_STATUS split over two records
    (C, "F8 30 DA"),
    (B, "50 03 00 03 10 00 40 50 03 00"),  # ERROR 0x0010, then the answer split
    (B, "02 50 03 02"),  # 80 %, charging on cable
    (C, "10 02 F8 30 DB"),  # checksum 0xDB, expected 0xDA
    (B, "50 03 00 03 40 00 10"),  # ERROR 0x0040
    (C, "10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27"),  # SET_V vx 0.2, omega 0.5
    (B, "50 12 00 02 00 00 01 00 00 00 FF FF 00 80 00 00 02 D2 04 00 00 15"),
    (C, "10 00 10 10 02 F8 35 DF"),  # a LEN = 0 frame, then GET_AUXILIARY_ANCHOR
    (B, "50 03 00 03 00 80 D0"),  # ERROR 0x8000
    (B, "50 03 00 02 50 03 02"),  # a stray OK: no request outstanding
    (C, "10 03 F8 30 00 DB"),  # GET_BASE_STATUS with an extra byte: a format error
    (B, "50 03 00 03 01 80 D1"),  # ERROR 0x8001
    (C, "10 02 F8 50 BA"),  # POLL_BASE_CMD
    (B, "50 03 00 02 FF 00 AE"),  # nothing pending, SDP Mini form
    (C, "10 03 00 55 55 13"),  # SYNC with filler
    (B, "10 03 00 55 55 13"),  # its copy
    (C, "10 02 F8 21 CB"),  # GET_BASE_CONF_ADV; the blob {x: 1.5, type: sonar}
    (B, "50 0C 00 02 50 02 0E 20 00 00 C0 3F 0B 31 15 F2"),
    (C, "10 04 F8 90 02 00 7E"),  # HEALTH_GET_ERROR 0: warning 0x01020100 "low battery"
    (
        B,
        "50 25 00 02 00 01 02 01 6C 6F 77 20 62 61 74 74 65 72 79"
        " 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 4C",
    ),
]

# Names in the dissector's tree that are not message fields.
_NOT_MESSAGE_FIELDS = (
    "ctrlbus.frame",
    "ctrlbus.msg.",
    "ctrlbus.stream.",
    "ctrlbus.binconf",
    "ctrlbus.expert",
)
_BYTES_FIELDS = ("filler", "data", "blob")


def write_conversation(path: Path) -> None:
    with CaptureWriter.create(path) as capture:
        for number, (direction, text) in enumerate(CONVERSATION):
            capture.write(direction, bytes.fromhex(text), EPOCH + number * 0.01)


def close_out(path: Path) -> None:
    """Add a SYNC in each direction a second after the end: any partial frame left times out in
    both tools (which apply the timeout when a direction's next record arrives), so the end of
    the input holds nothing that only `ctrlbus decode`'s end-of-input flush would show."""
    records = read_capture(path)
    end = max(record.time for record in records) + 1.0
    with CaptureWriter.create(path) as capture:
        for record in records:
            capture.write(record.direction, record.data, record.time)
        capture.write(C, SYNC, end)
        capture.write(B, SYNC, end + 0.001)


def tshark_tree(path: Path) -> ET.Element:
    assert TSHARK is not None
    result = subprocess.run(
        [
            TSHARK,
            "-X",
            f"lua_script:{DISSECTOR}",
            "-o",
            f"ctrlbus.timeout_ms:{TIMEOUT_MS}",
            "-r",
            str(path),
            "-T",
            "pdml",
        ],
        capture_output=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr.decode(errors="replace")
    assert b"Lua: Error" not in result.stderr, result.stderr.decode(errors="replace")
    return ET.fromstring(result.stdout)


def _children(element: ET.Element, name: str) -> list[ET.Element]:
    return [child for child in element if child.get("name") == name]


def _show(element: ET.Element, name: str) -> str | None:
    found = _children(element, name)
    return found[0].get("show") if found else None


def dissector_view(
    path: Path,
) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]], dict[int, dict[str, int]]]:
    """(frames, events, last counters per direction) as the dissector shows them."""
    frames: list[tuple[Any, ...]] = []
    events: list[tuple[Any, ...]] = []
    counters: dict[int, dict[str, int]] = {}
    for packet in tshark_tree(path).iter("packet"):
        proto = next(p for p in packet.iter("proto") if p.get("name") == "ctrlbus")
        direction = int(_show(proto, "ctrlbus.direction") or "-1")
        for element in proto.iter():
            name = element.get("name")
            if name == "ctrlbus.frame":
                fields = [
                    (str(field.get("name"))[len("ctrlbus.") :], field.get("show"))
                    for field in element.iter()
                    if field is not element
                    and not str(field.get("name")).startswith(_NOT_MESSAGE_FIELDS)
                    and str(field.get("name")).startswith("ctrlbus.")
                ]
                frames.append(
                    (
                        direction,
                        int(_show(element, "ctrlbus.stream.offset") or "-1"),
                        _show(element, "ctrlbus.msg.kind"),
                        _show(element, "ctrlbus.msg.name"),
                        _show(element, "ctrlbus.msg.to"),
                        _show(element, "ctrlbus.msg.error"),
                        fields,
                    )
                )
            event = _show(element, "ctrlbus.stream.event")
            if event is not None:
                expected = _show(element, "ctrlbus.stream.checksum_expected")
                found = _show(element, "ctrlbus.stream.checksum_found")
                events.append(
                    (
                        direction,
                        int(_show(element, "ctrlbus.stream.offset") or "-1"),
                        event,
                        None if expected is None else int(expected, 0),
                        None if found is None else int(found, 0),
                    )
                )
            if _children(element, "ctrlbus.counters.frames"):  # counters after this record
                counters[direction] = {
                    str(child.get("name"))[len("ctrlbus.counters.") :]: int(child.get("show") or "0")
                    for child in element
                    if str(child.get("name")).startswith("ctrlbus.counters.")
                }
    return sorted(frames, key=_order), sorted(events, key=_order), counters


def _order(item: tuple[Any, ...]) -> tuple[int, int]:
    return item[0], item[1]


def _flatten(fields: dict[str, Any] | None) -> list[tuple[str, str]]:
    """The contract's field form as the dissector lists fields: lists element by element, nested
    positions as parent.child, null and empty bytes left out, bytes as lowercase colon hex."""
    out: list[tuple[str, str]] = []
    for key, value in (fields or {}).items():
        if value is None:
            continue
        if key in _BYTES_FIELDS:
            if value:
                out.append((key, value.replace(" ", ":").lower()))
        elif isinstance(value, list):
            for item in value:
                if isinstance(item, dict):
                    out += [(f"{key}.{sub}", str(number)) for sub, number in item.items()]
                else:
                    out.append((key, str(item)))
        else:
            out.append((key, str(value)))
    return out


def decode_view(path: Path) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]], dict[int, dict[str, int]]]:
    """The same, as `ctrlbus decode --json` prints it."""
    result = subprocess.run(
        [sys.executable, "-m", "ctrlbus", "decode", str(path), "--json", "--timeout-ms", str(TIMEOUT_MS)],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert result.returncode == 0, result.stderr
    directions = {"core": int(C), "base": int(B)}
    frames: list[tuple[Any, ...]] = []
    events: list[tuple[Any, ...]] = []
    counters: dict[int, dict[str, int]] = {}
    for line in result.stdout.splitlines():
        record = json.loads(line)
        direction = directions[record["direction"]]
        if record["kind"] == "frame":
            # An OK with no request to read it by: decode says "unpaired", the dissector classes it
            # as unsupported (and flags it unpaired in its expert info).
            error = "unsupported" if record["error"] == "unpaired" else record["error"]
            # decode may read such an OK by its size (`guess`); the dissector does not guess.
            guessed = record["guess"] is not None
            frames.append(
                (
                    direction,
                    record["offset"],
                    record["role"],
                    record["name"],
                    record["to"],
                    error,
                    [] if guessed else _flatten(record["fields"]),
                )
            )
        elif record["kind"] == "rejected":
            assert record["reason"] != "incomplete"  # close_out() leaves nothing to flush
            if record["reason"] != "silent":
                events.append(
                    (
                        direction,
                        record["offset"],
                        record["reason"],
                        record["expected_checksum"],
                        record["found_checksum"],
                    )
                )
        else:
            counters[direction] = record["counters"]
    return sorted(frames, key=_order), sorted(events, key=_order), counters


def compare(path: Path) -> None:
    seen_frames, seen_events, seen_counters = dissector_view(path)
    frames, events, counters = decode_view(path)
    assert len(seen_frames) == len(frames)
    for theirs, ours in zip(seen_frames, frames, strict=True):
        assert theirs == ours
    assert seen_events == events
    assert seen_counters == counters


def test_hand_written_conversation(tmp_path: Path) -> None:
    path = tmp_path / "conversation.pcap"
    write_conversation(path)
    close_out(path)
    compare(path)


def test_noisy_session_of_the_core_emulator_and_the_simulated_base(tmp_path: Path) -> None:
    path = tmp_path / "noisy.pcap"
    record_session(path, seconds=6.0, noise=NOISE)
    close_out(path)
    compare(path)
