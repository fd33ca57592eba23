# SPDX-License-Identifier: MIT
"""Fault injection: a seeded model of a bad serial line, and a link that suffers from it.

The core is sans-IO: `FaultModel.apply(data, now)` takes one chunk that a writer put on the line
at time `now` and returns what reaches the other end and when, as `[(time, bytes), ...]` in
order. It never reads a clock and draws every random number from its own seeded generator, so
the same spec, seed, chunks and times always give the same faults.

    spec = FaultSpec.parse("ber=1e-4,burst=1e-3:1-64,drop=1e-4,delay=5ms,cut=2s@10s")
    to_base, to_core = fault_models(spec, seed=1)   # one model per direction, one shared clock
    pieces = to_base.apply(frame, now)             # [(arrival time, bytes), ...]

Three ways to use it:

- `FaultyLink(inner, spec, seed)`: any `Link` with faults applied to what is written (`tx`) and
  to what is read (`rx`), in real time; `ctrlbus.ports.open_link("fault:SPEC|URL")` builds one.
- `FaultFilter(model)`: the model as a `ctrlbus.vtime` byte filter (bytes in, bytes due out).
- `FaultModel` itself, for anything that moves bytes (the spy, a test).

docs/reliability.md is the manual: the spec grammar, what each fault does, and the counters.
"""

from __future__ import annotations

import math
import random
import re
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import asdict, dataclass, field
from typing import Any

from ctrlbus.compat import StrEnum
from ctrlbus.errors import UsageError
from ctrlbus.link import Link

__all__ = [
    "FAULT_URL_PREFIX",
    "CutWindow",
    "Delivery",
    "Direction",
    "DirectionFaults",
    "FaultCounters",
    "FaultFilter",
    "FaultModel",
    "FaultSpec",
    "FaultyLink",
    "fault_models",
    "split_fault_url",
]

FAULT_URL_PREFIX = "fault:"
FAULT_URL_SEPARATOR = "|"
DEFAULT_BURST_BYTES = (1, 64)
MAX_RUN_BYTES = 1 << 20  # largest burst, drop run or split piece a spec may ask for
_FLAGS = (0x10, 0x50)  # frame flags a garbage burst imitates


class Direction(StrEnum):
    """Which way bytes go, seen from whoever holds the link: `tx` is written, `rx` is read.

    For the Core emulator (and in `ctrlbus.vtime`, where the Core holds the line) tx is
    Core -> base and rx is base -> Core.
    """

    TX = "tx"
    RX = "rx"


# --- the spec ----------------------------------------------------------------------------------


@dataclass(frozen=True)
class CutWindow:
    """The line is silent for `duration_s` from `start_s` (seconds after the model's start),
    again every `every_s` if that is given."""

    duration_s: float
    start_s: float
    every_s: float | None = None

    def windows(self, until_s: float) -> list[tuple[float, float]]:
        """(start, end) of each occurrence that starts before `until_s`, relative to the start."""
        if self.start_s >= until_s:
            return []
        if self.every_s is None:
            return [(self.start_s, self.start_s + self.duration_s)]
        count = math.ceil((until_s - self.start_s) / self.every_s)
        return [
            (self.start_s + k * self.every_s, self.start_s + k * self.every_s + self.duration_s)
            for k in range(count)
        ]

    def begun(self, t_s: float) -> int:
        """How many occurrences have begun by `t_s` (relative to the start)."""
        if t_s < self.start_s:
            return 0
        if self.every_s is None:
            return 1
        return math.floor((t_s - self.start_s) / self.every_s) + 1

    def covers(self, t_s: float) -> bool:
        """Whether time `t_s` (relative to the start) is inside one of its occurrences."""
        if t_s < self.start_s:
            return False
        offset = t_s - self.start_s
        if self.every_s is not None:
            offset = math.fmod(offset, self.every_s)
        return offset < self.duration_s

    def __str__(self) -> str:
        text = f"{_seconds_text(self.duration_s)}@{_seconds_text(self.start_s)}"
        return text if self.every_s is None else f"{text}/{_seconds_text(self.every_s)}"


@dataclass(frozen=True)
class DirectionFaults:
    """The faults of one direction (see the module's manual, docs/reliability.md)."""

    ber: float = 0.0  # probability that a bit flips
    drop: float = 0.0  # probability, at each byte, that a run of bytes is lost from there
    drop_run: tuple[int, int] = (1, 1)  # length range of a lost run
    drop_chunk: float = 0.0  # probability that a whole chunk (one write) is lost
    burst: float = 0.0  # probability, at each byte, of garbage in front of it
    burst_bytes: tuple[int, int] = DEFAULT_BURST_BYTES
    split: tuple[int, int] | None = None  # deliver each chunk in pieces of this many bytes
    split_gap_s: float = 0.0  # time between two pieces of one chunk
    delay_s: float = 0.0
    jitter_s: float = 0.0  # extra delay, uniform in [0, jitter_s); order is kept
    cuts: tuple[CutWindow, ...] = ()

    @property
    def active(self) -> bool:
        return self != DirectionFaults()


@dataclass(frozen=True)
class FaultSpec:
    """A parsed fault spec: the faults of each direction and an optional seed."""

    tx: DirectionFaults = field(default_factory=DirectionFaults)
    rx: DirectionFaults = field(default_factory=DirectionFaults)
    seed: int | None = None

    def for_direction(self, direction: Direction) -> DirectionFaults:
        return self.tx if direction is Direction.TX else self.rx

    @classmethod
    def parse(cls, text: str) -> FaultSpec:
        """Parse `ITEM[,ITEM...]` (docs/reliability.md, "The fault spec"); UsageError naming the
        item that is wrong. An empty spec (or `none`) means no faults."""
        if not isinstance(text, str):
            raise UsageError(f"a fault spec must be text, got {type(text).__name__}")
        values: dict[Direction, dict[str, Any]] = {Direction.TX: {}, Direction.RX: {}}
        cuts: dict[Direction, list[CutWindow]] = {Direction.TX: [], Direction.RX: []}
        seed: int | None = None
        stripped = text.strip()
        if stripped.lower() == "none":
            stripped = ""
        for raw_item in stripped.split(","):
            item = raw_item.strip()
            if not item:
                if stripped:
                    raise UsageError(f"empty item in fault spec {text!r}")
                continue
            name, sep, value = item.partition("=")
            name, value = name.strip().lower(), value.strip()
            if not sep or not value:
                raise UsageError(f"bad fault spec item {item!r}: expected NAME=VALUE")
            scope, dot, key = name.rpartition(".")
            if dot and scope not in (Direction.TX, Direction.RX):
                raise UsageError(f"bad fault spec item {item!r}: direction must be tx or rx, not {scope!r}")
            directions = [Direction(scope)] if dot else [Direction.TX, Direction.RX]
            if key == "seed":
                if dot:
                    raise UsageError(f"bad fault spec item {item!r}: the seed is for both directions")
                if seed is not None:
                    raise UsageError(f"bad fault spec item {item!r}: seed given twice")
                seed = _parse_int(item, value, low=0, what="seed")
                continue
            parser = _ITEM_PARSERS.get(key)
            if parser is None:
                known = ", ".join([*_ITEM_PARSERS, "seed"])
                raise UsageError(f"bad fault spec item {item!r}: unknown fault {key!r} (known: {known})")
            parsed = parser(item, value)
            for direction in directions:
                if isinstance(parsed, CutWindow):
                    cuts[direction].append(parsed)
                    continue
                if key in values[direction]:
                    raise UsageError(f"bad fault spec item {item!r}: {key} given twice for {direction}")
                values[direction][key] = parsed
        built: dict[Direction, DirectionFaults] = {}
        for direction in Direction:
            settings: dict[str, Any] = {}
            for parsed in values[direction].values():
                settings.update(parsed)
            built[direction] = DirectionFaults(**settings, cuts=tuple(cuts[direction]))
        return cls(built[Direction.TX], built[Direction.RX], seed)

    def __str__(self) -> str:
        """The spec in canonical form (parses back to an equal spec)."""
        items: list[str] = []
        tx_items, rx_items = _items_of(self.tx), _items_of(self.rx)
        for item in tx_items:
            items.append(item if item in rx_items else f"tx.{item}")
        items += [f"rx.{item}" for item in rx_items if item not in tx_items]
        if self.seed is not None:
            items.append(f"seed={self.seed}")
        return ",".join(items) or "none"


def _items_of(faults: DirectionFaults) -> list[str]:
    items: list[str] = []
    if faults.ber:
        items.append(f"ber={faults.ber:g}")
    if faults.drop:
        items.append(f"drop={faults.drop:g}:{_range_text(faults.drop_run)}")
    if faults.drop_chunk:
        items.append(f"dropchunk={faults.drop_chunk:g}")
    if faults.burst:
        items.append(f"burst={faults.burst:g}:{_range_text(faults.burst_bytes)}")
    if faults.split is not None:
        gap = f":{_seconds_text(faults.split_gap_s)}" if faults.split_gap_s else ""
        items.append(f"split={_range_text(faults.split)}{gap}")
    if faults.delay_s or faults.jitter_s:
        jitter = f":{_seconds_text(faults.jitter_s)}" if faults.jitter_s else ""
        items.append(f"delay={_seconds_text(faults.delay_s)}{jitter}")
    items += [f"cut={cut}" for cut in faults.cuts]
    return items


def _range_text(bounds: tuple[int, int]) -> str:
    low, high = bounds
    return str(low) if low == high else f"{low}-{high}"


def _seconds_text(seconds: float) -> str:
    if seconds and seconds < 1.0:
        return f"{seconds * 1000.0:g}ms"
    return f"{seconds:g}s"


# --- parsing the values of the items -----------------------------------------------------------

_DURATION = re.compile(r"([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*(us|ms|s|min)")
_UNIT_S = {"us": 1e-6, "ms": 1e-3, "s": 1.0, "min": 60.0}


def _parse_probability(item: str, text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"bad fault spec item {item!r}: {what} {text!r} is not a number") from None
    if not (math.isfinite(value) and 0.0 <= value <= 1.0):
        raise UsageError(f"bad fault spec item {item!r}: {what} must be between 0 and 1, got {text}")
    return value


def _parse_int(item: str, text: str, *, low: int, what: str, high: int | None = None) -> int:
    if not text.isdigit():
        raise UsageError(f"bad fault spec item {item!r}: {what} {text!r} is not a whole number")
    value = int(text)
    if value < low or (high is not None and value > high):
        bound = f"{low}..{high}" if high is not None else f"at least {low}"
        raise UsageError(f"bad fault spec item {item!r}: {what} must be {bound}, got {value}")
    return value


def _parse_range(item: str, text: str, what: str) -> tuple[int, int]:
    low_text, dash, high_text = text.partition("-")
    low = _parse_int(item, low_text.strip(), low=1, high=MAX_RUN_BYTES, what=what)
    high = _parse_int(item, high_text.strip(), low=1, high=MAX_RUN_BYTES, what=what) if dash else low
    if high < low:
        raise UsageError(f"bad fault spec item {item!r}: {what} range {text!r} runs backwards")
    return low, high


def _parse_duration(item: str, text: str, what: str) -> float:
    match = _DURATION.fullmatch(text.strip())
    if match is None:
        raise UsageError(
            f"bad fault spec item {item!r}: {what} {text!r} is not a duration (a number and a unit: "
            "us, ms, s or min, as in 5ms)"
        )
    seconds = float(match.group(1)) * _UNIT_S[match.group(2)]
    if not math.isfinite(seconds):
        raise UsageError(f"bad fault spec item {item!r}: {what} {text!r} is too large")
    return seconds


def _parse_ber(item: str, value: str) -> dict[str, Any]:
    return {"ber": _parse_probability(item, value, "bit error rate")}


def _parse_drop(item: str, value: str) -> dict[str, Any]:
    probability, colon, run = value.partition(":")
    parsed: dict[str, Any] = {"drop": _parse_probability(item, probability, "drop probability")}
    if colon:
        parsed["drop_run"] = _parse_range(item, run, "run length")
    return parsed


def _parse_dropchunk(item: str, value: str) -> dict[str, Any]:
    return {"drop_chunk": _parse_probability(item, value, "chunk drop probability")}


def _parse_burst(item: str, value: str) -> dict[str, Any]:
    probability, colon, size = value.partition(":")
    parsed: dict[str, Any] = {"burst": _parse_probability(item, probability, "burst probability")}
    if colon:
        parsed["burst_bytes"] = _parse_range(item, size, "burst length")
    return parsed


def _parse_split(item: str, value: str) -> dict[str, Any]:
    size, colon, gap = value.partition(":")
    parsed: dict[str, Any] = {"split": _parse_range(item, size, "piece size")}
    if colon:
        parsed["split_gap_s"] = _parse_duration(item, gap, "gap")
    return parsed


def _parse_delay(item: str, value: str) -> dict[str, Any]:
    delay, colon, jitter = value.partition(":")
    parsed: dict[str, Any] = {"delay_s": _parse_duration(item, delay, "delay")}
    if colon:
        parsed["jitter_s"] = _parse_duration(item, jitter, "jitter")
    return parsed


def _parse_cut(item: str, value: str) -> CutWindow:
    duration_text, at, rest = value.partition("@")
    if not at:
        raise UsageError(
            f"bad fault spec item {item!r}: expected cut=DURATION@START[/EVERY], as in cut=2s@10s"
        )
    start_text, slash, every_text = rest.partition("/")
    duration = _parse_duration(item, duration_text, "cut duration")
    start = _parse_duration(item, start_text, "cut start")
    every = _parse_duration(item, every_text, "cut period") if slash else None
    if duration <= 0:
        raise UsageError(f"bad fault spec item {item!r}: a cut must last longer than 0 s")
    if every is not None and every <= duration:
        raise UsageError(f"bad fault spec item {item!r}: the cut period must be longer than the cut itself")
    return CutWindow(duration, start, every)


_ITEM_PARSERS: dict[str, Callable[[str, str], Any]] = {
    "ber": _parse_ber,
    "drop": _parse_drop,
    "dropchunk": _parse_dropchunk,
    "burst": _parse_burst,
    "split": _parse_split,
    "delay": _parse_delay,
    "cut": _parse_cut,
}


def _as_spec(spec: FaultSpec | str) -> FaultSpec:
    if isinstance(spec, FaultSpec):
        return spec
    return FaultSpec.parse(spec)


# --- the model ---------------------------------------------------------------------------------


@dataclass
class FaultCounters:
    """What a model has done so far (one direction)."""

    chunks: int = 0  # chunks given to apply()
    bytes_in: int = 0  # bytes given to apply()
    bytes_out: int = 0  # bytes delivered (garbage included)
    bits_flipped: int = 0
    bursts: int = 0
    burst_bytes: int = 0
    false_flags: int = 0  # 0x10 / 0x50 headers with a bogus length planted in bursts
    drop_runs: int = 0
    bytes_dropped: int = 0  # lost by `drop` (garbage included) and `dropchunk`
    chunks_dropped: int = 0  # lost whole by `dropchunk`
    cuts: int = 0  # cut windows that have begun
    bytes_cut: int = 0  # lost because they would have arrived during a cut
    pieces: int = 0  # deliveries made

    def as_dict(self) -> dict[str, int]:
        return asdict(self)


@dataclass(frozen=True)
class Delivery:
    """What became of one chunk: the pieces that arrive, and what happened on the way.

    `intact` says whether every byte of the chunk itself arrived unchanged, in one run with no
    garbage inside it (garbage in front of it and timing aside). `garbage` lists the bursts put
    on the line as (index of the chunk's byte they went in front of, length); `burst` is their
    total length. `flipped` and `dropped` count the chunk's own bits flipped and bytes lost (by
    drops and cuts).
    """

    pieces: list[tuple[float, bytes]]
    intact: bool
    burst: int = 0
    garbage: tuple[tuple[int, int], ...] = ()
    flipped: int = 0
    dropped: int = 0


class _Origin:
    """The time the cut windows count from: given, or the first time a model of the pair saw."""

    def __init__(self, value: float | None) -> None:
        self.value = value

    def at(self, now: float) -> float:
        if self.value is None:
            self.value = now
        return self.value


class FaultModel:
    """The faults of one direction of a line, sans-IO and deterministic.

    `spec` (a FaultSpec or spec text) and `direction` choose the faults; `seed` (default: the
    spec's `seed`, else 0) the random numbers; `origin` is the time the cut windows count from
    (default: the first `now` given). Not thread-safe: one caller at a time.
    """

    def __init__(
        self,
        spec: FaultSpec | str,
        seed: int | None = None,
        *,
        direction: Direction | str = Direction.TX,
        origin: float | None = None,
        _shared_origin: _Origin | None = None,
    ) -> None:
        self.spec = _as_spec(spec)
        try:
            self.direction = Direction(direction)
        except ValueError:
            raise UsageError(f"direction must be tx or rx, got {direction!r}") from None
        if seed is None:
            seed = self.spec.seed if self.spec.seed is not None else 0
        if isinstance(seed, bool) or not isinstance(seed, int):
            raise UsageError(f"seed must be an integer, got {seed!r}")
        self.seed = seed
        self.faults = self.spec.for_direction(self.direction)
        self.counters = FaultCounters()
        self._origin = _shared_origin if _shared_origin is not None else _Origin(origin)
        # One generator per concern, so that adding one fault does not reshuffle the others.
        self._rng = {
            name: random.Random(f"ctrlbus-faults:{seed}:{self.direction}:{name}")
            for name in ("chunk", "burst", "flip", "drop", "split", "delay")
        }
        # Bytes (bursts, drops) and bits (flips) to the next fault, carried from chunk to chunk so
        # that the faults do not depend on how the stream was cut into chunks.
        self._bytes_to_burst = self._gap(self._rng["burst"], self.faults.burst)
        self._bits_to_flip = self._gap(self._rng["flip"], self.faults.ber)
        self._bytes_to_drop = self._gap(self._rng["drop"], self.faults.drop)
        self._dropping = 0  # bytes still to lose of the current run
        self._last_delivery = -math.inf
        self._latest = -math.inf

    @property
    def origin(self) -> float | None:
        """The time cut windows count from, once known."""
        return self._origin.value

    def cut_windows(self, until: float) -> list[tuple[float, float]]:
        """Absolute (start, end) of every cut of this direction that begins before `until`."""
        origin = self._origin.value
        if origin is None:
            return []
        spans = [(origin + a, origin + b) for cut in self.faults.cuts for a, b in cut.windows(until - origin)]
        return sorted(spans)

    def in_cut(self, when: float) -> bool:
        origin = self._origin.at(when)
        return any(cut.covers(when - origin) for cut in self.faults.cuts)

    def apply(self, data: bytes | bytearray | memoryview, now: float) -> list[tuple[float, bytes]]:
        """The chunk `data`, written at `now`, as it arrives: `[(time, bytes), ...]`, times
        non-decreasing from call to call. An empty chunk only moves the model's time on."""
        return self.apply_detailed(data, now).pieces

    def apply_detailed(self, data: bytes | bytearray | memoryview, now: float) -> Delivery:
        """Like `apply`, with an account of what happened to the chunk."""
        if isinstance(now, bool) or not isinstance(now, int | float) or not math.isfinite(now):
            raise UsageError(f"time must be a finite number of seconds, got {now!r}")
        self._origin.at(now)
        self._note_time(now)
        chunk = bytes(data)
        if not chunk:
            return Delivery([], True)
        counters = self.counters
        counters.chunks += 1
        counters.bytes_in += len(chunk)
        if self.faults.drop_chunk and self._rng["chunk"].random() < self.faults.drop_chunk:
            counters.chunks_dropped += 1
            counters.bytes_dropped += len(chunk)
            return Delivery([], False, dropped=len(chunk))
        line, own, garbage = self._insert_bursts(chunk)
        flipped = self._flip(line, own)
        line, own, dropped = self._drop(line, own)
        pieces, cut = self._cut(self._schedule(bytes(line), now), own)
        counters.pieces += len(pieces)
        counters.bytes_out += sum(len(piece) for _, piece in pieces)
        inside = any(0 < at < len(chunk) for at, _ in garbage)
        intact = not (flipped or dropped or cut or inside)
        burst = sum(size for _, size in garbage)
        return Delivery(pieces, intact, burst, tuple(garbage), flipped, dropped + cut)

    # -- the faults, in the order they happen -------------------------------------------------
    #
    # `own` runs alongside the line: own[i] is 1 where line[i] is one of the chunk's bytes and 0
    # where it is garbage, so that each fault can tell what it hit.

    def _note_time(self, now: float) -> None:
        """Count the cut windows that have begun by `now`."""
        if now <= self._latest or not self.faults.cuts:
            return
        self._latest = now
        since = now - self._origin.at(now)
        self.counters.cuts = sum(cut.begun(since) for cut in self.faults.cuts)

    def _insert_bursts(self, chunk: bytes) -> tuple[bytearray, bytearray, list[tuple[int, int]]]:
        """Put garbage on the line in front of bytes of the chunk, each with the burst probability."""
        size = len(chunk)
        line = bytearray()
        own = bytearray()
        garbage: list[tuple[int, int]] = []
        start = 0
        while self.faults.burst and self._bytes_to_burst < size - start:
            at = start + self._bytes_to_burst
            burst = self._garbage()
            line += chunk[start:at]
            own += b"\x01" * (at - start)
            line += burst
            own += bytes(len(burst))
            garbage.append((at, len(burst)))
            start = at
            # The next burst goes in front of a later byte than this one.
            self._bytes_to_burst = 1 + self._gap(self._rng["burst"], self.faults.burst)
        if self.faults.burst:
            self._bytes_to_burst -= size - start
        line += chunk[start:]
        own += b"\x01" * (size - start)
        return line, own, garbage

    def _garbage(self) -> bytes:
        """Random bytes with one false frame header (0x10 or 0x50 and a bogus length) in them."""
        rng = self._rng["burst"]
        low, high = self.faults.burst_bytes
        garbage = bytearray(rng.randbytes(rng.randint(low, high)))
        if len(garbage) >= 2:
            flag = rng.choice(_FLAGS) if len(garbage) >= 3 else _FLAGS[0]
            header = 2 if flag == _FLAGS[0] else 3
            at = rng.randrange(len(garbage) - header + 1)
            garbage[at] = flag
            garbage[at + 1 : at + header] = rng.randbytes(header - 1)
            self.counters.false_flags += 1
        self.counters.bursts += 1
        self.counters.burst_bytes += len(garbage)
        return bytes(garbage)

    def _flip(self, line: bytearray, own: bytearray) -> int:
        """Flip bits at the bit error rate; returns how many flips hit the chunk's own bytes."""
        if not self.faults.ber:
            return 0
        bits = len(line) * 8
        position = self._bits_to_flip
        hits = 0
        while position < bits:
            line[position >> 3] ^= 1 << (position & 7)
            self.counters.bits_flipped += 1
            hits += own[position >> 3]
            position += 1 + self._gap(self._rng["flip"], self.faults.ber)
        self._bits_to_flip = position - bits
        return hits

    def _drop(self, line: bytearray, own: bytearray) -> tuple[bytearray, bytearray, int]:
        """Lose runs of bytes; returns the line and its own-mask without them, and how many of the
        chunk's own bytes were lost."""
        if not self.faults.drop and not self._dropping:
            return line, own, 0
        rng = self._rng["drop"]
        low, high = self.faults.drop_run
        size = len(line)
        kept = bytearray()
        kept_own = bytearray()
        lost_own = 0
        index = 0
        while index < size:
            if self._dropping:
                run = min(self._dropping, size - index)
                lost_own += own.count(1, index, index + run)
                self._dropping -= run
                self.counters.bytes_dropped += run
                index += run
                continue
            step = min(self._bytes_to_drop, size - index)
            kept += line[index : index + step]
            kept_own += own[index : index + step]
            index += step
            self._bytes_to_drop -= step
            if self._bytes_to_drop == 0 and self.faults.drop:
                # A run of lost bytes starts here; the gap after it is drawn now.
                self._dropping = rng.randint(low, high)
                self.counters.drop_runs += 1
                self._bytes_to_drop = self._gap(rng, self.faults.drop)
        return kept, kept_own, lost_own

    def _schedule(self, line: bytes, now: float) -> list[tuple[float, bytes]]:
        """Split into pieces and give each its arrival time (delay, jitter; order kept)."""
        if not line:
            return []
        faults = self.faults
        if faults.split is None:
            chunks = [line]
        else:
            rng = self._rng["split"]
            low, high = faults.split
            chunks = []
            index = 0
            while index < len(line):
                size = rng.randint(low, high)
                chunks.append(line[index : index + size])
                index += size
        delay = faults.delay_s
        if faults.jitter_s:
            delay += self._rng["delay"].random() * faults.jitter_s
        pieces: list[tuple[float, bytes]] = []
        for number, piece in enumerate(chunks):
            arrival = max(now + delay + number * faults.split_gap_s, self._last_delivery)
            self._last_delivery = arrival
            pieces.append((arrival, piece))
        return pieces

    def _cut(
        self, pieces: list[tuple[float, bytes]], own: bytearray
    ) -> tuple[list[tuple[float, bytes]], int]:
        """Lose the pieces that would arrive during a cut; returns the pieces left and how many of
        the chunk's own bytes were lost."""
        if not self.faults.cuts:
            return pieces, 0
        kept: list[tuple[float, bytes]] = []
        lost_own = 0
        offset = 0
        for arrival, piece in pieces:
            self._note_time(arrival)
            if self.in_cut(arrival):
                self.counters.bytes_cut += len(piece)
                lost_own += own.count(1, offset, offset + len(piece))
            else:
                kept.append((arrival, piece))
            offset += len(piece)
        return kept, lost_own

    @staticmethod
    def _gap(rng: random.Random, probability: float) -> int:
        """How many trials pass before the next hit, for independent hits of `probability`."""
        if probability <= 0.0:
            return 1 << 62
        if probability >= 1.0:
            return 0
        return int(math.log(1.0 - rng.random()) / math.log(1.0 - probability))


def fault_models(
    spec: FaultSpec | str, seed: int | None = None, *, origin: float | None = None
) -> tuple[FaultModel, FaultModel]:
    """(tx, rx): one model per direction of `spec`, counting cut windows from the same origin
    (`origin`, or the first time either model is given), so that a cut of both directions
    silences both at once."""
    parsed = _as_spec(spec)
    shared = _Origin(origin)
    return (
        FaultModel(parsed, seed, direction=Direction.TX, _shared_origin=shared),
        FaultModel(parsed, seed, direction=Direction.RX, _shared_origin=shared),
    )


class FaultFilter:
    """A FaultModel as a `ctrlbus.vtime` byte filter: `filter(data, now)` takes a write and
    returns the bytes due by `now` (held-back bytes come out on a later call, which vtime makes
    at every base tick)."""

    def __init__(
        self, model: FaultModel, observe: Callable[[bytes, float, Delivery], None] | None = None
    ) -> None:
        """`observe(chunk, now, delivery)`, if given, sees every non-empty chunk and its fate."""
        self.model = model
        self._observe = observe
        self._held: deque[tuple[float, bytes]] = deque()

    @property
    def held_bytes(self) -> int:
        return sum(len(piece) for _, piece in self._held)

    def __call__(self, data: bytes, now: float) -> bytes:
        delivery = self.model.apply_detailed(data, now)
        if data and self._observe is not None:
            self._observe(bytes(data), now, delivery)
        self._held.extend(delivery.pieces)
        out = bytearray()
        while self._held and self._held[0][0] <= now:
            out += self._held.popleft()[1]
        return bytes(out)


# --- the link ----------------------------------------------------------------------------------


class FaultyLink:
    """A Link that passes what is written through the `tx` faults and what is read through the
    `rx` faults, in real time.

    Delayed bytes are held in the wrapper: those due go out (or are returned) on the next `read`
    or `write`, and `read` wakes up for them, so with a runner reading every few milliseconds
    they are late by at most its read timeout. Cut windows count from the wrapper's creation.
    Thread-safe in the way links are: one reader, writers from any thread.
    """

    def __init__(
        self,
        inner: Link,
        spec: FaultSpec | str,
        seed: int | None = None,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.inner = inner
        self.spec = _as_spec(spec)
        self._clock = clock
        self.tx, self.rx = fault_models(self.spec, seed, origin=clock())
        self._tx_held: deque[tuple[float, bytes]] = deque()
        self._rx_held: deque[tuple[float, bytes]] = deque()
        self._lock = threading.Lock()

    @property
    def name(self) -> str:
        return f"{FAULT_URL_PREFIX}{self.spec}{FAULT_URL_SEPARATOR}{self.inner.name}"

    def counters(self) -> dict[str, dict[str, int]]:
        """What was injected so far, per direction."""
        with self._lock:
            return {"tx": self.tx.counters.as_dict(), "rx": self.rx.counters.as_dict()}

    def write(self, data: bytes) -> None:
        with self._lock:
            now = self._clock()
            self._tx_held.extend(self.tx.apply(data, now))
            self._flush_tx(now)

    def _flush_tx(self, now: float) -> None:
        """Write what is due (the caller holds the lock, which keeps the order of writes)."""
        due = bytearray()
        while self._tx_held and self._tx_held[0][0] <= now:
            due += self._tx_held.popleft()[1]
        if due:
            self.inner.write(bytes(due))

    def read(self, timeout: float) -> bytes:
        deadline = self._clock() + max(0.0, timeout)
        while True:
            now = self._clock()
            with self._lock:
                self._flush_tx(now)
                due = bytearray()
                while self._rx_held and self._rx_held[0][0] <= now:
                    due += self._rx_held.popleft()[1]
                wake = min([held[0][0] for held in (self._tx_held, self._rx_held) if held], default=deadline)
            if due:
                return bytes(due)
            # Read at least once, even with no time left: the bytes may be there already.
            data = self.inner.read(max(0.0, min(deadline, wake) - now))
            if data:
                arrived = self._clock()
                with self._lock:
                    self._rx_held.extend(self.rx.apply(data, arrived))
            elif self._clock() >= deadline:
                return b""

    def close(self) -> None:
        """Close the inner link; bytes still held back are lost, as on an unplugged cable."""
        with self._lock:
            self._tx_held.clear()
            self._rx_held.clear()
        self.inner.close()


def split_fault_url(url: str) -> tuple[FaultSpec, str]:
    """`fault:SPEC|URL` -> (the parsed spec, URL); UsageError if it is not of that form."""
    if not url.startswith(FAULT_URL_PREFIX):
        raise UsageError(f"not a fault URL (fault:SPEC|URL): {url!r}")
    spec_text, sep, inner = url[len(FAULT_URL_PREFIX) :].partition(FAULT_URL_SEPARATOR)
    if not sep or not inner.strip():
        raise UsageError(
            f"a fault URL needs the port after a '|': fault:SPEC|URL, as in "
            f"'fault:ber=1e-4|socket://127.0.0.1:5555'; got {url!r}"
        )
    return FaultSpec.parse(spec_text), inner.strip()
