# SPDX-License-Identifier: MIT
"""A hostile link against every shipped base (issue 17): posix_base over TCP, `ctrlbus sim` over
TCP and the QEMU firmware over its UART, each started as its users start it, black box.

Each category of malformed input is sent, the base's answers to it are checked where
docs/protocol.md §8 says what they are, and then the line falls silent for longer than the
base's inter-byte timeout (100 ms for the host bases, 500 ms for the firmware) and a valid
CONNECT_BASE and GET_BASE_STATUS must be answered correctly: nothing the link did leaves the base
deaf, confused or stuck. One base process serves every category (and every category uses the same
connection), so a category that left state behind would show in the next one's recovery check.

LEN = 0: the reference spec (control-bus.md) defines the frame but no answer; our bases answer it
ERROR 0x8001 as docs/protocol.md §3.3 says, and that is what is checked here.
"""

from __future__ import annotations

import random
import struct
import time
from collections.abc import Iterator

import pytest
from support.base_harness import FramePeer
from support.served_bases import BASE_NAMES, ServedBase, build_firmware, start_base

from ctrlbus.frame import Frame, encode

CMD_SYNC, CMD_ECHO, CMD_OK, CMD_ERROR, CMD_CTRL_BUS, CMD_BASE_CMD = 0x00, 0x01, 0x02, 0x03, 0xF8, 0xF9
ERR_GARBAGE, ERR_OVERSIZE, ERR_CHECKSUM = 0x0010, 0x0020, 0x0040
ERR_FORMAT = 0x8001
CONNECT_BASE_V1 = bytes((0x10, 0x01))
GET_BASE_STATUS = bytes((0x30,))
SILENCE_S = 0.6  # longer than every base's inter-byte timeout (100 ms; QEMU's firmware 500 ms)
QUIET_S = 0.4  # no answer for this long: the base has answered everything (QEMU may pause 0.1 s)
ANSWERS_LIMIT_S = 5.0

# The request payloads of docs/protocol.md §5 with their right argument lengths (after the code).
REQUEST_ARGUMENT_SIZES = {
    bytes((0x10,)): 1,  # CONNECT_BASE: protocol version
    bytes((0x20,)): 0,
    bytes((0x21,)): 0,
    bytes((0x30,)): 0,
    bytes((0x31,)): 0,
    bytes((0x32,)): 0,
    bytes((0x33,)): 0,
    bytes((0x34,)): 1,  # GET_CHARGER_DATA: data type
    bytes((0x35,)): 0,
    bytes((0x40,)): 16,  # SET_BASE_MOTOR: four s32 speeds
    bytes((0x41,)): 12,  # SET_V_AND_GET_DEADRECKON: three s32
    bytes((0x50,)): 0,
    bytes((0x5F,)): 0,
    bytes((0x60,)): 1,  # SEND_EVENT: event
    bytes((0x90, 0x01)): 0,  # HEALTH_GET_HEALTH
    bytes((0x90, 0x02)): 1,  # HEALTH_GET_ERROR: index
    bytes((0x90, 0x03)): 4,  # HEALTH_CLR_ERROR: error code
}


@pytest.fixture(scope="module", params=BASE_NAMES)
def link(request: pytest.FixtureRequest) -> Iterator[tuple[str, FramePeer]]:
    """One base, started once for every category, and the test's (single) connection to it."""
    name: str = request.param
    if name == "firmware":
        build_firmware()
    base: ServedBase = start_base(name)
    try:
        yield name, base.connect()
    finally:
        base.close()


def answers_to(peer: FramePeer, data: bytes, *, silence_after: bool = True) -> list[Frame]:
    """Send `data`, let the line fall silent, and return every frame the base answered."""
    peer.send(data)
    if silence_after:
        time.sleep(SILENCE_S)
    frames: list[Frame] = []
    deadline = time.monotonic() + ANSWERS_LIMIT_S
    while time.monotonic() < deadline:
        try:
            frames.append(peer.read_frame(limit_s=QUIET_S))
        except AssertionError:  # nothing more came for QUIET_S
            return frames
    raise AssertionError(f"{peer.name}: still answering after {ANSWERS_LIMIT_S} s ({len(frames)} frames)")


def error_codes(frames: list[Frame]) -> list[int]:
    codes = []
    for frame in frames:
        assert frame.cmd == CMD_ERROR and len(frame.payload) == 2, f"not an ERROR answer: {frame}"
        codes.append(struct.unpack("<H", frame.payload)[0])
    return codes


def assert_answers_the_core(name: str, peer: FramePeer) -> None:
    """After the hostile input and a silence: CONNECT_BASE and GET_BASE_STATUS answered right,
    each by the very next frame."""
    connect = peer.request(CMD_CTRL_BUS, CONNECT_BASE_V1)
    assert connect.cmd == CMD_OK and len(connect.payload) == 28, f"{name}: CONNECT_BASE answered {connect}"
    model = connect.payload[:12].rstrip(b"\0")
    assert model == b"ctrlbus sim", f"{name}: CONNECT_BASE model {model!r}"
    status = peer.request(CMD_CTRL_BUS, GET_BASE_STATUS)
    assert status.cmd == CMD_OK and len(status.payload) == 2, f"{name}: GET_BASE_STATUS answered {status}"
    battery, _power = status.payload
    assert 1 <= battery <= 100, f"{name}: battery {battery} %"


def test_random_bytes(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    noise = random.Random(17).randbytes(2048)
    answers_to(peer, noise)  # whatever the noise happens to spell; only the recovery is checked
    assert_answers_the_core(name, peer)


def test_false_flags_with_huge_lengths(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    # A long flag declaring 65535 bytes, a standard one declaring 255, each followed by a little
    # and then nothing: the base must not wait for the rest forever.
    for false_start in (bytes.fromhex("50 FF FF F8 30"), bytes.fromhex("10 FF F8 30 00 00")):
        answers_to(peer, false_start)
        assert_answers_the_core(name, peer)
    # A false flag right before a valid frame: the frame still comes through after the timeout.
    frames = answers_to(peer, bytes.fromhex("50 FF 7F") + encode(CMD_CTRL_BUS, GET_BASE_STATUS))
    assert any(frame.cmd == CMD_OK and len(frame.payload) == 2 for frame in frames), frames
    assert_answers_the_core(name, peer)


def test_empty_frames(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    frames = answers_to(peer, bytes.fromhex("10 00 10") + bytes.fromhex("50 00 00 50"))
    assert error_codes(frames) == [ERR_FORMAT, ERR_FORMAT]  # docs/protocol.md §3.3
    assert_answers_the_core(name, peer)


def test_oversize_long_frames(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    # 600 bytes of SET_BASE_MOTOR-looking payload: more than the bases' 512-byte request buffer.
    oversize = encode(CMD_CTRL_BUS, bytes((0x40,)) + bytes(599), long=True)
    frames = answers_to(peer, oversize)
    codes = error_codes(frames)
    assert codes and codes[0] == ERR_OVERSIZE, codes
    assert set(codes) <= {ERR_OVERSIZE, ERR_GARBAGE}, codes  # the payload bytes are garbage then
    assert_answers_the_core(name, peer)


def test_truncated_frames_then_silence(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    for cut in (
        encode(CMD_CTRL_BUS, GET_BASE_STATUS)[:-1],  # all but the checksum
        encode(CMD_CTRL_BUS, bytes((0x41,)) + bytes(12))[:7],  # half a SET_V
        encode(CMD_CTRL_BUS, bytes((0x40,)) + bytes(16), long=True)[:3],  # a long header cut short
    ):
        assert answers_to(peer, cut) == [], f"{name} answered a frame it never got whole"
        assert_answers_the_core(name, peer)


def test_bad_checksums(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    before = wheel_travel(peer)
    # One at a time: back to back, a flag inside one failed frame can make the next one's failure
    # silent (docs/protocol.md §7, the silent region), which is right but not this test's point.
    for payload in (GET_BASE_STATUS, CONNECT_BASE_V1, bytes((0x40,)) + struct.pack("<4i", 300, 300, 0, 0)):
        frame = bytearray(encode(CMD_CTRL_BUS, payload))
        frame[-1] ^= 0x5A
        assert error_codes(answers_to(peer, bytes(frame))) == [ERR_CHECKSUM], f"{name}: {frame.hex(' ')}"
    assert wheel_travel(peer) == before, f"{name}: a corrupted SET_BASE_MOTOR moved the wheels"
    assert_answers_the_core(name, peer)


def wheel_travel(peer: FramePeer) -> bytes:
    motor = peer.request(CMD_CTRL_BUS, bytes((0x31,)))
    assert motor.cmd == CMD_OK and len(motor.payload) == 9, motor
    return motor.payload[:8]


def test_sync_floods(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    flood = bytes.fromhex("10 01 00 11") * 200
    peer.send(flood)
    assert peer.read_bytes(len(flood)) == flood  # every SYNC copied back, none lost
    time.sleep(SILENCE_S)
    assert_answers_the_core(name, peer)


def test_wrong_payload_lengths_for_every_request_code(link: tuple[str, FramePeer]) -> None:
    name, peer = link
    burst = b""
    sent = []
    for request, size in REQUEST_ARGUMENT_SIZES.items():
        for wrong in sorted({size + 1, size + 5, size - 1} - {-1}):
            burst += encode(CMD_CTRL_BUS, request + bytes(wrong))
            sent.append(f"{request.hex()} with {wrong} argument bytes")
    for wrong in (0, 2):  # BASE_CMD takes one sub-command byte
        burst += encode(CMD_BASE_CMD, bytes(wrong))
        sent.append(f"BASE_CMD with {wrong} bytes")
    codes = error_codes(answers_to(peer, burst, silence_after=False))
    assert codes == [ERR_FORMAT] * len(sent), list(zip(sent, codes, strict=False))
    assert_answers_the_core(name, peer)
