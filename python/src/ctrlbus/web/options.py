# SPDX-License-Identifier: MIT
"""Where the dashboard listens and who may use it; checked before anything starts.

No aiohttp here, so the CLI can validate its options (and refuse an unsafe address) without the
web extra installed.
"""

from __future__ import annotations

import argparse
import ipaddress
import math
import os
import secrets
from dataclasses import dataclass

from ctrlbus.errors import UsageError

__all__ = [
    "DEFAULT_HTTP_HOST",
    "DEFAULT_HTTP_PORT",
    "DEFAULT_PUSH_HZ",
    "DEFAULT_TELEOP_HOLD_S",
    "GENERATE_TOKEN",
    "MAX_PUSH_HZ",
    "MIN_REMOTE_TOKEN_CHARS",
    "TOKEN_ENV",
    "DashboardOptions",
    "check_token",
    "generate_token",
    "is_loopback",
    "parse_http_address",
]

DEFAULT_HTTP_HOST = "127.0.0.1"
DEFAULT_HTTP_PORT = 8080
DEFAULT_PUSH_HZ = 15.0
MAX_PUSH_HZ = 100.0
# How long a teleop velocity stays in force without being repeated (the page repeats at 10 Hz).
DEFAULT_TELEOP_HOLD_S = 0.5
TOKEN_ENV = "CTRLBUS_DASHBOARD_TOKEN"
# A dashboard reachable from other machines needs a token nobody can guess by trying.
MIN_REMOTE_TOKEN_CHARS = 16
GENERATE_TOKEN = "generate"  # --token generate: a random token, printed once at start
_GENERATED_TOKEN_BYTES = 24  # 32 URL-safe characters


def generate_token() -> str:
    """A random token for the dashboard: 32 URL-safe characters (192 bits)."""
    return secrets.token_urlsafe(_GENERATED_TOKEN_BYTES)


@dataclass(frozen=True)
class DashboardOptions:
    host: str = DEFAULT_HTTP_HOST
    port: int = DEFAULT_HTTP_PORT
    token: str | None = None
    push_hz: float = DEFAULT_PUSH_HZ
    teleop_hold_s: float = DEFAULT_TELEOP_HOLD_S
    # Where the token came from: from the environment it is never printed (display_url hides it);
    # a generated one is printed once so that its user can open the page.
    token_from_env: bool = False
    token_generated: bool = False

    def __post_init__(self) -> None:
        if not 0 <= self.port <= 65535:
            raise UsageError(f"dashboard port out of range: {self.port}")
        if not (math.isfinite(self.push_hz) and 1.0 <= self.push_hz <= MAX_PUSH_HZ):
            raise UsageError(f"--push-hz must be between 1 and {MAX_PUSH_HZ:g}, got {self.push_hz}")
        if not (math.isfinite(self.teleop_hold_s) and self.teleop_hold_s > 0):
            raise UsageError(f"teleop hold time must be positive, got {self.teleop_hold_s}")
        if self.token is not None:
            check_token(self.token)
        if not is_loopback(self.host) and not self.token:
            raise UsageError(
                f"the dashboard would listen on {self.host}, which is not loopback: "
                f"give --token (or set {TOKEN_ENV}) so that only holders of it can read or control; "
                f"--token {GENERATE_TOKEN} makes a random one"
            )
        if not is_loopback(self.host) and self.token and len(self.token) < MIN_REMOTE_TOKEN_CHARS:
            raise UsageError(
                f"the dashboard would listen on {self.host}, which is not loopback: its token must have "
                f"at least {MIN_REMOTE_TOKEN_CHARS} characters (this one has {len(self.token)}); "
                f"--token {GENERATE_TOKEN} makes a random one"
            )

    @classmethod
    def from_args(cls, args: argparse.Namespace) -> DashboardOptions:
        """From the options `ctrlbus.cli.common.add_dashboard_arguments` adds."""
        host, port = parse_http_address(args.http)
        if args.token == GENERATE_TOKEN:
            generated = generate_token()
            return cls(host=host, port=port, token=generated, push_hz=args.push_hz, token_generated=True)
        if args.token is not None:
            return cls(host=host, port=port, token=args.token, push_hz=args.push_hz)
        token = os.environ.get(TOKEN_ENV) or None
        return cls(host=host, port=port, token=token, push_hz=args.push_hz, token_from_env=token is not None)

    @property
    def url(self) -> str:
        """The address to open in a browser (the token included, when there is one)."""
        host = self.host
        if host in ("0.0.0.0", ""):
            host = "127.0.0.1"
        elif host == "::":
            host = "::1"
        if ":" in host:
            host = f"[{host}]"
        query = f"/?token={self.token}" if self.token else "/"
        return f"http://{host}:{self.port}{query}"

    @property
    def display_url(self) -> str:
        """The address to print: `url`, but a token from the environment stays a secret (the
        page is opened with `?token=` and the variable's value, which its owner knows)."""
        if self.token_from_env:
            return self.url.replace(f"token={self.token}", f"token=${TOKEN_ENV}")
        return self.url


def parse_http_address(text: str, default_port: int = DEFAULT_HTTP_PORT) -> tuple[str, int]:
    """'HOST', 'HOST:PORT' or '[V6]:PORT' -> (host, port); UsageError otherwise."""
    text = text.strip()
    if not text:
        raise UsageError("empty dashboard address")
    if text.startswith("["):
        host, bracket, rest = text[1:].partition("]")
        if not bracket or (rest and not rest.startswith(":")):
            raise UsageError(f"bad dashboard address {text!r}: expected [V6ADDR] or [V6ADDR]:PORT")
        port_text = rest[1:] if rest else ""
    elif text.count(":") == 1:
        host, _, port_text = text.partition(":")
    else:
        host, port_text = text, ""  # a bare host name, IPv4 or unbracketed IPv6 address
    if not host:
        raise UsageError(f"bad dashboard address {text!r}: no host")
    if not port_text:
        return host, default_port
    try:
        port = int(port_text)
    except ValueError:
        raise UsageError(f"bad dashboard address {text!r}: port must be a number") from None
    if not 0 <= port <= 65535:
        raise UsageError(f"bad dashboard address {text!r}: port out of range")
    return host, port


def is_loopback(host: str) -> bool:
    """Only addresses that are certainly this machine count; any other name needs a token."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


def check_token(token: str) -> None:
    if not token:
        raise UsageError("the dashboard token must not be empty")
    printable = token.isascii() and token.isprintable() and not any(ch.isspace() for ch in token)
    if not printable or len(token) > 256:
        raise UsageError("the dashboard token must be at most 256 printable ASCII characters without spaces")
    if any(ch in token for ch in "&#%?+/"):
        raise UsageError("the dashboard token must not contain & # % ? + or / (it travels in a URL)")
