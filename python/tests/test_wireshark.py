# SPDX-License-Identifier: MIT
"""The Wireshark dissector tools/wireshark/ctrlbus.lua, run by tshark on captures written by
ctrlbus.capture from hand-written frames (checksums worked out by hand, not by our encoder)."""

from __future__ import annotations

import json
import random
import shutil
import struct
import subprocess
from pathlib import Path
from typing import Any

import pytest

from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.frame import DecoderEvent, Frame, StreamDecoder

TSHARK = shutil.which("tshark")
ROOT = Path(__file__).resolve().parents[2]
DISSECTOR = ROOT / "tools" / "wireshark" / "ctrlbus.lua"
STREAM_VECTORS = json.loads((ROOT / "vectors" / "streams.json").read_text(encoding="utf-8"))["streams"]
EPOCH = 1_700_000_000.0


@pytest.fixture(autouse=True)
def _tshark_is_installed() -> None:
    """scripts/setup.sh installs tshark, so its absence is a broken set-up, not a reason to skip."""
    if TSHARK is None:
        pytest.fail("tshark is not installed: scripts/setup.sh installs it (apt-get install tshark)")


C = Direction.CORE_TO_BASE
B = Direction.BASE_TO_CORE

# (direction, hex chunk as read); one pcap record each, 10 ms apart.
CONVERSATION: list[tuple[Direction, str]] = [
    # 1-2: CONNECT_BASE v1 (reference §6) and a 28-byte answer from "ref base", firmware 1.20
    (C, "10 03 F8 10 01 FA"),
    (
        B,
        "50 1D 00 02 72 65 66 20 62 61 73 65 00 00 00 00 14 01 01 00 01 00 00 00 02 00 00 00 03 00 00 00 1F",
    ),
    # 3-6: GET_BASE_STATUS; the answer (80 %, charging on cable) split over three records
    (C, "10 02 F8 30 DA"),
    (B, "50 03"),
    (B, "00 02 50"),
    (B, "03 02"),
    # 7-9: garbage, then GET_BASE_STATUS split; the base answers ERROR 0x0010 and OK in one record
    (C, "AA BB 10 02"),
    (C, "F8 30 DA"),
    (B, "50 03 00 03 10 00 40 50 03 00 02 50 03 02"),
    # 10-11: a request with a bad checksum (0xDB, expected 0xDA) and the base's ERROR 0x0040
    (C, "10 02 F8 30 DB"),
    (B, "50 03 00 03 40 00 10"),
    # 12-13: SET_V_AND_GET_DEADRECKON (reference §6) and a 17-byte answer
    (C, "10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27"),
    (B, "50 12 00 02 00 00 01 00 00 00 FF FF 00 80 00 00 02 D2 04 00 00 15"),
    # 14-15: GET_BASE_CONF_ADV and a blob {x: 1.5, type: sonar}
    (C, "10 02 F8 21 CB"),
    (B, "50 0C 00 02 50 02 0E 20 00 00 C0 3F 0B 31 15 F2"),
    # 16-17: HEALTH_GET_ERROR index 0: warning 0x01020100 "low battery"
    (C, "10 04 F8 90 02 00 7E"),
    (
        B,
        "50 25 00 02 00 01 02 01 6C 6F 77 20 62 61 74 74 65 72 79"
        " 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 00 4C",
    ),
    # 18-19: POLL_BASE_CMD, nothing pending in the SDP Mini form (reference §6)
    (C, "10 02 F8 50 BA"),
    (B, "50 03 00 02 FF 00 AE"),
    # 20-21: GET_BASE_STATUS with an extra byte: a format error, answered ERROR 0x8001
    (C, "10 03 F8 30 00 DB"),
    (B, "50 03 00 03 01 80 D1"),
    # 22-23: SYNC with filler, answered by a copy
    (C, "10 03 00 55 55 13"),
    (B, "10 03 00 55 55 13"),
    # 24-25: GET_BASE_BUMPER_DATA answered with the 2018 one-byte form
    (C, "10 02 F8 33 D9"),
    (B, "50 02 00 02 FC AC"),
    # 26: a LEN = 0 frame (no CMD byte), then GET_AUXILIARY_ANCHOR; 27: ERROR 0x8000
    (C, "10 00 10 10 02 F8 35 DF"),
    (B, "50 03 00 03 00 80 D0"),
]

FIELDS = [
    "frame.number",
    "ctrlbus.direction",
    "ctrlbus.msg.kind",
    "ctrlbus.msg.name",
    "ctrlbus.msg.to",
    "ctrlbus.msg.request_in",
    "ctrlbus.msg.error",
    "ctrlbus.stream.event",
    "ctrlbus.stream.silent",
    "ctrlbus.stream.offset",
    "ctrlbus.stream.checksum_expected",
    "ctrlbus.stream.checksum_found",
    "ctrlbus.stream.discarded",
    "ctrlbus.stream.buffered",
    "ctrlbus.stream.declared_size",
    "ctrlbus.frame.long",
    "ctrlbus.frame.first_packet",
    "ctrlbus.counters.frames",
    "ctrlbus.counters.bytes_discarded",
    "ctrlbus.protocol_version",
    "ctrlbus.model",
    "ctrlbus.firmware_version",
    "ctrlbus.hardware_version",
    "ctrlbus.serial",
    "ctrlbus.firmware_version_suffix",
    "ctrlbus.battery_percent",
    "ctrlbus.power_status",
    "ctrlbus.vx_mps_q16",
    "ctrlbus.vy_mps_q16",
    "ctrlbus.omega_radps_q16",
    "ctrlbus.dx_mm_q16",
    "ctrlbus.dy_mm_q16",
    "ctrlbus.dtheta_deg_q16",
    "ctrlbus.status",
    "ctrlbus.timestamp_ms",
    "ctrlbus.blob",
    "ctrlbus.index",
    "ctrlbus.error_code",
    "ctrlbus.message",
    "ctrlbus.command",
    "ctrlbus.payload_size",
    "ctrlbus.pad",
    "ctrlbus.filler",
    "ctrlbus.bitmap",
]


def write_capture(path: Path, records: list[tuple[Direction, str]], step_s: float = 0.01) -> None:
    with CaptureWriter.create(path) as writer:
        for index, (direction, hex_text) in enumerate(records):
            writer.write(direction, bytes.fromhex(hex_text), EPOCH + index * step_s)


def run_tshark(pcap: Path, *extra: str) -> str:
    assert TSHARK is not None
    done = subprocess.run(
        [TSHARK, "-n", "-X", f"lua_script:{DISSECTOR}", "-r", str(pcap), *extra],
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )
    # As root tshark warns that it "could be dangerous"; Lua still runs where init.lua sets
    # run_user_scripts_when_superuser = true (Debian's does). Anything else on stderr is a failure.
    problems = [
        line for line in done.stderr.splitlines() if line.strip() and "could be dangerous" not in line
    ]
    assert done.returncode == 0 and not problems, done.stderr
    assert "Lua Error" not in done.stdout, done.stdout
    return done.stdout


def tshark_fields(pcap: Path, *prefs: str, fields: list[str] = FIELDS) -> list[dict[str, list[str]]]:
    """One dict per packet: field -> the values of its occurrences, in order (absent = [])."""
    args: list[str] = ["-T", "fields", "-E", "separator=\t", "-E", "occurrence=a", "-E", "aggregator=|"]
    for field in fields:
        args += ["-e", field]
    for pref in prefs:
        args += ["-o", pref]
    packets = []
    for line in run_tshark(pcap, *args).splitlines():
        values = line.split("\t")
        assert len(values) == len(fields), line
        packets.append(
            {field: value.split("|") if value else [] for field, value in zip(fields, values, strict=True)}
        )
    return packets


@pytest.fixture(scope="module")
def conversation(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, list[dict[str, list[str]]]]:
    pcap = tmp_path_factory.mktemp("wireshark") / "conversation.pcap"
    write_capture(pcap, CONVERSATION)
    return pcap, tshark_fields(pcap)


def packet(conversation: tuple[Path, list[dict[str, list[str]]]], number: int) -> dict[str, list[str]]:
    fields = conversation[1][number - 1]
    assert fields["frame.number"] == [str(number)]
    return fields


def test_every_record_is_dissected_with_its_direction(
    conversation: tuple[Path, list[dict[str, list[str]]]],
) -> None:
    directions = [fields["ctrlbus.direction"] for fields in conversation[1]]
    assert directions == [[str(int(direction))] for direction, _ in CONVERSATION]


def test_requests_and_answers_are_named_and_paired(
    conversation: tuple[Path, list[dict[str, list[str]]]],
) -> None:
    expected = {
        1: (["request"], ["CONNECT_BASE"], [], []),
        2: (["answer"], ["OK"], ["CONNECT_BASE"], ["1"]),
        3: (["request"], ["GET_BASE_STATUS"], [], []),
        6: (["answer"], ["OK"], ["GET_BASE_STATUS"], ["3"]),
        8: (["request"], ["GET_BASE_STATUS"], [], []),
        # ERROR 0x0010 answers the garbage, not a request; the OK answers packet 8's request
        9: (["answer", "answer"], ["ERROR", "OK"], ["GET_BASE_STATUS"], ["8"]),
        11: (["answer"], ["ERROR"], [], []),
        12: (["request"], ["SET_V_AND_GET_DEADRECKON"], [], []),
        13: (["answer"], ["OK"], ["SET_V_AND_GET_DEADRECKON"], ["12"]),
        15: (["answer"], ["OK"], ["GET_BASE_CONF_ADV"], ["14"]),
        16: (["request"], ["HEALTH_GET_ERROR"], [], []),
        17: (["answer"], ["OK"], ["HEALTH_GET_ERROR"], ["16"]),
        21: (["answer"], ["ERROR"], ["GET_BASE_STATUS"], ["20"]),
        23: (["answer"], ["SYNC"], ["SYNC"], ["22"]),
        25: (["answer"], ["OK"], ["GET_BASE_BUMPER_DATA"], ["24"]),
        26: (["request"], ["GET_AUXILIARY_ANCHOR"], [], []),
        27: (["answer"], ["ERROR"], ["GET_AUXILIARY_ANCHOR"], ["26"]),
    }
    for number, (kind, name, to, request_in) in expected.items():
        fields = packet(conversation, number)
        got = (fields["ctrlbus.msg.kind"], fields["ctrlbus.msg.name"], fields["ctrlbus.msg.to"])
        assert got == (kind, name, to), number
        assert fields["ctrlbus.msg.request_in"] == request_in, number


def test_frames_split_across_records_are_reassembled(
    conversation: tuple[Path, list[dict[str, list[str]]]],
) -> None:
    for number in (4, 5):
        fields = packet(conversation, number)
        assert fields["ctrlbus.msg.name"] == []
    assert packet(conversation, 4)["ctrlbus.stream.buffered"] == ["2"]
    assert packet(conversation, 5)["ctrlbus.stream.buffered"] == ["5"]
    answer = packet(conversation, 6)
    assert answer["ctrlbus.frame.first_packet"] == ["4"]
    assert answer["ctrlbus.frame.long"] == ["1"]
    assert (answer["ctrlbus.battery_percent"], answer["ctrlbus.power_status"]) == (["80"], ["3"])
    # base→core stream: the 33-byte CONNECT answer, then this one from offset 33
    assert answer["ctrlbus.stream.offset"] == ["33"]
    request = packet(conversation, 8)
    assert request["ctrlbus.frame.first_packet"] == ["7"]
    assert request["ctrlbus.frame.long"] == ["0"]


def test_garbage_and_checksum_errors_are_flagged(
    conversation: tuple[Path, list[dict[str, list[str]]]],
) -> None:
    garbage = packet(conversation, 7)
    assert garbage["ctrlbus.stream.event"] == ["garbage"]
    assert garbage["ctrlbus.stream.discarded"] == ["aabb"]
    assert garbage["ctrlbus.stream.offset"] == ["11"]  # after CONNECT_BASE (6) and GET_BASE_STATUS (5)
    assert garbage["ctrlbus.stream.buffered"] == ["2"]
    assert garbage["ctrlbus.counters.bytes_discarded"] == ["2"]
    bad = packet(conversation, 10)
    assert bad["ctrlbus.stream.event"] == ["checksum_error"]
    assert (bad["ctrlbus.stream.checksum_expected"], bad["ctrlbus.stream.checksum_found"]) == (
        ["0xda"],
        ["0xdb"],
    )
    # after the failure the four bytes behind its flag are rescanned: garbage, but silent
    assert bad["ctrlbus.stream.discarded"] == ["02f830db"]
    assert bad["ctrlbus.counters.bytes_discarded"] == ["7"]
    assert bad["ctrlbus.msg.name"] == []
    assert packet(conversation, 11)["ctrlbus.error_code"] == ["64"]
    empty = packet(conversation, 26)
    assert empty["ctrlbus.stream.event"] == ["empty_frame"]
    assert empty["ctrlbus.msg.name"] == ["GET_AUXILIARY_ANCHOR"]


def test_message_fields_use_the_contract_names(conversation: tuple[Path, list[dict[str, list[str]]]]) -> None:
    connect = packet(conversation, 1)
    assert connect["ctrlbus.protocol_version"] == ["1"]
    answer = packet(conversation, 2)
    assert answer["ctrlbus.model"] == ["ref base"]
    assert answer["ctrlbus.firmware_version"] == [str(0x0114)]
    assert answer["ctrlbus.hardware_version"] == ["1"]
    assert answer["ctrlbus.serial"] == ["1", "2", "3"]
    assert answer["ctrlbus.firmware_version_suffix"] == []  # null in the 28-byte form
    setv = packet(conversation, 12)
    assert (setv["ctrlbus.vx_mps_q16"], setv["ctrlbus.vy_mps_q16"], setv["ctrlbus.omega_radps_q16"]) == (
        ["13107"],
        ["0"],
        ["32768"],
    )
    reckon = packet(conversation, 13)
    assert (reckon["ctrlbus.dx_mm_q16"], reckon["ctrlbus.dy_mm_q16"], reckon["ctrlbus.dtheta_deg_q16"]) == (
        ["65536"],
        ["-65536"],
        ["32768"],
    )
    assert (reckon["ctrlbus.status"], reckon["ctrlbus.timestamp_ms"]) == (["2"], ["1234"])
    assert packet(conversation, 15)["ctrlbus.blob"] == ["50020e200000c03f0b3115"]
    health = packet(conversation, 17)
    assert health["ctrlbus.error_code"] == [str(0x01020100)]
    assert health["ctrlbus.message"] == ["low battery"]
    assert packet(conversation, 16)["ctrlbus.index"] == ["0"]
    poll = packet(conversation, 19)
    assert (poll["ctrlbus.command"], poll["ctrlbus.payload_size"], poll["ctrlbus.pad"]) == ([], ["2"], ["0"])
    assert packet(conversation, 21)["ctrlbus.error_code"] == [str(0x8001)]
    assert packet(conversation, 22)["ctrlbus.filler"] == ["5555"]
    bumper = packet(conversation, 25)
    assert (bumper["ctrlbus.bitmap"], bumper["ctrlbus.payload_size"]) == ([str(0xFC)], ["1"])
    assert packet(conversation, 27)["ctrlbus.error_code"] == [str(0x8000)]


def test_format_errors_are_reported(conversation: tuple[Path, list[dict[str, list[str]]]]) -> None:
    wrong = packet(conversation, 20)
    assert wrong["ctrlbus.msg.name"] == ["GET_BASE_STATUS"]
    assert wrong["ctrlbus.msg.error"] == ["format"]
    assert packet(conversation, 12)["ctrlbus.msg.error"] == []


def test_values_the_message_codec_refuses_are_flagged_like_it(tmp_path: Path) -> None:
    """The same verdicts as ctrlbus.messages: MessageFormatError -> format,
    UnsupportedMessageError -> unsupported."""
    pcap = tmp_path / "refused.pcap"
    write_capture(
        pcap,
        [
            (C, "10 03 F8 10 02 F9"),  # CONNECT_BASE protocol version 2
            # model "r\xe9f": not ASCII
            (
                B,
                "50 1D 00 02 72 E9 66 00 00 00 00 00 00 00 00 00 14 01 01 00"
                " 01 00 00 00 02 00 00 00 03 00 00 00 A6",
            ),
            (C, "10 03 F8 34 01 DE"),  # GET_CHARGER_DATA data type 1
            (C, "10 03 F8 34 00 DF"),
            (B, "50 06 00 02 03 03 01 02 04 53"),  # 3 beacons, 3 probes: left, main, right
            (C, "10 04 F8 90 02 01 7F"),
            (B, "50 25 00 02 00 01 02 01" + " 41" * 32 + " 75"),  # message without a NUL
            (C, "10 01 00 11"),
            (B, "50 01 00 02 53"),  # an OK after a SYNC: a SYNC has no such answer
        ],
    )
    packets = tshark_fields(
        pcap, fields=[*FIELDS, "ctrlbus.probes", "ctrlbus.probe_count", "ctrlbus.data_type"]
    )
    assert [fields["ctrlbus.msg.error"] for fields in packets] == [
        ["unsupported"],
        ["format"],
        ["unsupported"],
        [],
        [],
        [],
        ["format"],
        [],
        ["unsupported"],
    ]
    assert packets[4]["ctrlbus.probes"] == ["1", "2", "4"]
    assert packets[4]["ctrlbus.probe_count"] == ["3"]
    assert packets[3]["ctrlbus.data_type"] == ["0"]
    assert packets[8]["ctrlbus.msg.to"] == []  # it fits no waiting request: unpaired


def test_verbose_view_shows_units_checksums_and_the_configuration_tree(
    conversation: tuple[Path, list[dict[str, list[str]]]],
) -> None:
    text = run_tshark(conversation[0], "-V")
    for expected in [
        "Checksum error: expected 0xDA, found 0xDB",
        "vx_mps_q16: 13107 (0.199997 m/s)",
        "omega_radps_q16: 32768 (0.5 rad/s)",
        "dtheta_deg_q16: 32768 (0.5 °)",
        "dy_mm_q16: -65536 (-1 mm)",
        "battery_percent: 80 %",
        "power_status: 3 (0x03) (charging, DC connected)",
        "root: object of 2",
        "x: 1.5 (f32)",
        "type: sonar (dictionary id 0x15)",
        "error_code: 16908544 (0x01020100) (warning, power, type 0x01, index 0)",
        "Frame: answer OK → GET_BASE_STATUS (7 bytes, long)",
        "Frame: request GET_BASE_STATUS [GET_BASE_STATUS takes 0 argument bytes, got 1] (6 bytes, standard)",
        "2 garbage byte(s)",
        "(inside the span of an earlier failure)",
    ]:
        assert expected in text, expected


def test_inter_byte_timeout_and_oversize_follow_the_preferences(tmp_path: Path) -> None:
    pcap = tmp_path / "stale.pcap"
    # a partial frame, then a whole one 100 ms later in the next record
    write_capture(pcap, [(C, "10 05 F8"), (C, "10 02 F8 30 DA")], step_s=0.1)
    without = tshark_fields(pcap)[1]
    assert without["ctrlbus.stream.event"] == ["checksum_error"]  # 10 05 F8 10 02 F8 30 DA as one frame
    assert without["ctrlbus.msg.name"] == ["GET_BASE_STATUS"]
    with_timeout = tshark_fields(pcap, "ctrlbus.timeout_ms:20")[1]
    assert with_timeout["ctrlbus.stream.event"] == ["timeout"]
    assert with_timeout["ctrlbus.stream.silent"] == []
    assert with_timeout["ctrlbus.msg.name"] == ["GET_BASE_STATUS"]

    pcap = tmp_path / "oversize.pcap"
    write_capture(pcap, [(C, "50 20 00 10 02 F8 30 DA")])
    fields = tshark_fields(pcap, "ctrlbus.max_frame:16")[0]
    assert fields["ctrlbus.stream.event"] == ["oversize"]
    assert fields["ctrlbus.stream.declared_size"] == ["36"]
    assert fields["ctrlbus.stream.discarded"] == ["2000"]
    assert fields["ctrlbus.msg.name"] == ["GET_BASE_STATUS"]


def test_records_that_are_not_ctrlbus_are_flagged(tmp_path: Path) -> None:
    pcap = tmp_path / "odd.pcap"
    write_capture(pcap, [(C, "10 01 00 11")])
    data = bytearray(pcap.read_bytes())
    data[24 + 16] = 7  # the direction byte of the only record
    pcap.write_bytes(bytes(data))
    text = run_tshark(pcap, "-V")
    assert "A record must start with a direction byte, 0 or 1" in text


# ---------------------------------------------------------------------------------------------
# The dissector's stream decoder against the contract: every vector of vectors/streams.json, fed
# once as whole chunks (core→base) and once byte by byte (base→core) in the same capture.

COUNTERS = ["frames", "bytes_discarded", "checksum_errors", "oversize", "timeouts", "empty_frames", "resyncs"]
DECODER_FIELDS = [
    "ctrlbus.direction",
    "ctrlbus.frame.long",
    "ctrlbus.frame.cmd",
    "ctrlbus.frame.len",
    "ctrlbus.frame.payload",
    "ctrlbus.stream.event",
    *[f"ctrlbus.counters.{name}" for name in COUNTERS],
]


def frames_of(packet_fields: dict[str, list[str]]) -> list[tuple[bool, int, str]]:
    """(long, cmd, payload hex) of each frame a packet shows (an empty payload has no field)."""
    payloads = iter(packet_fields["ctrlbus.frame.payload"])
    frames = []
    for long, cmd, length in zip(
        packet_fields["ctrlbus.frame.long"],
        packet_fields["ctrlbus.frame.cmd"],
        packet_fields["ctrlbus.frame.len"],
        strict=True,
    ):
        frames.append((long == "1", int(cmd), next(payloads) if int(length) > 1 else ""))
    return frames


def append_empty_record(path: Path, direction: Direction, time: float) -> None:
    """A record holding only the direction byte: time passes with no bytes (the writer never makes
    one, but the dissector must take it as a moment to check the inter-byte timeout)."""
    microseconds = round(time * 1_000_000)
    with path.open("ab") as capture:
        capture.write(struct.pack("<IIII", microseconds // 1_000_000, microseconds % 1_000_000, 1, 1))
        capture.write(bytes([direction]))


@pytest.mark.parametrize("vector", STREAM_VECTORS, ids=[vector["name"] for vector in STREAM_VECTORS])
def test_stream_vectors(vector: dict[str, Any], tmp_path: Path) -> None:
    pcap = tmp_path / "vector.pcap"
    chunks = vector["chunks"]
    last_time = EPOCH
    with CaptureWriter.create(pcap) as writer:
        for chunk in chunks:
            last_time = EPOCH + chunk["t_ms"] / 1000
            data = bytes.fromhex(chunk["hex"])
            writer.write(C, data, last_time)
            for byte in data:
                writer.write(B, bytes([byte]), last_time)
    idle_ms = vector.get("final_idle_ms")
    if isinstance(idle_ms, int):
        for direction in (C, B):
            append_empty_record(pcap, direction, last_time + idle_ms / 1000)
    prefs = [
        f"ctrlbus.max_frame:{vector.get('max_frame', 65539)}",
        f"ctrlbus.timeout_ms:{vector.get('timeout_ms', 0)}",
    ]
    packets = tshark_fields(pcap, *prefs, fields=DECODER_FIELDS)

    expected_frames = [
        (frame["long"], frame["cmd"], frame["payload"].replace(" ", "").lower())
        for frame in vector["expect_frames"]
    ]
    expected_counters = vector["expect_counters"]
    for direction in (C, B):
        mine = [fields for fields in packets if fields["ctrlbus.direction"] == [str(int(direction))]]
        assert [frame for fields in mine for frame in frames_of(fields)] == expected_frames, direction
        assert [event for fields in mine for event in fields["ctrlbus.stream.event"]] == vector[
            "expect_events"
        ]
        final = {name: int(mine[-1][f"ctrlbus.counters.{name}"][0]) for name in expected_counters}
        assert final == expected_counters, direction


# ---------------------------------------------------------------------------------------------
# A noisy two-way capture: the dissector and ctrlbus.frame.StreamDecoder see the same frames,
# events and counters after every record.


def noisy_stream(rng: random.Random, segments: int) -> bytes:
    def frame(body: bytes, long: bool) -> bytes:
        header = bytes([0x50, len(body) & 0xFF, len(body) >> 8]) if long else bytes([0x10, len(body)])
        checksum = 0
        for byte in header + body:
            checksum ^= byte
        return header + body + bytes([checksum])

    out = bytearray()
    for _ in range(segments):
        body = bytes([rng.choice([0x00, 0x01, 0x02, 0x03, 0xF8])]) + rng.randbytes(rng.randint(0, 20))
        kind = rng.random()
        if kind < 0.5:
            out += frame(body, rng.random() < 0.5)
        elif kind < 0.7:  # line noise, flag bytes included
            out += bytes(rng.choice([0x00, 0x10, 0x33, 0xAA, 0xF8, 0xFF]) for _ in range(rng.randint(1, 6)))
        elif kind < 0.85:  # a frame with a flipped bit after its header (a flipped long LEN
            # could announce 64 KiB and, with no timeout, swallow the rest of the capture)
            long = rng.random() < 0.5
            damaged = bytearray(frame(body, long))
            damaged[rng.randrange(3 if long else 2, len(damaged))] ^= 1 << rng.randrange(8)
            out += damaged
        elif kind < 0.9:
            out += bytes.fromhex("10 00 10")  # LEN = 0
        else:  # a frame cut short
            whole = frame(body, rng.random() < 0.5)
            out += whole[: rng.randrange(1, len(whole))]
    return bytes(out)


def test_noisy_capture_matches_the_python_stream_decoder(tmp_path: Path) -> None:
    rng = random.Random(2024)
    pending = {direction: noisy_stream(rng, 200) for direction in (C, B)}
    records: list[tuple[Direction, bytes]] = []
    while any(pending.values()):
        direction = rng.choice([d for d in (C, B) if pending[d]])
        size = rng.randint(1, 12)
        records.append((direction, pending[direction][:size]))
        pending[direction] = pending[direction][size:]
    pcap = tmp_path / "noisy.pcap"
    with CaptureWriter.create(pcap) as writer:
        for index, (direction, data) in enumerate(records):
            writer.write(direction, data, EPOCH + index * 0.001)
    packets = tshark_fields(pcap, fields=DECODER_FIELDS)
    assert len(packets) == len(records)

    decoders = {direction: StreamDecoder(timeout=0) for direction in (C, B)}
    seen = {"frames": 0, "events": 0}
    for index, ((direction, data), fields) in enumerate(zip(records, packets, strict=True)):
        items = decoders[direction].feed_items(data, index * 0.001)
        frames = [(item.long, item.cmd, item.payload.hex()) for item in items if isinstance(item, Frame)]
        events = [str(item.kind) for item in items if isinstance(item, DecoderEvent)]
        assert frames_of(fields) == frames, f"record {index + 1}"
        assert fields["ctrlbus.stream.event"] == events, f"record {index + 1}"
        stats = decoders[direction].stats
        assert {name: int(fields[f"ctrlbus.counters.{name}"][0]) for name in COUNTERS} == {
            name: getattr(stats, name) for name in COUNTERS
        }, f"record {index + 1}"
        seen["frames"] += len(frames)
        seen["events"] += len(events)
    # the capture is as noisy as intended: plenty of frames and of every kind of rejection
    assert seen["frames"] > 100 and seen["events"] > 40
    assert all(decoders[direction].stats.checksum_errors > 5 for direction in (C, B))
    assert all(decoders[direction].stats.empty_frames > 0 for direction in (C, B))
