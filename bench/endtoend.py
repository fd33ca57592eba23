# SPDX-License-Identifier: MIT
"""End to end: the Core emulator against real base processes, and the link efficiency at 115200 8N1.

Two benchmarks share this module, and the bases they drive:

- the C host base, `posix_base --pty` (the C base stack serving the simulated base), built here as
  a Release copy in build/bench/c-release/;
- the Python simulated base, `ctrlbus sim --pty`.

Each runs as its own process behind a pseudo-terminal, which the master opens as a serial port
(`ctrlbus.ports.open_link`, pyserial), as it would a USB adapter.

**end_to_end** (no baud limit; a pty passes bytes as fast as the processes move them). Two
masters, each for a few seconds, against each base in turn:

- *back to back*: a master loop that sends SET_V_AND_GET_DEADRECKON, reads until its answer is
  decoded, and sends the next at once. It encodes and decodes with the Core emulator's own code
  (`messages.request_frame`, `frame.StreamDecoder`, `messages.decode_answer`): what the link and the
  base sustain, request after request;
- *Core emulator*: the real thing, `CoreSession` driven by its real-time runner `CoreRunner`,
  polling SET_V_AND_GET_DEADRECKON at the highest rate its configuration accepts (1000 Hz) and
  nothing else once connected. Its exchanges/s are the answers it completed; its schedule, not
  the base, is what limits it when the exchange takes less than a millisecond.

**link_efficiency**: both masters (as above) through `PacedLink`, a link wrapper that lets bytes
through no faster than a UART at 115200 8N1 (10 bits per byte) would, in each direction: a request
reaches the base only once its last byte would have arrived, and an answer reaches the master only
once its last byte would have. The base's reply latency (request handed over -> its answer's first
bytes read back) and the master's turnaround (answer returned -> next request written) are real.
Efficiency = achieved exchanges/s / (11520 B/s / (request + answer bytes)), the sizes read off the
frames that crossed the link. The Core session against the Python simulated base in virtual time
(`ctrlbus.vtime`, the line modelled at the same rate) shows the efficiency for a given base reply
latency and an instant Core: a sweep of latencies, and the latencies measured in real time.
"""

from __future__ import annotations

import contextlib
import os
import select
import shlex
import statistics
import subprocess
import sys
import time
from collections import deque
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common import (
    BUILD_DIR,
    FULL,
    MEASURED,
    REPO,
    SMOKE,
    BenchContext,
    BenchError,
    ensure_ctrlbus_importable,
    run_command,
    stop_process,
)
from findings import PARTIAL, Findings

ensure_ctrlbus_importable()

from ctrlbus.core.config import BITS_PER_BYTE, CoreConfig, PollRates  # noqa: E402  (after the path is set up)
from ctrlbus.core.runner import CoreRunner  # noqa: E402
from ctrlbus.core.session import CoreSession  # noqa: E402
from ctrlbus.frame import Frame, StreamDecoder  # noqa: E402
from ctrlbus.link import Link  # noqa: E402
from ctrlbus.messages import (  # noqa: E402
    Response,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    decode_answer,
    request_frame,
)
from ctrlbus.ports import open_link  # noqa: E402
from ctrlbus.sim.server import SimSettings, build_simulated_stack  # noqa: E402
from ctrlbus.vtime import VirtualBus  # noqa: E402

E2E_NAME = "end_to_end"
E2E_TITLE = "End to end: exchanges/s, Core emulator against the C host base and the Python simulated base"
E2E_GOAL = "measured and published (pty, no baud limit)"
LINK_NAME = "link_efficiency"
LINK_TITLE = "Link efficiency at 115200 8N1: SET_V exchanges/s over the theoretical maximum"
LINK_GOAL = "≥ 95 %"

C_SOURCE = REPO / "c"
C_BUILD = BUILD_DIR / "c-release"
POSIX_BASE = C_BUILD / "examples" / "posix_base" / "posix_base"

BAUD = 115200
BYTE_TIME_S = BITS_PER_BYTE / BAUD
EFFICIENCY_GOAL_PCT = 95.0

RUN_S = {FULL: 4.0, SMOKE: 0.5}  # measuring window of each real-time run
WARMUP_S = {FULL: 0.5, SMOKE: 0.2}  # after connecting, before the window opens
VIRTUAL_S = {FULL: 10.0, SMOKE: 1.0}  # simulated seconds per virtual-time run
LATENCY_SWEEP_MS = {FULL: [0.0, 0.05, 0.1, 0.2, 0.5, 1.0, 2.0, 5.0], SMOKE: [0.0, 1.0]}
START_LIMIT_S = 15.0
ANSWER_LIMIT_S = 1.0
# The Core emulator's fastest schedule: SET_V_AND_GET_DEADRECKON at the highest rate its
# configuration accepts, nothing else once connected.
SET_V_ONLY = PollRates(
    set_v_hz=1000.0,
    bumper_hz=0.0,
    sensor_hz=0.0,
    status_hz=0.0,
    motor_hz=0.0,
    poll_cmd_hz=0.0,
    health_hz=0.0,
    charger_hz=0.0,
)


# ---------------------------------------------------------------------------------------------
# The bases


@dataclass(frozen=True)
class BaseUnderTest:
    key: str
    label: str
    command: list[str]


def build_posix_base(ctx: BenchContext) -> Path:
    """A Release build of posix_base in build/bench/c-release (incremental)."""
    run_command(
        ctx,
        [
            "cmake",
            "-S",
            str(C_SOURCE),
            "-B",
            str(C_BUILD),
            "-G",
            "Ninja",
            "-DCMAKE_BUILD_TYPE=Release",
            "-DCTRLBUS_BUILD_TESTS=OFF",
        ],
    )
    run_command(ctx, ["cmake", "--build", str(C_BUILD), "--target", "posix_base"])
    if not POSIX_BASE.is_file():
        raise BenchError(f"the build made no {POSIX_BASE.relative_to(REPO)}")
    return POSIX_BASE


def bases_under_test(ctx: BenchContext) -> tuple[list[BaseUnderTest], list[str]]:
    """The two bases (the C one built first); and what is pending, if a base is missing."""
    bases: list[BaseUnderTest] = []
    pending: list[str] = []
    if (C_SOURCE / "examples" / "posix_base" / "main.c").is_file():
        bases.append(
            BaseUnderTest("c_base", "C host base (posix_base)", [str(build_posix_base(ctx)), "--pty"])
        )
    else:
        pending.append("the C host base (c/examples/posix_base) is not written yet")
    bases.append(
        BaseUnderTest(
            "python_base", "Python simulated base", [sys.executable, "-m", "ctrlbus", "sim", "--pty"]
        )
    )
    return bases, pending


@contextlib.contextmanager
def served_base(ctx: BenchContext, base: BaseUnderTest, log_path: Path) -> Iterator[str]:
    """Start the base, wait for its `pty: PATH` line, yield PATH; stop the base afterwards."""
    ctx.commands.append(shlex.join(base.command))
    env = {**os.environ, "PYTHONPATH": str(REPO / "python" / "src")}
    with open(log_path, "wb") as log:
        process = subprocess.Popen(
            base.command, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE, stderr=log, env=env
        )
    try:
        assert process.stdout is not None
        line = b""
        deadline = time.monotonic() + START_LIMIT_S
        while b"\n" not in line:
            ready, _, _ = select.select([process.stdout], [], [], max(0.0, deadline - time.monotonic()))
            chunk = os.read(process.stdout.fileno(), 256) if ready else b""
            if not chunk:
                raise BenchError(f"{base.label} printed no pty path: {log_path.read_text()[-500:]}")
            line += chunk
        first = line.split(b"\n", 1)[0].decode(errors="replace").strip()
        if not first.startswith("pty: "):
            raise BenchError(f"{base.label} printed {first!r}, not 'pty: PATH'")
        yield first.removeprefix("pty: ")
    finally:
        stop_process(process)


def load_row(before: float, after: float) -> list[str]:
    """The machine's load around a real-time run: other work on the cores slows every figure."""
    cores = os.cpu_count() or 1
    return [
        f"machine load during these runs (1-minute load average, {cores} cores)",
        "published",
        f"{before:.2f} at the start, {after:.2f} at the end",
        "",
        "",
        "yes",
    ]


def _percentile_ms(values: list[float], fraction: float) -> float:
    ordered = sorted(values)
    return 1000.0 * ordered[min(len(ordered) - 1, int(fraction * len(ordered)))]


# ---------------------------------------------------------------------------------------------
# Masters


def back_to_back(link: Link, seconds: float, warmup_s: float) -> dict[str, Any]:
    """SET_V_AND_GET_DEADRECKON, its answer, the next at once: for `seconds` after a warm-up; and
    the window's start and end (time.perf_counter). Closes the link."""
    decoder = StreamDecoder()
    latencies: list[float] = []
    exchanges = 0
    clock = time.perf_counter
    try:
        started = clock()
        window_start: float | None = None
        k = 0
        while True:
            now = clock()
            if window_start is None and now - started >= warmup_s:
                window_start, exchanges, latencies = now, 0, []
            if window_start is not None and now - window_start >= seconds:
                break
            request = SetVAndGetDeadreckon.from_si(0.2, 0.0, 0.5 if k % 2 else -0.5)
            k += 1
            sent = clock()
            link.write(request_frame(request))
            frames: list[Frame] = []
            while not frames:
                data = link.read(ANSWER_LIMIT_S)
                if not data:
                    raise BenchError(
                        f"{link.name}: no answer to SET_V_AND_GET_DEADRECKON within {ANSWER_LIMIT_S} s"
                    )
                frames = decoder.feed(data, clock())
            if len(frames) != 1 or frames[0].cmd != Response.OK:
                raise BenchError(f"{link.name}: answered {frames!r} to one SET_V_AND_GET_DEADRECKON")
            answer = decode_answer(request, frames[0].cmd, frames[0].payload)
            if not isinstance(answer, SetVAndGetDeadreckonAnswer):
                raise BenchError(f"{link.name}: answered {answer!r}")
            latencies.append(clock() - sent)
            exchanges += 1
        ended = clock()
    finally:
        link.close()
    return {
        "seconds": round(ended - window_start, 3),
        "exchanges": exchanges,
        "exchanges_per_s": round(exchanges / (ended - window_start), 1),
        "round_trip_p50_ms": round(_percentile_ms(latencies, 0.5), 3),
        "round_trip_p99_ms": round(_percentile_ms(latencies, 0.99), 3),
        "window": (window_start, ended),
    }


def run_core(link: Link, seconds: float, warmup_s: float) -> dict[str, Any]:
    """The Core emulator (CoreRunner, SET_V only at 1000 Hz) on `link`: answers completed per second
    over `seconds`, once connected and warmed up; and the window's start and end (time.perf_counter)."""
    session = CoreSession(CoreConfig(rates=SET_V_ONLY, byte_time_s=BYTE_TIME_S))
    runner = CoreRunner(session, link)
    runner.start()
    try:
        deadline = time.monotonic() + START_LIMIT_S

        def link_stats() -> dict[str, Any]:
            with runner.lock:  # the session is lock-free: its runner's lock guards it
                return session.link_stats()

        while not session.connected:
            if time.monotonic() > deadline or runner.failure or not runner.running:
                reason = link_stats()["reason"]
                raise BenchError(f"the Core emulator did not connect to {link.name}: {reason}")
            time.sleep(0.01)
        time.sleep(warmup_s)
        before, started = link_stats(), time.perf_counter()
        time.sleep(seconds)
        after, ended = link_stats(), time.perf_counter()
    finally:
        runner.stop()
    if runner.failure:
        raise BenchError(f"the Core runner failed: {runner.failure}")
    answers = after["answers"] - before["answers"]
    if answers <= 0:
        raise BenchError(f"the Core emulator completed no exchange with {link.name}")
    elapsed = ended - started
    return {
        "seconds": round(elapsed, 3),
        "exchanges": answers,
        "exchanges_per_s": round(answers / elapsed, 1),
        "requests": after["requests"] - before["requests"],
        "timeouts": after["timeouts"] - before["timeouts"],
        "retries": after["retries"] - before["retries"],
        # The session's own statistic, over its last 500 answers.
        "latency_p50_ms": after["latency_p50_ms"],
        "latency_p99_ms": after["latency_p99_ms"],
        "window": (started, ended),
    }


# ---------------------------------------------------------------------------------------------
# A link paced like a UART


SPIN_S = 0.0003  # the last stretch of a wait is spun on the clock: select() wakes up too late


class PacedLink:
    """`inner` with each direction limited to one byte per `byte_time_s`, as a UART line.

    write() waits until the data's last byte would have reached the other end, then hands it to
    `inner` whole: the base can act on a request only once its last byte is in anyway. (Handing
    it over byte by byte, as a UART would, costs a pyserial write and flush per byte, about as
    long as a byte takes at 115200 baud: the emulation falls behind the line.) Bytes read from
    `inner` are stamped when they are read; they start on the modelled line then (or when the
    bytes before them have left it) and read() returns them once their last byte has arrived.
    Records, with the time of each: the frames written and read (their sizes), the base's reply
    latency (request handed over -> first answer bytes read back), the master's turnaround (answer
    returned -> next write called) and how late the emulation let each frame through.
    """

    def __init__(
        self, inner: Link, byte_time_s: float, clock: Callable[[], float] = time.perf_counter
    ) -> None:
        self.inner = inner
        self.byte_time_s = byte_time_s
        self._clock = clock
        self._tx_free = 0.0
        self._rx_free = 0.0
        self._arriving: deque[tuple[float, bytes]] = deque()  # (arrival time, bytes)
        self._handed_over: float | None = None  # a request given to the base, its answer not seen yet
        self._returned: float | None = None  # an answer given to the master, no request since
        self.requests: list[tuple[float, float]] = []  # (when written, frame size): one write per frame
        self.answers: list[tuple[float, float]] = []  # (when read, frame size)
        self._answer_decoder = StreamDecoder(timeout=0)
        self.reply_latencies: list[tuple[float, float]] = []  # (when, seconds)
        self.turnarounds: list[tuple[float, float]] = []
        # How late the emulation itself lets bytes through (its waits end after the modelled time).
        self.write_lateness: list[tuple[float, float]] = []
        self.read_lateness: list[tuple[float, float]] = []

    @property
    def name(self) -> str:
        return f"paced({self.inner.name})"

    def write(self, data: bytes) -> None:
        now = self._clock()
        if self._returned is not None:
            self.turnarounds.append((now, now - self._returned))
            self._returned = None
        done = max(now, self._tx_free) + len(data) * self.byte_time_s
        self._tx_free = done
        self.requests.append((now, len(data)))
        self._pump(done)
        # The base's reply latency counts from here: passing the bytes through the OS (and
        # pyserial's flush) is part of the real path.
        handed_over = self._clock()
        self.write_lateness.append((handed_over, handed_over - done))
        self.inner.write(data)
        self._handed_over = handed_over

    def read(self, timeout: float) -> bytes:
        end = self._clock() + max(0.0, timeout)
        while True:
            now = self._clock()
            if self._arriving and self._arriving[0][0] <= now:
                pieces = []
                while self._arriving and self._arriving[0][0] <= now:
                    arrival, piece = self._arriving.popleft()
                    pieces.append(piece)
                self.read_lateness.append((now, now - arrival))
                self._returned = now
                return b"".join(pieces)
            if now >= end:
                return b""
            until = min(self._arriving[0][0], end) if self._arriving else end
            self._pump(until, stop_on_data=not self._arriving)

    def _pump(self, until: float, stop_on_data: bool = False) -> None:
        """Wait until `until`, stamping what `inner` delivers meanwhile; return early on new bytes
        if `stop_on_data`."""
        while True:
            left = until - self._clock()
            if left <= 0:
                return
            data = self.inner.read(left - SPIN_S if left > SPIN_S else 0.0)
            if data:
                self._stamp(data)
                if stop_on_data:
                    return

    def _stamp(self, data: bytes) -> None:
        now = self._clock()
        if self._handed_over is not None:
            self.reply_latencies.append((now, now - self._handed_over))
            self._handed_over = None
        arrival = max(now, self._rx_free) + len(data) * self.byte_time_s
        self._rx_free = arrival
        self._arriving.append((arrival, data))
        self.answers += [(now, frame.size) for frame in self._answer_decoder.feed(data)]

    def close(self) -> None:
        self.inner.close()


def theoretical_max(request_bytes: float, answer_bytes: float) -> float:
    """Exchanges per second when the line never idles: 11520 B/s over the bytes of one exchange."""
    return BAUD / BITS_PER_BYTE / (request_bytes + answer_bytes)


MASTERS = {
    "core": "Core emulator (CoreRunner)",
    "loop": "master loop (the Core's codec, no session)",
}


def paced_run(path: str, master: str, seconds: float, warmup_s: float) -> dict[str, Any]:
    """A master (`core` or `loop`) through a PacedLink at 115200 8N1 to the base on `path`."""
    link = PacedLink(open_link(path), BYTE_TIME_S)
    result = run_core(link, seconds, warmup_s) if master == "core" else back_to_back(link, seconds, warmup_s)
    started, ended = result.pop("window")

    def in_window(samples: list[tuple[float, float]]) -> list[float]:
        return [value for when, value in samples if started <= when <= ended]

    latencies, turnarounds = in_window(link.reply_latencies), in_window(link.turnarounds)
    requests, answers = in_window(link.requests), in_window(link.answers)
    if not latencies or not turnarounds or not requests or not answers:
        raise BenchError(f"no exchange through the paced link to {path} in the window")
    # The frames as the master sent them and the base answered (all of one size each, here).
    request_bytes, answer_bytes = statistics.fmean(requests), statistics.fmean(answers)
    maximum = theoretical_max(request_bytes, answer_bytes)
    result.update(
        {
            "request_bytes": round(request_bytes, 3),
            "answer_bytes": round(answer_bytes, 3),
            "theoretical_max_per_s": round(maximum, 2),
            "efficiency_pct": round(100.0 * result["exchanges_per_s"] / maximum, 2),
            "period_ms": round(1000.0 / result["exchanges_per_s"], 3),
            "line_time_ms": round(1000.0 * (request_bytes + answer_bytes) * BYTE_TIME_S, 3),
            "base_reply_latency_ms": round(1000.0 * statistics.median(latencies), 3),
            "base_reply_latency_mean_ms": round(1000.0 * statistics.fmean(latencies), 3),
            "base_reply_latency_p99_ms": round(_percentile_ms(latencies, 0.99), 3),
            "master_turnaround_ms": round(1000.0 * statistics.median(turnarounds), 3),
            "master_turnaround_mean_ms": round(1000.0 * statistics.fmean(turnarounds), 3),
            "master_turnaround_p99_ms": round(_percentile_ms(turnarounds, 0.99), 3),
            # How late the emulation let the request through to the base, and the answer to the master.
            "request_lateness_mean_ms": round(1000.0 * statistics.fmean(in_window(link.write_lateness)), 3),
            "answer_lateness_mean_ms": round(1000.0 * statistics.fmean(in_window(link.read_lateness)), 3),
        }
    )
    return result


# ---------------------------------------------------------------------------------------------
# Virtual time: the efficiency for a given base reply latency, the Core taking no time


def _next_answer(bus: VirtualBus, core: CoreSession) -> float:
    """Run until the Core completes its next answer; returns when it did (to 10 µs)."""
    count = core.link_stats()["answers"]
    if not bus.run_until(lambda: core.link_stats()["answers"] > count, timeout_s=1.0, check_period_s=1e-5):
        raise BenchError("no answer within a second in virtual time")
    return bus.now


def virtual_efficiency(latency_s: float, seconds: float) -> dict[str, Any]:
    """The Core session (SET_V only) against the Python simulated base in ctrlbus.vtime, the line
    at 115200 8N1, the base answering `latency_s` after a request's last byte."""
    _, stack = build_simulated_stack(SimSettings())
    core = CoreSession(CoreConfig(rates=SET_V_ONLY, byte_time_s=BYTE_TIME_S))
    bus = VirtualBus(core, stack, byte_time_s=BYTE_TIME_S, base_latency_s=latency_s)
    if not bus.run_until(lambda: core.connected, timeout_s=10.0):
        raise BenchError("the Core session did not connect to the simulated base in virtual time")
    bus.run_for(0.5)
    # The window runs from one answer's completion to another's, so no exchange is cut in two.
    started = _next_answer(bus, core)
    answers, to_base, to_core = (
        core.link_stats()["answers"],
        bus.to_base_line.bytes_sent,
        bus.to_core_line.bytes_sent,
    )
    bus.run_for(seconds)
    ended = _next_answer(bus, core)
    exchanges = core.link_stats()["answers"] - answers
    request_bytes = (bus.to_base_line.bytes_sent - to_base) / exchanges
    answer_bytes = (bus.to_core_line.bytes_sent - to_core) / exchanges
    achieved = exchanges / (ended - started)
    maximum = theoretical_max(request_bytes, answer_bytes)
    return {
        "base_reply_latency_ms": round(1000.0 * latency_s, 3),
        "exchanges_per_s": round(achieved, 2),
        "request_bytes": round(request_bytes, 3),
        "answer_bytes": round(answer_bytes, 3),
        "theoretical_max_per_s": round(maximum, 2),
        "efficiency_pct": round(100.0 * achieved / maximum, 2),
    }


# ---------------------------------------------------------------------------------------------
# The benchmarks


def run_end_to_end(ctx: BenchContext) -> Findings:
    bases, pending = bases_under_test(ctx)
    seconds, warmup = RUN_S[ctx.mode], WARMUP_S[ctx.mode]
    figures: dict[str, Any] = {}
    rows: list[list[str]] = []
    details: dict[str, Any] = {
        "run_seconds": seconds,
        "warmup_seconds": warmup,
        "core_rates": vars(SET_V_ONLY),
    }
    load_before = os.getloadavg()[0]
    for base in bases:
        with served_base(ctx, base, ctx.work_dir / f"{base.key}-loop.log") as path:
            loop = back_to_back(open_link(path), seconds, warmup)
        with served_base(ctx, base, ctx.work_dir / f"{base.key}-core.log") as path:
            core = run_core(open_link(path), seconds, warmup)
        loop.pop("window")
        core.pop("window")
        details[base.key] = {"command": base.command, "back_to_back": loop, "core_emulator": core}
        figures[f"{base.key}_back_to_back_exchanges_per_s"] = loop["exchanges_per_s"]
        figures[f"{base.key}_back_to_back_round_trip_p50_ms"] = loop["round_trip_p50_ms"]
        figures[f"{base.key}_back_to_back_round_trip_p99_ms"] = loop["round_trip_p99_ms"]
        figures[f"{base.key}_core_exchanges_per_s"] = core["exchanges_per_s"]
        figures[f"{base.key}_core_latency_p50_ms"] = core["latency_p50_ms"]
        figures[f"{base.key}_core_latency_p99_ms"] = core["latency_p99_ms"]
        figures[f"{base.key}_core_timeouts"] = core["timeouts"]
        rows.append(
            [
                f"{base.label}, pty: {MASTERS['loop']}, SET_V_AND_GET_DEADRECKON back to back",
                "published",
                f"{loop['exchanges_per_s']:,.0f} exchanges/s (round trip p50 "
                f"{loop['round_trip_p50_ms']:.2f} ms, p99 {loop['round_trip_p99_ms']:.2f} ms)",
                "",
                "",
                "yes",
            ]
        )
        rows.append(
            [
                f"{base.label}, pty: {MASTERS['core']}, SET_V polled at its 1000 Hz ceiling",
                "published",
                f"{core['exchanges_per_s']:,.0f} exchanges/s (latency p50 {core['latency_p50_ms']:.2f} ms, "
                f"p99 {core['latency_p99_ms']:.2f} ms; {core['timeouts']} timeouts)",
                "",
                "",
                "yes",
            ]
        )
    load_after = os.getloadavg()[0]
    rows.append(load_row(load_before, load_after))
    details["load_average_1min"] = [load_before, load_after]
    return Findings(MEASURED if not pending else PARTIAL, figures, rows, pending, details)


def _paced_row(base: BaseUnderTest, master: str, result: dict[str, Any]) -> list[str]:
    efficiency = result["efficiency_pct"]
    emulation = result["request_lateness_mean_ms"] + result["answer_lateness_mean_ms"]
    turnaround = "Core" if master == "core" else "master"
    return [
        f"{base.label}, {MASTERS[master]}, real time, pty paced at {BAUD} 8N1 "
        f"({result['request_bytes']:.0f} B request + {result['answer_bytes']:.0f} B answer)",
        f"≥ {EFFICIENCY_GOAL_PCT:g} %",
        f"{efficiency:.1f} %: {result['exchanges_per_s']:,.1f} of "
        f"{result['theoretical_max_per_s']:,.1f} exchanges/s. Per exchange (means): "
        f"{result['period_ms']:.3f} ms = {result['line_time_ms']:.3f} on the line + "
        f"{result['base_reply_latency_mean_ms']:.3f} base reply + "
        f"{result['master_turnaround_mean_ms']:.3f} {turnaround} turnaround + {emulation:.3f} emulation",
        "",
        f"{efficiency / 100:.3f}",
        "yes" if efficiency >= EFFICIENCY_GOAL_PCT else "**no**",
    ]


def run_link_efficiency(ctx: BenchContext) -> Findings:
    bases, pending = bases_under_test(ctx)
    seconds, warmup = RUN_S[ctx.mode], WARMUP_S[ctx.mode]
    figures: dict[str, Any] = {"baud": BAUD, "bits_per_byte": BITS_PER_BYTE}
    rows: list[list[str]] = []
    details: dict[str, Any] = {"run_seconds": seconds, "warmup_seconds": warmup, "spin_s": SPIN_S}
    line_ms: list[float] = []
    load_before = os.getloadavg()[0]
    for base in bases:
        details[base.key] = {"command": base.command}
        for master in MASTERS:
            with served_base(ctx, base, ctx.work_dir / f"{base.key}-{master}-paced.log") as path:
                result = paced_run(path, master, seconds, warmup)
            details[base.key][master] = result
            line_ms.append(result["line_time_ms"])
            for key in (
                "exchanges_per_s",
                "theoretical_max_per_s",
                "efficiency_pct",
                "base_reply_latency_mean_ms",
                "master_turnaround_mean_ms",
                "request_bytes",
                "answer_bytes",
                "timeouts",
            ):
                if key in result:
                    figures[f"{base.key}_{master}_{key}"] = result[key]
            rows.append(_paced_row(base, master, result))
    load_after = os.getloadavg()[0]
    rows.append(load_row(load_before, load_after))
    details["load_average_1min"] = [load_before, load_after]
    # What 95 % leaves per exchange for everything that is not the line.
    line = statistics.fmean(line_ms)
    budget_ms = line * (100.0 / EFFICIENCY_GOAL_PCT - 1.0)
    figures["turnaround_budget_ms"] = round(budget_ms, 3)
    rows.append(
        [
            f"time off the line per exchange that {EFFICIENCY_GOAL_PCT:g} % allows "
            f"(base reply + master turnaround)",
            "published",
            f"{budget_ms:.3f} ms (the line takes {line:.3f} ms)",
            "",
            "",
            "yes",
        ]
    )
    # Virtual time: an instant Core, the base replying after the latencies measured above, and a sweep.
    virtual_s = VIRTUAL_S[ctx.mode]
    measured = {base.key: details[base.key]["core"]["base_reply_latency_mean_ms"] for base in bases}
    latencies_ms = sorted({*LATENCY_SWEEP_MS[ctx.mode], *measured.values()})
    sweep = [virtual_efficiency(ms / 1000.0, virtual_s) for ms in latencies_ms]
    details["virtual_time"] = {"simulated_seconds": virtual_s, "sweep": sweep}
    by_latency = {point["base_reply_latency_ms"]: point for point in sweep}
    shown = [(measured[base.key], f"as measured for the {base.label}") for base in bases]
    if 1.0 in by_latency:
        shown.append((1.0, "vtime's default; the reference firmware answers 1-5 ms after a request"))
    for ms, why in shown:
        point = by_latency[round(ms, 3)]
        rows.append(
            [
                f"virtual time, Core taking no time, base reply latency {ms:.3f} ms ({why})",
                "published",
                f"{point['efficiency_pct']:.1f} % ({point['exchanges_per_s']:,.1f} exchanges/s)",
                "",
                f"{point['efficiency_pct'] / 100:.3f}",
                "yes",
            ]
        )
    for key, ms in measured.items():
        figures[f"{key}_virtual_efficiency_pct"] = by_latency[round(ms, 3)]["efficiency_pct"]
    return Findings(MEASURED if not pending else PARTIAL, figures, rows, pending, details)
