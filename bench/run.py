#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Run the ctrlbus benchmarks: `make bench` runs this with no arguments.

Every benchmark writes bench/results/<name>.json (its figures, the exact commands, the machine
and the git revision), then the plots go to docs/img/ and the generated tables of
docs/performance.md are rewritten between their marker comments.

    .venv/bin/python bench/run.py                    # full run, updates docs/
    .venv/bin/python bench/run.py --smoke --out DIR  # tiny inputs, seconds; results, plots and a
                                                     # rendered copy of the docs go to DIR only
    .venv/bin/python bench/run.py --only c_parser_cost python_throughput
    .venv/bin/python bench/run.py --capture session.pcap   # parse a recorded session instead

Benchmarks that wait for a part of ctrlbus that does not exist yet report "pending" and say
what they wait for; a benchmark that fails makes the run exit with status 1.
"""

from __future__ import annotations

import argparse
import datetime
import json
import shlex
import sys
import tempfile
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import endtoend
import exchange
import footprint
import soak
from callgrind import (
    OPT_LEVELS,
    HarnessRun,
    callgrind,
    compile_flags,
    compile_harness,
    opt_key,
    per_byte,
    top_functions,
)
from common import (
    BENCH_DIR,
    BUILD_DIR,
    C_INCLUDE,
    FAILED,
    FULL,
    MEASURED,
    PENDING,
    REPO,
    SMOKE,
    BenchContext,
    BenchError,
    git_revision,
    machine_facts,
)
from mavlink.generate import generate_c, generate_python
from mavlink.stream import mavlink_capture, split_mavlink
from ours import FeedFrames, Pending, c_decoder_sources, python_decoder_counting, python_decoder_frames
from refmodel import ReferenceModelDecoder
from session import (
    Capture,
    NoisyStream,
    add_noise,
    encoder_in_use,
    load_capture,
    split_frames,
    synthetic_capture,
    timed_session_frames,
)

PARTIAL = "partial"  # the peer's side measured, ours pending

# Stream sizes per run mode.
C_STREAM_BYTES = {FULL: 4 << 20, SMOKE: 64 << 10}
PY_STREAM_BYTES = {FULL: 50_000_000, SMOKE: 256 << 10}
PY_REPEATS = {FULL: 3, SMOKE: 1}
RECOVERY_SESSION_S = {FULL: 3600.0, SMOKE: 60.0}

FEED_CHUNK = 4096  # bytes handed to a Python decoder per call, as a serial read would
NOISE_BER = 1e-4
BURSTS_PER_FRAME = 0.01
BURST_MAX = 64


@dataclass
class Options:
    capture: Path | None = None
    # The commit the run measures, read once before it starts: the run writes result files, which
    # would otherwise make every benchmark after the first look measured on a modified tree.
    git: dict[str, Any] = field(default_factory=git_revision)


@dataclass
class Outcome:
    """What a benchmark found. `rows` are the table lines for docs/performance.md."""

    status: str
    figures: dict[str, Any] = field(default_factory=dict)
    rows: list[list[str]] = field(default_factory=list)
    pending: list[str] = field(default_factory=list)
    details: dict[str, Any] = field(default_factory=dict)


BenchFunction = Callable[[BenchContext, Options], Outcome]


@dataclass(frozen=True)
class Benchmark:
    name: str
    title: str
    goal: str
    run: BenchFunction


BENCHMARKS: dict[str, Benchmark] = {}


def benchmark(name: str, title: str, goal: str) -> Callable[[BenchFunction], BenchFunction]:
    def register(func: BenchFunction) -> BenchFunction:
        BENCHMARKS[name] = Benchmark(name, title, goal, func)
        return func

    return register


# ---------------------------------------------------------------------------------------------
# Formatting helpers for table rows


def fmt(value: float | None, digits: int = 1) -> str:
    return "pending" if value is None else f"{value:,.{digits}f}"


def verdict(met: bool | None) -> str:
    return "pending" if met is None else ("yes" if met else "**no**")


def ratio(numerator: float | None, denominator: float | None) -> float | None:
    if numerator is None or denominator is None or denominator == 0:
        return None
    return numerator / denominator


# ---------------------------------------------------------------------------------------------
# Captures shared by the benchmarks


def ctrlbus_capture(ctx: BenchContext, opts: Options, target_bytes: int) -> Capture:
    """The synthetic session, or the recording given with --capture repeated whole up to the size."""
    if opts.capture is None:
        return synthetic_capture(target_bytes)
    recording = load_capture(opts.capture)
    if not recording.data:
        raise BenchError(f"{opts.capture}: the recording holds no bytes")
    copies = max(1, target_bytes // len(recording.data))
    return Capture(recording.data * copies, 0, f"{recording.source}, {copies} times")


def write_stream(ctx: BenchContext, name: str, data: bytes) -> Path:
    path = ctx.work_dir / "streams" / f"{name}.bin"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_bytes(data)
    return path


def noisy(frames: list[bytes], *, ber: float = NOISE_BER, seed: int = 7) -> NoisyStream:
    return add_noise(frames, ber=ber, bursts_per_frame=BURSTS_PER_FRAME, burst_max=BURST_MAX, seed=seed)


# ---------------------------------------------------------------------------------------------
# 1. C parser cost, instructions per byte under callgrind


# The per-byte ratios to mavlink_parse_char are published, no longer judged: issue 27 retired
# them for the exchange cost (bench/exchange.py), which is what a firmware pays.
# Our decoder's harness modes: what each feeds per call.
CTRLBUS_MODES = {
    "push": "byte by byte (ctrlbus_decoder_push)",
    "bytes": "byte by byte through feed (ctrlbus_decoder_feed of 1 byte, then next)",
    "chunks": "in 64-byte chunks (ctrlbus_decoder_take)",
    "feedchunks": "in 64-byte chunks through feed (ctrlbus_decoder_feed, then next)",
}
# The byte-by-byte row of the table: the byte API a UART interrupt uses.
BYTE_MODE = "push"


@benchmark(
    "c_parser_cost",
    "C parser cost: instructions per byte (callgrind)",
    "published beside MAVLink's mavlink_parse_char built with the same flags, one call site "
    "(the per-byte goals were retired for the exchange cost)",
)
def c_parser_cost(ctx: BenchContext, opts: Options) -> Outcome:
    size = C_STREAM_BYTES[ctx.mode]
    ours_capture = ctrlbus_capture(ctx, opts, size)
    try:
        ours_noisy = noisy(split_frames(ours_capture.data))
    except ValueError as exc:
        raise BenchError(f"the noisy variant needs a capture made of whole frames: {exc}") from None
    dialect = generate_python(ctx)
    peer_capture = mavlink_capture(dialect, len(ours_capture.data))
    peer_noisy = noisy(split_mavlink(peer_capture.data))
    streams = {
        "clean": (
            write_stream(ctx, "ctrlbus-clean", ours_capture.data),
            write_stream(ctx, "mavlink-clean", peer_capture.data),
        ),
        "noisy": (
            write_stream(ctx, "ctrlbus-noisy", ours_noisy.data),
            write_stream(ctx, "mavlink-noisy", peer_noisy.data),
        ),
    }

    include = generate_c(ctx)
    figures: dict[str, Any] = {
        "ctrlbus_stream_bytes": len(ours_capture.data),
        "ctrlbus_frames": ours_capture.frames,
        "mavlink_stream_bytes": len(peer_capture.data),
        "mavlink_messages": peer_capture.frames,
        "noisy_bit_errors": ours_noisy.bit_errors,
        "noisy_bursts": ours_noisy.bursts,
    }
    # runs[variant][f"{level}_{who}"]
    runs: dict[str, dict[str, HarnessRun]] = {v: {} for v in streams}
    builds: dict[str, list[str]] = {}
    pending: list[str] = []
    profile: dict[str, dict[str, list[tuple[str, float]]]] = {}

    def measure(
        level: str, who: str, binary: Path, mode: str, variant: str, stream: Path, base: HarnessRun
    ) -> None:
        run = callgrind(ctx, binary, mode, stream)
        runs[variant][f"{level}_{who}"] = run
        figures[f"{variant}_{level}_{who}_ipb"] = round(per_byte(run, base), 3)

    for opt in OPT_LEVELS:
        level = opt_key(opt)
        peers = {
            "mavlink_parse_char": ((), "parse"),
            "mavlink_frame_char_buffer": (("PEER_FRAME_CHAR_BUFFER",), "parse"),
        }
        for who, (defines, mode) in peers.items():
            binary = compile_harness(
                ctx, f"mavlink_{who}", [BENCH_DIR / "c" / "mavlink_parse.c"], [include], "gnu99", opt, defines
            )
            builds[f"{level}_{who}"] = compile_flags(opt, "gnu99", defines)
            for variant, (_, peer_stream) in streams.items():
                base = callgrind(ctx, binary, "baseline", peer_stream)
                measure(level, who, binary, mode, variant, peer_stream, base)
        floor_bin = compile_harness(ctx, "xor_floor", [BENCH_DIR / "c" / "xor_floor.c"], [], "gnu99", opt)
        builds[f"{level}_floor"] = compile_flags(opt, "gnu99")
        for variant, (ours_stream, _) in streams.items():
            base = callgrind(ctx, floor_bin, "baseline", ours_stream)
            for mode in ("inline", "call"):
                measure(level, f"floor_{mode}", floor_bin, mode, variant, ours_stream, base)
        clean_peer = runs["clean"][f"{level}_mavlink_parse_char"].report["messages"]
        if clean_peer != peer_capture.frames:
            raise BenchError(
                f"MAVLink ({opt}) parsed {clean_peer} messages of {peer_capture.frames} in the clean stream"
            )
        clean_floor = runs["clean"][f"{level}_floor_inline"].report["frames"]
        if opts.capture is None and clean_floor != ours_capture.frames:
            raise BenchError(f"the XOR floor ({opt}) found {clean_floor} frames of {ours_capture.frames}")

        try:
            ours_bin = compile_harness(
                ctx,
                "ctrlbus_parse",
                [BENCH_DIR / "c" / "ctrlbus_parse.c", *c_decoder_sources()],
                [C_INCLUDE],
                opt=opt,
            )
        except Pending as why:
            pending.append(f"ctrlbus: {why}")
            continue
        builds[f"{level}_ctrlbus"] = compile_flags(opt)
        for variant, (ours_stream, _) in streams.items():
            base = callgrind(ctx, ours_bin, "baseline", ours_stream)
            for mode in CTRLBUS_MODES:
                measure(level, f"ctrlbus_{mode}", ours_bin, mode, variant, ours_stream, base)
            peer_ipb = figures[f"{variant}_{level}_mavlink_parse_char_ipb"]
            for mode in CTRLBUS_MODES:
                figures[f"{variant}_{level}_ratio_{mode}_vs_parse_char"] = round(
                    figures[f"{variant}_{level}_ctrlbus_{mode}_ipb"] / peer_ipb, 4
                )
        for mode in CTRLBUS_MODES:
            got = runs["clean"][f"{level}_ctrlbus_{mode}"].report["frames"]
            if opts.capture is None and got != ours_capture.frames:
                raise BenchError(f"ctrlbus {mode} ({opt}) decoded {got} frames of {ours_capture.frames}")
        profile[level] = {
            mode: top_functions(ctx, runs["clean"][f"{level}_ctrlbus_{mode}"]) for mode in CTRLBUS_MODES
        }

    rows: list[list[str]] = []
    for opt in OPT_LEVELS:
        level = opt_key(opt)
        for variant in streams:
            peer_ipb = figures[f"{variant}_{level}_mavlink_parse_char_ipb"]
            buffer_ipb = figures[f"{variant}_{level}_mavlink_frame_char_buffer_ipb"]
            peer = (
                f"{fmt(peer_ipb)} mavlink_parse_char, {fmt(buffer_ipb)} mavlink_frame_char_buffer "
                f"(gcc {opt}, one call site); XOR floor "
                f"{fmt(figures[f'{variant}_{level}_floor_inline_ipb'])} inlined, "
                f"{fmt(figures[f'{variant}_{level}_floor_call_ipb'])} with a call per byte"
            )
            for mode in (BYTE_MODE, "chunks"):
                ours_ipb = figures.get(f"{variant}_{level}_ctrlbus_{mode}_ipb")
                r = ratio(ours_ipb, peer_ipb)
                rows.append(
                    [
                        f"{variant} stream, gcc {opt}, ctrlbus {CTRLBUS_MODES[mode]}",
                        "published",
                        fmt(ours_ipb),
                        peer,
                        fmt(r, 3),
                        "pending" if r is None else "yes",
                    ]
                )
    details = {
        "builds": {key: shlex.join(["gcc", *flags]) for key, flags in builds.items()},
        "byte_mode": BYTE_MODE,
        "peer_build_note": "each MAVLink binary calls one parser API from exactly one place, as a "
        "MAVLink user's receive loop does, so gcc inlines MAVLink's static inline parser",
        "ctrlbus_profile_clean_per_byte": profile,
        "capture": ours_capture.source,
        "encoder": encoder_in_use(),
        "mavlink_capture": peer_capture.source,
        "noise": {"ber": NOISE_BER, "bursts_per_frame": BURSTS_PER_FRAME, "burst_max": BURST_MAX},
        "instructions": {v: {k: r.instructions for k, r in m.items()} for v, m in runs.items()},
        "harness_reports": {v: {k: r.report for k, r in m.items()} for v, m in runs.items()},
    }
    return Outcome(PARTIAL if pending else MEASURED, figures, rows, pending, details)


# ---------------------------------------------------------------------------------------------
# 2. Python decoder throughput


def _time_feed(make: Callable[[], Callable[[bytes], int]], data: bytes) -> tuple[float, int]:
    """CPU time of a fresh decoder fed the whole stream in FEED_CHUNK pieces, and its frame count.

    CPU time of this process rather than wall time: the decoders are single-threaded, so the two
    are equal on an idle machine, and other processes on a busy one do not count.
    """
    view = memoryview(data)
    feed = make()
    count = 0
    start = time.process_time()
    for pos in range(0, len(data), FEED_CHUNK):
        count += feed(bytes(view[pos : pos + FEED_CHUNK]))
    return time.process_time() - start, count


def _pymavlink_counting(dialect: ModuleType) -> Callable[[], Callable[[bytes], int]]:
    def make() -> Callable[[bytes], int]:
        parser = dialect.MAVLink(None)

        def feed(chunk: bytes) -> int:
            messages = parser.parse_buffer(chunk)
            return len(messages) if messages else 0

        return feed

    return make


@benchmark(
    "python_throughput",
    "Python decoder throughput (MB/s)",
    "ctrlbus.frame.StreamDecoder ≥ 10 × pymavlink's bytes per second",
)
def python_throughput(ctx: BenchContext, opts: Options) -> Outcome:
    size = PY_STREAM_BYTES[ctx.mode]
    repeats = PY_REPEATS[ctx.mode]
    dialect = generate_python(ctx)
    ours_capture = ctrlbus_capture(ctx, opts, size)
    peer_capture = mavlink_capture(dialect, len(ours_capture.data))
    try:
        make_ours: Callable[[], Callable[[bytes], int]] | None = python_decoder_counting()
        pending: list[str] = []
    except Pending as why:
        make_ours, pending = None, [f"ctrlbus: {why}"]
    # Runs alternate between the two parsers and the best of each counts, so that a change in the
    # machine's load during the run hits both alike.
    peer_s = ours_s = float("inf")
    peer_count = ours_count = 0
    for _ in range(repeats):
        seconds, peer_count = _time_feed(_pymavlink_counting(dialect), peer_capture.data)
        peer_s = min(peer_s, seconds)
        if make_ours is not None:
            seconds, ours_count = _time_feed(make_ours, ours_capture.data)
            ours_s = min(ours_s, seconds)
    if peer_count != peer_capture.frames:
        raise BenchError(f"pymavlink parsed {peer_count} messages of {peer_capture.frames}")
    peer_mbps = len(peer_capture.data) / peer_s / 1e6
    figures: dict[str, Any] = {
        "mavlink_stream_bytes": len(peer_capture.data),
        "mavlink_messages": peer_count,
        "pymavlink_cpu_seconds": round(peer_s, 4),
        "pymavlink_mb_per_s": round(peer_mbps, 3),
    }
    ours_mbps: float | None = None
    if make_ours is not None:
        if opts.capture is None and ours_count != ours_capture.frames:
            raise BenchError(f"ctrlbus.frame decoded {ours_count} frames of {ours_capture.frames}")
        ours_mbps = len(ours_capture.data) / ours_s / 1e6
        figures.update(
            {
                "ctrlbus_stream_bytes": len(ours_capture.data),
                "ctrlbus_frames": ours_count,
                "ctrlbus_cpu_seconds": round(ours_s, 4),
                "ctrlbus_mb_per_s": round(ours_mbps, 3),
                "ratio": round(ours_mbps / peer_mbps, 3),
            }
        )
    r = ratio(ours_mbps, peer_mbps)
    facts = machine_facts()
    fastcrc = facts.get("fastcrc", "not installed")
    crc = "pure Python" if fastcrc == "not installed" else f"fastcrc {fastcrc} (compiled)"
    rows = [
        [
            f"{len(ours_capture.data) / 1e6:.1f} MB stream, {FEED_CHUNK}-byte reads",
            "≥ 10 × pymavlink",
            fmt(ours_mbps, 2),
            f"{fmt(peer_mbps, 2)} (pymavlink {facts.get('pymavlink')} parse_buffer, the Python dialect "
            f"mavgen generated, CRC from {crc})",
            fmt(r, 2),
            verdict(None if r is None else r >= 10.0),
        ]
    ]
    details = {"repeats": repeats, "feed_chunk": FEED_CHUNK, "mavlink_capture": peer_capture.source}
    return Outcome(PARTIAL if pending else MEASURED, figures, rows, pending, details)


# ---------------------------------------------------------------------------------------------
# 3. Garbage-burst recovery: ours vs a model of the reference firmware's receiver


@dataclass(frozen=True)
class Recovery:
    recovered: int
    intact_sent: int
    false_accepts: int

    @property
    def percent(self) -> float:
        return 100.0 * self.recovered / self.intact_sent if self.intact_sent else 0.0


MATCH_WINDOW = 1024  # how far ahead in the sent frames a decoded frame is looked for


def score_recovery(stream: NoisyStream, decoded: list[bytes]) -> Recovery:
    """Match decoded frames, in order, to the frames sent; count the intact ones recovered.

    A decoded frame equal to none of the next sent frames was made up from corrupted bytes and
    passed the 8-bit checksum: a false accept.
    """
    recovered = false_accepts = 0
    next_sent = 0
    for frame in decoded:
        for k in range(next_sent, min(next_sent + MATCH_WINDOW, len(stream.sent))):
            if stream.sent[k] == frame:
                recovered += stream.intact[k]
                next_sent = k + 1
                break
        else:
            false_accepts += 1
    return Recovery(recovered, sum(stream.intact), false_accepts)


@benchmark(
    "garbage_recovery",
    "Recovery after garbage bursts: valid frames recovered",
    "ctrlbus recovers ≥ 99.9 % of the valid frames",
)
def garbage_recovery(ctx: BenchContext, opts: Options) -> Outcome:
    seconds = RECOVERY_SESSION_S[ctx.mode]
    timed = list(timed_session_frames(seconds))
    frames = [frame for _, frame in timed]
    times_s = [t_ms / 1000.0 for t_ms, _ in timed]
    pending: list[str] = []
    make_ours: Callable[[], FeedFrames] | None = None
    try:
        make_ours, ours_settings = python_decoder_frames()
    except Pending as why:
        pending.append(f"ctrlbus: {why}")
        ours_settings = "pending"
    figures: dict[str, Any] = {"frames_sent": len(frames), "session_seconds": seconds}
    rows: list[list[str]] = []
    details: dict[str, Any] = {
        "bursts_per_frame": BURSTS_PER_FRAME,
        "burst_max": BURST_MAX,
        "ctrlbus_settings": ours_settings + ", fed each frame (and the burst before it) with its send time",
        "reference_model": "bench/refmodel.py: no backtracking, no timeout, 512-byte receive buffer",
    }
    for scenario, ber in (("bursts", 0.0), ("bursts_ber", NOISE_BER)):
        stream = noisy(frames, ber=ber, seed=11)
        reference = ReferenceModelDecoder()
        ref = score_recovery(stream, [f for piece in stream.pieces for f in reference.feed(piece)])
        figures.update(
            {
                f"{scenario}_intact_frames": ref.intact_sent,
                f"{scenario}_bursts": stream.bursts,
                f"{scenario}_bit_errors": stream.bit_errors,
                f"{scenario}_reference_model_recovered_pct": round(ref.percent, 4),
                f"{scenario}_reference_model_false_accepts": ref.false_accepts,
            }
        )
        details[f"{scenario}_reference_model_counters"] = vars(reference.counters)
        ours: Recovery | None = None
        if make_ours is not None:
            feed = make_ours()
            decoded = [f for piece, now in zip(stream.pieces, times_s, strict=True) for f in feed(piece, now)]
            decoded += feed(b"", times_s[-1] + 1.0)  # the line goes quiet: a pending candidate times out
            ours = score_recovery(stream, decoded)
            figures.update(
                {
                    f"{scenario}_ctrlbus_recovered_pct": round(ours.percent, 4),
                    f"{scenario}_ctrlbus_false_accepts": ours.false_accepts,
                }
            )
        label = "garbage bursts" if ber == 0 else f"garbage bursts + BER {ber:g}"
        rows.append(
            [
                f"{label}: {stream.bursts} bursts, {ref.intact_sent:,} valid frames",
                "≥ 99.9 %",
                "pending" if ours is None else f"{ours.percent:.3f} %",
                f"{ref.percent:.3f} % (reference receiver model, bench/refmodel.py: no backtracking, "
                "no timeout)",
                "pending" if ours is None else f"false accepts: {ours.false_accepts} vs {ref.false_accepts}",
                verdict(None if ours is None else ours.percent >= 99.9),
            ]
        )
    return Outcome(PARTIAL if pending else MEASURED, figures, rows, pending, details)


# ---------------------------------------------------------------------------------------------
# Slots for benchmarks whose subject does not exist yet. Each reports "pending" and what it
# waits for, until someone fills it in.


def _pending(reason: str) -> Callable[[BenchContext, Options], Outcome]:
    def slot(ctx: BenchContext, opts: Options) -> Outcome:
        return Outcome(PENDING, pending=[reason], rows=[["—", "", "pending", "", "", "pending"]])

    return slot


@benchmark(soak.NAME, soak.TITLE, soak.GOAL)
def fault_soak(ctx: BenchContext, opts: Options) -> Outcome:
    found = soak.run(ctx)  # bench/soak.py; docs/reliability.md
    return Outcome(found.status, found.figures, found.rows, found.pending, found.details)


@benchmark(exchange.NAME, exchange.TITLE, exchange.GOAL)
def base_exchange(ctx: BenchContext, opts: Options) -> Outcome:
    return Outcome(**vars(exchange.run(ctx)))  # bench/exchange.py


@benchmark(footprint.NAME, footprint.TITLE, footprint.GOAL)
def footprint_table(ctx: BenchContext, opts: Options) -> Outcome:
    return Outcome(**vars(footprint.run(ctx)))  # bench/footprint.py


@benchmark(endtoend.E2E_NAME, endtoend.E2E_TITLE, endtoend.E2E_GOAL)
def end_to_end(ctx: BenchContext, opts: Options) -> Outcome:
    return Outcome(**vars(endtoend.run_end_to_end(ctx)))  # bench/endtoend.py


@benchmark(endtoend.LINK_NAME, endtoend.LINK_TITLE, endtoend.LINK_GOAL)
def link_efficiency(ctx: BenchContext, opts: Options) -> Outcome:
    return Outcome(**vars(endtoend.run_link_efficiency(ctx)))  # bench/endtoend.py


# ---------------------------------------------------------------------------------------------
# Driver


def run_one(bench: Benchmark, ctx: BenchContext, opts: Options) -> dict[str, Any]:
    started = time.perf_counter()
    try:
        outcome = bench.run(ctx, opts)
    except BenchError as exc:
        outcome = Outcome(FAILED, details={"error": str(exc)})
    except Exception as exc:  # a broken benchmark is reported, the others still run
        outcome = Outcome(
            FAILED, details={"error": f"{type(exc).__name__}: {exc}", "traceback": traceback.format_exc()}
        )
    return {
        "name": bench.name,
        "title": bench.title,
        "goal": bench.goal,
        "status": outcome.status,
        "mode": ctx.mode,
        "figures": outcome.figures,
        "table": outcome.rows,
        "pending": outcome.pending,
        "details": outcome.details,
        "command": "make bench" if ctx.mode == FULL else "bench/run.py --smoke",
        "invocation": shlex.join([Path(sys.executable).name, *sys.argv]),
        "tool_commands": ctx.commands,
        "seconds": round(time.perf_counter() - started, 2),
        "machine": machine_facts(),
        "git": opts.git,
        "when": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
    }


def load_result(out_dir: Path, name: str) -> dict[str, Any] | None:
    path = out_dir / f"{name}.json"
    if not path.is_file():
        return None
    result: dict[str, Any] = json.loads(path.read_text())
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    parser.add_argument("--smoke", action="store_true", help="tiny inputs, for make test")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="results directory (default bench/results; with --smoke it is required and "
        "the docs are rendered there instead of into docs/)",
    )
    parser.add_argument("--only", nargs="+", choices=sorted(BENCHMARKS), help="run only these benchmarks")
    parser.add_argument(
        "--capture",
        type=Path,
        default=None,
        help="parse this recorded session (pcap from ctrlbus.capture, or raw bytes) instead of "
        "the synthetic one",
    )
    args = parser.parse_args(argv)
    if args.smoke and args.out is None:
        parser.error("--smoke needs --out DIR (smoke results never replace bench/results)")
    if args.capture is not None and not args.capture.is_file():
        parser.error(f"--capture {args.capture}: no such file")
    mode = SMOKE if args.smoke else FULL
    out_dir: Path = args.out or BENCH_DIR / "results"
    out_dir.mkdir(parents=True, exist_ok=True)
    opts = Options(capture=args.capture)

    from report import render_plots, update_performance_md  # matplotlib only once benchmarks ran

    results: list[dict[str, Any]] = []
    BUILD_DIR.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="ctrlbus-bench-", dir=BUILD_DIR) as work:
        for name, bench in BENCHMARKS.items():
            if args.only and name not in args.only:
                continue
            ctx = BenchContext(mode, Path(work) / name)
            ctx.work_dir.mkdir(parents=True)
            print(f"bench: {name} ...", flush=True)
            result = run_one(bench, ctx, opts)
            (out_dir / f"{name}.json").write_text(json.dumps(result, indent=2) + "\n")
            summary = result["status"]
            if result["pending"]:
                summary += " (" + "; ".join(result["pending"]) + ")"
            if result["status"] == FAILED:
                summary += ": " + result["details"]["error"]
            print(f"bench: {name}: {summary} [{result['seconds']} s]", flush=True)
            results.append(result)

    # The docs show every benchmark: those not run this time keep their last results.
    published = [r for name in BENCHMARKS if (r := load_result(out_dir, name)) is not None]
    img_dir = out_dir / "img" if args.smoke else REPO / "docs" / "img"
    doc = REPO / "docs" / "performance.md"
    doc_out = out_dir / "performance.md" if args.smoke else doc
    plots = render_plots(published, img_dir)
    update_performance_md(doc, doc_out, published, plots)
    soak.update_reliability_md(published, out_dir if args.smoke else None)
    print(f"bench: results in {out_dir}, plots in {img_dir}, tables in {doc_out}")
    return 1 if any(r["status"] == FAILED for r in results) else 0


if __name__ == "__main__":
    sys.exit(main())
