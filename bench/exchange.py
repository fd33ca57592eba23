# SPDX-License-Identifier: MIT
"""Full base exchange: instructions for the C base stack to take one SET_V_AND_GET_DEADRECKON
request and stream out its answer, under callgrind.

The harness (bench/c/base_exchange.c) runs the real stack (c/src/*.c behind ctrlbus/base.h) with a
set_velocity handler and a write callback that only counts. It gets a file of requests and
handles them one at a time: feed the request, poll; the stack decodes it, calls the handler and
writes the answer through the callback, field by field. Method as for the C parser cost
(bench/callgrind.py): the whole program's instruction count under callgrind, minus that of the
same program in `baseline` mode (start the base, walk the same bytes request by request, neither
feed nor poll), divided by the number of exchanges. The answers are checked once outside
callgrind (`dump` mode): one SET_V_AND_GET_DEADRECKON OK answer per request, with the values the
handler computes.
"""

from __future__ import annotations

import math
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

ensure_ctrlbus_importable()

from ctrlbus.frame import StreamDecoder  # noqa: E402  (after the path is set up)
from ctrlbus.messages import (  # noqa: E402
    Response,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    decode_answer,
    request_frame,
)

NAME = "base_exchange"
TITLE = "Full base exchange: instructions per SET_V_AND_GET_DEADRECKON (callgrind)"
GOAL = "measured and published (parse the request, stream out the answer through the base stack)"

BASE_HEADER = C_INCLUDE / "ctrlbus" / "base.h"
HARNESS = BENCH_DIR / "c" / "base_exchange.c"
EXCHANGES = {FULL: 100_000, SMOKE: 2_000}
MODES = {
    "frames": "request fed whole (a DMA or ring-buffer reader), then one poll",
    "bytes": "request fed byte by byte (a UART interrupt per byte), then one poll",
    "polled": "one byte fed, then a poll, for every byte (a main loop polling faster than bytes arrive)",
}
PROFILE_TOP = 8


def velocity_requests(count: int) -> list[SetVAndGetDeadreckon]:
    """A Core driving around: forward speed and turn rate moving smoothly, now and then negative."""
    return [
        SetVAndGetDeadreckon.from_si(0.45 * math.sin(k / 40.0), 0.0, 1.4 * math.sin(k / 23.0 + 1.0))
        for k in range(count)
    ]


def expected_answer(request: SetVAndGetDeadreckon) -> SetVAndGetDeadreckonAnswer:
    """What the harness's set_velocity handler answers: the motion over 50 ms (its C code, in Python)."""
    dtheta = request.omega_radps_q16 * 2865
    # C's integer division truncates towards zero.
    dtheta = dtheta // 1000 if dtheta >= 0 else -((-dtheta) // 1000)
    return SetVAndGetDeadreckonAnswer(request.vx_mps_q16 * 50, 0, dtheta, 0)


def check_answers(requests: list[SetVAndGetDeadreckon], answers: bytes) -> int:
    """Every request got its OK answer in a long frame with the handler's values; returns the
    answer frame size. BenchError otherwise."""
    frames = StreamDecoder(timeout=0).feed(answers)
    if len(frames) != len(requests):
        raise BenchError(f"the base stack answered {len(frames)} of {len(requests)} requests")
    sizes = {frame.size for frame in frames}
    for k, (request, frame) in enumerate(zip(requests, frames, strict=True)):
        if frame.cmd != Response.OK or not frame.long:
            raise BenchError(f"answer {k} is not an OK long frame: {frame.raw.hex(' ')}")
        answer = decode_answer(request, frame.cmd, frame.payload)
        if answer != expected_answer(request):
            raise BenchError(f"answer {k} is {answer}, expected {expected_answer(request)}")
    if len(sizes) != 1:
        raise BenchError(f"answers of several sizes: {sorted(sizes)}")
    return sizes.pop()


def per_exchange(run: HarnessRun, baseline: HarnessRun) -> float:
    exchanges = run.report["exchanges"]
    if (
        exchanges <= 0
        or baseline.report["exchanges"] != exchanges
        or baseline.report["bytes"] != run.report["bytes"]
    ):
        raise BenchError(f"{run.mode}: baseline and run read different request files")
    extra = run.instructions - baseline.instructions
    if extra <= 0:
        raise BenchError(f"{run.mode}: not more instructions than the baseline ({extra})")
    return extra / exchanges


def run(ctx: BenchContext) -> Findings:
    if not BASE_HEADER.is_file():
        return Findings(PENDING, pending=["the C base stack (c/include/ctrlbus/base.h) is not written yet"])
    count = EXCHANGES[ctx.mode]
    requests = velocity_requests(count)
    wire = [request_frame(request) for request in requests]
    stream = ctx.work_dir / "requests.bin"
    stream.write_bytes(b"".join(wire))
    sources = [HARNESS, *sorted(C_SRC.glob("*.c"))]
    request_size = len(wire[0])
    figures: dict[str, Any] = {"exchanges": count, "request_bytes": request_size}
    instructions: dict[str, dict[str, int]] = {}
    reports: dict[str, dict[str, dict[str, int]]] = {}
    profile: dict[str, dict[str, list[tuple[str, float]]]] = {}
    builds: dict[str, str] = {}
    rows: list[list[str]] = []
    for opt in OPT_LEVELS:
        level = opt_key(opt)
        binary = compile_harness(ctx, "base_exchange", sources, [C_INCLUDE], opt=opt)
        builds[level] = " ".join(["gcc", *compile_flags(opt)])

        answers_file = ctx.work_dir / f"answers{opt}.bin"
        run_command(ctx, [str(binary), "dump", str(stream), str(answers_file)])
        answer_size = check_answers(requests, answers_file.read_bytes())
        figures["answer_bytes"] = answer_size

        baseline = callgrind(ctx, binary, "baseline", stream)
        runs = {mode: callgrind(ctx, binary, mode, stream) for mode in MODES}
        for mode, harness_run in runs.items():
            report = harness_run.report
            if report["exchanges"] != count or report["answer_bytes"] != count * answer_size:
                raise BenchError(
                    f"{mode} ({opt}): {report['answer_bytes']} answer bytes, {report['exchanges']} exchanges"
                )
            cost = per_exchange(harness_run, baseline)
            figures[f"{level}_{mode}_instructions_per_exchange"] = round(cost, 1)
            figures[f"{level}_{mode}_instructions_per_wire_byte"] = round(
                cost / (request_size + answer_size), 2
            )
        writes = runs["frames"].report["writes"] / count
        max_write = runs["frames"].report["max_write"]
        figures["write_calls_per_answer"] = round(writes, 2)
        figures["largest_write_bytes"] = max_write

        # Where the instructions go, per exchange (callgrind's per-function self cost).
        stream_bytes = runs["frames"].report["bytes"]
        profile[level] = {
            mode: [
                (name, round(per_byte * stream_bytes / count, 1))
                for name, per_byte in top_functions(ctx, harness_run, PROFILE_TOP)
            ]
            for mode, harness_run in runs.items()
        }
        instructions[level] = {
            "baseline": baseline.instructions,
            **{m: r.instructions for m, r in runs.items()},
        }
        reports[level] = {"baseline": baseline.report, **{m: r.report for m, r in runs.items()}}

        for mode, label in MODES.items():
            rows.append(
                [
                    f"gcc {opt}: one exchange ({request_size} B request, {answer_size} B answer): {label}",
                    "published",
                    f"{figures[f'{level}_{mode}_instructions_per_exchange']:,.0f} instructions "
                    f"({figures[f'{level}_{mode}_instructions_per_wire_byte']:.1f} per byte on the wire)",
                    "",
                    "",
                    "yes",
                ]
            )
        top = ", ".join(f"{name} {cost:,.0f}" for name, cost in profile[level]["frames"][:6])
        rows.append(
            [f"gcc {opt}: where they go (request fed whole), per exchange", "published", top, "", "", "yes"]
        )
    rows.append(
        [
            "the answer leaves through write() as",
            "no transmit buffer",
            f"{figures['write_calls_per_answer']:g} calls of at most {figures['largest_write_bytes']} bytes "
            "(streamed field by field)",
            "",
            "",
            "yes" if figures["largest_write_bytes"] < figures["answer_bytes"] else "**no**",
        ]
    )
    details: dict[str, Any] = {
        "harness": str(HARNESS.relative_to(BENCH_DIR.parent)),
        "sources": [str(path.relative_to(BENCH_DIR.parent)) for path in sorted(C_SRC.glob("*.c"))],
        "modes": MODES,
        "clock": "50 ms per request (20 Hz): the watchdog stays fed, nothing times out",
        "builds": builds,
        "instructions": instructions,
        "harness_reports": reports,
        "profile_per_exchange": profile,
    }
    return Findings(MEASURED, figures, rows, [], details)
