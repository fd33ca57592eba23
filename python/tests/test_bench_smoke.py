# SPDX-License-Identifier: MIT
"""The benchmarks cannot rot: a smoke run of every one (bench/run.py --smoke) gives sane results.

No timing is asserted here (speed goals are checked and published by `make bench`); these tests
check that every benchmark ran or says why not, that its figures are positive and its ratios
computed, and that the results render into the docs. Also: the reference receiver model that
the recovery comparison rests on behaves as control-bus.md §4 describes.
"""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
RUN = REPO / "bench" / "run.py"

BENCHMARKS = {
    "c_parser_cost",
    "python_throughput",
    "garbage_recovery",
    "soak",
    "base_exchange",
    "footprint",
    "end_to_end",
    "link_efficiency",
}
RAN = {"measured", "partial"}  # partial: the peer's side measured, ours pending


@pytest.fixture(scope="module")
def smoke(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, dict[str, dict[str, Any]]]:
    out = tmp_path_factory.mktemp("bench-smoke")
    proc = subprocess.run(
        [sys.executable, str(RUN), "--smoke", "--out", str(out)],
        capture_output=True,
        text=True,
        timeout=600,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    results = {path.stem: json.loads(path.read_text()) for path in out.glob("*.json")}
    return out, results


def test_every_benchmark_reports(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    _, results = smoke
    assert set(results) == BENCHMARKS
    for name, result in results.items():
        assert result["name"] == name
        assert result["mode"] == "smoke"
        assert result["status"] in RAN | {"pending"}, (name, result["status"], result["details"])
        assert result["git"]["commit"]
        assert result["machine"]["cpu"]
        if result["status"] == "pending":
            assert result["pending"] and all(reason.strip() for reason in result["pending"])
            assert result["figures"] == {}
        else:
            assert all(isinstance(v, int | float) and v >= 0 for v in result["figures"].values()), name
        if result["status"] == "partial":
            assert result["pending"], name


def test_c_parser_cost_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["c_parser_cost"]
    assert result["status"] in RAN
    f = result["figures"]
    assert f["mavlink_messages"] > 0 and f["ctrlbus_frames"] > 0
    # The peer stream is the same size as ours, within one MAVLink frame.
    assert 0 <= f["ctrlbus_stream_bytes"] - f["mavlink_stream_bytes"] < 300
    levels = ("O2", "Os")
    for variant in ("clean", "noisy"):
        for level in levels:
            for who in ("mavlink_parse_char", "mavlink_frame_char_buffer", "floor_inline", "floor_call"):
                assert f[f"{variant}_{level}_{who}_ipb"] > 1.0
    commands = "\n".join(result["tool_commands"])
    assert "valgrind --tool=callgrind" in commands and "pymavlink.tools.mavgen --lang=C" in commands
    # Every binary's flags are in the result, and each level was built.
    builds = result["details"]["builds"]
    for level in levels:
        assert f"-{level}" in builds[f"{level}_mavlink_parse_char"]
    reports = result["details"]["harness_reports"]
    for level in levels:
        assert reports["clean"][f"{level}_mavlink_parse_char"]["messages"] == f["mavlink_messages"]
        assert reports["noisy"][f"{level}_mavlink_parse_char"]["messages"] < f["mavlink_messages"]
        assert reports["clean"][f"{level}_floor_inline"]["frames"] == f["ctrlbus_frames"]
    if result["status"] == "measured":
        for variant in ("clean", "noisy"):
            for level in levels:
                for mode in ("push", "bytes", "chunks", "feedchunks"):
                    ours = f[f"{variant}_{level}_ctrlbus_{mode}_ipb"]
                    assert ours > 0
                    expected = ours / f[f"{variant}_{level}_mavlink_parse_char_ipb"]
                    assert f[f"{variant}_{level}_ratio_{mode}_vs_parse_char"] == pytest.approx(
                        expected, rel=1e-2
                    )
        for level in levels:
            for mode in ("push", "bytes", "chunks", "feedchunks"):
                assert reports["clean"][f"{level}_ctrlbus_{mode}"]["frames"] == f["ctrlbus_frames"]


def test_python_throughput_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["python_throughput"]
    assert result["status"] in RAN
    f = result["figures"]
    assert f["pymavlink_mb_per_s"] > 0 and f["mavlink_messages"] > 0
    if result["status"] == "measured":
        assert f["ctrlbus_mb_per_s"] > 0 and f["ctrlbus_frames"] > 0
        assert f["ratio"] == pytest.approx(f["ctrlbus_mb_per_s"] / f["pymavlink_mb_per_s"], rel=1e-2)


def test_garbage_recovery_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["garbage_recovery"]
    assert result["status"] in RAN
    f = result["figures"]
    for scenario in ("bursts", "bursts_ber"):
        assert f[f"{scenario}_bursts"] > 0
        assert 0 < f[f"{scenario}_intact_frames"] <= f["frames_sent"]
        assert 0 < f[f"{scenario}_reference_model_recovered_pct"] <= 100
        if result["status"] == "measured":
            assert 0 < f[f"{scenario}_ctrlbus_recovered_pct"] <= 100
            assert f[f"{scenario}_ctrlbus_false_accepts"] >= 0
    assert f["bursts_bit_errors"] == 0 and f["bursts_ber_bit_errors"] > 0


def test_results_render_into_the_docs(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    out, results = smoke
    doc = (out / "performance.md").read_text()
    for name in BENCHMARKS | {"summary"}:
        begin, end = f"<!-- bench:{name}:begin -->", f"<!-- bench:{name}:end -->"
        block = doc.split(begin, 1)[1].split(end, 1)[0]
        assert "(generated by `make bench`)" not in block, name
        if name in results and results[name]["status"] in RAN:
            assert "| Measure |" in block and results[name]["goal"] in block
    for png in ("bench-c-parser-cost.png", "bench-python-throughput.png", "bench-garbage-recovery.png"):
        assert (out / "img" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_a_recorded_pcap_replaces_the_synthetic_session(tmp_path: Path) -> None:
    from ctrlbus.capture import CaptureWriter, Direction
    from ctrlbus.frame import encode

    requests = [encode(0xF8, bytes([0x30])), encode(0xF8, bytes([0x41]) + bytes(range(12)))]
    answers = [encode(0x02, bytes([80, 3]), long=True), encode(0x02, bytes(13), long=True)]
    with CaptureWriter.create(tmp_path / "session.pcap") as writer:
        for k in range(50):
            for request, answer in zip(requests, answers, strict=True):
                # Chunks split inside frames, as a serial reader delivers them.
                writer.write(Direction.CORE_TO_BASE, request[:3], k * 0.1)
                writer.write(Direction.CORE_TO_BASE, request[3:], k * 0.1 + 0.001)
                writer.write(Direction.BASE_TO_CORE, answer, k * 0.1 + 0.003)
    out = tmp_path / "out"
    proc = subprocess.run(
        [
            sys.executable,
            str(RUN),
            "--smoke",
            "--out",
            str(out),
            "--only",
            "python_throughput",
            "--capture",
            str(tmp_path / "session.pcap"),
        ],
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    result = json.loads((out / "python_throughput.json").read_text())
    recording_bytes = 50 * sum(len(frame) for frame in requests + answers)
    copies = result["figures"]["ctrlbus_stream_bytes"] // recording_bytes
    assert copies >= 1 and result["figures"]["ctrlbus_stream_bytes"] == copies * recording_bytes
    if result["status"] == "measured":
        assert result["figures"]["ctrlbus_frames"] == copies * 200


def _reference_model() -> Any:
    spec = importlib.util.spec_from_file_location("bench_refmodel", REPO / "bench" / "refmodel.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up there
    spec.loader.exec_module(module)
    return module


STATUS_REQUEST = bytes.fromhex("10 02 F8 30 DA")
STATUS_ANSWER = bytes.fromhex("50 03 00 02 50 03 02")


def test_reference_model_delivers_clean_frames_split_anywhere() -> None:
    model = _reference_model().ReferenceModelDecoder()
    stream = b"\x00\x33" + STATUS_REQUEST + STATUS_ANSWER
    frames = [frame for byte in stream for frame in model.feed(bytes([byte]))]
    assert frames == [STATUS_REQUEST, STATUS_ANSWER]
    assert model.counters.bytes_discarded == 2


def test_reference_model_false_flag_swallows_the_next_frame() -> None:
    # A false 0x10 with length 5 takes the real request's 5 bytes as its body and checksum and
    # fails; with no backtracking the request is lost, the answer after it still arrives.
    model = _reference_model().ReferenceModelDecoder()
    frames = model.feed(b"\x10\x04" + STATUS_REQUEST + STATUS_ANSWER)
    assert frames == [STATUS_ANSWER]
    assert model.counters.checksum_errors == 1


def test_reference_model_waits_for_ever_and_resets_on_oversize() -> None:
    module = _reference_model()
    model = module.ReferenceModelDecoder()
    # No timeout: a bogus standard length of 200 keeps swallowing until 200 + 1 bytes came.
    assert model.feed(b"\x10\xc8" + STATUS_REQUEST * 40) == []
    # A long LEN above the 512-byte receive buffer resets right after the length bytes.
    model = module.ReferenceModelDecoder()
    assert model.feed(b"\x50\xff\x01" + STATUS_REQUEST) == [STATUS_REQUEST]
    assert model.counters.oversize == 1


# --- base_exchange, footprint, end_to_end, link_efficiency (bench/exchange.py, footprint.py,
# endtoend.py): their smoke results are whole and consistent; no speed is asserted.


def test_base_exchange_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["base_exchange"]
    assert result["status"] in RAN | {"pending"}
    if result["status"] == "pending":
        return
    f = result["figures"]
    assert f["exchanges"] > 0 and f["set_v_request_bytes"] == 17 and f["set_v_answer_bytes"] in (18, 22)
    assert f["status_request_bytes"] == 5 and f["status_answer_bytes"] == 7
    for level in ("O2", "Os"):
        for kind in ("set_v", "status"):
            ours = f[f"{level}_{kind}_ours_per_exchange"]
            floor = f[f"{level}_{kind}_floor_per_exchange"]
            assert ours > 0 and floor > 0 and f[f"{level}_{kind}_mavlink_parse_per_message"] > 0
            assert f[f"{level}_{kind}_ours_over_floor"] == pytest.approx(ours / floor, abs=0.01)
        assert 0 < f[f"{level}_mcu_load_percent"] < 100
        assert result["details"]["profile_per_exchange"][level]
    # Streamed: several write calls per answer, none holding the whole answer.
    assert f["write_calls_per_answer"] > 1 and 0 < f["largest_write_bytes"] < f["set_v_answer_bytes"]
    assert "valgrind --tool=callgrind" in "\n".join(result["tool_commands"])
    # The table judges the SET_V exchange against its goal at both levels.
    judged = [row for row in result["table"] if row[1].startswith("≤ 1.5")]
    assert len(judged) == 2


def test_footprint_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["footprint"]
    assert result["status"] in RAN | {"pending"}
    if result["status"] == "pending":
        return
    f = result["figures"]
    assert f["sizeof_ctrlbus_base_t"] > 0 and f["sizeof_ctrlbus_decoder_t"] > 0
    text = f["cortex_m0plus_base_stack_text"]
    assert text > 0
    # The per-object breakdown from the linker map accounts for every byte size(1) counts.
    by_object = result["details"]["base_stack_by_object"]["cortex-m0plus"]
    assert sum(sizes["text"] for sizes in by_object.values()) == text
    assert {"base.c", "frame.c"} <= set(by_object)
    assert "scripts/size.sh" in "\n".join(result["tool_commands"])
    # The per-target table: the minimal configuration is smaller, and poll's stack was measured.
    assert 0 < f["cortex_m0plus_minimal_Os_text"] < f["cortex_m0plus_default_Os_text"]
    assert f["cortex_m0plus_default_Os_stack"] > 0


def test_end_to_end_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["end_to_end"]
    assert result["status"] in RAN
    f = result["figures"]
    bases = ["python_base"] + (["c_base"] if result["status"] == "measured" else [])
    for base in bases:
        assert f[f"{base}_back_to_back_exchanges_per_s"] > 0
        assert 0 < f[f"{base}_back_to_back_round_trip_p50_ms"] <= f[f"{base}_back_to_back_round_trip_p99_ms"]
        assert f[f"{base}_core_exchanges_per_s"] > 0
        assert result["details"][base]["core_emulator"]["exchanges"] > 0


def test_link_efficiency_figures(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["link_efficiency"]
    assert result["status"] in RAN
    f = result["figures"]
    bases = ["python_base"] + (["c_base"] if result["status"] == "measured" else [])
    for base in bases:
        for master in ("core", "loop"):
            run = result["details"][base][master]
            assert run["request_bytes"] == 17 and run["answer_bytes"] in (18, 22)
            maximum = 115200 / 10 / (run["request_bytes"] + run["answer_bytes"])
            assert run["theoretical_max_per_s"] == pytest.approx(maximum, abs=0.01)
            assert f[f"{base}_{master}_efficiency_pct"] > 0
            assert run["base_reply_latency_mean_ms"] > 0 and run["master_turnaround_mean_ms"] > 0
    # Virtual time is deterministic: with an instant base the line never idles, and a slower
    # base only costs efficiency.
    sweep = result["details"]["virtual_time"]["sweep"]
    assert sweep[0]["base_reply_latency_ms"] == 0
    assert sweep[0]["efficiency_pct"] == pytest.approx(100.0, abs=0.5)
    efficiencies = [point["efficiency_pct"] for point in sweep]
    assert efficiencies == sorted(efficiencies, reverse=True) and efficiencies[-1] < efficiencies[0]


def test_plots_of_the_base_and_link_benchmarks(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    out, results = smoke
    plots = {
        "base_exchange": "bench-base-exchange.png",
        "footprint": "bench-footprint.png",
        "end_to_end": "bench-end-to-end.png",
        "link_efficiency": "bench-link-efficiency.png",
    }
    for name, png in plots.items():
        if results[name]["status"] in RAN:
            assert (out / "img" / png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n", name


def _bench_module(name: str) -> Any:
    """A module of bench/ (they import each other by their bare names, so bench/ goes on the path
    while it loads)."""
    bench = str(REPO / "bench")
    sys.path.insert(0, bench)
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(bench)


class _FakeClock:
    """Time that moves only when read (a microsecond per reading, as code takes time) or when a
    read of the scripted link waits."""

    def __init__(self) -> None:
        self.now = 0.0

    def __call__(self) -> float:
        self.now += 1e-6
        return self.now


class _ScriptedBase:
    """A link whose far end answers every request `latency_s` after it was written; reading
    advances the fake clock as a blocking read would."""

    def __init__(self, clock: _FakeClock, answer: bytes, latency_s: float) -> None:
        self.clock = clock
        self.answer = answer
        self.latency_s = latency_s
        self.due: float | None = None
        self.written: list[tuple[float, bytes]] = []

    @property
    def name(self) -> str:
        return "scripted"

    def write(self, data: bytes) -> None:
        self.written.append((self.clock.now, data))
        self.due = self.clock.now + self.latency_s

    def read(self, timeout: float) -> bytes:
        if self.due is not None and self.due <= self.clock.now + timeout:
            self.clock.now = max(self.clock.now, self.due)
            self.due = None
            return self.answer
        self.clock.now += timeout
        return b""

    def close(self) -> None:
        pass


def test_paced_link_delivers_at_the_line_rate() -> None:
    endtoend = _bench_module("endtoend")
    from ctrlbus.messages import SetVAndGetDeadreckon, SetVAndGetDeadreckonAnswer, answer_frame, request_frame

    request = request_frame(SetVAndGetDeadreckon.from_si(0.1, 0.0, 0.2))
    answer = answer_frame(SetVAndGetDeadreckonAnswer(1, 2, 3), long=True)
    byte_time = 10 / 115200
    clock = _FakeClock()
    base = _ScriptedBase(clock, answer, latency_s=0.0005)
    link = endtoend.PacedLink(base, byte_time, clock=clock)
    link.write(request)
    # The request reaches the base once its last byte has crossed the line, not before.
    ((handed_at, data),) = base.written
    assert data == request and handed_at == pytest.approx(len(request) * byte_time, abs=2e-5)
    got = b""
    while len(got) < len(answer):
        got += link.read(0.01)
    assert got == answer
    # The answer left the base 0.5 ms after the request and took its own line time to arrive.
    assert clock.now == pytest.approx(handed_at + 0.0005 + len(answer) * byte_time, abs=2e-5)
    assert link.reply_latencies[0][1] == pytest.approx(0.0005, abs=2e-5)
    assert [size for _, size in link.requests] == [len(request)]
    assert [size for _, size in link.answers] == [len(answer)]
    link.write(request)
    assert link.turnarounds[0][1] == pytest.approx(0.0, abs=2e-5)


def test_soak_real_time_runs(smoke: tuple[Path, dict[str, dict[str, Any]]]) -> None:
    result = smoke[1]["soak"]
    assert result["status"] in RAN
    bases = ["python_base"] + (["c_base"] if result["status"] == "measured" else [])
    for base in bases:
        run = result["details"][f"realtime_{base}"]
        # It ran to its exchange count (300 in the smoke run) unless it hit its time limit.
        assert run["exchanges"] == result["figures"][f"{base}_exchanges"] > 0
        assert run["exchanges"] >= 300 or run["seconds"] >= 20.0
        assert run["request_timeout_s"] < 0.2 and run["exchanges_per_s"] > 0


def test_soak_against_the_reference_quirks_base_loses_no_request(
    smoke: tuple[Path, dict[str, dict[str, Any]]],
) -> None:
    result = smoke[1]["soak"]
    assert result["status"] in RAN
    figures = result["figures"]
    assert figures["quirks_exchanges"] >= 2000 and figures["quirks_lost_requests"] == 0


def _fake_fuzz_build(root: Path, *, crash_in: str | None = None) -> Path:
    """A fuzz build directory as scripts/fuzz.sh leaves it: a log per target, corpora, coverage."""
    logs = root / "logs"
    logs.mkdir(parents=True)
    for number, target in enumerate(("decoder", "base", "fixup"), start=1):
        lines = [
            "INFO: Loaded 1 modules   (600 inline 8-bit counters): 600 [0x1, 0x2),",
            f"#1000\tNEW    cov: {100 * number} ft: {1000 * number} corp: 5/1Kb exec/s: 0 rss: 40Mb",
        ]
        if target == crash_in:
            lines += ["==42==ERROR: AddressSanitizer: heap-buffer-overflow on address 0x1", "SUMMARY: ..."]
        else:
            lines.append(f"Done {10_000_000 + number} runs in 900 second(s)")
        lines += [
            f"stat::number_of_executed_units: {10_000_000 + number}",
            "stat::average_exec_per_sec:     11111",
        ]
        (logs / f"{target}.log").write_text("\n".join(lines) + "\n")
        corpus = root / "corpus" / target
        corpus.mkdir(parents=True)
        for i in range(number):
            (corpus / str(i)).write_bytes(b"x")
    header = (
        "Filename Regions Missed Cover Functions Missed Executed Lines Missed Cover Branches Missed Cover"
    )
    (logs / "coverage.txt").write_text(
        f"{header}\n/x/c/src/frame.c 400 20 95.00% 30 0 100.00% 700 10 98.57% 300 30 90.00%\n"
        "TOTAL 1000 100 90.00% 90 1 98.89% 2000 50 97.50% 800 80 90.00%\n"
    )
    return root


def test_fuzz_report_reads_the_logs_and_the_coverage(tmp_path: Path) -> None:
    fuzz_report = _bench_module("fuzz_report")
    result = fuzz_report.build_result(_fake_fuzz_build(tmp_path / "ok"), "make fuzz")
    f = result["figures"]
    assert [f[f"{t}_executions"] for t in ("decoder", "base", "fixup")] == [
        10_000_001,
        10_000_002,
        10_000_003,
    ]
    assert (f["base_coverage_edges"], f["base_instrumented_edges"], f["base_findings"]) == (200, 600, 0)
    assert f["library_line_coverage"] == "97.50%"
    assert [row[-1] for row in result["table"][:3]] == ["yes"] * 3
    assert result["details"]["coverage"]["frame.c"]["branches"] == "90.00%"
    # A target that found something: its row fails, and the finding is named.
    crashed = fuzz_report.build_result(_fake_fuzz_build(tmp_path / "crash", crash_in="base"), "make fuzz")
    row = crashed["table"][1]
    assert row[-1] == "**no**" and "heap-buffer-overflow" in row[2]
    assert crashed["figures"]["base_findings"] == 2
