# SPDX-License-Identifier: MIT
"""Record a libFuzzer run of scripts/fuzz.sh: bench/results/fuzz.json and the fuzzing table of
docs/reliability.md (the block between `<!-- bench:fuzz:begin -->` and `<!-- bench:fuzz:end -->`).

    python bench/fuzz_report.py [--build build/fuzz] [--command "make fuzz FUZZ_SECONDS=900"]

It reads what the run left behind: each target's libFuzzer log (`<build>/logs/<target>.log`: runs,
seconds, executions per second, coverage and feature counts, whether it found something), the
size of its corpus, and the line coverage report of the library (`<build>/logs/coverage.txt`,
written when the run had FUZZ_COVERAGE=1). scripts/fuzz.sh calls it with FUZZ_RECORD=1, as
`make fuzz` does; nothing here fuzzes.
"""

from __future__ import annotations

import argparse
import datetime
import json
import re
import sys
from pathlib import Path
from typing import Any

from common import REPO, BenchError, git_revision, machine_facts
from report import render_block, replace_block

NAME = "fuzz"
TITLE = "Fuzzing: libFuzzer targets of the C library, with AddressSanitizer and UndefinedBehaviorSanitizer"
GOAL_EXECUTIONS = 10_000_000
GOAL = f"≥ {GOAL_EXECUTIONS / 1e6:g} M executions of each target without a finding"
TARGETS = ("decoder", "base", "fixup")
WHAT = {
    "decoder": "stream decoder (feed, byte path and chunk path against each other)",
    "base": "whole base stack, bytes in, answers out",
    "fixup": "base stack and message codecs, lengths and checksums fixed up",
}


def _last_int(pattern: str, text: str) -> int | None:
    found = re.findall(pattern, text, re.MULTILINE)
    return int(found[-1]) if found else None


def read_target(build: Path, target: str) -> dict[str, Any]:
    """The figures of one target's run, from its log."""
    log_path = build / "logs" / f"{target}.log"
    try:
        log = log_path.read_text(errors="replace")
    except OSError as exc:
        raise BenchError(f"no log of the {target} target ({log_path}): {exc.strerror}") from None
    done = re.findall(r"^Done (\d+) runs in (\d+) second", log, re.MULTILINE)
    findings = re.findall(r"^(?:==\d+==ERROR: .*|SUMMARY: .*|.*fuzz invariant broken.*)$", log, re.MULTILINE)
    corpus = build / "corpus" / target
    return {
        "target": target,
        "executions": (
            int(done[-1][0]) if done else _last_int(r"^stat::number_of_executed_units:\s+(\d+)", log)
        ),
        "seconds": int(done[-1][1]) if done else None,
        "finished": bool(done),
        "exec_per_s": _last_int(r"^stat::average_exec_per_sec:\s+(\d+)", log),
        "coverage_edges": _last_int(r"\bcov: (\d+)", log),
        "instrumented_edges": _last_int(r"Loaded \d+ modules\s+\((\d+) inline 8-bit counters\)", log),
        "features": _last_int(r"\bft: (\d+)", log),
        "corpus_files": sum(1 for path in corpus.iterdir() if path.is_file()) if corpus.is_dir() else 0,
        "findings": findings[:5],
    }


def read_coverage(build: Path) -> dict[str, dict[str, str]]:
    """llvm-cov's report per file (and TOTAL): region, function, line and branch coverage."""
    path = build / "logs" / "coverage.txt"
    if not path.is_file():
        return {}
    rows: dict[str, dict[str, str]] = {}
    for line in path.read_text().splitlines():
        cells = line.split()
        # Filename, then Regions Missed Cover, Functions Missed Executed, Lines Missed Cover,
        # Branches Missed Cover.
        if len(cells) == 13 and cells[3].endswith("%") and (cells[0].endswith(".c") or cells[0] == "TOTAL"):
            rows[Path(cells[0]).name] = {
                "regions": cells[3],
                "functions": cells[6],
                "lines": cells[9],
                "branches": cells[12],
            }
    return rows


def build_result(build: Path, command: str) -> dict[str, Any]:
    targets = [read_target(build, target) for target in TARGETS]
    coverage = read_coverage(build)
    rows: list[list[str]] = []
    figures: dict[str, Any] = {}
    for run in targets:
        name = run["target"]
        executions = run["executions"] or 0
        met = executions >= GOAL_EXECUTIONS and run["finished"] and not run["findings"]
        found = "; ".join(run["findings"]) if run["findings"] else "none"
        rows.append(
            [
                f"`fuzz_{name}`: {WHAT[name]}; executions in {run['seconds'] or '?'} s (per second; "
                "edges of the library reached / instrumented; features; corpus files; findings)",
                f"≥ {GOAL_EXECUTIONS:,}, no finding",
                f"{executions:,} ({run['exec_per_s'] or 0:,}/s; {run['coverage_edges']} / "
                f"{run['instrumented_edges']}; {run['features']}; {run['corpus_files']:,}; {found})",
                "",
                "",
                "yes" if met else "**no**",
            ]
        )
        figures[f"{name}_executions"] = executions
        figures[f"{name}_exec_per_s"] = run["exec_per_s"]
        figures[f"{name}_coverage_edges"] = run["coverage_edges"]
        figures[f"{name}_instrumented_edges"] = run["instrumented_edges"]
        figures[f"{name}_findings"] = len(run["findings"])
    if coverage:
        for file, cover in coverage.items():
            rows.append(
                [
                    f"coverage of {'the library (c/src)' if file == 'TOTAL' else f'`c/src/{file}`'} by the "
                    "corpora and seeds of all targets: regions / functions / lines / branches",
                    "published",
                    " / ".join(cover[key] for key in ("regions", "functions", "lines", "branches")),
                    "",
                    "",
                    "yes",
                ]
            )
        figures["library_line_coverage"] = coverage.get("TOTAL", {}).get("lines")
    return {
        "name": NAME,
        "title": TITLE,
        "goal": GOAL,
        "status": "measured",
        "mode": "full",
        "when": datetime.datetime.now(datetime.timezone.utc).isoformat(timespec="seconds"),
        "command": command,
        "machine": machine_facts(),
        "git": git_revision(),
        "figures": figures,
        "table": rows,
        "pending": [],
        "details": {"targets": targets, "coverage": coverage},
        "tool_commands": [command],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--build", type=Path, default=REPO / "build" / "fuzz", help="fuzz build directory")
    parser.add_argument("--command", default="make fuzz", help="the command that ran the fuzzers")
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "results", help="where fuzz.json goes")
    parser.add_argument("--doc", type=Path, default=REPO / "docs" / "reliability.md", help="page to update")
    args = parser.parse_args(argv)
    try:
        result = build_result(args.build, args.command)
        args.out.mkdir(parents=True, exist_ok=True)
        (args.out / f"{NAME}.json").write_text(json.dumps(result, indent=2) + "\n")
        text = replace_block(args.doc.read_text(), NAME, render_block(result, None, args.doc.parent))
        args.doc.write_text(text)
    except (BenchError, OSError) as exc:
        print(f"fuzz_report: {exc}", file=sys.stderr)
        return 2
    print(f"fuzz_report: {args.out / (NAME + '.json')} and the fuzzing table of {args.doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
