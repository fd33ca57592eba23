# SPDX-License-Identifier: MIT
"""Generate the MAVLink peer from bench/mavlink/ctrlbus_peer.xml with pymavlink's mavgen.

Nothing generated is committed: the C headers and the Python dialect module are written under
build/bench/mavlink/ on every run (it takes a fraction of a second). Run as a script to generate
them by hand: `.venv/bin/python bench/mavlink/generate.py`.
"""

from __future__ import annotations

import importlib.util
import sys
from pathlib import Path
from types import ModuleType

if __package__ in (None, ""):
    sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from common import BUILD_DIR, BenchContext, run_command

DIALECT_XML = Path(__file__).resolve().parent / "ctrlbus_peer.xml"
DIALECT = DIALECT_XML.stem
OUT_DIR = BUILD_DIR / "mavlink"


def generate_c(ctx: BenchContext | None) -> Path:
    """Generate the C headers; returns the include directory (holding `ctrlbus_peer/mavlink.h`)."""
    out = OUT_DIR / "c"
    out.mkdir(parents=True, exist_ok=True)
    run_command(
        ctx,
        [
            sys.executable,
            "-m",
            "pymavlink.tools.mavgen",
            "--lang=C",
            "--wire-protocol=2.0",
            f"--output={out}",
            str(DIALECT_XML),
        ],
    )
    if not (out / DIALECT / "mavlink.h").is_file():
        raise FileNotFoundError(f"mavgen wrote no {out / DIALECT / 'mavlink.h'}")
    return out


def generate_python(ctx: BenchContext | None) -> ModuleType:
    """Generate the Python dialect module and import it (pymavlink's parser and encoder for our dialect)."""
    out = OUT_DIR / "py"
    out.mkdir(parents=True, exist_ok=True)
    target = out / f"{DIALECT}.py"
    run_command(
        ctx,
        [
            sys.executable,
            "-m",
            "pymavlink.tools.mavgen",
            "--lang=Python3",
            "--wire-protocol=2.0",
            f"--output={target}",
            str(DIALECT_XML),
        ],
    )
    name = f"bench_mavlink_{DIALECT}"
    spec = importlib.util.spec_from_file_location(name, target)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot import {target}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


if __name__ == "__main__":
    print(generate_c(None))
    print(generate_python(None).__file__)
