"""Argument helpers shared by the subcommands, so every command spells its options the same way."""

from __future__ import annotations

import argparse

from ctrlbus.link import DEFAULT_BAUD, parse_host_port

__all__ = ["DEFAULT_BAUD", "add_baud_argument", "add_port_argument", "add_serve_arguments", "parse_host_port"]


def add_port_argument(
    parser: argparse.ArgumentParser,
    *,
    name: str = "--port",
    required: bool = True,
    help_text: str = "pyserial URL of the port: /dev/ttyUSB0, socket://127.0.0.1:5555, loop://",
) -> None:
    parser.add_argument(name, required=required, metavar="URL", help=help_text)


def add_baud_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--baud",
        type=int,
        default=DEFAULT_BAUD,
        metavar="N",
        help=f"baud rate for real serial ports (default {DEFAULT_BAUD})",
    )


def add_serve_arguments(parser: argparse.ArgumentParser) -> None:
    """How a base offers its end of the link: a new pty, or TCP where each connection is a link."""
    group = parser.add_mutually_exclusive_group(required=True)
    group.add_argument("--pty", action="store_true", help="create a pseudo-terminal and print its path")
    group.add_argument(
        "--listen",
        metavar="HOST:PORT",
        help="accept TCP connections; each one is a serial link (a new one replaces the old)",
    )
    group.add_argument("--port", metavar="URL", help="serve on an existing port (pyserial URL)")
    add_baud_argument(parser)
