# SPDX-License-Identifier: MIT
"""Opening ports by URL: one table of schemes, one place where opening can fail.

Each kind of port the tools accept is one `PortScheme` in `SCHEMES`, matched in order:

- `fault:SPEC|URL`: URL (any scheme, nested too) behind the fault injector (ctrlbus.faults);
- `socket://`, `loop://`, `rfc2217://`, `spy://`, `hwgrep://`, `alt://`, `cp2110://`: pyserial's
  URL handlers (ctrlbus.link.SerialLink);
- `pty`: a new pseudo-terminal for the peer to open (serving side, ctrlbus.link.PtyLink);
- `listen:HOST:PORT`: a TCP listener, one connection at a time (serving side,
  ctrlbus.link.TcpServerLink);
- anything else without `scheme://` is a serial device path: /dev/ttyUSB0, COM3.

`open_link(url)` opens an existing port (what a master or a checker does); tools that sit on a
link (spy, capture, replay) also accept the serving schemes with `serving=True`; `serve_link()` is
what a base offers (`--pty`, `--listen`, `--port`).

Any failure to open becomes a `PortOpenError` (the port is absent, busy, refused) or a
`PortURLError` (the URL itself is wrong: unknown scheme, bad option, bad fault spec), both
naming the URL on one line, so the CLI prints it and exits 2. pyserial's handlers are third-party
code that raises whatever it likes (KeyError for `loop://?logging=bogus`, re.error for
`hwgrep://[`), so every exception from an opener is caught here and typed.

A new scheme is one `register_scheme(PortScheme(...))` call; the table is the only dispatcher.
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from dataclasses import dataclass

from ctrlbus.errors import CtrlbusError, LinkError, PortOpenError, PortURLError, UsageError
from ctrlbus.faults import FAULT_URL_PREFIX, FaultyLink, split_fault_url
from ctrlbus.link import DEFAULT_BAUD, Link, PtyLink, SerialLink, TcpServerLink, parse_host_port

__all__ = [
    "LISTEN_PREFIX",
    "PTY_NAME",
    "SCHEMES",
    "PortScheme",
    "open_link",
    "register_scheme",
    "scheme_for",
    "serve_link",
]

PTY_NAME = "pty"
LISTEN_PREFIX = "listen:"

# pyserial's own URL handlers (serial.urlhandler.protocol_*), opened through serial_for_url.
PYSERIAL_SCHEMES = ("socket", "loop", "rfc2217", "spy", "hwgrep", "alt", "cp2110")

_URL_SCHEME = re.compile(r"^([A-Za-z][A-Za-z0-9+.-]*)://")


@dataclass(frozen=True)
class PortScheme:
    """One kind of port: which URLs it takes, how to open one, and whether it serves.

    `serving` schemes create an endpoint for the peer to open (a pty, a TCP listener) rather than
    opening an existing one; `open_link` takes them only when asked (`serving=True`).
    """

    name: str
    matches: Callable[[str], bool]
    open: Callable[[str, int], Link]
    serving: bool = False
    help: str = ""


SCHEMES: list[PortScheme] = []


def register_scheme(scheme: PortScheme, *, first: bool = False) -> None:
    """Add a scheme to the table (at the end, or before all others with `first`)."""
    if any(known.name == scheme.name for known in SCHEMES):
        raise ValueError(f"port scheme {scheme.name!r} is registered already")
    if first:
        SCHEMES.insert(0, scheme)
    else:
        SCHEMES.append(scheme)


def scheme_for(url: str) -> PortScheme:
    """The table's entry for `url`; PortURLError if none takes it."""
    if not url.strip():
        raise PortURLError(
            url, "empty port URL: give a device path, a pyserial URL, 'pty' or 'listen:HOST:PORT'"
        )
    for scheme in SCHEMES:
        if scheme.matches(url):
            return scheme
    match = _URL_SCHEME.match(url)
    known = ", ".join(s.name for s in SCHEMES if s.name.endswith("://") or s.name.endswith(":"))
    what = f"unknown scheme {match.group(1)}://" if match else "not a port URL"
    raise PortURLError(url, f"{what} (known: {known})")


def open_link(url: str, baud: int = DEFAULT_BAUD, *, serving: bool = False) -> Link:
    """Open the port `url` names; PortOpenError / PortURLError (one line, naming it) on failure.

    `fault:SPEC|URL` opens URL behind the fault injector (docs/reliability.md). With `serving`,
    `pty` and `listen:HOST:PORT` are accepted too (they create the endpoint the peer opens).
    """
    scheme = scheme_for(url)
    if scheme.serving and not serving:
        raise PortURLError(
            url, f"{scheme.name} creates a port for the peer to open; give an existing port here"
        )
    if baud <= 0:
        raise PortURLError(url, f"baud rate must be positive, got {baud}")
    try:
        return scheme.open(url, baud)
    except (PortOpenError, KeyboardInterrupt):
        raise
    except UsageError as exc:
        raise PortURLError(url, _reason(exc)) from None
    except CtrlbusError as exc:
        raise PortOpenError(url, _reason(exc)) from None
    except (ValueError, LookupError, re.error) as exc:
        # pyserial's handlers reject bad options and patterns this way (loop://?logging=bogus,
        # hwgrep://[): the URL is wrong.
        raise PortURLError(url, _reason(exc)) from None
    except Exception as exc:
        raise PortOpenError(url, _reason(exc)) from None


def serve_link(
    *, pty: bool = False, listen: str | None = None, port: str | None = None, baud: int = DEFAULT_BAUD
) -> Link:
    """Open the base side of a link the way `--pty`, `--listen HOST:PORT` or `--port URL` say."""
    if sum((pty, listen is not None, port is not None)) != 1:
        raise UsageError("give exactly one of --pty, --listen HOST:PORT, --port URL")
    if pty:
        return open_link(PTY_NAME, baud, serving=True)
    if listen is not None:
        return open_link(LISTEN_PREFIX + listen, baud, serving=True)
    assert port is not None
    return open_link(port, baud)


def _reason(exc: BaseException) -> str:
    """One line saying why, without repeating the URL the caller names anyway."""
    if isinstance(exc, OSError) and exc.errno and exc.strerror:
        return os.strerror(exc.errno)  # pyserial's text repeats the errno and the path twice
    kind = (
        type(exc).__name__
        if type(exc).__module__ == "builtins"
        else f"{type(exc).__module__}.{type(exc).__name__}"
    )
    if isinstance(exc, LookupError):
        # pyserial's handlers fail this way on options they cannot read (loop://?bogus=1).
        return f"pyserial cannot read the URL's options ({kind}: {exc})"
    text = str(exc).strip()
    if not text:
        return kind
    first = text.splitlines()[0]
    return first if isinstance(exc, CtrlbusError | OSError) else f"{first} ({kind})"


# --- the table --------------------------------------------------------------------------------


def _open_fault(url: str, baud: int) -> Link:
    spec, inner_url = split_fault_url(url)
    return FaultyLink(open_link(inner_url, baud), spec)


def _open_pty(url: str, baud: int) -> Link:
    return PtyLink()


def _open_listener(url: str, baud: int) -> Link:
    host, tcp_port = parse_host_port(url[len(LISTEN_PREFIX) :])
    try:
        return TcpServerLink(host, tcp_port)
    except LinkError as exc:  # "cannot listen on HOST:PORT: why" says it better than "cannot open"
        raise PortOpenError(url, _reason(exc), message=str(exc)) from None


def _open_serial(url: str, baud: int) -> Link:
    return SerialLink(url, baud)


def _starts_with(prefix: str) -> Callable[[str], bool]:
    return lambda url: url.lower().startswith(prefix)


def _is_device_path(url: str) -> bool:
    return (
        url != PTY_NAME
        and _URL_SCHEME.match(url) is None
        and not url.startswith((FAULT_URL_PREFIX, LISTEN_PREFIX))
    )


register_scheme(
    PortScheme(
        FAULT_URL_PREFIX,
        _starts_with(FAULT_URL_PREFIX),
        _open_fault,
        help="fault:SPEC|URL: URL behind the fault injector (docs/reliability.md)",
    )
)
for _name in PYSERIAL_SCHEMES:
    register_scheme(
        PortScheme(
            f"{_name}://",
            _starts_with(f"{_name}://"),
            _open_serial,
            help="pyserial URL handler",
        )
    )
register_scheme(
    PortScheme(PTY_NAME, lambda url: url == PTY_NAME, _open_pty, serving=True, help="a new pseudo-terminal")
)
register_scheme(
    PortScheme(
        LISTEN_PREFIX,
        _starts_with(LISTEN_PREFIX),
        _open_listener,
        serving=True,
        help="listen:HOST:PORT: accept TCP connections, one at a time (port 0 picks a free one)",
    )
)
register_scheme(
    PortScheme("device path", _is_device_path, _open_serial, help="a serial port: /dev/ttyUSB0, COM3")
)
