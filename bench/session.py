# SPDX-License-Identifier: MIT
"""Captures for the parser benchmarks: a synthetic Core<->base session, a noisy variant, or a real recording.

The synthetic session is what the Core emulator does at its default rates: SET_V_AND_GET_DEADRECKON
at 20 Hz, bumpers and distance sensors at 10 Hz, POLL_BASE_CMD at 5 Hz, status and health at 1 Hz,
each request followed by its answer. Requests are standard (0x10) frames, answers long (0x50)
frames with the base_ref v4 payload sizes (deadreckon 13 bytes, bumper bitmap 4 bytes, "nothing
pending" as OK 0), as the reference base sends them.

The same sequence of messages is what bench/mavlink/stream.py turns into MAVLink frames, so the
two parsers see the same traffic mix.
"""

from __future__ import annotations

import math
import random
import struct
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ours import Pending, ctrlbus_module

FLAG_STANDARD = 0x10
FLAG_LONG = 0x50
CMD_CTRL_BUS = 0xF8
CMD_OK = 0x02

# Default poll rates of the Core emulator (Hz), by control-bus request.
DEFAULT_RATES_HZ: dict[str, int] = {
    "SET_V_AND_GET_DEADRECKON": 20,
    "GET_BASE_BUMPER_DATA": 10,
    "GET_BASE_SENSOR_DATA": 10,
    "POLL_BASE_CMD": 5,
    "GET_BASE_STATUS": 1,
    "HEALTH_GET_HEALTH": 1,
}

REQUEST_CODES: dict[str, bytes] = {
    "SET_V_AND_GET_DEADRECKON": bytes([0x41]),
    "GET_BASE_BUMPER_DATA": bytes([0x33]),
    "GET_BASE_SENSOR_DATA": bytes([0x32]),
    "POLL_BASE_CMD": bytes([0x50]),
    "GET_BASE_STATUS": bytes([0x30]),
    "HEALTH_GET_HEALTH": bytes([0x90, 0x01]),
}

DISTANCE_SENSORS_IN_USE = 8


@dataclass(frozen=True)
class SessionMessage:
    """One request or answer of the session, as values (the wire form is chosen by the encoder)."""

    t_ms: float
    direction: str  # "request" (Core to base) or "answer" (base to Core)
    name: str  # the control-bus request this is, or answers
    fields: dict[str, int | tuple[int, ...]]


@dataclass(frozen=True)
class Capture:
    """A byte stream and the frames it is made of, in order (for synthetic captures)."""

    data: bytes
    frames: int
    source: str


@dataclass(frozen=True)
class NoisyStream:
    """A capture after noise: what went on the line for each frame (any burst, then the frame with
    its bit errors), each sent frame's original bytes, and whether that frame stayed intact."""

    pieces: list[bytes]
    sent: list[bytes]
    intact: list[bool]
    bit_errors: int
    bursts: int
    burst_bytes: int

    @property
    def data(self) -> bytes:
        return b"".join(self.pieces)


def _q16(value: float) -> int:
    return round(value * 65536)


def core_session(seconds: float, seed: int = 1) -> Iterator[SessionMessage]:
    """The messages of a session of the given length at the default rates, in wire order."""
    rng = random.Random(seed)
    schedule: list[tuple[float, int, str]] = []
    for order, (name, rate) in enumerate(DEFAULT_RATES_HZ.items()):
        period_ms = 1000.0 / rate
        # Spread the request streams over the period so they interleave as a poll loop would.
        phase = period_ms * order / (len(DEFAULT_RATES_HZ) + 1)
        for k in range(int(seconds * rate)):
            schedule.append((phase + k * period_ms, order, name))
    schedule.sort()
    sensors = [rng.randrange(200, 4000) for _ in range(DISTANCE_SENSORS_IN_USE)]
    for t_ms, _, name in schedule:
        request, answer = _exchange(name, t_ms, rng, sensors)
        yield SessionMessage(t_ms, "request", name, request)
        yield SessionMessage(t_ms + 2.0, "answer", name, answer)


def _exchange(
    name: str, t_ms: float, rng: random.Random, sensors: list[int]
) -> tuple[dict[str, int | tuple[int, ...]], dict[str, int | tuple[int, ...]]]:
    """Plausible request and answer values for one exchange at time t_ms."""
    t = t_ms / 1000.0
    if name == "SET_V_AND_GET_DEADRECKON":
        vx = 0.3 + 0.2 * math.sin(t / 7.0)
        omega = 0.6 * math.sin(t / 3.0)
        dt = 0.05
        return (
            {"vx_mps_q16": _q16(vx), "vy_mps_q16": 0, "omega_radps_q16": _q16(omega)},
            {
                "dx_mm_q16": _q16(vx * dt * 1000.0 + rng.uniform(-0.5, 0.5)),
                "dy_mm_q16": _q16(rng.uniform(-0.2, 0.2)),
                "dtheta_deg_q16": _q16(math.degrees(omega * dt)),
                "status": 0,
            },
        )
    if name == "GET_BASE_BUMPER_DATA":
        pressed = rng.random() < 0.02
        return {}, {"bitmap": 0xFFFFFFFE if pressed else 0xFFFFFFFF}
    if name == "GET_BASE_SENSOR_DATA":
        for i, distance in enumerate(sensors):
            sensors[i] = min(6000, max(50, distance + rng.randrange(-40, 41)))
        readings = tuple(d << 16 for d in sensors) + (0,) * (16 - DISTANCE_SENSORS_IN_USE)
        return {}, {"distances_mm_q16": readings}
    if name == "POLL_BASE_CMD":
        return {}, {}
    if name == "GET_BASE_STATUS":
        return {}, {"battery_percent": max(5, 95 - int(t / 60)), "power_status": 0}
    if name == "HEALTH_GET_HEALTH":
        return {}, {"flags": 0, "error_count": 0}
    raise ValueError(f"no exchange model for {name}")


def answer_payload(message: SessionMessage) -> bytes:
    """The OK payload of an answer, field by field, little-endian."""
    f = message.fields
    if message.name == "SET_V_AND_GET_DEADRECKON":
        return struct.pack("<iiiB", f["dx_mm_q16"], f["dy_mm_q16"], f["dtheta_deg_q16"], f["status"])
    if message.name == "GET_BASE_BUMPER_DATA":
        return struct.pack("<I", f["bitmap"])
    if message.name == "GET_BASE_SENSOR_DATA":
        readings = f["distances_mm_q16"]
        assert isinstance(readings, tuple)
        return struct.pack("<16I", *readings)
    if message.name == "POLL_BASE_CMD":
        return b""
    if message.name == "GET_BASE_STATUS":
        return struct.pack("<BB", f["battery_percent"], f["power_status"])
    if message.name == "HEALTH_GET_HEALTH":
        return struct.pack("<BB", f["flags"], f["error_count"])
    raise ValueError(f"no answer layout for {message.name}")


def request_payload(message: SessionMessage) -> bytes:
    """The CTRL_BUS payload of a request: request code, then arguments."""
    code = REQUEST_CODES[message.name]
    if message.name == "SET_V_AND_GET_DEADRECKON":
        f = message.fields
        return code + struct.pack("<iii", f["vx_mps_q16"], f["vy_mps_q16"], f["omega_radps_q16"])
    return code


def encode_frame(long: bool, cmd: int, payload: bytes) -> bytes:
    """One frame on the wire, through ctrlbus.frame's encoder when it exists."""
    encoder = _ctrlbus_encoder()
    if encoder is not None:
        return bytes(encoder(cmd, payload, long=long))
    return _bench_encode_frame(long, cmd, payload)


def _ctrlbus_encoder() -> Any:
    try:
        frame = ctrlbus_module("frame")
    except Pending:
        return None
    return getattr(frame, "encode", None)


def _bench_encode_frame(long: bool, cmd: int, payload: bytes) -> bytes:
    # Used only until ctrlbus.frame provides the encoder (the bench report says which one ran).
    size = len(payload) + 1
    head = bytes([FLAG_LONG, size & 0xFF, size >> 8]) if long else bytes([FLAG_STANDARD, size])
    body = head + bytes([cmd]) + payload
    checksum = 0
    for byte in body:
        checksum ^= byte
    return body + bytes([checksum])


def encoder_in_use() -> str:
    """Which frame encoder built the synthetic captures (for the results)."""
    probe = encode_frame(False, 0x00, b"")
    if probe != _bench_encode_frame(False, 0x00, b""):
        raise ValueError("ctrlbus.frame encoder disagrees with the wire reference on a SYNC frame")
    if _ctrlbus_encoder() is None:
        return "bench-local encoder (ctrlbus.frame has no encoder yet)"
    return "ctrlbus.frame.encode"


def timed_session_frames(seconds: float, seed: int = 1) -> Iterator[tuple[float, bytes]]:
    """The synthetic session as wire frames with the time (ms) each is sent, in order."""
    for message in core_session(seconds, seed):
        if message.direction == "request":
            yield message.t_ms, encode_frame(False, CMD_CTRL_BUS, request_payload(message))
        else:
            yield message.t_ms, encode_frame(True, CMD_OK, answer_payload(message))


def session_frames(seconds: float, seed: int = 1) -> Iterator[bytes]:
    """The synthetic session as wire frames, in order."""
    for _, frame in timed_session_frames(seconds, seed):
        yield frame


def tile(units: Sequence[bytes], target_bytes: int) -> tuple[bytes, int]:
    """Repeat a sequence of whole frames until the next one would pass target_bytes.

    Returns the stream and how many frames it holds. Used to reach 50 MB without encoding
    millions of frames one by one; a parser has no way to tell a repeated period.
    """
    period = b"".join(units)
    if not period:
        raise ValueError("cannot tile an empty sequence of frames")
    whole, rest = divmod(target_bytes, len(period))
    count = whole * len(units)
    tail = bytearray()
    for unit in units:
        if len(tail) + len(unit) > rest:
            break
        tail += unit
        count += 1
    return period * whole + bytes(tail), count


SYNTHETIC_PERIOD_S = 600.0


def synthetic_capture(target_bytes: int, seed: int = 1) -> Capture:
    """A synthetic session of about target_bytes (whole frames; periods of 10 minutes repeated)."""
    seconds = SYNTHETIC_PERIOD_S
    frames = list(session_frames(seconds, seed))
    period_bytes = sum(len(f) for f in frames)
    if period_bytes > target_bytes:
        seconds = max(1.0, seconds * target_bytes / period_bytes + 1.0)
        frames = list(session_frames(seconds, seed))
    data, count = tile(frames, target_bytes)
    return Capture(data, count, f"synthetic Core<->base session at default rates, seed {seed}")


def load_capture(path: Path) -> Capture:
    """A recorded capture: a pcap written by ctrlbus.capture, or raw bytes as read from the UART.

    A pcap holds both directions in chunks that need not end on frame boundaries, so the Core's
    bytes and the base's bytes are each kept whole and in order: all requests, then all answers.
    """
    raw = path.read_bytes()
    try:
        capture = ctrlbus_module("capture")  # recorded sessions are written by this module
    except Pending:
        capture = None
    if capture is not None and capture.looks_like_capture(raw[:4]):
        records = capture.read_capture(path)
        sides = [b"".join(r.data for r in records if r.direction == side) for side in capture.Direction]
        return Capture(b"".join(sides), 0, f"pcap recording {path.name} (Core→base bytes, then base→Core)")
    return Capture(raw, 0, f"raw recording {path.name}")


def split_frames(data: bytes) -> list[bytes]:
    """Cut a clean stream of frames (no noise) into its frames, by their length fields."""
    frames: list[bytes] = []
    pos = 0
    while pos < len(data):
        flag = data[pos]
        if flag == FLAG_STANDARD and pos + 1 < len(data):
            size = 2 + data[pos + 1] + 1
        elif flag == FLAG_LONG and pos + 2 < len(data):
            size = 3 + (data[pos + 1] | data[pos + 2] << 8) + 1
        else:
            raise ValueError(f"byte {pos} of the capture does not start a frame (0x{flag:02X})")
        if pos + size > len(data):
            raise ValueError(f"the capture ends inside a frame at byte {pos}")
        frames.append(data[pos : pos + size])
        pos += size
    return frames


def add_noise(
    frames: Sequence[bytes],
    *,
    ber: float = 1e-4,
    bursts_per_frame: float = 0.01,
    burst_max: int = 64,
    seed: int = 7,
) -> NoisyStream:
    """The frames with independent bit errors at `ber` and bursts of random bytes between frames.

    A burst (1..burst_max random bytes) lands before a frame with probability bursts_per_frame,
    so it may contain false flags with bogus lengths in front of a valid frame: the case the
    recovery comparison is about. A frame counts as intact when none of its own bits flipped.
    """
    rng = random.Random(seed)
    pieces: list[bytes] = []
    intact: list[bool] = []
    bit_errors = bursts = burst_bytes = 0
    # Distance in bits to the next flipped bit (geometric), carried across frames.
    next_flip = _geometric(rng, ber)
    for frame in frames:
        burst = b""
        if rng.random() < bursts_per_frame:
            burst = rng.randbytes(rng.randint(1, burst_max))
            bursts += 1
            burst_bytes += len(burst)
        body = bytearray(frame)
        bits = len(body) * 8
        hit = False
        position = next_flip
        while position < bits:
            body[position // 8] ^= 1 << (position % 8)
            bit_errors += 1
            hit = True
            position += 1 + _geometric(rng, ber)
        next_flip = position - bits
        intact.append(not hit)
        pieces.append(burst + body)
    return NoisyStream(pieces, list(frames), intact, bit_errors, bursts, burst_bytes)


def _geometric(rng: random.Random, p: float) -> int:
    """Number of unflipped bits before the next flip, for independent flips of probability p."""
    if p <= 0.0:
        return 1 << 62
    return int(math.log(1.0 - rng.random()) / math.log(1.0 - p))
