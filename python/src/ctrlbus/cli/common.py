# SPDX-License-Identifier: MIT
"""Argument helpers shared by the subcommands, so every command spells its options the same way."""

from __future__ import annotations

import argparse
import contextlib
import math
import os
import re
import signal
import sys
import threading
from collections.abc import Iterator
from pathlib import Path
from types import FrameType
from typing import TextIO

from ctrlbus.errors import UsageError
from ctrlbus.link import DEFAULT_BAUD, Link, PtyLink, TcpServerLink, parse_host_port
from ctrlbus.ports import open_link

__all__ = [
    "BOM",
    "DEFAULT_BAUD",
    "add_baud_argument",
    "add_color_argument",
    "add_dashboard_arguments",
    "add_decoder_arguments",
    "add_direction_argument",
    "add_port_argument",
    "add_serve_arguments",
    "decoder_settings",
    "endpoint_address",
    "format_hex",
    "hex_or_binary",
    "hex_token_bytes",
    "hex_token_problem",
    "open_endpoint",
    "parse_hex_text",
    "parse_host_port",
    "positive_number",
    "read_input_bytes",
    "stop_on_signals",
    "use_color",
    "write_output",
]


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


def add_dashboard_arguments(parser: argparse.ArgumentParser) -> None:
    """Where the browser dashboard listens and its access token (read by ctrlbus.web.options)."""
    # Imported here: ctrlbus.web.options is plain Python, but the CLI should not pull the web
    # package in for commands that never show a dashboard.
    from ctrlbus.web.options import (
        DEFAULT_HTTP_HOST,
        DEFAULT_HTTP_PORT,
        DEFAULT_PUSH_HZ,
        GENERATE_TOKEN,
        MIN_REMOTE_TOKEN_CHARS,
        TOKEN_ENV,
    )

    parser.add_argument(
        "--http",
        "--listen",
        dest="http",
        default=f"{DEFAULT_HTTP_HOST}:{DEFAULT_HTTP_PORT}",
        metavar="HOST[:PORT]",
        help=f"dashboard address (default {DEFAULT_HTTP_HOST}:{DEFAULT_HTTP_PORT}); "
        "an address other than loopback needs --token",
    )
    parser.add_argument(
        "--token",
        default=None,
        metavar="TOKEN",
        help=f"secret every dashboard request must carry (?token=... or an X-Ctrlbus-Token header); "
        f"'{GENERATE_TOKEN}' makes a random one (printed in the dashboard address); an address other "
        f"than loopback needs at least {MIN_REMOTE_TOKEN_CHARS} characters; default: ${TOKEN_ENV} "
        "(never printed)",
    )
    parser.add_argument(
        "--push-hz",
        type=float,
        default=DEFAULT_PUSH_HZ,
        metavar="HZ",
        help=f"dashboard update rate (default {DEFAULT_PUSH_HZ:g})",
    )


# --- input and output of bytes ------------------------------------------------------------------

# Hex text as people paste it: pairs or runs of hex digits, optionally 0x-prefixed, separated by
# spaces, newlines, commas or colons; '#' starts a comment that runs to the end of the line.
_HEX_TOKEN = re.compile(r"(?:0[xX])?([0-9A-Fa-f]+)")
_NOT_SEPARATOR = re.compile(r"[^\s,:]+")  # \s: any Unicode space, a no-break space included
BOM = "\ufeff"  # a byte order mark, as editors put at the start of UTF-8 text


def read_input_bytes(path: str) -> bytes:
    """The bytes of a file, or of stdin when `path` is '-' (OSError if unreadable)."""
    if path == "-":
        return sys.stdin.buffer.read()
    return Path(path).read_bytes()


def hex_token_bytes(token: str) -> bytes | None:
    """The bytes one hex token spells ("10", "0x1", "F830DA"), each token on its own: one digit
    is one byte, an even number of digits that many halves; None for anything else (an odd number
    of digits past one included: digits never pair across tokens, so "0x10 0x1 0x0" cannot
    silently become 10 10)."""
    match = _HEX_TOKEN.fullmatch(token)
    if match is None:
        return None
    digits = match.group(1)
    if len(digits) == 1:
        return bytes([int(digits, 16)])
    if len(digits) % 2:
        return None
    return bytes.fromhex(digits)


def hex_token_problem(token: str) -> str:
    """Why `token` is not a hex token (for an error message)."""
    if _HEX_TOKEN.fullmatch(token):
        return f"not hex text: {token!r} has an odd number of digits (a byte is one or two)"
    return f"not hex text: {token!r}"


def parse_hex_text(text: str) -> bytes:
    """Bytes from hex text ("10 02 F8 30 DA", "0x10,0x02", "1002f830da", "0x1 0x0"); a leading
    byte order mark is ignored; UsageError naming the line and column of anything else."""
    out = bytearray()
    for line_number, line in enumerate(text.removeprefix(BOM).splitlines(), start=1):
        for token in _NOT_SEPARATOR.finditer(line.split("#", 1)[0]):
            spelled = hex_token_bytes(token.group())
            if spelled is None:
                where = f"line {line_number} column {token.start() + 1}"
                raise UsageError(f"{hex_token_problem(token.group())} at {where}")
            out += spelled
    return bytes(out)


def hex_or_binary(data: bytes) -> bytes:
    """`data` itself, unless it is hex text (ASCII of hex digits, separators and comments only),
    in which case the bytes it spells."""
    try:
        text = data.decode("ascii")
    except UnicodeDecodeError:
        return data
    try:
        return parse_hex_text(text)
    except UsageError:
        return data


def format_hex(data: bytes, per_line: int = 16) -> str:
    """Uppercase hex pairs separated by spaces (the vectors' style), `per_line` bytes a line."""
    lines = [data[i : i + per_line].hex(" ").upper() for i in range(0, len(data), per_line)]
    return "\n".join(lines) + "\n" if lines else ""


def write_output(path: str | None, data: bytes | str) -> None:
    """Write text or bytes to a file, or to stdout when `path` is None or '-'."""
    if path is None or path == "-":
        if isinstance(data, bytes):
            sys.stdout.buffer.write(data)
            sys.stdout.buffer.flush()
        else:
            sys.stdout.write(data)
            sys.stdout.flush()
    elif isinstance(data, bytes):
        Path(path).write_bytes(data)
    else:
        Path(path).write_text(data, encoding="utf-8")


# --- stopping a long-running command ---------------------------------------------------------------

STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM, signal.SIGHUP)


@contextlib.contextmanager
def stop_on_signals(stop: threading.Event) -> Iterator[None]:
    """Inside, Ctrl-C, SIGTERM and SIGHUP set `stop` instead of interrupting, so a command's loop
    ends cleanly. Outside the main thread (where signal handlers cannot be set) it does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def on_signal(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in STOP_SIGNALS}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)


# --- endpoints, directions, decoder settings, colour ------------------------------------------

ENDPOINT_HELP = (
    "a pyserial URL (/dev/ttyUSB0, socket://HOST:PORT), 'pty' (create a pseudo-terminal and print "
    "its path) or 'listen:HOST:PORT' (accept one TCP connection at a time; port 0 picks a free one)"
)


def open_endpoint(spec: str, baud: int = DEFAULT_BAUD) -> Link:
    """Open one end of a link the way the tools that sit on a link (spy, capture, replay) take it:
    'pty', 'listen:HOST:PORT' or a pyserial URL. PortOpenError / PortURLError naming it otherwise."""
    return open_link(spec, baud, serving=True)


def endpoint_address(link: Link) -> str:
    """What to tell a person about an opened endpoint: 'pty: /dev/pts/N', 'listen: HOST:PORT' or
    'port: URL' (the form `ctrlbus sim` prints)."""
    if isinstance(link, PtyLink):
        return f"pty: {link.path}"
    if isinstance(link, TcpServerLink):
        host = f"[{link.host}]" if ":" in str(link.host) else str(link.host)
        return f"listen: {host}:{link.port}"
    return f"port: {link.name}"


def add_direction_argument(parser: argparse.ArgumentParser, *, default: str | None, help_text: str) -> None:
    """--direction core|base: who sent the bytes (core = core→base, base = base→core)."""
    parser.add_argument("--direction", choices=("core", "base"), default=default, help=help_text)


def positive_number(option: str, text: str, *, allow_zero: bool = False) -> float:
    """A finite number > 0 (or >= 0 with allow_zero); UsageError naming the option otherwise."""
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{option} wants a number, got {text!r}") from None
    if not math.isfinite(value) or value < 0 or (value == 0 and not allow_zero):
        bound = ">= 0" if allow_zero else "> 0"
        raise UsageError(f"{option} wants a finite number {bound}, got {text!r}")
    return value


def add_decoder_arguments(parser: argparse.ArgumentParser, *, timeout_ms: int) -> None:
    """The stream decoder's settings (docs/protocol.md §7.1) for the tools that decode."""
    parser.add_argument(
        "--timeout-ms",
        default=str(timeout_ms),
        metavar="N",
        help=f"inter-byte timeout of the stream decoder, applied with the chunks' times (default "
        f"{timeout_ms}; 0 switches it off)",
    )
    parser.add_argument(
        "--max-frame",
        default="65539",
        metavar="N",
        help="largest whole frame accepted, 5..65539 (default 65539; a base uses its buffer size, 512)",
    )


def decoder_settings(args: argparse.Namespace) -> tuple[float, int]:
    """(timeout in seconds, max_frame) from add_decoder_arguments' options, checked."""
    timeout_ms = positive_number("--timeout-ms", args.timeout_ms, allow_zero=True)
    try:
        max_frame = int(args.max_frame, 0)
    except ValueError:
        raise UsageError(f"--max-frame wants an integer, got {args.max_frame!r}") from None
    if not 5 <= max_frame <= 65539:
        raise UsageError(f"--max-frame must be 5..65539, got {max_frame}")
    return timeout_ms / 1000.0, max_frame


def add_color_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--color",
        choices=("auto", "always", "never"),
        default="auto",
        help="colour the output: auto (when stdout is a terminal and $NO_COLOR is unset or empty, "
        "default), always, never",
    )


def use_color(choice: str, stream: TextIO | None = None) -> bool:
    """Whether to colour: 'always', 'never', or 'auto' = the stream is a terminal and NO_COLOR
    (no-color.org) is not set to a non-empty value."""
    if choice == "always":
        return True
    if choice == "never" or os.environ.get("NO_COLOR"):
        return False
    stream = stream if stream is not None else sys.stdout
    isatty = getattr(stream, "isatty", None)
    return bool(isatty is not None and isatty())
