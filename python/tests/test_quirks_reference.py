# SPDX-License-Identifier: MIT
"""The reference-quirks model (ctrlbus.quirks) against what the vendor's reference firmware
answered to the same bytes (issue 23, item 2).

Each sequence below was sent to the real firmware, base_ref v4 of slamware_kit_v6 (commit
2ea1f06d) built unchanged for Linux (docs/protocol.md §8.5, "refbase"), in its virtual-time mode:

    refbase --script FILE      # FILE: one "T_MS HEX.." or "+T_MS HEX.." line per write

(T_MS: milliseconds after power-on; "+T_MS": after the previous write's last byte), 115,200 baud,
20 µs main-loop passes (its defaults). Its answers, recorded 2026-11-28, are the expected data
here, written as the sequence of answer frames: "E0010" an ERROR frame with that code, "OK2" an OK
answer with 2 payload bytes, "C00:3" a frame with CMD 0x00 (an echo) and 3 payload bytes. The
tests feed the model the same bytes at the same times; none of them runs the firmware.
"""

from __future__ import annotations

import struct

import pytest

from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.frame import Frame, StreamDecoder, encode
from ctrlbus.quirks import BOOT_SILENCE_S, DEAF_S, Quirks, ReferenceReceiver
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.vtime import DEFAULT_BYTE_TIME_S

STATUS = bytes.fromhex("10 02 F8 30 DA")  # GET_BASE_STATUS: its OK answer has 2 payload bytes
CONNECT = encode(0xF8, bytes([0x10, 0x01]))  # CONNECT_BASE v1: 28 bytes
SET_V = encode(0xF8, bytes([0x41]) + struct.pack("<iii", 0x3333, 0, 0))  # 13-byte answer
BAD_SET_V = SET_V[:-1] + bytes([SET_V[-1] ^ 1])
LEN0 = bytes.fromhex("10 00 10")
GARBAGE = bytes(range(1, 17))  # no 0x10 or 0x50 among them
# A long frame announcing 597 bytes (more than the 512-byte buffer holds), 600 bytes in all.
LONG_600_ZEROS = bytes([0x50]) + struct.pack("<H", 597) + bytes([0xF8, 0x30]) + bytes(595)
# The same with payload bytes 0x20, 0x21, ...: some of them are 0x10 or 0x50 (false frame starts).
LONG_600_COUNTING = (
    bytes([0x50]) + struct.pack("<H", 597) + bytes([0xF8, 0x30]) + bytes(range(0x20, 0xE8)) * 3
)[:600]

Write = tuple[str, bytes]  # (time as in a refbase script, bytes)

# (name, writes, the reference's answers)
SEQUENCES: list[tuple[str, list[Write], list[str]]] = [
    # The table: the 6 sequences the previous model got wrong.
    ("bad checksum + status, one write", [("2500", BAD_SET_V + STATUS)], ["E00C0", "OK2"]),
    ("1 garbage byte + status", [("2500", GARBAGE[:1] + STATUS)], ["E0010", "OK2"]),
    ("2 garbage bytes + status", [("2500", GARBAGE[:2] + STATUS)], ["E0010", "E0010", "OK2"]),
    ("4 garbage bytes + status", [("2500", GARBAGE[:4] + STATUS)], ["E0010"] * 4),
    ("8 garbage bytes + status", [("2500", GARBAGE[:8] + STATUS)], ["E0010"] * 3 + ["E0090"]),
    ("600-byte long frame", [("2500", LONG_600_ZEROS)], ["E0020"] + ["E0010"] * 87),
    # Every other garbage length up to 16.
    ("no garbage + status", [("2500", STATUS)], ["OK2"]),
    ("3 garbage bytes + status", [("2500", GARBAGE[:3] + STATUS)], ["E0010"] * 3),
    ("5 garbage bytes + status", [("2500", GARBAGE[:5] + STATUS)], ["E0010"] * 4),
    ("6 garbage bytes + status", [("2500", GARBAGE[:6] + STATUS)], ["E0010"] * 4),
    ("7 garbage bytes + status", [("2500", GARBAGE[:7] + STATUS)], ["E0010"] * 3 + ["OK2"]),
    ("9 garbage bytes + status", [("2500", GARBAGE[:9] + STATUS)], ["E0010"] * 3 + ["E0090"]),
    ("10 garbage bytes + status", [("2500", GARBAGE[:10] + STATUS)], ["E0010"] * 4),
    ("11 garbage bytes + status", [("2500", GARBAGE[:11] + STATUS)], ["E0010"] * 5),
    ("12 garbage bytes + status", [("2500", GARBAGE[:12] + STATUS)], ["E0010"] * 5),
    ("13 garbage bytes + status", [("2500", GARBAGE[:13] + STATUS)], ["E0010"] * 5),
    ("14 garbage bytes + status", [("2500", GARBAGE[:14] + STATUS)], ["E0010"] * 4 + ["OK2"]),
    ("15 garbage bytes + status", [("2500", GARBAGE[:15] + STATUS)], ["E0010"] * 4 + ["E0090"]),
    ("16 garbage bytes + status", [("2500", GARBAGE[:16] + STATUS)], ["E0010"] * 5),
    # What the previous model already did as the reference does.
    ("bad checksum alone", [("2500", BAD_SET_V)], ["E00C0"]),
    ("LEN=0 re-runs GET_BASE_STATUS", [("2500", STATUS), ("+50", LEN0)], ["OK2", "OK2"]),
    ("LEN=0 re-runs SET_V", [("2500", SET_V), ("+50", LEN0)], ["OK13", "OK13"]),
    ("request split, 5 s between", [("2500", STATUS[:2]), ("+5000", STATUS[2:])], ["OK2"]),
    (
        "request byte by byte, 1 ms apart",
        [("2500", STATUS[:1])] + [("+1", STATUS[i : i + 1]) for i in range(1, 5)],
        ["OK2"],
    ),
    (
        "10 FF swallows the requests behind it",
        [("2500", bytes.fromhex("10 FF")), ("+10", STATUS), ("+10", STATUS)],
        [],
    ),
    (
        "10 FF, a status, then a flushing SYNC",
        [("2500", bytes.fromhex("10 FF")), ("+10", STATUS), ("+10", encode(0x00, bytes(251)))],
        ["E00C0", "E0010", "E0010"],
    ),
    ("SYNC is echoed", [("2500", encode(0x00, b"abc"))], ["C00:3"]),
    ("ECHO is echoed", [("2500", encode(0x01, b"hello"))], ["C01:5"]),
    ("unknown CMD", [("2500", encode(0x77, b""))], ["E8000"]),
    ("two requests in one write", [("2500", STATUS * 2)], ["OK2", "OK2"]),
    ("three requests in one write", [("2500", STATUS * 3)], ["OK2"] * 3),
    ("a request 0.2 ms after the previous", [("2500", STATUS), ("+0.2", STATUS)], ["OK2", "OK2"]),
    ("status, then 3 garbage bytes", [("2500", STATUS + GARBAGE[:3])], ["OK2", "E0010", "E0010"]),
    ("status in a long frame", [("2500", encode(0xF8, bytes([0x30]), long=True))], ["OK2"]),
    (
        "long LEN 510 does not fit",
        [("2500", bytes([0x50, 0xFE, 0x01]) + bytes(20))],
        ["E0020"] + ["E0010"] * 4,
    ),
    ("27 bytes 01..1B (one false start at 0x10)", [("2500", bytes(range(1, 28)))], ["E0010"] * 6),
    (
        "600-byte long frame with false starts in it, then a status",
        [("2500", LONG_600_COUNTING), ("+100", STATUS)],
        ["E0020"] + ["E0010"] * 8 + ["E0030"] + ["E0010"] * 56 + ["E0030"] + ["E0010"] * 21 + ["OK2"],
    ),
    (
        "4 garbage bytes + status, resent 20 ms later",
        [("2500", GARBAGE[:4] + STATUS), ("+20", STATUS)],
        ["E0010"] * 4 + ["OK2"],
    ),
    # Power-on: deaf for about 100 ms, then the main loop starts 1.9 s after power-on.
    ("status at 0 ms (nothing hears it)", [("0", STATUS)], []),
    ("status cut by the end of the deaf start", [("100", STATUS)], ["E0010"]),
    ("bad checksum cut by the end of the deaf start", [("100", BAD_SET_V)], ["E0010"]),
    ("status 40 µs later: heard whole", [("100.04", STATUS)], ["OK2"]),
    ("status during the beeps", [("1000", STATUS)], ["OK2"]),
    ("bad checksum during the beeps", [("1000", BAD_SET_V)], ["E00C0"]),
    ("status, then CONNECT_BASE during the beeps", [("100", STATUS), ("500", CONNECT)], ["E0090"]),
    ("garbage, then status during the beeps", [("100", GARBAGE[:2]), ("500", STATUS)], ["E0090"]),
    (
        "status then CONNECT_BASE, both heard, the last answered",
        [("200", STATUS), ("500", CONNECT)],
        ["OK28"],
    ),
    ("CONNECT_BASE after the beeps", [("2500", CONNECT)], ["OK28"]),
]


def answers_of(writes: list[Write]) -> list[str]:
    """Feed the writes to a quirks-mode base powered on at 0 s, timed as refbase's script mode
    times them (each write's bytes one byte time apart from the line being free); the answers,
    summarised as in SEQUENCES."""
    stack = BaseStack(SimulatedBase(World(seed=1)), BaseConfig(quirks=Quirks.REFERENCE))
    out = bytearray(stack.tick(0.0))
    line_free = 0.0
    for when, data in writes:
        at = line_free + float(when[1:]) / 1000 if when.startswith("+") else float(when) / 1000
        start = max(at, line_free)
        line_free = start + len(data) * DEFAULT_BYTE_TIME_S
        out += stack.tick(at)
        out += stack.receive(data, line_free)
    out += stack.tick(line_free + 2.0)
    return [summary(frame.cmd, frame.payload) for frame in StreamDecoder().feed(bytes(out), 0.0)]


def summary(cmd: int, payload: bytes) -> str:
    if cmd == 0x03:
        return f"E{int.from_bytes(payload, 'little'):04X}"
    if cmd == 0x02:
        return f"OK{len(payload)}"
    return f"C{cmd:02X}:{len(payload)}"


@pytest.mark.parametrize(
    ("writes", "observed"), [(w, o) for _, w, o in SEQUENCES], ids=[n for n, _, _ in SEQUENCES]
)
def test_the_model_answers_as_the_reference_did(writes: list[Write], observed: list[str]) -> None:
    assert answers_of(writes) == observed


# --- the mechanism, piece by piece -------------------------------------------------------------


def fed(receiver: ReferenceReceiver, data: bytes, now: float) -> list[Frame | int | bytes]:
    """What the main loop acted on when `data` arrived (its last byte at `now`); errors are
    answered with a 7-byte frame, requests with a 7-byte one too."""
    acted: list[Frame | int | bytes] = []

    def serve(item: Frame | int | bytes) -> bytes:
        acted.append(item)
        return item if isinstance(item, bytes) else bytes(7)

    receiver.feed(data, now, serve)
    return acted


def booted() -> ReferenceReceiver:
    receiver = ReferenceReceiver()
    receiver.power_on(0.0)
    receiver.feed(b"", BOOT_SILENCE_S + 0.01, lambda item: b"")
    return receiver


def test_a_frame_completing_while_another_waits_replaces_it() -> None:
    receiver = ReferenceReceiver()
    receiver.power_on(0.0)
    connect_then_status = CONNECT + STATUS
    assert fed(receiver, connect_then_status, 1.0) == []  # the loop has not started
    acted = fed(receiver, b"", BOOT_SILENCE_S + 0.001)
    assert [item.payload for item in acted if isinstance(item, Frame)] == [STATUS[3:4]]
    assert receiver.dropped_frames == 1


def test_the_main_loops_clear_cuts_the_frame_being_received() -> None:
    receiver = booted()
    at = 3.0
    # One garbage byte is reported at once; the second is reported while the transmitter is
    # still busy with the first report, so the loop waits; meanwhile the third garbage byte and
    # the first three bytes of the request arrive. The next pass reports the third byte and
    # clears the receiver mid-frame: the request's last bytes are thrown away.
    acted = fed(receiver, GARBAGE[:3] + STATUS, at + 8 * DEFAULT_BYTE_TIME_S)
    acted += fed(receiver, b"", at + 1.0)
    assert acted == [0x10, 0x10, 0x10]
    assert receiver.dropped_frames == 1


def test_an_error_bit_and_a_ready_frame_at_one_poll_make_0090_and_the_frame_is_dropped() -> None:
    receiver = booted()
    acted = fed(receiver, GARBAGE[:8] + STATUS, 3.0) + fed(receiver, b"", 4.0)
    assert acted == [0x10, 0x10, 0x10, 0x90]
    assert receiver.dropped_frames == 1


def test_the_bytes_of_the_first_100_ms_are_lost() -> None:
    receiver = ReferenceReceiver()
    receiver.power_on(0.0)
    assert fed(receiver, STATUS, DEAF_S - 0.001) == []
    assert fed(receiver, b"", BOOT_SILENCE_S + 0.001) == []
    assert receiver.reports == 0
