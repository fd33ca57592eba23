#!/usr/bin/env bash
# SPDX-License-Identifier: MIT
# Runs the C library's libFuzzer targets (c/fuzz/README.md). `make fuzz` calls it (10 M executions
# per target), `make fuzz-smoke` (part of `make test`) runs it for 30 s per target.
#
#   scripts/fuzz.sh [SECONDS]                    every target for SECONDS each (default 30), in turn
#   FUZZ_TARGETS="decoder" scripts/fuzz.sh 600   some targets only
#   FUZZ_RUNS=10000000 scripts/fuzz.sh 3600      each target until N executions, SECONDS at most
#   FUZZ_COVERAGE=1 scripts/fuzz.sh [SECONDS]    then the line coverage of c/src by the corpora
#                                                (SECONDS 0: the coverage only, no fuzzing)
#   FUZZ_RECORD=1 scripts/fuzz.sh [SECONDS]      then record the run (bench/fuzz_report.py):
#                                                bench/results/fuzz.json and the fuzzing table
#                                                of docs/reliability.md (`make fuzz` does this)
#
# It configures and builds build/fuzz with clang (libFuzzer, AddressSanitizer, UndefinedBehavior-
# Sanitizer; that build writes the seed corpora from vectors/*.json), then runs each target with
# -max_total_time=SECONDS on its corpus build/fuzz/corpus/<target> (kept, so that a run starts from
# what earlier runs found) plus the seeds; the full log of a run is build/fuzz/logs/<target>.log. It
# prints one line per target: executions, executions per second, coverage as libFuzzer counts it
# (edges of the library reached, of all its instrumented edges) and its feature count, and the
# corpus size.
#
# With FUZZ_COVERAGE=1 it then replays every target's corpus and seeds with the replay programs
# built with clang's source-based coverage (build/fuzz-cov) and prints llvm-cov's report for
# c/src/*.c: the share of the library's regions, functions, lines and branches the corpora reach.
#
# Exit status: 0 when no target found anything; 1 when one crashed, leaked, timed out or broke an
# invariant (the reproducer's path is printed: replay it with build/fuzz/fuzz/fuzz_<target> FILE,
# and once fixed keep it in c/fuzz/regressions/<target>/); 2 when something cannot be built.
set -euo pipefail

# The last value of a libFuzzer status field ("cov: 123") or final statistic in a log, or "?".
# (Every pipeline here ends in `|| ...`: with pipefail, a line missing from a log must not stop us.)
field() { grep -oE "$1: [0-9]+" "$2" | tail -1 | grep -oE '[0-9]+$' || echo "?"; }
stat() { grep -E "^stat::$1:" "$2" | tail -1 | grep -oE '[0-9]+$' || echo "?"; }

# Runs one target; prints its line; returns 1 if it found something.
fuzz_target() {
  local target=$1 seconds=$2 build=$3 max_len=$4
  local corpus="$build/corpus/$target" artifacts="$build/artifacts/$target/"
  local log="$build/logs/$target.log" status=0 edges crash result=ok
  mkdir -p "$corpus" "$artifacts"
  "$build/fuzz/fuzz_$target" -max_total_time="$seconds" -runs="${FUZZ_RUNS:--1}" -max_len="$max_len" \
    -timeout=10 -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$artifacts" \
    "$corpus" "$build/fuzz/seeds/$target" >"$log" 2>&1 || status=$?
  edges=$(grep -oE 'Loaded [0-9]+ modules +\([0-9]+ inline 8-bit counters\)' "$log" |
            grep -oE '\([0-9]+' | tr -d '(' | head -1 || true)
  if ((status != 0)); then
    crash=$(grep -oE "Test unit written to [^ ]+" "$log" | tail -1 | sed 's/Test unit written to //' || true)
    result="FAILED (exit $status): ${crash:-no reproducer written, see $log}"
  fi
  printf '%-8s %8s %12s %8s %14s %7s %7s  %s\n' "$target" "$seconds" \
    "$(stat number_of_executed_units "$log")" "$(stat average_exec_per_sec "$log")" \
    "$(field cov "$log")/${edges:-?}" "$(field ft "$log")" "$(find "$corpus" -type f | wc -l)" "$result"
  if ((status != 0)); then
    grep -E "fuzz invariant broken|ERROR: |SUMMARY: " "$log" | head -5 | sed 's/^/    /' || true
    return 1
  fi
}

# Replays the corpora with coverage-instrumented programs and prints llvm-cov's report.
coverage_report() {
  local build=$1 cc=$2 targets=$3 cov_build=build/fuzz-cov target
  local objects=()
  if ! { cmake -S c -B "$cov_build" -G Ninja -DCMAKE_C_COMPILER="$cc" -DCMAKE_BUILD_TYPE=Debug \
           -DCMAKE_C_FLAGS="-fprofile-instr-generate -fcoverage-mapping" &&
         cmake --build "$cov_build" --target $(printf 'replay_%s ' $targets); } >"$cov_build.log" 2>&1; then
    tail -30 "$cov_build.log" >&2
    echo "fuzz.sh: the coverage build failed (log: $cov_build.log)" >&2
    return 2
  fi
  rm -f "$cov_build"/*.profraw
  for target in $targets; do
    mkdir -p "$build/corpus/$target"
    LLVM_PROFILE_FILE="$cov_build/$target.profraw" "$cov_build/fuzz/replay_$target" \
      "$build/corpus/$target" "$cov_build/fuzz/seeds/$target" >/dev/null
    objects+=(-object "$cov_build/fuzz/replay_$target")
  done
  llvm-profdata merge -o "$cov_build/merged.profdata" "$cov_build"/*.profraw
  echo
  echo "coverage of the library by the corpora and seeds of: $targets"
  llvm-cov report "${objects[@]:1}" -instr-profile="$cov_build/merged.profdata" c/src/*.c |
    tee "$build/logs/coverage.txt"
}

# All of it in one function, read whole before it runs: editing this file while a long run is
# going cannot derail that run.
main() {
  cd "$(dirname "$0")/.."
  local seconds=${1:-30}
  local build=${FUZZ_BUILD:-build/fuzz}
  local targets=${FUZZ_TARGETS:-"decoder base fixup"}
  local max_len=${FUZZ_MAX_LEN:-4096}
  local cc=${FUZZ_CC:-clang}
  local coverage=${FUZZ_COVERAGE:-0}
  local failed=0 target

  if ! [[ "$seconds" =~ ^[0-9]+$ ]] || { ((seconds == 0)) && [ "$coverage" != 1 ]; }; then
    echo "fuzz.sh: SECONDS must be a positive whole number, not '$seconds'" >&2
    exit 2
  fi
  if ! command -v "$cc" >/dev/null; then
    echo "fuzz.sh: $cc not found; scripts/setup.sh installs it (apt: clang, libclang-rt-14-dev)" >&2
    exit 2
  fi
  if ((seconds > 0)); then
    mkdir -p "$build/logs"
    # Only the fuzz targets are built: the library's own configuration, with clang.
    if ! { cmake -S c -B "$build" -G Ninja -DCMAKE_C_COMPILER="$cc" -DCTRLBUS_FUZZ=ON \
             -DCMAKE_BUILD_TYPE=RelWithDebInfo &&
           cmake --build "$build" --target $(printf 'fuzz_%s ' $targets); } \
         >"$build/logs/build.log" 2>&1; then
      tail -30 "$build/logs/build.log" >&2
      echo "fuzz.sh: the fuzz targets did not build (log: $build/logs/build.log)" >&2
      exit 2
    fi
    printf '%-8s %8s %12s %8s %14s %7s %7s  %s\n' target seconds executions exec/s "cov (edges)" \
      ft corpus result
    for target in $targets; do
      fuzz_target "$target" "$seconds" "$build" "$max_len" || failed=1
    done
  fi
  if [ "$coverage" = 1 ]; then
    mkdir -p "$build/logs"
    rm -f "$build/logs/coverage.txt"
    coverage_report "$build" "$cc" "$targets" || exit 2
  fi
  if [ "${FUZZ_RECORD:-0}" = 1 ]; then
    local python=.venv/bin/python
    [ -x "$python" ] || python=python3
    (cd bench && "../$python" fuzz_report.py --build "../$build" \
       --command "${FUZZ_COMMAND:-FUZZ_COVERAGE=$coverage FUZZ_RECORD=1 scripts/fuzz.sh $seconds}") || exit 2
  fi
  exit $failed
}

main "$@"
