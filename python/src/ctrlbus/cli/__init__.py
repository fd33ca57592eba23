# SPDX-License-Identifier: MIT
"""The `ctrlbus` command: one entry point, one module per subcommand.

Each subcommand module defines `register(subparsers)`, which adds its parser and sets
`func=run` with `run(args) -> int`. Errors derived from CtrlbusError (and OSError) become one
line on stderr and exit code 2; nobody sees a traceback for bad input.
"""

from __future__ import annotations

import argparse
import importlib
import sys
from collections.abc import Sequence
from typing import NoReturn

from ctrlbus import __version__
from ctrlbus.errors import CtrlbusError

__all__ = [
    "SUBCOMMANDS",
    "OneLineErrorParser",
    "build_parser",
    "main",
]

# Subcommand modules, in the order `ctrlbus --help` lists them. A module that is missing
# (an optional layer not installed) is skipped rather than breaking the whole command.
SUBCOMMANDS: tuple[str, ...] = (
    "core",
    "ros2",
    "sim",
    "check",
    "decode",
    "spy",
    "capture",
    "replay",
    "record",
    "config",
    "demo",
    "completion",
)


class OneLineErrorParser(argparse.ArgumentParser):
    """argparse prints usage plus the error; we print one line naming the problem, exit 2."""

    def error(self, message: str) -> NoReturn:
        self.exit(2, f"{self.prog}: error: {message} (see --help)\n")


def build_parser() -> argparse.ArgumentParser:
    parser = OneLineErrorParser(
        prog="ctrlbus",
        description="SLAMWARE Control Bus tools: Core emulator, simulated base, conformance checker, "
        "decoders.",
    )
    parser.add_argument("--version", action="version", version=f"ctrlbus {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=OneLineErrorParser)
    for name in SUBCOMMANDS:
        try:
            module = importlib.import_module(f"ctrlbus.cli.{name}_cmd")
        except ModuleNotFoundError as exc:
            if exc.name == f"ctrlbus.cli.{name}_cmd":
                continue
            raise
        module.register(subparsers)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "func", None) is None:
        parser.print_help()
        return 2
    try:
        result: int = args.func(args)
    except KeyboardInterrupt:
        return 130
    except (CtrlbusError, OSError) as exc:
        print(f"ctrlbus {args.command}: error: {exc}", file=sys.stderr)
        return 2
    return result


if __name__ == "__main__":
    sys.exit(main())
