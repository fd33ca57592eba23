# SPDX-License-Identifier: MIT
"""Publish benchmark results: PNG plots (matplotlib, Agg) and the generated parts of docs/performance.md.

docs/performance.md is hand-written prose with generated blocks. Each block sits between

    <!-- bench:NAME:begin -->
    ...
    <!-- bench:NAME:end -->

and only what is between the markers is rewritten, so the prose around them stays. NAME is a
benchmark name (its table), or `summary` (one line per goal).
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from common import FAILED, PENDING, BenchError

TABLE_HEADER = ["Measure", "Goal", "ctrlbus", "Peer, same run", "Ratio", "Goal met"]


def _save(fig: Any, path: Path) -> Path:
    """Lay out, write and close a figure; returns where it went."""
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path)
    plt.close(fig)
    return path


def _bar_chart(
    path: Path,
    title: str,
    ylabel: str,
    groups: list[str],
    series: list[tuple[str, list[float | None]]],
    ymin: float | None = None,
) -> Path:
    fig, ax = plt.subplots(figsize=(7.5, 4.4), dpi=110)
    width = 0.8 / max(1, len(series))
    for i, (label, values) in enumerate(series):
        xs = [g + (i - (len(series) - 1) / 2) * width for g in range(len(groups))]
        heights = [v if v is not None else (ymin or 0.0) for v in values]
        bars = ax.bar(xs, heights, width, label=label)
        for bar, value in zip(bars, values, strict=True):
            text = "pending" if value is None else f"{value:,.4g}"
            ax.annotate(
                text,
                (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                ha="center",
                va="bottom",
                fontsize=7,
                xytext=(0, 2),
                textcoords="offset points",
            )
    ax.set_xticks(range(len(groups)), groups)
    ax.set_ylabel(ylabel)
    ax.set_title(title, fontsize=10)
    if ymin is not None:
        top = max([v for _, values in series for v in values if v is not None] or [ymin + 1.0])
        ax.set_ylim(ymin, top + (top - ymin) * 0.12)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.1), ncol=2, frameon=False)
    ax.margins(y=0.12)
    return _save(fig, path)


def _plot_c_parser_cost(result: dict[str, Any], img_dir: Path) -> Path:
    f = result["figures"]
    groups = [(v, level) for level in ("O2", "Os") for v in ("clean", "noisy")]
    series: list[tuple[str, list[float | None]]] = [
        (label, [f.get(f"{v}_{level}_{who}_ipb") for v, level in groups])
        for label, who in (
            ("MAVLink mavlink_parse_char (one call site)", "mavlink_parse_char"),
            ("XOR state machine, inlined (floor)", "floor_inline"),
            ("XOR state machine, a call per byte", "floor_call"),
            ("ctrlbus, byte by byte", "ctrlbus_" + result["details"].get("byte_mode", "bytes")),
            ("ctrlbus, in 64-byte chunks", "ctrlbus_chunks"),
        )
    ]
    return _bar_chart(
        img_dir / "bench-c-parser-cost.png",
        "C parser: instructions per byte (callgrind, Release builds)",
        "instructions / byte",
        [f"{v}, gcc -{level}" for v, level in groups],
        series,
    )


def _plot_python_throughput(result: dict[str, Any], img_dir: Path) -> Path:
    f = result["figures"]
    series: list[tuple[str, list[float | None]]] = [
        ("pymavlink parse_buffer", [f.get("pymavlink_mb_per_s")]),
        ("ctrlbus.frame.StreamDecoder", [f.get("ctrlbus_mb_per_s")]),
    ]
    return _bar_chart(
        img_dir / "bench-python-throughput.png",
        "Python decoders: throughput",
        "MB/s",
        [f"{f.get('mavlink_stream_bytes', 0) / 1e6:.1f} MB stream"],
        series,
    )


def _plot_garbage_recovery(result: dict[str, Any], img_dir: Path) -> Path:
    f = result["figures"]
    scenarios = ["bursts", "bursts_ber"]
    series: list[tuple[str, list[float | None]]] = [
        ("reference receiver model", [f.get(f"{s}_reference_model_recovered_pct") for s in scenarios]),
        ("ctrlbus decoder", [f.get(f"{s}_ctrlbus_recovered_pct") for s in scenarios]),
    ]
    return _bar_chart(
        img_dir / "bench-garbage-recovery.png",
        "Valid frames recovered after garbage bursts (axis zoomed)",
        "% of valid frames",
        ["garbage bursts", "bursts + BER 1e-4"],
        series,
        # Zoomed in: the difference is in the last per cent.
        ymin=max(0.0, min([v for _, vs in series for v in vs if v is not None] or [100.0]) - 1.0),
    )


def _plot_base_exchange(result: dict[str, Any], img_dir: Path) -> Path:
    """Instructions per exchange on the firmware timeline: ours, the floor, MAVLink's parse."""
    f = result["figures"]
    groups = [(level, kind) for level in ("O2", "Os") for kind in ("set_v", "status")]
    labels = [f"{'SET_V' if kind == 'set_v' else 'STATUS'} -{level}" for level, kind in groups]
    series = [
        ("ctrlbus base stack", [f[f"{lv}_{k}_ours_per_exchange"] for lv, k in groups]),
        ("hand-written floor", [f[f"{lv}_{k}_floor_per_exchange"] for lv, k in groups]),
        ("MAVLink parse (same payload)", [f[f"{lv}_{k}_mavlink_parse_per_message"] for lv, k in groups]),
    ]
    fig, ax = plt.subplots(figsize=(7.5, 4.4), dpi=110)
    width = 0.27
    for index, (name, values) in enumerate(series):
        xs = [x + (index - 1) * width for x in range(len(groups))]
        bars = ax.bar(xs, values, width, label=name)
        for bar, value in zip(bars, values, strict=True):
            ax.annotate(
                f"{value:,.0f}",
                (bar.get_x() + bar.get_width() / 2, bar.get_height()),
                ha="center",
                fontsize=6,
                xytext=(0, 2),
                textcoords="offset points",
            )
    ax.set_xticks(range(len(groups)), labels)
    ax.set_ylabel("instructions per exchange (callgrind)")
    ax.set_title("One exchange as a firmware runs it (byte interrupt, poll per ms)", fontsize=9)
    ax.legend(fontsize=7)
    return _save(fig, img_dir / "bench-base-exchange.png")


def _plot_footprint(result: dict[str, Any], img_dir: Path) -> Path:
    """The base stack's linked .text per CPU, stacked by the object file it comes from."""
    by_cpu: dict[str, dict[str, dict[str, int]]] = result["details"]["base_stack_by_object"]
    cpus = list(by_cpu)
    owners = sorted(
        {o for objs in by_cpu.values() for o in objs},
        key=lambda o: -by_cpu[cpus[0]].get(o, {}).get("text", 0),
    )
    fig, ax = plt.subplots(figsize=(7.5, 4.4), dpi=110)
    bottoms = [0.0] * len(cpus)
    for owner in owners:
        values = [float(by_cpu[cpu].get(owner, {}).get("text", 0)) for cpu in cpus]
        ax.bar(cpus, values, 0.5, bottom=bottoms, label=owner)
        bottoms = [b + v for b, v in zip(bottoms, values, strict=True)]
    for x, total in enumerate(bottoms):
        ax.annotate(
            f"{total:,.0f} B",
            (x, total),
            ha="center",
            va="bottom",
            fontsize=8,
            xytext=(0, 2),
            textcoords="offset points",
        )
    ax.axhline(2048, color="black", linestyle="--", linewidth=1)
    ax.annotate("goal: 2 KiB", (-0.45, 2048), ha="left", va="bottom", fontsize=8, zorder=4)
    ax.set_ylabel(".text bytes (arm-none-eabi-gcc -Os, --gc-sections)")
    ax.set_title("C base stack, linked: where the .text comes from", fontsize=10)
    ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.08), ncol=3, frameon=False)
    ax.margins(y=0.1)
    return _save(fig, img_dir / "bench-footprint.png")


def _plot_end_to_end(result: dict[str, Any], img_dir: Path) -> Path:
    f = result["figures"]
    bases = [("c_base", "C host base (posix_base)"), ("python_base", "Python simulated base")]
    present = [(key, label) for key, label in bases if f"{key}_core_exchanges_per_s" in f]
    series: list[tuple[str, list[float | None]]] = [
        (
            "SET_V back to back (master loop)",
            [f.get(f"{key}_back_to_back_exchanges_per_s") for key, _ in present],
        ),
        (
            "Core emulator, SET_V at its 1000 Hz ceiling",
            [f.get(f"{key}_core_exchanges_per_s") for key, _ in present],
        ),
    ]
    return _bar_chart(
        img_dir / "bench-end-to-end.png",
        "Exchanges per second over a pty, no baud limit",
        "exchanges / s",
        [label for _, label in present],
        series,
    )


def _plot_link_efficiency(result: dict[str, Any], img_dir: Path) -> Path:
    """Efficiency against the time per exchange spent off the line: the virtual-time sweep, and
    where the real-time runs landed."""
    details = result["details"]
    sweep = details["virtual_time"]["sweep"]
    fig, ax = plt.subplots(figsize=(7.5, 4.4), dpi=110)
    ax.plot(
        [p["base_reply_latency_ms"] for p in sweep],
        [p["efficiency_pct"] for p in sweep],
        marker="o",
        color="0.4",
        label="virtual time: Core instant, base replying after x",
    )
    bases = (("c_base", "C host base"), ("python_base", "Python simulated base"))
    masters = (("core", "Core emulator"), ("loop", "master loop"))
    for key, label in bases:
        for master, master_label in masters:
            run = details.get(key, {}).get(master)
            if run is None:
                continue
            off_line = run["period_ms"] - run["line_time_ms"]
            ax.scatter(
                [off_line],
                [run["efficiency_pct"]],
                zorder=3,
                label=f"real time: {label}, {master_label} ({run['efficiency_pct']:.1f} %)",
            )
    ax.axhline(95.0, color="black", linestyle="--", linewidth=1)
    ax.annotate(
        "goal: 95 %",
        (max(p["base_reply_latency_ms"] for p in sweep), 95.0),
        ha="right",
        va="bottom",
        fontsize=8,
    )
    ax.set_xscale("symlog", linthresh=0.1)
    ax.set_xlabel("time per exchange off the line (base reply + master turnaround), ms")
    ax.set_ylabel("% of the theoretical maximum")
    ax.set_title("SET_V_AND_GET_DEADRECKON at 115200 8N1: link efficiency", fontsize=10)
    ax.legend(fontsize=8, loc="lower left", frameon=False)
    return _save(fig, img_dir / "bench-link-efficiency.png")


PLOTTERS = {
    "c_parser_cost": _plot_c_parser_cost,
    "python_throughput": _plot_python_throughput,
    "garbage_recovery": _plot_garbage_recovery,
    "base_exchange": _plot_base_exchange,
    "footprint": _plot_footprint,
    "end_to_end": _plot_end_to_end,
    "link_efficiency": _plot_link_efficiency,
}


def render_plots(results: list[dict[str, Any]], img_dir: Path) -> dict[str, Path]:
    """One PNG per benchmark that has figures; returns them by benchmark name."""
    plots: dict[str, Path] = {}
    for result in results:
        plotter = PLOTTERS.get(result["name"])
        if plotter is not None and result["status"] not in (PENDING, FAILED):
            plots[result["name"]] = plotter(result, img_dir)
    return plots


def _table(rows: list[list[str]]) -> str:
    lines = ["| " + " | ".join(TABLE_HEADER) + " |", "|" + "---|" * len(TABLE_HEADER)]
    lines += ["| " + " | ".join(cell.replace("|", "\\|") for cell in row) + " |" for row in rows]
    return "\n".join(lines)


def _provenance(result: dict[str, Any]) -> str:
    git = result["git"]
    commit = git["commit"][:12] + (" with uncommitted changes" if git["dirty"] else "")
    machine = result["machine"]
    return (
        f"Measured {result['when']} by `{result['command']}` on {machine['cpu']} ({machine['cores']} cores), "
        f"{machine['gcc']}, {machine['valgrind']}, Python {machine['python']}, "
        f"pymavlink {machine['pymavlink']}; commit {commit}. "
        f"Figures and exact commands: `bench/results/{result['name']}.json`."
    )


def render_block(result: dict[str, Any], plot: Path | None, doc_dir: Path) -> str:
    parts = [f"**{result['title']}.** Goal: {result['goal']}.", ""]
    if result["status"] == FAILED:
        parts.append(f"Last run failed: {result['details'].get('error', 'unknown error')}")
    else:
        parts.append(_table(result["table"]))
    for reason in result["pending"]:
        parts += ["", f"Pending: {reason}."]
    if plot is not None:
        rel = Path("img") / plot.name if plot.parent.name == "img" else plot
        parts += ["", f"![{result['title']}]({rel.as_posix()})"]
    parts += ["", _provenance(result)]
    return "\n".join(parts)


def render_summary(results: list[dict[str, Any]]) -> str:
    lines = ["| Benchmark | Goal | Status | Goal met |", "|---|---|---|---|"]
    for result in results:
        mets = [row[-1] for row in result["table"] if row]
        met = (
            "pending"
            if not mets or "pending" in mets
            else ("yes" if all(m == "yes" for m in mets) else "**no**")
        )
        lines.append(f"| {result['title']} | {result['goal']} | {result['status']} | {met} |")
    return "\n".join(lines)


def _marker(name: str, edge: str) -> str:
    return f"<!-- bench:{name}:{edge} -->"


def replace_block(text: str, name: str, body: str) -> str:
    begin, end = _marker(name, "begin"), _marker(name, "end")
    pattern = re.compile(re.escape(begin) + r".*?" + re.escape(end), re.DOTALL)
    if not pattern.search(text):
        raise BenchError(f"the page has no {begin} ... {end} block")
    return pattern.sub(lambda _: f"{begin}\n{body}\n{end}", text, count=1)


def update_performance_md(
    source: Path, target: Path, results: list[dict[str, Any]], plots: dict[str, Path]
) -> None:
    """Rewrite the generated blocks of `source` from the results and write it to `target`."""
    text = source.read_text()
    for result in results:
        text = replace_block(
            text, result["name"], render_block(result, plots.get(result["name"]), target.parent)
        )
    if results:
        text = replace_block(text, "summary", render_summary(results))
    target.write_text(text)
