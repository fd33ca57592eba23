# SPDX-License-Identifier: MIT
"""Build the C harnesses and count their instructions under callgrind.

Method: each harness program takes a mode and a stream file. Mode `baseline` reads the file and
walks its bytes without parsing; the other modes parse. callgrind counts every instruction the
program executes (Ir, deterministic: same binary and input give the same count), start-up and
file reading included. Instructions per byte of parsing are

    (Ir(mode) - Ir(baseline)) / stream bytes

so the start-up, the file reading and the bare loop over the bytes cancel out, and what remains
is the parser's own work, its calls and its bookkeeping.
"""

from __future__ import annotations

import re
import shutil
from dataclasses import dataclass
from pathlib import Path

from common import BenchContext, BenchError, run_command

# Release builds, as users build: -O2 for a host, -Os for MCU firmware. Every C figure is given
# for both (the figure keys and table rows name the level).
OPT_LEVELS = ("-O2", "-Os")
CFLAGS = ["-g0", "-Wall"]


def opt_key(opt: str) -> str:
    """The level as it appears in figure keys: "-O2" -> "O2"."""
    return opt.lstrip("-")


@dataclass(frozen=True)
class HarnessRun:
    mode: str
    instructions: int
    report: dict[str, int]
    profile: Path


def require_tools() -> None:
    for tool in ("gcc", "valgrind"):
        if shutil.which(tool) is None:
            raise BenchError(f"{tool} not found (scripts/setup.sh installs it)")


def compile_flags(opt: str, std: str = "c99", defines: tuple[str, ...] = ()) -> list[str]:
    """The gcc flags a harness is built with (recorded in the results)."""
    return [f"-std={std}", opt, *CFLAGS, *(f"-D{d}" for d in defines)]


def compile_harness(
    ctx: BenchContext,
    name: str,
    sources: list[Path],
    include_dirs: list[Path],
    std: str = "c99",
    opt: str = "-O2",
    defines: tuple[str, ...] = (),
) -> Path:
    """gcc the harness (Release: opt is -O2 or -Os) into the context's work directory; returns the
    executable, named after name and the level."""
    require_tools()
    out = ctx.work_dir / "bin" / f"{name}{opt}"
    out.parent.mkdir(parents=True, exist_ok=True)
    argv = ["gcc", *compile_flags(opt, std, defines)]
    argv += [f"-I{d}" for d in include_dirs]
    argv += ["-o", str(out), *(str(s) for s in sources)]
    run_command(ctx, argv)
    return out


_REPORT_FIELD = re.compile(r"(\w+)=(\d+)")
_TOTAL = re.compile(r"^(?:summary|totals):\s*(\d+)", re.MULTILINE)


def callgrind(ctx: BenchContext, binary: Path, mode: str, stream: Path, *args: str) -> HarnessRun:
    """Run the harness in one mode under callgrind (args after the stream file); returns its Ir
    total and its own report line."""
    out_file = ctx.work_dir / f"callgrind.{binary.name}.{mode}.{stream.stem}.out"
    stdout = run_command(
        ctx,
        [
            "valgrind",
            "--tool=callgrind",
            f"--callgrind-out-file={out_file}",
            str(binary),
            mode,
            str(stream),
            *args,
        ],
    )
    match = _TOTAL.search(out_file.read_text())
    if match is None:
        raise BenchError(f"no instruction total in {out_file}")
    report = {key: int(value) for key, value in _REPORT_FIELD.findall(stdout)}
    if report.get("bytes") is None:
        raise BenchError(f"{binary.name} {mode}: no report line in its output: {stdout!r}")
    return HarnessRun(mode, int(match.group(1)), report, out_file)


_FUNCTION_LINE = re.compile(r"^\s*([\d,]+)\s+\(\s*[\d.]+%\)\s+(\S+)")


def top_functions(ctx: BenchContext, run: HarnessRun, count: int = 8) -> list[tuple[str, float]]:
    """The functions that executed the most instructions in a run, as (name, instructions per byte)."""
    text = run_command(ctx, ["callgrind_annotate", "--inclusive=no", str(run.profile)])
    size = run.report["bytes"]
    rows: list[tuple[str, float]] = []
    for line in text.splitlines():
        match = _FUNCTION_LINE.match(line)
        if match and "PROGRAM TOTALS" not in line:
            name = match.group(2).split(":", 1)[-1]
            rows.append((name, round(int(match.group(1).replace(",", "")) / size, 2)))
    return rows[:count]


def per_byte(run: HarnessRun, baseline: HarnessRun) -> float:
    """Instructions per byte of parsing: the run's Ir minus the baseline's, over the stream size."""
    size = run.report["bytes"]
    if size <= 0 or baseline.report["bytes"] != size:
        raise BenchError(f"{run.mode}: baseline and run read different streams")
    extra = run.instructions - baseline.instructions
    if extra <= 0:
        raise BenchError(f"{run.mode}: not more instructions than the baseline ({extra})")
    return extra / size
