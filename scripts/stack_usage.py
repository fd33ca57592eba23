#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Worst-case stack of a function, from gcc's -fstack-usage and the linked program's call graph
(called by scripts/size.sh).

    stack_usage.py OBJDUMP ELF ROOT SU_FILE...

Method: every function's own frame comes from the .su files gcc writes with -fstack-usage
(static, or bounded: the bound is used; a dynamic frame is an error, as unbounded). Functions
without a .su entry (libgcc, libc) get the frame their prologue sets up, read from the
disassembly (pushes, `sub sp,#N`, `addi sp,sp,-N`). On AVR a call also pushes its 2-byte return
address, which the .su figures leave out: 2 bytes are added per frame there.

The call graph is read from the disassembly of the linked ELF: an instruction that names another
function symbol (a call, or a tail branch) is an edge. The library calls nothing of its own
through a pointer (answers are written by one table-walking writer), so every indirect call goes
into the application (handlers, the write callback), whose own stack is not the library's and
comes on top. The result is the largest sum of frames
along any path from ROOT (recursion is an error: the library has none).

Prints one line: `<bytes> <path>` with the path's functions joined by " > ".
"""

from __future__ import annotations

import re
import subprocess
import sys
from functools import cache
from pathlib import Path

_FUNCTION = re.compile(r"^[0-9a-f]+ <([^>]+)>:$")
_REFERENCE = re.compile(r"<([A-Za-z_.$][\w.$]*)(?:[+-]0x[0-9a-f]+)?>")
# AVR's conditional branches (breq, brne, brcc, ...) stay inside a function: gcc never makes them
# tail calls, and libgcc's division loops branch between local labels that look like functions.
_BRANCH_AVR = re.compile(r"\tbr[a-z]{2}\s")
_INDIRECT = re.compile(r"\t(blx\s+r\d+|jalr\s|c\.jalr\s|icall|eicall)\b")
_PUSH_ARM = re.compile(r"\tpush\s+\{([^}]*)\}")
_SUB_SP_ARM = re.compile(r"\tsub\s+sp,\s*#(\d+)")
_ADDI_SP_RISCV = re.compile(r"\t(?:c\.)?addi(?:16sp)?\s+sp,\s*sp,\s*-(\d+)")
_PUSH_AVR = re.compile(r"\tpush\s+r\d+")


def read_frames(su_files: list[str]) -> dict[str, int | None]:
    """Frame bytes per function name (None: dynamic, unbounded)."""
    frames: dict[str, int | None] = {}
    for su in su_files:
        for line in Path(su).read_text().splitlines():
            location, size, kind = line.rsplit("\t", 2)
            name = location.rsplit(":", 1)[1]
            frames[name] = None if kind.strip() == "dynamic" else int(size)
    return frames


def prologue_frame(body: list[str]) -> int:
    """Stack a function without a .su entry sets up, from its first instructions."""
    total = 0
    for line in body[:12]:
        if m := _PUSH_ARM.search(line):
            total += 4 * len(m.group(1).split(","))
        elif (m := _SUB_SP_ARM.search(line)) or (m := _ADDI_SP_RISCV.search(line)):
            total += int(m.group(1))
        elif _PUSH_AVR.search(line):
            total += 1
    return total


def main() -> int:
    if len(sys.argv) < 5:
        print(__doc__, file=sys.stderr)
        return 2
    objdump, elf, root, su_files = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
    frames = read_frames(su_files)
    listing = subprocess.run([objdump, "-d", elf], check=True, capture_output=True, text=True).stdout
    bodies: dict[str, list[str]] = {}
    current: str | None = None
    for line in listing.splitlines():
        if m := _FUNCTION.match(line):
            current = m.group(1)
            bodies[current] = []
        elif current is not None and line.strip():
            bodies[current].append(line)
    calls: dict[str, set[str]] = {}
    app_callbacks: set[str] = set()
    for name, body in bodies.items():
        callees: set[str] = set()
        for line in body:
            if _BRANCH_AVR.search(line):
                continue
            for ref in _REFERENCE.findall(line):
                if ref != name and ref in bodies:
                    callees.add(ref)
            if _INDIRECT.search(line):
                app_callbacks.add(name)
        calls[name] = callees
    if root not in bodies:
        print(f"stack_usage.py: {root} is not in {elf}", file=sys.stderr)
        return 2

    return_address = 2 if "avr" in Path(objdump).name else 0

    def frame(name: str) -> int:
        known = name if name in frames else name.split(".")[0]
        if known in frames:
            size = frames[known]
            if size is None:
                raise SystemExit(f"stack_usage.py: {name} has a dynamic frame (unbounded)")
            return size
        return prologue_frame(bodies[name])

    @cache
    def worst(name: str, depth: int = 0) -> tuple[int, tuple[str, ...]]:
        if depth > 64:
            raise SystemExit(f"stack_usage.py: recursion through {name}")
        best: tuple[int, tuple[str, ...]] = (0, ())
        for callee in sorted(calls[name]):
            candidate = worst(callee, depth + 1)
            if candidate[0] > best[0]:
                best = candidate
        return frame(name) + return_address + best[0], (name, *best[1])

    total, path = worst(root)
    print(f"{total} {' > '.join(path)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
