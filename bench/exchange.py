# SPDX-License-Identifier: MIT
"""Exchanges as a firmware pays for them: instructions per Core<->base exchange under callgrind.

What a base firmware pays for the protocol is the work of each exchange, not a per-byte ratio: at
115200 baud the line carries at most ~11.5 kB/s, so a SET_V_AND_GET_DEADRECKON exchange (17 + 18
bytes) comes at most ~330 times a second. Every harness runs the same firmware timeline
(bench/c/exchange_timeline.h): each request byte handed to the receive "interrupt", the clock
advancing 1 ms every 11 byte slots, the main loop's poll once per millisecond, the answer streamed
out while the line carries it. Three rows per exchange and build (gcc -O2, -Os):

- ours: the C base stack (bench/c/base_exchange.c: ctrlbus_base_feed_byte() from the interrupt,
  ctrlbus_base_poll() per ms, the answer through a counting write callback);
- the floor: a minimal hand-written base on the same timeline (bench/c/floor_exchange.c: a plain
  state machine, switch dispatch, the answer written straight from its fields; no watchdog, limits,
  registry, backtracking, timeout or error answers);
- MAVLink: mavlink_parse_char() on a message with the same payload (bench/c/mavlink_parse.c, one
  call site), the parse alone.

Figure = (Ir(firmware) - Ir(baseline)) / exchanges, where baseline runs the same timeline with the
interrupt and the poll replaced by stores. Answers are checked outside callgrind (`dump` mode):
ours and the floor's must be byte for byte the same, and decode to the handler's values. The MCU
load is derived: instructions per exchange x 330 exchanges/s over 48 M instructions/s (a 48 MHz
Cortex-M0+ at one instruction per cycle): x86-64 instructions stand in for Thumb ones, so it is an
order of magnitude, not a cycle count.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

from callgrind import (
    OPT_LEVELS,
    HarnessRun,
    callgrind,
    compile_flags,
    compile_harness,
    opt_key,
    top_functions,
)
from common import (
    BENCH_DIR,
    C_INCLUDE,
    C_SRC,
    FULL,
    MEASURED,
    PENDING,
    SMOKE,
    BenchContext,
    BenchError,
    ensure_ctrlbus_importable,
    run_command,
)
from findings import Findings
from mavlink.generate import generate_c, generate_python

ensure_ctrlbus_importable()

from ctrlbus.frame import StreamDecoder  # noqa: E402  (after the path is set up)
from ctrlbus.messages import (  # noqa: E402
    GetBaseStatus,
    GetBaseStatusAnswer,
    Response,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    decode_answer,
    request_frame,
)

NAME = "base_exchange"
TITLE = "Exchange cost: instructions per exchange as a firmware runs it (callgrind)"
GOAL = "SET_V_AND_GET_DEADRECKON exchange ≤ 1.5 × the hand-written floor, at -O2 and at -Os"
GOAL_RATIO = 1.5

BASE_HEADER = C_INCLUDE / "ctrlbus" / "base.h"
HARNESS = BENCH_DIR / "c" / "base_exchange.c"
FLOOR = BENCH_DIR / "c" / "floor_exchange.c"
PEER = BENCH_DIR / "c" / "mavlink_parse.c"
EXCHANGES = {FULL: 20_000, SMOKE: 500}
PROFILE_TOP = 10
# The line's limit for the SET_V exchange (docs/protocol.md §2) and the MCU it is set against.
EXCHANGES_PER_S = 330
MCU_HZ = 48_000_000
# The handler values (bench/c/base_exchange.c and floor_exchange.c).
BATTERY_PERCENT = 87


def velocity_requests(count: int) -> list[SetVAndGetDeadreckon]:
    """A Core driving around: forward speed and turn rate moving smoothly, now and then negative."""
    return [
        SetVAndGetDeadreckon.from_si(0.45 * math.sin(k / 40.0), 0.0, 1.4 * math.sin(k / 23.0 + 1.0))
        for k in range(count)
    ]


def expected_velocity_answer(request: SetVAndGetDeadreckon) -> SetVAndGetDeadreckonAnswer:
    """What the harnesses' set_velocity answers: the motion over 50 ms (their C code, in Python)."""
    dtheta = request.omega_radps_q16 * 2865
    # C's integer division truncates towards zero.
    dtheta = dtheta // 1000 if dtheta >= 0 else -((-dtheta) // 1000)
    return SetVAndGetDeadreckonAnswer(request.vx_mps_q16 * 50, 0, dtheta, 0)


def check_answers(requests: list[Any], expected: list[Any], answers: bytes) -> int:
    """Every request got its OK answer in a long frame with the handler's values; returns the
    answer frame size. BenchError otherwise."""
    frames = StreamDecoder(timeout=0).feed(answers)
    if len(frames) != len(requests):
        raise BenchError(f"{len(frames)} answers to {len(requests)} requests")
    sizes = {frame.size for frame in frames}
    for k, (request, frame) in enumerate(zip(requests, frames, strict=True)):
        if frame.cmd != Response.OK or not frame.long:
            raise BenchError(f"answer {k} is not an OK long frame: {frame.raw.hex(' ')}")
        answer = decode_answer(request, frame.cmd, frame.payload)
        if answer != expected[k]:
            raise BenchError(f"answer {k} is {answer}, expected {expected[k]}")
    if len(sizes) != 1:
        raise BenchError(f"answers of several sizes: {sorted(sizes)}")
    return sizes.pop()


def per_item(run: HarnessRun, baseline: HarnessRun, key: str) -> float:
    count = run.report[key]
    if count <= 0 or baseline.report["bytes"] != run.report["bytes"]:
        raise BenchError(f"{run.mode}: baseline and run read different files")
    extra = run.instructions - baseline.instructions
    if extra <= 0:
        raise BenchError(f"{run.mode}: not more instructions than the baseline ({extra})")
    return extra / count


def mavlink_stream(dialect: Any, kind: str, requests: list[Any]) -> bytes:
    """The same requests as MAVLink v2 messages of our dialect (bench/mavlink/ctrlbus_peer.xml)."""
    mav = dialect.MAVLink(None, srcSystem=1, srcComponent=1)
    out = bytearray()
    for request in requests:
        if kind == "set_v":
            message = mav.base_velocity_command_encode(
                request.vx_mps_q16, request.vy_mps_q16, request.omega_radps_q16
            )
        else:
            message = mav.base_request_encode(0x30, 0)
        out += message.pack(mav)
        mav.seq = (mav.seq + 1) % 256
    return bytes(out)


def run(ctx: BenchContext) -> Findings:
    if not BASE_HEADER.is_file():
        return Findings(PENDING, pending=["the C base stack (c/include/ctrlbus/base.h) is not written yet"])
    count = EXCHANGES[ctx.mode]
    velocity = velocity_requests(count)
    status = [GetBaseStatus() for _ in range(count)]
    kinds: dict[str, tuple[str, list[Any], list[Any]]] = {
        "set_v": (
            "SET_V_AND_GET_DEADRECKON",
            velocity,
            [expected_velocity_answer(r) for r in velocity],
        ),
        "status": (
            "GET_BASE_STATUS",
            status,
            [GetBaseStatusAnswer(BATTERY_PERCENT, 0) for _ in status],
        ),
    }
    dialect = generate_python(ctx)
    include = generate_c(ctx)
    figures: dict[str, Any] = {"exchanges": count}
    streams: dict[str, tuple[Path, Path, int]] = {}
    for kind, (_, requests, _) in kinds.items():
        wire = [request_frame(r) for r in requests]
        path = ctx.work_dir / f"{kind}-requests.bin"
        path.write_bytes(b"".join(wire))
        peer = mavlink_stream(dialect, kind, requests)
        peer_path = ctx.work_dir / f"{kind}-mavlink.bin"
        peer_path.write_bytes(peer)
        streams[kind] = (path, peer_path, len(wire[0]))
        figures[f"{kind}_request_bytes"] = len(wire[0])
        figures[f"{kind}_mavlink_message_bytes"] = len(peer) // count

    sources = [HARNESS, *sorted(C_SRC.glob("*.c"))]
    builds: dict[str, list[str]] = {}
    profile: dict[str, list[tuple[str, float]]] = {}
    rows: list[list[str]] = []
    for opt in OPT_LEVELS:
        level = opt_key(opt)
        ours_bin = compile_harness(ctx, "base_exchange", sources, [C_INCLUDE, BENCH_DIR / "c"], opt=opt)
        floor_bin = compile_harness(ctx, "floor_exchange", [FLOOR], [BENCH_DIR / "c"], opt=opt)
        peer_bin = compile_harness(ctx, "mavlink_exchange_peer", [PEER], [include], "gnu99", opt)
        builds[level] = compile_flags(opt)
        builds[f"{level}_mavlink"] = compile_flags(opt, "gnu99")
        for kind, (label, requests, expected) in kinds.items():
            path, peer_path, request_size = streams[kind]
            # The answer size first (ours, dump), then both harnesses with that many idle slots.
            probe = ctx.work_dir / f"probe-{kind}{opt}.bin"
            run_command(ctx, [str(ours_bin), "dump", str(path), "32", str(probe)])
            answer_size = check_answers(requests, expected, probe.read_bytes())
            figures[f"{kind}_answer_bytes"] = answer_size
            slots = str(answer_size)
            answers: dict[str, bytes] = {}
            for who, binary in (("ours", ours_bin), ("floor", floor_bin)):
                dumped = ctx.work_dir / f"answers-{who}-{kind}{opt}.bin"
                run_command(ctx, [str(binary), "dump", str(path), slots, str(dumped)])
                answers[who] = dumped.read_bytes()
                check_answers(requests, expected, answers[who])
            if answers["ours"] != answers["floor"]:
                raise BenchError(f"{kind} ({opt}): the floor's answers differ from ours")
            for who, binary in (("ours", ours_bin), ("floor", floor_bin)):
                base = callgrind(ctx, binary, "baseline", path, slots)
                measured = callgrind(ctx, binary, "firmware", path, slots)
                if (
                    measured.report["exchanges"] != count
                    or measured.report["answer_bytes"] != count * answer_size
                ):
                    raise BenchError(f"{who} {kind} ({opt}): {measured.report}")
                figures[f"{level}_{kind}_{who}_per_exchange"] = round(
                    per_item(measured, base, "exchanges"), 1
                )
                if who == "ours" and kind == "set_v":
                    stream_bytes = measured.report["bytes"]
                    # (main: the harness's timeline, whose own cost the baseline mostly cancels)
                    profile[level] = [
                        (name, round(per_byte * stream_bytes / count, 1))
                        for name, per_byte in top_functions(ctx, measured, PROFILE_TOP)
                        if name != "main"
                    ]
                    figures["write_calls_per_answer"] = round(measured.report["writes"] / count, 2)
                    figures["largest_write_bytes"] = measured.report["max_write"]
            base = callgrind(ctx, peer_bin, "baseline", peer_path)
            parsed = callgrind(ctx, peer_bin, "parse", peer_path)
            if parsed.report["messages"] != count:
                raise BenchError(f"MAVLink ({opt}) parsed {parsed.report['messages']} of {count} messages")
            figures[f"{level}_{kind}_mavlink_parse_per_message"] = round(
                per_item(parsed, base, "messages"), 1
            )

            ours = figures[f"{level}_{kind}_ours_per_exchange"]
            floor = figures[f"{level}_{kind}_floor_per_exchange"]
            ratio = ours / floor
            figures[f"{level}_{kind}_ours_over_floor"] = round(ratio, 2)
            peer = figures[f"{level}_{kind}_mavlink_parse_per_message"]
            wire_bytes = request_size + answer_size
            judged = kind == "set_v"
            rows.append(
                [
                    f"gcc {opt}: {label} exchange ({request_size} B request, {answer_size} B answer)",
                    f"≤ {GOAL_RATIO:g} × floor" if judged else "published",
                    f"{ours:,.0f} instructions (floor {floor:,.0f}: {ratio:.2f} ×; "
                    f"{ours / wire_bytes:.1f} per wire byte)",
                    f"MAVLink parse of the request's payload ({figures[f'{kind}_mavlink_message_bytes']} B "
                    f"message): {peer:,.0f}",
                    "",
                    ("yes" if ratio <= GOAL_RATIO else "**no**") if judged else "yes",
                ]
            )
        load = figures[f"{level}_set_v_ours_per_exchange"] * EXCHANGES_PER_S / MCU_HZ
        floor_load = figures[f"{level}_set_v_floor_per_exchange"] * EXCHANGES_PER_S / MCU_HZ
        figures[f"{level}_mcu_load_percent"] = round(100 * load, 2)
        figures[f"{level}_floor_mcu_load_percent"] = round(100 * floor_load, 2)
        rows.append(
            [
                f"gcc {opt}: derived load of {EXCHANGES_PER_S} SET_V exchanges/s on a 48 MHz Cortex-M0+",
                "published",
                f"{100 * load:.2f} % (floor {100 * floor_load:.2f} %)",
                "",
                "",
                "yes",
            ]
        )
        top = ", ".join(f"{name} {cost:,.0f}" for name, cost in profile[level][:8])
        rows.append([f"gcc {opt}: where ours go (SET_V), per exchange", "published", top, "", "", "yes"])
    met = all(figures[f"{opt_key(o)}_set_v_ours_over_floor"] <= GOAL_RATIO for o in OPT_LEVELS)
    figures["goal_met"] = met
    details: dict[str, Any] = {
        "harnesses": [str(p.relative_to(BENCH_DIR.parent)) for p in (HARNESS, FLOOR, PEER)],
        "timeline": "bench/c/exchange_timeline.h: 1 ms per 11 byte slots (115200 baud), one poll per ms",
        "sources": [str(path.relative_to(BENCH_DIR.parent)) for path in sorted(C_SRC.glob("*.c"))],
        "builds": builds,
        "profile_per_exchange": profile,
        "mcu_load": f"instructions per exchange x {EXCHANGES_PER_S}/s / {MCU_HZ} (x86-64 as a proxy)",
    }
    return Findings(MEASURED, figures, rows, [], details)
