# SPDX-License-Identifier: MIT
"""Footprint of the C library on Cortex-M: what `make size` (scripts/size.sh) prints, tabled
against the goals, and where the base stack's bytes go.

Two sources, checked against each other:

- `scripts/size.sh` itself: per CPU, .text/.data/.bss of each layer linked with --gc-sections from
  the functions its header declares, and the sizes of the state structs. These are the figures.
- the same compile and link steps for the base stack (scripts/size.sh's flags), with a linker map:
  it says which object file (base.c, frame.c, messages.c, diffdrive.c, libgcc) each kept section
  comes from, and which functions are the largest. Its totals must equal scripts/size.sh's, or the
  benchmark fails.
"""

from __future__ import annotations

import json
import os
import re
import shutil
from collections import defaultdict
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from common import (
    C_INCLUDE,
    C_SRC,
    FULL,
    MEASURED,
    PENDING,
    REPO,
    SMOKE,
    BenchContext,
    BenchError,
    run_command,
)
from findings import Findings

NAME = "footprint"
TITLE = "Footprint from make size (cortex-m0plus/m3/m4)"
GOAL = (
    "base stack on cortex-m0plus -Os ≤ 4,096 B .text (default configuration) and ≤ 2,560 B "
    "(minimal), never above the reference's framer + dispatcher; ctrlbus_base_poll() stack ≤ 256 B; "
    "≤ 64 B instance state; no transmit buffer"
)

SIZE_SCRIPT = REPO / "scripts" / "size.sh"
# The reference's framer + dispatcher (scripts/reference_footprint.sh), measured only where a
# checkout of the vendor's public sources is given; otherwise the last recorded figures are kept.
REFERENCE_SCRIPT = REPO / "scripts" / "reference_footprint.sh"
REFERENCE_CHECKOUT_ENV = "CTRLBUS_REFERENCE_CHECKOUT"
REFERENCE_INCLUDE_ENV = "CTRLBUS_REFERENCE_DEVICE_INCLUDE"
_SWITCH_ROW = re.compile(r"^\s+switch (CTRLBUS_CONFIG_\w+)=0\s+(\d+) B \.text, saves\s+(-?\d+) B")
_REFERENCE_ROW = re.compile(r"^(\S+)\s+(-O\w)\s+(\S+)\s+(\d+)\s+(\d+)\s+(\d+)\s*$")
CROSS = "arm-none-eabi-"
CPUS = {FULL: ["cortex-m0plus", "cortex-m3", "cortex-m4"], SMOKE: ["cortex-m0plus"]}
GOAL_CPU = "cortex-m0plus"
TEXT_GOAL = 4096
MINIMAL_TEXT_GOAL = 2560
STACK_GOAL = 256
# scripts/size.sh's per-target table (TARGETS): base stack per target, configuration and -O level.
TARGETS = {
    FULL: ["cortex-m0plus", "cortex-m3", "cortex-m4", "atmega328p", "rv32imac"],
    SMOKE: ["cortex-m0plus"],
}
_TARGET_ROW = re.compile(r"^(\S+)\s+(default|minimal)\s+(-O\w)\s+(\d+)\s+(\d+)\s+(\d+)\s+(\d+)\s*$")
STATE_GOAL = 64
# scripts/size.sh's compile flags, and the layer whose bytes are broken down.
CFLAGS = ["-std=c99", "-Os", "-ffunction-sections", "-fdata-sections", "-Wall", "-Wextra", "-Werror"]
BASE_LAYER = "base stack (base.h)"
BASE_HEADER = C_INCLUDE / "ctrlbus" / "base.h"
LAYERS = ["frame layer (frame.h)", "messages (messages.h)", BASE_LAYER]
STRUCTS = ["ctrlbus_base_t", "ctrlbus_decoder_t", "ctrlbus_sink_t"]
PADDING = "alignment padding"


@dataclass(frozen=True)
class Sections:
    text: int
    data: int
    bss: int


@dataclass
class SizeReport:
    """What scripts/size.sh printed."""

    layers: dict[str, dict[str, Sections]]  # cpu -> layer label -> sections (implemented layers only)
    objects: dict[str, dict[str, Sections]]  # cpu -> "base.c" -> sections, unlinked
    structs: dict[str, int]  # struct name -> bytes on a 32-bit target


_ROW = re.compile(r"^(\S+)?\s+(.+?)\s+(\d+)\s+(\d+)\s+(\d+)(?:\s.*)?$")
_CPU_HEADER = re.compile(r"^(cortex-\S+)\s+what\s")
_STRUCT = re.compile(r"^\s+(ctrlbus_\w+)\s+(\d+)\b")
_OBJECT = re.compile(r"object (\S+) \(unlinked\)")


def parse_size_report(text: str) -> SizeReport:
    report = SizeReport({}, {}, {})
    cpu: str | None = None
    for line in text.splitlines():
        header = _CPU_HEADER.match(line)
        if header:
            cpu = header.group(1)
            report.layers[cpu], report.objects[cpu] = {}, {}
            continue
        struct = _STRUCT.match(line)
        if struct and not line.lstrip().startswith("object"):
            report.structs[struct.group(1)] = int(struct.group(2))
            continue
        row = _ROW.match(line)
        if cpu is None or row is None:
            continue
        label = row.group(2).strip()
        sections = Sections(int(row.group(3)), int(row.group(4)), int(row.group(5)))
        obj = _OBJECT.search(label)
        if obj:
            report.objects[cpu][obj.group(1)] = sections
        elif label in LAYERS:
            report.layers[cpu][label] = sections
    return report


# ---------------------------------------------------------------------------------------------
# The base stack linked again, with a map


# (not static inline functions: the header defines those itself)
_DECLARED = re.compile(r"^(?!static )[a-z_][a-z0-9_ *]*[ *](ctrlbus_[a-z0-9_]+)\(", re.MULTILINE)


def declared_functions(header: Path) -> set[str]:
    """The functions a public header declares (scripts/size.sh's rule)."""
    return set(_DECLARED.findall(header.read_text()))


_OUTPUT_SECTION = re.compile(r"^(\.[\w.]+)(?:\s+0x[0-9a-f]+\s+0x[0-9a-f]+)?\s*$")
_INPUT_NAME_ONLY = re.compile(r"^ (\.\S+|COMMON)\s*$")
_INPUT = re.compile(r"^ (?:(\S+)\s+)?\s*0x([0-9a-f]+)\s+0x([0-9a-f]+)(?:\s+(\S.*?))?\s*$")
_TEXT_SECTIONS = (".text", ".rodata", ".ARM.exidx", ".ARM.extab", ".init", ".fini")
_DATA_SECTIONS = (".data",)
_BSS_SECTIONS = (".bss", ".persistent", ".noinit")


@dataclass
class MapBreakdown:
    by_object: dict[str, dict[str, int]]  # object -> {"text", "data", "bss"} bytes
    functions: list[tuple[str, str, int]]  # (function, object, .text bytes), largest first


def _owner(path: str | None) -> str:
    if path is None:
        return PADDING
    name = Path(path.split("(", 1)[0]).name
    if name.startswith("libgcc"):
        return "libgcc"
    return name[:-2] + ".c" if name.endswith(".o") else name


def parse_map(text: str) -> MapBreakdown:
    """Bytes per object file and per function in the output sections size(1) counts."""
    start = text.find("Linker script and memory map")
    if start < 0:
        raise BenchError("the linker map has no memory map")
    by_object: dict[str, dict[str, int]] = defaultdict(lambda: {"text": 0, "data": 0, "bss": 0})
    functions: list[tuple[str, str, int]] = []
    kind: str | None = None
    pending_name: str | None = None
    for line in text[start:].splitlines():
        output = _OUTPUT_SECTION.match(line)
        if output:
            name = output.group(1)
            kind = (
                "text"
                if name.startswith(_TEXT_SECTIONS)
                else "data"
                if name in _DATA_SECTIONS
                else "bss"
                if name in _BSS_SECTIONS
                else None
            )
            pending_name = None
            continue
        name_only = _INPUT_NAME_ONLY.match(line)
        if name_only:
            pending_name = name_only.group(1)
            continue
        entry = _INPUT.match(line)
        if entry is None or kind is None:
            continue
        section = entry.group(1) or pending_name
        pending_name = None
        size = int(entry.group(3), 16)
        if size == 0:
            continue
        owner = _owner(None if section == "*fill*" else entry.group(4))
        by_object[owner][kind] += size
        if kind == "text" and section is not None and section.startswith(".text.") and owner != PADDING:
            functions.append((section.removeprefix(".text."), owner, size))
    functions.sort(key=lambda item: -item[2])
    return MapBreakdown(dict(by_object), functions)


def link_base_stack(ctx: BenchContext, cpu: str) -> tuple[Sections, MapBreakdown]:
    """Compile c/src/*.c for `cpu` and link the base stack as scripts/size.sh does, with a map."""
    out_dir = ctx.work_dir / cpu
    out_dir.mkdir(parents=True, exist_ok=True)
    objects: list[Path] = []
    for source in sorted(C_SRC.glob("*.c")):
        obj = out_dir / f"{source.stem}.o"
        run_command(
            ctx,
            [
                f"{CROSS}gcc",
                f"-mcpu={cpu}",
                "-mthumb",
                *CFLAGS,
                f"-I{C_INCLUDE}",
                "-c",
                str(source),
                "-o",
                str(obj),
            ],
        )
        objects.append(obj)
    symbols = run_command(ctx, [f"{CROSS}nm", "--defined-only", *map(str, objects)])
    defined = {
        parts[2] for line in symbols.splitlines() if len(parts := line.split()) == 3 and parts[1] == "T"
    }
    roots = sorted(declared_functions(BASE_HEADER) & defined)
    if not roots:
        raise BenchError("nothing that ctrlbus/base.h declares is implemented")
    elf, map_file = out_dir / "base.elf", out_dir / "base.map"
    argv = [
        f"{CROSS}gcc",
        f"-mcpu={cpu}",
        "-mthumb",
        "-nostdlib",
        "-Wl,--gc-sections",
        f"-Wl,--entry={roots[0]}",
    ]
    argv += ["-Wl,--unresolved-symbols=ignore-all", *(f"-Wl,--undefined={fn}" for fn in roots)]
    argv += [f"-Wl,-Map={map_file}", "-o", str(elf), *map(str, objects), "-lgcc"]
    run_command(ctx, argv)
    berkeley = run_command(ctx, [f"{CROSS}size", "-B", str(elf)]).splitlines()[1].split()
    totals = Sections(int(berkeley[0]), int(berkeley[1]), int(berkeley[2]))
    return totals, parse_map(map_file.read_text())


# ---------------------------------------------------------------------------------------------
# The benchmark


def _sections_text(s: Sections) -> str:
    return f"{s.text:,} B .text, {s.data} B .data, {s.bss} B .bss"


def reference_figures(ctx: BenchContext) -> dict[str, Any] | None:
    """The reference's framer + dispatcher on cortex-m0plus -Os and -O2: measured when a checkout
    is given (CTRLBUS_REFERENCE_CHECKOUT, optionally CTRLBUS_REFERENCE_DEVICE_INCLUDE), else the
    figures of the last run that measured them (bench/results/footprint.json), else None."""
    checkout = os.environ.get(REFERENCE_CHECKOUT_ENV)
    if checkout:
        argv = [str(REFERENCE_SCRIPT), checkout]
        if os.environ.get(REFERENCE_INCLUDE_ENV):
            argv.append(os.environ[REFERENCE_INCLUDE_ENV])
        output = run_command(ctx, ["env", "CPUS=cortex-m0plus", "OPTS=-Os -O2", *argv])
        files: dict[str, dict[str, int]] = defaultdict(dict)
        for line in output.splitlines():
            if m := _REFERENCE_ROW.match(line):
                files[m.group(2)][m.group(3)] = int(m.group(4))
        if "total" not in files.get("-Os", {}):
            raise BenchError(f"scripts/reference_footprint.sh printed no total:\n{output}")
        return {"measured_in_this_run": True, "text": dict(files), "compiler": output.splitlines()[0]}
    previous = REPO / "bench" / "results" / f"{NAME}.json"
    if previous.is_file():
        recorded = json.loads(previous.read_text()).get("details", {}).get("reference")
        if recorded:
            return {**recorded, "measured_in_this_run": False}
    return None


def run(ctx: BenchContext) -> Findings:
    if shutil.which(f"{CROSS}gcc") is None:
        return Findings(
            PENDING, pending=[f"{CROSS}gcc not found (scripts/setup.sh installs gcc-arm-none-eabi)"]
        )
    if not BASE_HEADER.is_file():
        return Findings(PENDING, pending=["the C base stack (c/include/ctrlbus/base.h) is not written yet"])
    cpus = CPUS[ctx.mode]
    targets = TARGETS[ctx.mode]
    output = run_command(
        ctx, ["env", f"CPUS={' '.join(cpus)}", f"TARGETS={' '.join(targets)}", str(SIZE_SCRIPT)]
    )
    report = parse_size_report(output)
    # target -> (config, opt) -> (.text, .data, .bss, worst stack of ctrlbus_base_poll)
    per_target: dict[str, dict[tuple[str, str], tuple[int, int, int, int]]] = defaultdict(dict)
    for line in output.splitlines():
        if m := _TARGET_ROW.match(line):
            per_target[m.group(1)][(m.group(2), m.group(3))] = (
                int(m.group(4)),
                int(m.group(5)),
                int(m.group(6)),
                int(m.group(7)),
            )
    if any(len(per_target.get(target, {})) != 4 for target in targets):
        raise BenchError(f"scripts/size.sh printed no per-target table for {targets}:\n{output}")
    missing = [cpu for cpu in cpus if BASE_LAYER not in report.layers.get(cpu, {})]
    if missing or "ctrlbus_base_t" not in report.structs:
        raise BenchError(
            f"scripts/size.sh printed no base stack figures for {missing or 'the struct'}:\n{output}"
        )

    figures: dict[str, Any] = {}
    rows: list[list[str]] = []
    breakdowns: dict[str, MapBreakdown] = {}
    for cpu in cpus:
        stack = report.layers[cpu][BASE_LAYER]
        totals, breakdown = link_base_stack(ctx, cpu)
        if totals != stack:
            raise BenchError(
                f"{cpu}: the base stack linked with a map is {totals}, scripts/size.sh says {stack}"
            )
        sums = {k: sum(o[k] for o in breakdown.by_object.values()) for k in ("text", "data", "bss")}
        if (sums["text"], sums["data"], sums["bss"]) != (stack.text, stack.data, stack.bss):
            raise BenchError(f"{cpu}: the linker map accounts for {sums}, size(1) for {stack}")
        breakdowns[cpu] = breakdown
        key = cpu.replace("-", "_")
        for label, sections in report.layers[cpu].items():
            layer = label.split(" (")[0].replace(" ", "_")
            figures[f"{key}_{layer}_text"] = sections.text
            figures[f"{key}_{layer}_data"] = sections.data
            figures[f"{key}_{layer}_bss"] = sections.bss
        for owner, sizes in breakdown.by_object.items():
            figures[f"{key}_base_stack_text_{owner.replace('.', '_').replace(' ', '_')}"] = sizes["text"]
        variables = sum(
            sizes["data"] + sizes["bss"] for owner, sizes in breakdown.by_object.items() if owner != PADDING
        )
        figures[f"{key}_base_stack_static_variables"] = variables
        padding = breakdown.by_object.get(PADDING, {}).get("bss", 0)
        note = (
            f" (the {padding} B .bss are the linker script's alignment padding, no variable)"
            if padding and not variables
            else ""
        )
        goal_row = cpu == GOAL_CPU
        rows.append(
            [
                f"{cpu}: base stack (everything base.h declares), linked",
                f"≤ {TEXT_GOAL:,} B .text" if goal_row else "published",
                _sections_text(stack) + note,
                "",
                f"{stack.text / TEXT_GOAL:.2f} × the goal" if goal_row else "",
                ("yes" if stack.text <= TEXT_GOAL else "**no**") if goal_row else "yes",
            ]
        )

    goal_breakdown = breakdowns[GOAL_CPU]
    text_total = report.layers[GOAL_CPU][BASE_LAYER].text
    parts = sorted(goal_breakdown.by_object.items(), key=lambda item: -item[1]["text"])
    rows.append(
        [
            f"{GOAL_CPU}: where the base stack's .text comes from",
            "published",
            "; ".join(
                f"{owner} {sizes['text']:,} B ({100 * sizes['text'] / text_total:.0f} %)"
                for owner, sizes in parts
                if sizes["text"]
            ),
            "",
            "",
            "yes",
        ]
    )
    rows.append(
        [
            f"{GOAL_CPU}: its largest functions",
            "published",
            "; ".join(f"{fn} ({owner}) {size:,} B" for fn, owner, size in goal_breakdown.functions[:6]),
            "",
            "",
            "yes",
        ]
    )
    for label in LAYERS[:-1]:
        if all(label in report.layers[cpu] for cpu in cpus):
            rows.append(
                [
                    f"{label} alone, linked ({' / '.join(cpus)})",
                    "published",
                    " / ".join(f"{report.layers[cpu][label].text:,}" for cpu in cpus) + " B .text",
                    "",
                    "",
                    "yes",
                ]
            )
    for target in targets:
        for (config, opt), target_sizes in sorted(per_target[target].items()):
            key = f"{target.replace('-', '_')}_{config}_{opt.lstrip('-')}"
            for name, value in zip(("text", "data", "bss", "stack"), target_sizes, strict=True):
                figures[f"{key}_{name}"] = value
        cells = "; ".join(
            f"{config} {opt}: {sizes[0]:,} B .text, {sizes[1]} B .data, stack {sizes[3]} B"
            for (config, opt), sizes in sorted(per_target[target].items())
        )
        rows.append([f"{target}: base stack per configuration", "published", cells, "", "", "yes"])
    minimal_text = per_target[GOAL_CPU][("minimal", "-Os")][0]
    rows.append(
        [
            f"{GOAL_CPU} -Os: minimal configuration (every ctrlbus_config.h switch off)",
            f"≤ {MINIMAL_TEXT_GOAL:,} B .text",
            f"{minimal_text:,} B .text",
            "",
            f"{minimal_text / MINIMAL_TEXT_GOAL:.2f} × the goal",
            "yes" if minimal_text <= MINIMAL_TEXT_GOAL else "**no**",
        ]
    )
    reference = reference_figures(ctx) if ctx.mode == FULL else None
    if reference is not None:
        ref_os = reference["text"]["-Os"]["total"]
        figures["reference_framer_dispatcher_text_Os"] = ref_os
        figures["reference_framer_dispatcher_text_O2"] = reference["text"].get("-O2", {}).get("total")
        ref_files = ", ".join(f"{f} {n:,}" for f, n in reference["text"]["-Os"].items() if f != "total")
        when = "" if reference["measured_in_this_run"] else " (recorded by an earlier run)"
        rows.append(
            [
                f"{GOAL_CPU} -Os: the reference's framer + dispatcher, same compiler and flags "
                "(scripts/reference_footprint.sh)",
                "published",
                f"{ref_os:,} B .text: {ref_files}{when}",
                "",
                "",
                "yes",
            ]
        )
        rows.append(
            [
                f"{GOAL_CPU} -Os: minimal configuration against the reference",
                "never above it",
                f"{minimal_text:,} B against {ref_os:,} B",
                "",
                f"{minimal_text / ref_os:.2f} ×",
                "yes" if minimal_text <= ref_os else "**no**",
            ]
        )
    switches = {
        m.group(1): (int(m.group(2)), int(m.group(3)))
        for m in map(_SWITCH_ROW.match, output.splitlines())
        if m
    }
    for switch, (text, saves) in switches.items():
        figures[f"{GOAL_CPU.replace('-', '_')}_without_{switch}_text"] = text
        figures[f"{GOAL_CPU.replace('-', '_')}_{switch}_saves"] = saves
    if switches:
        rows.append(
            [
                f"{GOAL_CPU} -Os: what each ctrlbus_config.h switch saves, turned off alone",
                "published",
                "; ".join(f"{switch} {saves:,} B" for switch, (_, saves) in switches.items()),
                "",
                "",
                "yes",
            ]
        )
    poll_stack = per_target[GOAL_CPU][("default", "-Os")][3]
    rows.append(
        [
            f"{GOAL_CPU} -Os: worst stack of ctrlbus_base_poll() (default configuration, "
            "-fstack-usage along the call graph, callbacks not included)",
            f"≤ {STACK_GOAL} B",
            f"{poll_stack} B",
            "",
            f"{poll_stack / STACK_GOAL:.2f} × the goal",
            "yes" if poll_stack <= STACK_GOAL else "**no**",
        ]
    )
    for struct in STRUCTS:
        if struct in report.structs:
            figures[f"sizeof_{struct}"] = report.structs[struct]
    state = report.structs["ctrlbus_base_t"]
    rows.append(
        [
            "ctrlbus_base_t, the base stack's instance state (32-bit target)",
            f"≤ {STATE_GOAL} B",
            f"{state} B, besides the caller's receive ring and frame buffer",
            "",
            f"{state / STATE_GOAL:.2f} × the goal",
            "yes" if state <= STATE_GOAL else "**no**",
        ]
    )
    decoder, sink = report.structs.get("ctrlbus_decoder_t"), report.structs.get("ctrlbus_sink_t")
    if decoder is not None and sink is not None:
        rows.append(
            [
                "frame layer state: ctrlbus_decoder_t (inside ctrlbus_base_t) / ctrlbus_sink_t (on the "
                "stack while an answer is written)",
                "published",
                f"{decoder} B / {sink} B",
                "",
                "",
                "yes",
            ]
        )
    variables = figures[f"{GOAL_CPU.replace('-', '_')}_base_stack_static_variables"]
    rows.append(
        [
            "static RAM of the base stack (.data and .bss variables); transmit buffer",
            "none",
            f"{variables} B; no transmit buffer (answers stream through write(): see the base exchange)",
            "",
            "",
            "yes" if variables == 0 else "**no**",
        ]
    )
    details: dict[str, Any] = {
        "size_report": output,
        "reference": (
            None if reference is None else {k: v for k, v in reference.items() if k != "measured_in_this_run"}
        ),
        "cflags": CFLAGS,
        "base_stack_by_object": {cpu: b.by_object for cpu, b in breakdowns.items()},
        "base_stack_largest_functions": {cpu: b.functions[:20] for cpu, b in breakdowns.items()},
        "unlinked_objects": {
            cpu: {o: vars(s) for o, s in objs.items()} for cpu, objs in report.objects.items()
        },
    }
    return Findings(MEASURED, figures, rows, [], details)
