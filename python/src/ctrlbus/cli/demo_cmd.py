# SPDX-License-Identifier: MIT
"""`ctrlbus demo`: a base, the Core emulator talking to it over a pty, and the dashboard
(ctrlbus.demo, what `make demo` runs)."""

from __future__ import annotations

import argparse
from typing import Any

from ctrlbus import demo

__all__ = ["register"]


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "demo",
        help="run a simulated base, the Core emulator and the browser dashboard together",
        description=demo.DESCRIPTION
        + " --base c and --base qemu need a checkout with the C builds (make demo builds them).",
    )
    demo.add_demo_arguments(parser)
    parser.set_defaults(func=demo.run)
