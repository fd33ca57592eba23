# SPDX-License-Identifier: MIT
"""Fault-injection soak: the Core emulator drives a base through the fault injector for a long run.

Two kinds of run:

- **virtual time** (`run_virtual`): a `ctrlbus.core.CoreSession` and the Python simulated base
  (`ctrlbus.base.BaseStack` + `ctrlbus.sim.SimulatedBase`) in `ctrlbus.vtime`, with a
  `ctrlbus.faults.FaultModel` on each direction of the line. Deterministic and fast. Both ends
  are instrumented: a shadow decoder with the receiver's own settings sees exactly the bytes and
  times the receiver sees, and the fault filter records where each sent frame landed in the
  received stream and whether it arrived intact, so every frame a receiver accepts is known to
  be genuine or a corrupted one that passed the 8-bit XOR.
- **real time** (`run_realtime`): a base process listening on TCP (the C host base, or the Python
  simulated base for comparison), the Core emulator's real-time runner on a `FaultyLink` to it.
  Only what the Core sees can be counted there.

bench/run.py registers the benchmark (`soak`); docs/reliability.md explains the figures.
"""

from __future__ import annotations

import math
import os
import re
import select
import shlex
import statistics
import subprocess
import sys
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from common import (
    FULL,
    MEASURED,
    PENDING,
    REPO,
    SMOKE,
    BenchContext,
    BenchError,
    ensure_ctrlbus_importable,
    stop_process,
)
from endtoend import build_posix_base
from refmodel import ReferenceModelDecoder
from session import split_frames

ensure_ctrlbus_importable()

from ctrlbus import messages as m  # noqa: E402  (after the path is set up)
from ctrlbus.base import BaseConfig, BaseStack, VelocityLimits  # noqa: E402
from ctrlbus.core.config import CoreConfig, PollRates  # noqa: E402
from ctrlbus.core.runner import CoreRunner  # noqa: E402
from ctrlbus.core.session import ConnectionState, CoreSession  # noqa: E402
from ctrlbus.errors import MessageError  # noqa: E402
from ctrlbus.faults import Delivery, FaultFilter, FaultSpec, FaultyLink, fault_models  # noqa: E402
from ctrlbus.frame import Frame, StreamDecoder  # noqa: E402
from ctrlbus.link import Link  # noqa: E402
from ctrlbus.messages import SetVAndGetDeadreckonAnswer  # noqa: E402
from ctrlbus.ports import open_link  # noqa: E402
from ctrlbus.quirks import Quirks  # noqa: E402
from ctrlbus.sim.base import SimulatedBase  # noqa: E402
from ctrlbus.sim.world import World  # noqa: E402
from ctrlbus.vtime import VirtualBus  # noqa: E402

PARTIAL = "partial"
NAME = "soak"
TITLE = "Fault-injection soak: the Core emulator against a base through the fault injector"
GOAL = (
    "0 commands outside the velocity limits executed; wheels stopped ≤ 1.0 s after a cut; "
    "≥ 99.9 % of the valid requests recovered behind garbage bursts; 0 requests lost against the "
    "reference-quirks base"
)

# The line: bit errors at BER 1e-4 and a garbage burst (with a false header) in front of one byte
# in a thousand, both directions; a 2-second cable pull every two minutes (every 32 s in the smoke
# run). The cuts begin 2 s after a change of the velocity command (DRIVE_STEP_S): the robot is
# moving when the line goes silent.
SPEC = {
    FULL: "ber=1e-4,burst=1e-3:1-64,cut=2s@46s/120s",
    SMOKE: "ber=1e-4,burst=1e-3:1-64,cut=2s@10s/32s",
}
EXCHANGES = {FULL: 100_000, SMOKE: 2_000}
# The real-time runs go on until this many exchanges have completed, or for at most this long.
REALTIME_EXCHANGES = {FULL: 100_000, SMOKE: 300}
REALTIME_LIMIT_S = {FULL: 900.0, SMOKE: 20.0}
# Timeouts for a TCP link on one machine, where a base answers within a few milliseconds: the
# defaults (200 ms per request, 100 ms between bytes) are for a UART behind a USB adapter and would
# make the run wait out most of its time after the bursts.
REALTIME_REQUEST_TIMEOUT_S = 0.025
REALTIME_DECODER_TIMEOUT_S = 0.02
REALTIME_SPEC = {
    FULL: "ber=1e-4,burst=1e-3:1-64,cut=2s@22s/32s",
    SMOKE: "ber=1e-4,burst=1e-3:1-64,cut=1.5s@1.5s",
}
SEED = 1
WATCHDOG_GOAL_S = 1.0
WATCHDOG_LIMIT_S = WATCHDOG_GOAL_S + 1e-9  # the stack stops at last request + 1 s: float rounding only
RECOVERY_GOAL_PCT = 99.9

# The base refuses more than this; the Core is allowed more, and is told to go faster than the base
# allows part of the time, so that the limits have something to do.
BASE_LIMITS = {"max_vx_mps": 0.5, "max_omega_radps": 1.5, "max_wheel_mm_s": 600.0}
CORE_CONFIG = CoreConfig(max_vx_mps=1.0, max_omega_radps=3.0)
DRIVE_PATTERN = [(0.3, 0.4), (0.8, 0.5), (0.2, 2.5), (-0.3, -1.0), (0.6, -2.0), (0.1, 1.2)]
DRIVE_STEP_S = 4.0
VIRTUAL_SLICE_S = 1.0

LISTEN_ANY = ["--listen", "127.0.0.1:0"]  # the base picks a free port and prints it
# The bases' inter-byte timeout in the real-time runs: that of a base reading a UART at wire pace
# (their default, 100 ms, is for a host behind a USB adapter, and a false header in a burst would
# hold the line that long).
REALTIME_BASE_OPTIONS = ["--frame-timeout-ms", "20"]
LISTEN_LINE = re.compile(r"listen: 127\.0\.0\.1:(\d+)")
START_LIMIT_S = 15.0


@dataclass
class SoakOutcome:
    """Same fields as run.py's Outcome, which run.py builds from it."""

    status: str
    figures: dict[str, Any] = field(default_factory=dict)
    rows: list[list[str]] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)


# ---------------------------------------------------------------------------------------------
# Instrumentation


@dataclass
class Ledger:
    """One direction of the line, as the fault filter saw it: where each sent frame landed in
    the received stream, and whether it landed intact."""

    genuine: dict[int, bytes] = field(default_factory=dict)  # stream offset -> intact frame there
    starts: dict[int, bytes] = field(default_factory=dict)  # stream offset -> frame sent there
    received: list[bytes] = field(default_factory=list)  # the received stream, write by write
    bursts: list[float] = field(default_factory=list)  # when garbage went on the line
    frames_sent: int = 0
    corrupted_arrived: int = 0  # frames that arrived altered (bits flipped, garbage inside, cut short)
    offset: int = 0  # received stream offset of the next byte

    def observe(self, chunk: bytes, now: float, delivery: Delivery) -> None:
        arrived = b"".join(piece for _, piece in delivery.pieces)
        self.received.append(arrived)
        if delivery.garbage and arrived:
            self.bursts.append(now)
        # With nothing lost, the chunk's byte i landed at i plus the garbage put in front of it.
        nothing_lost = len(arrived) == len(chunk) + delivery.burst
        start = 0
        for frame in split_frames(chunk):
            end = start + len(frame)
            whole = False
            if nothing_lost:
                landed_at = start + sum(size for at, size in delivery.garbage if at <= start)
                broken = any(start < at < end for at, _ in delivery.garbage)
                self.starts[self.offset + landed_at] = frame
                whole = not broken and arrived[landed_at : landed_at + len(frame)] == frame
                if whole:
                    self.genuine[self.offset + landed_at] = frame
            if not whole and arrived:
                self.corrupted_arrived += 1
            self.frames_sent += 1
            start = end
        self.offset += len(arrived)


@dataclass(frozen=True)
class Accepted:
    """A frame a receiver accepted, and when."""

    frame: Frame
    time: float

    @property
    def offset(self) -> int:
        return self.frame.offset

    @property
    def raw(self) -> bytes:
        return self.frame.raw


class ShadowedBase:
    """A BaseStack with a second decoder that sees the same bytes at the same times, so that the
    frames the base accepts are known (the stack does not hand them out)."""

    def __init__(self, stack: BaseStack) -> None:
        self.stack = stack
        config = stack.config
        self.decoder = StreamDecoder(max_frame=config.max_frame, timeout=config.frame_timeout_s)
        self.accepted: list[Accepted] = []

    def _shadow(self, data: bytes, now: float) -> None:
        for frame in self.decoder.feed(data, now):
            self.accepted.append(Accepted(frame, now))

    def receive(self, data: bytes, now: float) -> bytes:
        self._shadow(data, now)
        return self.stack.receive(data, now)

    def tick(self, now: float) -> bytes:
        self._shadow(b"", now)
        return self.stack.tick(now)


class SoakSimulatedBase(SimulatedBase):
    """The simulated base, noting every motion command the stack passes on and every stop."""

    def __init__(self, world: World) -> None:
        super().__init__(world)
        self.now = 0.0
        self.motion: list[tuple[float, str, float, float]] = []  # (time, kind, a, b)
        self.stops: list[float] = []

    def advance(self, now: float) -> None:
        self.now = now  # the watchdog advances the world to its deadline before it stops it
        super().advance(now)

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        self.motion.append((self.now, "velocity", vx_mps, omega_radps))
        return super().set_velocity(vx_mps, vy_mps, omega_radps)

    def set_wheel_speeds(self, left_mm_s: float, right_mm_s: float) -> None:
        self.motion.append((self.now, "wheels", left_mm_s, right_mm_s))
        super().set_wheel_speeds(left_mm_s, right_mm_s)

    def stop_motors(self) -> None:
        self.stops.append(self.now)
        super().stop_motors()


class SoakCore(CoreSession):
    """The Core emulator, noting when each exchange completes and what it accepted."""

    def __init__(self, config: CoreConfig) -> None:
        super().__init__(config, port="soak")
        # The session's own decoder settings, so that this one accepts exactly what it accepts.
        self.decoder = StreamDecoder(max_frame=config.max_frame, timeout=config.decoder_timeout_s)
        self.accepted: list[Accepted] = []
        self.completions: list[float] = []
        self.states: list[tuple[float, ConnectionState]] = []
        self._now_seen = 0.0
        self._answers = 0
        self.subscribe(self._on_change)

    def _on_change(self, topic: str) -> None:
        if topic == "connection":
            self.states.append((self._now_seen, self.state))

    def poll(self, now: float) -> bytes | None:
        self._now_seen = now
        return super().poll(now)

    def receive(self, data: bytes, now: float) -> None:
        self._now_seen = now
        frames = self.decoder.feed(data, now)
        super().receive(data, now)
        if frames:
            self.accepted += [Accepted(frame, now) for frame in frames]
            answers = int(self.link_stats()["answers"])
            self.completions += [now] * (answers - self._answers)
            self._answers = answers


# ---------------------------------------------------------------------------------------------
# Virtual time: the Python simulated base


def _first_after(times: Sequence[float], moment: float) -> float | None:
    """The first of the ascending `times` at or after `moment`."""
    low, high = 0, len(times)
    while low < high:
        middle = (low + high) // 2
        if times[middle] < moment:
            low = middle + 1
        else:
            high = middle
    return times[low] if low < len(times) else None


def _percentile(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return ordered[max(0, min(len(ordered) - 1, math.ceil(fraction * len(ordered)) - 1))]


def score_by_offset(offsets: Sequence[int], raws: Sequence[bytes], ledger: Ledger) -> tuple[int, int]:
    """(valid frames recovered, false accepts) of frames a decoder delivered at these stream
    offsets: a delivered frame is a sent one when the sender's intact frame landed there."""
    recovered = sum(1 for at, raw in zip(offsets, raws, strict=True) if ledger.genuine.get(at) == raw)
    return recovered, len(raws) - recovered


def _false_accepts(accepted: list[Accepted], ledger: Ledger) -> tuple[list[Accepted], list[Accepted]]:
    """Accepted frames that were not sent as they are: (real frames altered on the way that
    still passed the checksum, frames made up of garbage and real bytes)."""
    altered: list[Accepted] = []
    made_up: list[Accepted] = []
    for frame in accepted:
        if ledger.genuine.get(frame.offset) == frame.raw:
            continue
        sent = ledger.starts.get(frame.offset)
        (altered if sent is not None and len(sent) == len(frame.raw) else made_up).append(frame)
    return altered, made_up


def _over_limits(kind: str, a: float, b: float, limits: VelocityLimits, track_mm: float) -> bool:
    slack = 1e-9
    if kind == "wheels":
        wheel_limit = limits.max_wheel_mm_s or math.inf
        return max(abs(a), abs(b)) > wheel_limit * (1 + slack)
    vx_limit = limits.max_vx_mps or math.inf
    omega_limit = limits.max_omega_radps or math.inf
    if abs(a) > vx_limit * (1 + slack) or abs(b) > omega_limit * (1 + slack):
        return True
    wheel_limit = limits.max_wheel_mm_s or math.inf
    return abs(1000.0 * a) + abs(b) * track_mm / 2.0 > wheel_limit * (1 + slack)


def _cut_recovery(cut: tuple[float, float], core: SoakCore) -> dict[str, Any]:
    """When exchanges went on after a cut, and when the Core was connected again."""
    start, end = cut
    first = _first_after(core.completions, end)
    connected = next((t for t, state in core.states if t >= end and state is ConnectionState.CONNECTED), None)
    return {
        "start_s": start,
        "end_s": end,
        "first_exchange_after_s": None if first is None else first - end,
        "reconnected_after_s": None if connected is None else connected - end,
    }


def _stop_after_cut(
    start: float, stops: list[float], ctrl_times: list[float]
) -> tuple[float | None, float | None]:
    """(seconds from the cut's start, seconds from the last request the base accepted) to the
    watchdog's stop; (0, None) when the wheels were stopped already when the cut began, (None,
    None) if they never stopped."""
    earlier = [t for t in stops if t < start]
    if earlier and not any(earlier[-1] < t <= start for t in ctrl_times):
        return 0.0, None
    stop = _first_after(stops, start)
    if stop is None:
        return None, None
    last = [t for t in ctrl_times if t < stop]
    return stop - start, (stop - last[-1]) if last else None


def run_virtual(spec_text: str, exchanges: int, seed: int = SEED) -> dict[str, Any]:
    """Drive the Python simulated base for `exchanges` completed exchanges in virtual time and
    measure everything; returns a dict of plain figures, plus the request ledger and the frames
    the base accepted for the recovery comparison."""
    spec = FaultSpec.parse(spec_text)
    world = World(seed=seed)
    track_mm = world.base.wheel_track_mm
    limits = VelocityLimits(**BASE_LIMITS, wheel_track_mm=track_mm)
    app = SoakSimulatedBase(world)
    stack = BaseStack(app, BaseConfig(limits=limits))
    base = ShadowedBase(stack)
    core = SoakCore(CORE_CONFIG)
    to_base_model, to_core_model = fault_models(spec, seed, origin=0.0)
    to_base, to_core = Ledger(), Ledger()
    bus = VirtualBus(
        core,
        base,
        to_base=FaultFilter(to_base_model, to_base.observe),
        to_core=FaultFilter(to_core_model, to_core.observe),
    )
    started = time.perf_counter()
    step = 0
    while len(core.completions) < exchanges:
        if core.connected and bus.now >= step * DRIVE_STEP_S:
            vx, omega = DRIVE_PATTERN[step % len(DRIVE_PATTERN)]
            core.set_velocity(vx, omega)
            step += 1
        bus.run_for(VIRTUAL_SLICE_S)
        if bus.now > 100.0 + exchanges:  # far beyond any plausible rate: the run is stuck
            raise BenchError(f"the soak stalled: {len(core.completions)} exchanges in {bus.now:.0f} s")
    wall_s = time.perf_counter() - started

    # Frames the base accepted that the Core never sent there: corrupted, yet through the XOR.
    base_altered, base_made_up = _false_accepts(base.accepted, to_base)
    base_false = base_altered + base_made_up
    executed = motion_wrong = 0
    for accepted in base_false:
        try:
            request = m.decode_request(accepted.frame.cmd, accepted.frame.payload)
        except MessageError:
            continue  # answered with an error, not executed
        executed += 1
        motion_wrong += isinstance(request, m.SetVAndGetDeadreckon | m.SetBaseMotor)
    core_altered, core_made_up = _false_accepts(core.accepted, to_core)
    over = [entry for entry in app.motion if _over_limits(entry[1], entry[2], entry[3], limits, track_mm)]

    # Cuts: when the wheels stopped, and how long until exchanges went on.
    ctrl_times = [accepted.time for accepted in base.accepted if accepted.frame.cmd == m.Cmd.CTRL_BUS]
    cuts = []
    for start, end in to_base_model.cut_windows(bus.now):
        if end + 1.0 > bus.now:
            continue
        cut = _cut_recovery((start, end), core)
        cut["stop_after_cut_s"], cut["stop_after_last_command_s"] = _stop_after_cut(
            start, app.stops, ctrl_times
        )
        cuts.append(cut)

    # Bursts: time from the garbage to the next completed exchange.
    cut_starts = [start for start, _ in to_base_model.cut_windows(bus.now)]
    burst_recovery = []
    for when in sorted(to_base.bursts + to_core.bursts):
        done = _first_after(core.completions, when)
        if done is None or any(when <= start <= done for start in cut_starts):
            continue  # a cut came first: it, not the burst, decides when exchanges go on
        burst_recovery.append(done - when)

    link = core.link_stats()
    counters = stack.counters()
    return {
        "spec": str(spec),
        "seed": seed,
        "virtual_s": bus.now,
        "wall_s": wall_s,
        "exchanges": len(core.completions),
        "requests": link["requests"],
        "retries": link["retries"],
        "timeouts": link["timeouts"],
        "disconnects": link["disconnects"],
        "base_frames_accepted": len(base.accepted),
        "requests_sent": to_base.frames_sent,
        "requests_corrupted_arrived": to_base.corrupted_arrived,
        "requests_false_accepts": len(base_false),
        "requests_altered_accepted": len(base_altered),
        "requests_made_up_accepted": len(base_made_up),
        "false_accepts_executed": executed,
        "motion_commands_wrong_values": motion_wrong,
        "answers_corrupted_arrived": to_core.corrupted_arrived,
        "answers_false_accepts": len(core_altered) + len(core_made_up),
        "answers_altered_accepted": len(core_altered),
        "answers_made_up_accepted": len(core_made_up),
        "false_accepts_at_base": [(round(a.time, 6), a.raw.hex(" ")) for a in base_false[:20]],
        "motion_commands": len(app.motion),
        "commands_clamped": counters.clamped_commands,
        "commands_over_limits": len(over),
        "watchdog_trips": counters.watchdog_trips,
        "cuts": cuts,
        "burst_recovery_s": burst_recovery,
        "faults_to_base": to_base_model.counters.as_dict(),
        "faults_to_core": to_core_model.counters.as_dict(),
        "base_decoder": asdict(counters.decoder),
        "ledger_to_base": to_base,
        "accepted_by_base": base.accepted,
        "limits": {**BASE_LIMITS, "wheel_track_mm": track_mm},
    }


# ---------------------------------------------------------------------------------------------
# Virtual time: the simulated base in reference-quirks mode

# The reference's own behaviour on a noisy line (reference §2-§4, ctrlbus.quirks): combined error
# bits, requests dropped behind garbage reports, no inter-byte timeout, the power-on silence. No
# cut: this run is about line faults, and what the Core loses to them.
QUIRKS_SPEC = "ber=1e-4,burst=1e-3:1-64"
QUIRKS_EXCHANGES = {FULL: 100_000, SMOKE: 2_000}


def run_quirks(spec_text: str, exchanges: int, seed: int = SEED) -> dict[str, Any]:
    """The Core emulator against the simulated base in reference-quirks mode, in virtual time,
    until `exchanges` exchanges have completed: the fate of every request the Core sent (the
    Core's own accounting, checked to add up) and every line-fault code by its bits."""
    spec = FaultSpec.parse(spec_text)
    world = World(seed=seed)
    limits = VelocityLimits(**BASE_LIMITS, wheel_track_mm=world.base.wheel_track_mm)
    stack = BaseStack(SimulatedBase(world), BaseConfig(limits=limits, quirks=Quirks.REFERENCE))
    core = SoakCore(CORE_CONFIG)
    to_base_model, to_core_model = fault_models(spec, seed, origin=0.0)
    bus = VirtualBus(core, stack, to_base=FaultFilter(to_base_model), to_core=FaultFilter(to_core_model))
    started = time.perf_counter()
    step = 0
    while len(core.completions) < exchanges:
        if core.connected and bus.now >= step * DRIVE_STEP_S:
            vx, omega = DRIVE_PATTERN[step % len(DRIVE_PATTERN)]
            core.set_velocity(vx, omega)
            step += 1
        bus.run_for(VIRTUAL_SLICE_S)
        if bus.now > 100.0 + exchanges:
            raise BenchError(f"the quirks soak stalled: {len(core.completions)} exchanges in {bus.now:.0f} s")
    wall_s = time.perf_counter() - started
    link = core.link_stats()
    in_flight = link["requests_tracked"] - (
        link["requests_answered"]
        + link["superseded"]
        + link["abandoned_at_disconnect"]
        + link["lost_requests"]
    )
    if in_flight not in (0, 1):  # at most the request in flight when the run stopped
        raise BenchError(f"the Core's request accounting does not add up: {in_flight} requests unaccounted")
    receiver = stack._reference_rx
    return {
        "spec": str(spec),
        "seed": seed,
        "virtual_s": round(bus.now, 1),
        "wall_s": round(wall_s, 1),
        "exchanges": len(core.completions),
        "requests_sent": link["requests"],
        "requests_tracked": link["requests_tracked"],
        "requests_answered": link["requests_answered"],
        "superseded": link["superseded"],
        "abandoned_at_disconnect": link["abandoned_at_disconnect"],
        "lost_requests": link["lost_requests"],
        "retries": link["retries"],
        "timeouts": link["timeouts"],
        "disconnects": link["disconnects"],
        "errors_by_code": link["errors_by_code"],
        "line_faults_by_bit": link["line_faults_by_bit"],
        "base_frames_never_run": None if receiver is None else receiver.dropped_frames,
        "base_error_reports": None if receiver is None else receiver.reports,
        "faults_to_base": to_base_model.counters.as_dict(),
        "faults_to_core": to_core_model.counters.as_dict(),
    }


# ---------------------------------------------------------------------------------------------
# Real time: a base process on TCP


class RecordingLink:
    """A link that keeps a copy of every byte it reads (what the base really sent)."""

    def __init__(self, inner: Link) -> None:
        self.inner = inner
        self.received = bytearray()

    @property
    def name(self) -> str:
        return self.inner.name

    def read(self, timeout: float) -> bytes:
        data = self.inner.read(timeout)
        self.received += data
        return data

    def write(self, data: bytes) -> None:
        self.inner.write(data)

    def close(self) -> None:
        self.inner.close()


def _start_listening(command: list[str], log_path: Path) -> tuple[subprocess.Popen[bytes], int]:
    """Start a base that prints `listen: 127.0.0.1:PORT` first; returns it and the port."""
    with open(log_path, "wb") as log:
        process = subprocess.Popen(command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=log)
    assert process.stdout is not None
    line = b""
    deadline = time.monotonic() + START_LIMIT_S
    while b"\n" not in line:
        remaining = deadline - time.monotonic()
        ready, _, _ = select.select([process.stdout], [], [], max(0.0, remaining))
        chunk = os.read(process.stdout.fileno(), 256) if ready else b""
        if not chunk:
            stop_process(process)
            raise BenchError(
                f"{' '.join(command)} printed no listening address: {log_path.read_text()[-500:]}"
            )
        line += chunk
    match = LISTEN_LINE.fullmatch(line.split(b"\n", 1)[0].decode(errors="replace").strip())
    if match is None:
        stop_process(process)
        raise BenchError(f"{' '.join(command)} printed {line!r}, not 'listen: 127.0.0.1:PORT'")
    return process, int(match.group(1))


def run_realtime(
    command: list[str], spec_text: str, exchanges: int, limit_s: float, log_path: Path, seed: int = SEED
) -> dict[str, Any]:
    """The Core emulator (real-time runner, polling SET_V as fast as the base answers) against a
    base process on TCP, through a FaultyLink, until `exchanges` have completed or for `limit_s`."""
    process, port = _start_listening(command, log_path)
    config = CoreConfig(
        rates=PollRates(set_v_hz=1000.0),
        max_vx_mps=CORE_CONFIG.max_vx_mps,
        max_omega_radps=CORE_CONFIG.max_omega_radps,
        request_timeout_s=REALTIME_REQUEST_TIMEOUT_S,
        decoder_timeout_s=REALTIME_DECODER_TIMEOUT_S,
    )
    core = SoakCore(config)
    recording = RecordingLink(open_link(f"socket://127.0.0.1:{port}"))
    link = FaultyLink(recording, spec_text, seed)
    runner = CoreRunner(core, link)
    started = time.monotonic()
    try:
        runner.start()
        step = 0
        while len(core.completions) < exchanges and time.monotonic() - started < limit_s:
            with runner.lock:  # the session is lock-free: its runner's lock guards it
                if core.connected and time.monotonic() - started >= step * DRIVE_STEP_S:
                    core.set_velocity(*DRIVE_PATTERN[step % len(DRIVE_PATTERN)])
                    step += 1
            time.sleep(0.05)
        elapsed = time.monotonic() - started
    finally:
        runner.stop()
        stop_process(process)
    if runner.failure:
        raise BenchError(f"the Core runner failed: {runner.failure}")
    # What the base really sent, before the faults: an answer the Core accepted that is none of
    # those passed the checksum corrupted (one that happens to equal another answer is missed).
    sent = {frame.raw for frame in StreamDecoder(timeout=0).feed(bytes(recording.received))}
    false_accepts = sum(1 for accepted in core.accepted if accepted.raw not in sent)
    cuts = []
    for window in link.tx.cut_windows(started + elapsed):
        if window[1] + 1.0 > started + elapsed:
            continue
        cuts.append(_cut_recovery(window, core))
    stats = core.link_stats()
    return {
        "command": command,
        "spec": str(link.spec),
        "seconds": elapsed,
        "request_timeout_s": config.request_timeout_s,
        "decoder_timeout_s": config.decoder_timeout_s,
        "exchanges": len(core.completions),
        "exchanges_per_s": len(core.completions) / elapsed,
        "retries": stats["retries"],
        "timeouts": stats["timeouts"],
        "disconnects": stats["disconnects"],
        "answers_false_accepts": false_accepts,
        "cuts": cuts,
        "faults": link.counters(),
    }


# ---------------------------------------------------------------------------------------------
# The benchmark


def _seconds(value: float | None) -> str:
    return "—" if value is None else f"{value:.3f} s"


def _worst(values: list[float | None]) -> float | None:
    known = [value for value in values if value is not None]
    return max(known) if known else None


def run(ctx: BenchContext) -> SoakOutcome:
    """The soak benchmark (registered in run.py)."""
    mode = ctx.mode
    spec = SPEC[mode]
    virtual = run_virtual(spec, EXCHANGES[mode])
    ledger: Ledger = virtual.pop("ledger_to_base")
    accepted: list[Accepted] = virtual.pop("accepted_by_base")

    # Recovery behind garbage: the requests as they reached the base, for our base's decoder and
    # for the reference receiver model (bench/refmodel.py) fed the same bytes. A delivered frame
    # counts when the Core's intact frame landed at that very offset of the stream (the ledger
    # knows), which stays exact with retries and look-alike frames in the stream.
    valid = len(ledger.genuine)
    ours, ours_false = score_by_offset(
        [frame.offset for frame in accepted], [frame.raw for frame in accepted], ledger
    )
    reference = ReferenceModelDecoder()
    delivered = [frame for piece in ledger.received for frame in reference.feed(piece)]
    theirs, theirs_false = score_by_offset(reference.offsets, delivered, ledger)
    ours_pct = 100.0 * ours / valid if valid else 0.0
    theirs_pct = 100.0 * theirs / valid if valid else 0.0

    cuts = virtual["cuts"]
    stops = [cut["stop_after_last_command_s"] for cut in cuts]
    stops_from_cut = [cut["stop_after_cut_s"] for cut in cuts]
    never_stopped = sum(1 for cut in cuts if cut["stop_after_cut_s"] is None)
    stop_worst = _worst(stops)
    first_after_cut = _worst([cut["first_exchange_after_s"] for cut in cuts])
    reconnect_worst = _worst([cut["reconnected_after_s"] for cut in cuts])
    bursts = virtual["burst_recovery_s"]
    corrupted = virtual["requests_corrupted_arrived"]
    false_pct = 100.0 * virtual["requests_false_accepts"] / corrupted if corrupted else 0.0

    figures: dict[str, Any] = {
        "virtual_exchanges": virtual["exchanges"],
        "virtual_seconds": round(virtual["virtual_s"], 1),
        "virtual_wall_seconds": round(virtual["wall_s"], 2),
        "virtual_retries": virtual["retries"],
        "virtual_timeouts": virtual["timeouts"],
        "virtual_disconnects": virtual["disconnects"],
        "requests_sent": virtual["requests_sent"],
        "requests_corrupted_arrived": corrupted,
        "requests_false_accepts": virtual["requests_false_accepts"],
        "requests_altered_accepted": virtual["requests_altered_accepted"],
        "requests_made_up_accepted": virtual["requests_made_up_accepted"],
        "requests_false_accept_pct": round(false_pct, 3),
        "false_accepts_executed": virtual["false_accepts_executed"],
        "motion_commands_wrong_values": virtual["motion_commands_wrong_values"],
        "answers_corrupted_arrived": virtual["answers_corrupted_arrived"],
        "answers_false_accepts": virtual["answers_false_accepts"],
        "motion_commands": virtual["motion_commands"],
        "commands_clamped": virtual["commands_clamped"],
        "commands_over_limits": virtual["commands_over_limits"],
        "cuts": len(cuts),
        "cuts_never_stopped": never_stopped,
        "bursts": len(bursts),
        "valid_requests": valid,
        "ctrlbus_recovered_pct": round(ours_pct, 4),
        "ctrlbus_false_accepts": ours_false,
        "reference_model_recovered_pct": round(theirs_pct, 4),
        "reference_model_false_accepts": theirs_false,
    }
    optional = {
        "stop_after_last_command_worst_s": stop_worst,
        "stop_after_cut_worst_s": _worst(stops_from_cut),
        "first_exchange_after_cut_worst_s": first_after_cut,
        "reconnected_after_cut_worst_s": reconnect_worst,
    }
    if bursts:
        optional.update(
            {
                "burst_recovery_p50_s": statistics.median(bursts),
                "burst_recovery_p99_s": _percentile(bursts, 0.99),
                "burst_recovery_max_s": max(bursts),
            }
        )
    figures.update({key: round(value, 4) for key, value in optional.items() if value is not None})

    stop_met = bool(cuts) and never_stopped == 0 and stop_worst is not None and stop_worst <= WATCHDOG_LIMIT_S
    rows = [
        [
            f"Python simulated base, virtual time, `{spec}`: exchanges completed (retries, disconnects)",
            f"{EXCHANGES[mode]:,}",
            f"{virtual['exchanges']:,} ({virtual['retries']:,}, {virtual['disconnects']})",
            "",
            "",
            "yes" if virtual["exchanges"] >= EXCHANGES[mode] else "**no**",
        ],
        [
            "corrupted requests the base accepted (passed the 8-bit XOR): altered / made of garbage",
            "published",
            f"{virtual['requests_false_accepts']} of {corrupted:,} corrupted ({false_pct:.2f} %): "
            f"{virtual['requests_altered_accepted']} / {virtual['requests_made_up_accepted']}",
            "",
            "",
            "yes",
        ],
        [
            "of those, executed as requests / as motion commands (values the Core did not send)",
            "published",
            f"{virtual['false_accepts_executed']} / {virtual['motion_commands_wrong_values']}",
            "",
            "",
            "yes",
        ],
        [
            "corrupted answers the Core accepted",
            "published",
            f"{virtual['answers_false_accepts']} of {virtual['answers_corrupted_arrived']:,} corrupted",
            "",
            "",
            "yes",
        ],
        [
            f"motion commands outside the velocity limits executed (of {virtual['motion_commands']:,}; "
            f"{virtual['commands_clamped']:,} clamped)",
            "0",
            str(virtual["commands_over_limits"]),
            "",
            "",
            "yes" if virtual["commands_over_limits"] == 0 else "**no**",
        ],
        [
            f"wheels stopped after a cut, worst of {len(cuts)}: from the last request that got through "
            "/ from the cut's start",
            f"≤ {WATCHDOG_GOAL_S:.1f} s",
            f"{_seconds(stop_worst)} / {_seconds(_worst(stops_from_cut))}"
            + (f" ({never_stopped} never stopped)" if never_stopped else ""),
            "",
            "",
            "yes" if stop_met else "**no**",
        ],
        [
            "recovery after a cut, worst: first exchange / connected again (from the cut's end)",
            "published",
            f"{_seconds(first_after_cut)} / {_seconds(reconnect_worst)}",
            "",
            "",
            "yes",
        ],
        [
            f"recovery after a burst: next exchange, p50 / p99 / max of {len(bursts):,} bursts",
            "published",
            " / ".join(_seconds(figures.get(f"burst_recovery_{k}_s")) for k in ("p50", "p99", "max")),
            "",
            "",
            "yes",
        ],
        [
            f"valid requests the base's decoder recovered (of {valid:,}, same stream)",
            f"≥ {RECOVERY_GOAL_PCT} %",
            f"{ours_pct:.3f} %",
            f"{theirs_pct:.3f} % (reference receiver model, bench/refmodel.py: no backtracking, no timeout)",
            f"false accepts: {ours_false} vs {theirs_false}",
            "yes" if ours_pct >= RECOVERY_GOAL_PCT else "**no**",
        ],
    ]
    details: dict[str, Any] = {
        "virtual": {key: value for key, value in virtual.items() if key not in ("cuts", "burst_recovery_s")},
        "virtual_cuts": cuts,
        "reference_model_counters": vars(reference.counters),
        "core_config": {"max_vx_mps": CORE_CONFIG.max_vx_mps, "max_omega_radps": CORE_CONFIG.max_omega_radps},
        "drive_pattern": DRIVE_PATTERN,
        "drive_step_s": DRIVE_STEP_S,
    }

    # The reference-quirks base (ctrlbus.quirks): what the Core loses to the reference's own ways.
    quirks = run_quirks(QUIRKS_SPEC, QUIRKS_EXCHANGES[mode])
    details["quirks"] = quirks
    figures.update(
        {
            "quirks_exchanges": quirks["exchanges"],
            "quirks_lost_requests": quirks["lost_requests"],
            "quirks_superseded": quirks["superseded"],
            "quirks_disconnects": quirks["disconnects"],
        }
    )
    line_faults = ", ".join(
        f"{code}: {count:,}" for code, count in quirks["errors_by_code"].items() if int(code, 16) < 0x100
    )
    rows.append(
        [
            f"reference-quirks simulated base, virtual time, `{quirks['spec']}`: requests lost "
            f"(of {quirks['requests_tracked']:,} that matter; {quirks['superseded']:,} periodic ones "
            f"superseded, {quirks['disconnects']} disconnects; line faults {line_faults})",
            "0",
            str(quirks["lost_requests"]),
            "",
            "",
            "yes" if quirks["lost_requests"] == 0 else "**no**",
        ]
    )

    pending: list[str] = []
    realtime_spec = REALTIME_SPEC[mode]
    # The C base as benchmarks build it: Release, shared with end_to_end (build/bench/c-release).
    build_error = ""
    try:
        c_base: list[str] | None = [str(build_posix_base(ctx)), *LISTEN_ANY, *REALTIME_BASE_OPTIONS]
    except BenchError as exc:
        c_base, build_error = None, str(exc).splitlines()[0]
    targets: list[tuple[str, str, list[str] | None]] = [
        ("c_base", "C host base (posix_base)", c_base),
        (
            "python_base",
            "Python simulated base",
            [sys.executable, "-m", "ctrlbus", "sim", *LISTEN_ANY, *REALTIME_BASE_OPTIONS],
        ),
    ]
    for key, name, command in targets:
        if command is None:
            pending.append(f"the {name} did not build ({build_error}): its real-time run waits for it")
            rows.append([f"{name}, TCP, real time: exchanges/s", "published", "pending", "", "", "pending"])
            continue
        ctx.commands.append(shlex.join(command))
        target = REALTIME_EXCHANGES[mode]
        result = run_realtime(
            command, realtime_spec, target, REALTIME_LIMIT_S[mode], ctx.work_dir / f"{key}.log"
        )
        details[f"realtime_{key}"] = result
        first = _worst([cut["first_exchange_after_s"] for cut in result["cuts"]])
        figures[f"{key}_exchanges_per_s"] = round(result["exchanges_per_s"], 1)
        figures[f"{key}_exchanges"] = result["exchanges"]
        figures[f"{key}_retries"] = result["retries"]
        figures[f"{key}_answers_false_accepts"] = result["answers_false_accepts"]
        rows.append(
            [
                f"{name}, TCP, real time, `{realtime_spec}`: exchanges completed in "
                f"{result['seconds']:.0f} s (exchanges/s; retries, disconnects; corrupted answers the Core "
                "accepted; worst time to the first exchange after the end of a cut, of "
                f"{len(result['cuts'])})",
                f"{target:,}",
                f"{result['exchanges']:,} ({result['exchanges_per_s']:,.0f}/s; {result['retries']:,}, "
                f"{result['disconnects']}; {result['answers_false_accepts']}; {_seconds(first)})",
                "",
                "",
                "yes" if result["exchanges"] >= target else "**no**",
            ]
        )
    status = PARTIAL if pending else MEASURED
    return SoakOutcome(status, figures, rows, pending, details)


# ---------------------------------------------------------------------------------------------
# Publishing into docs/reliability.md


def update_reliability_md(results: list[dict[str, Any]], target_dir: Path | None) -> None:
    """Rewrite the soak block of docs/reliability.md (or of a copy in `target_dir`, for a smoke
    run) from the soak result, if there is one."""
    from report import render_block, replace_block

    result = next((r for r in results if r["name"] == NAME), None)
    if result is None or result["status"] == PENDING:
        return
    source = REPO / "docs" / "reliability.md"
    target = source if target_dir is None else target_dir / "reliability.md"
    text = replace_block(source.read_text(), NAME, render_block(result, None, target.parent))
    target.write_text(text)


def main(argv: Sequence[str] | None = None) -> int:
    """`python bench/soak.py --quirks [--exchanges N]`: the reference-quirks run on its own, its
    figures as JSON on stdout (docs/reliability.md quotes them)."""
    import argparse
    import json

    parser = argparse.ArgumentParser(description=main.__doc__)
    parser.add_argument(
        "--quirks", action="store_true", help="run against the reference-quirks simulated base"
    )
    parser.add_argument("--exchanges", type=int, default=QUIRKS_EXCHANGES[FULL])
    parser.add_argument("--spec", default=QUIRKS_SPEC)
    parser.add_argument("--seed", type=int, default=SEED)
    args = parser.parse_args(argv)
    if not args.quirks:
        parser.error("only --quirks runs on its own; the whole soak is `bench/run.py --only soak`")
    print(json.dumps(run_quirks(args.spec, args.exchanges, args.seed), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
