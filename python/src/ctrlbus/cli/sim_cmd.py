# SPDX-License-Identifier: MIT
"""`ctrlbus sim`: serve the simulated base (a differential-drive robot in a room) on a link.

    ctrlbus sim --pty | --listen HOST:PORT | --port URL [--config FILE] [--room FILE]
                [--binary-config FILE | --no-binary-config] [--profile reference|sdk2020]
                [--time-scale X] [--seed N]
                [--watchdog-ms N] [--frame-timeout-ms N] [--max-wheel-speed MM_S]
                [--reference-checksum] [--quirks none|reference]

Prints where it serves on stdout as one line (`pty: /dev/pts/N`, `listen: HOST:PORT` or
`port: URL`), then answers the Core until Ctrl-C or SIGTERM (exit 0).
"""

from __future__ import annotations

import argparse
import sys
import threading
from typing import Any

from ctrlbus.base import DEFAULT_FRAME_TIMEOUT_S, DEFAULT_WATCHDOG_S, serve
from ctrlbus.cli.common import add_serve_arguments, stop_on_signals
from ctrlbus.cli.completion_cmd import offer_values
from ctrlbus.constants import Profile
from ctrlbus.errors import UsageError
from ctrlbus.quirks import Quirks, parse_quirks
from ctrlbus.sim.description import load_base_description
from ctrlbus.sim.server import MAX_TIME_SCALE, SimServer, SimSettings

__all__ = [
    "DESCRIPTION",
    "MAX_FRAME_TIMEOUT_MS",
    "register",
    "run",
    "settings_from_args",
]

MAX_FRAME_TIMEOUT_MS = 60_000  # as posix_base's --frame-timeout-ms

DESCRIPTION = """\
Serve the simulated base on a link: a differential-drive robot in a 2-D room with distance
sensors, bumpers, cliff sensors, a battery and a charging dock (docs/simulator.md). It answers
every Control Bus request as a real base would (docs/base-framework.md). The first line on stdout
says where it serves: 'pty: /dev/pts/N', 'listen: HOST:PORT' or 'port: URL'. Ctrl-C stops it.
"""


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "sim",
        help="serve the simulated base on a pty, TCP or a serial port",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_serve_arguments(parser)
    parser.add_argument(
        "--config", metavar="FILE", help="base description, JSON (default: the packaged robot)"
    )
    parser.add_argument("--room", metavar="FILE", help="room description, JSON (default: the packaged room)")
    parser.add_argument(
        "--binary-config",
        metavar="FILE",
        help="JSON binary configuration (see `ctrlbus config example`) served for GET_BASE_CONF_ADV "
        "(0x21) (default: one made from the base description, every sensor included)",
    )
    parser.add_argument(
        "--no-binary-config",
        action="store_true",
        help="serve no binary configuration: 0x21 is answered ERROR 0x8000 and the Core falls back "
        "to GET_BASE_CONF (to exercise that fallback)",
    )
    profile = parser.add_argument(
        "--profile",
        default=Profile.REFERENCE.value,
        metavar="NAME",
        help="answer variants: reference (2018 firmware sizes, default) or sdk2020 (2020 SDK sizes)",
    )
    parser.add_argument(
        "--time-scale",
        default="1",
        metavar="X",
        help=f"simulated seconds per real second (default 1, at most {MAX_TIME_SCALE:g})",
    )
    parser.add_argument("--seed", default=None, metavar="N", help="noise seed (default: the description's)")
    parser.add_argument(
        "--watchdog-ms",
        default=str(round(DEFAULT_WATCHDOG_S * 1000)),
        metavar="N",
        help=f"motor watchdog: stop after N ms without a CTRL_BUS request (default "
        f"{DEFAULT_WATCHDOG_S * 1000:g}; 0 switches it off)",
    )
    parser.add_argument(
        "--frame-timeout-ms",
        default=f"{DEFAULT_FRAME_TIMEOUT_S * 1000:g}",
        metavar="N",
        help=f"drop a partial frame after N ms without a byte (default {DEFAULT_FRAME_TIMEOUT_S * 1000:g}, "
        "for a host behind a USB-serial adapter; 0 switches it off)",
    )
    parser.add_argument(
        "--max-wheel-speed",
        default=None,
        metavar="MM_S",
        help="limit what the Core commands to MM_S mm/s per wheel, scaling both wheels together so "
        "that a curve keeps its curvature (default: the robot's max_wheel_speed_mm_s, "
        f"{_packaged_top_speed():g} for the packaged robot, with its wheel track; 0 switches the limit off)",
    )
    parser.add_argument(
        "--reference-checksum",
        action="store_true",
        help="answer checksum errors with 0x00C0 as the reference firmware does (default 0x0040)",
    )
    quirks = parser.add_argument(
        "--quirks",
        default="none",
        metavar="MODE",
        help="reference: behave as the reference firmware was seen to (combined error bits, 0x00C0, "
        "requests dropped behind garbage reports, LEN=0 re-running the previous request, no "
        "inter-byte timeout, 1.9 s of silence and a low battery at power-on; docs/simulator.md); "
        "none (default): the documented ctrlbus behaviour",
    )
    offer_values(profile, (item.value for item in Profile))
    offer_values(quirks, (item.value for item in Quirks))
    parser.set_defaults(func=run)


def _packaged_top_speed() -> float:
    """The packaged robot's top wheel speed, for --help (the description is small and local)."""
    return load_base_description(None).max_wheel_speed_mm_s


def _number(option: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise UsageError(f"{option} wants a number, got {text!r}") from None
    return value


def _integer(option: str, text: str) -> int:
    try:
        return int(text, 0)
    except ValueError:
        raise UsageError(f"{option} wants an integer, got {text!r}") from None


def settings_from_args(args: argparse.Namespace) -> SimSettings:
    """The checked settings; UsageError (one line) for a bad value."""
    watchdog_ms = _number("--watchdog-ms", args.watchdog_ms)
    if not watchdog_ms >= 0 or watchdog_ms == float("inf"):
        raise UsageError(f"--watchdog-ms wants a number of milliseconds >= 0, got {args.watchdog_ms!r}")
    frame_timeout_ms = _number("--frame-timeout-ms", args.frame_timeout_ms)
    if not 0 <= frame_timeout_ms <= MAX_FRAME_TIMEOUT_MS:
        raise UsageError(
            f"--frame-timeout-ms wants a number of milliseconds from 0 to {MAX_FRAME_TIMEOUT_MS}, "
            f"got {args.frame_timeout_ms!r}"
        )
    max_wheel = None if args.max_wheel_speed is None else _number("--max-wheel-speed", args.max_wheel_speed)
    if max_wheel is not None and not 0 <= max_wheel < float("inf"):
        raise UsageError(f"--max-wheel-speed wants a number of mm/s >= 0, got {args.max_wheel_speed!r}")
    if args.binary_config is not None and args.no_binary_config:
        raise UsageError("--binary-config and --no-binary-config exclude each other")
    seed = None if args.seed is None else _integer("--seed", args.seed)
    if seed is not None and seed < 0:
        raise UsageError(f"--seed wants an integer >= 0, got {args.seed!r}")
    return SimSettings(
        config=args.config,
        room=args.room,
        binary_config=args.binary_config,
        serve_binary_config=not args.no_binary_config,
        profile=args.profile,
        time_scale=_number("--time-scale", args.time_scale),
        seed=seed,
        watchdog_s=watchdog_ms / 1000.0 if watchdog_ms > 0 else None,
        frame_timeout_s=frame_timeout_ms / 1000.0,
        reference_checksum_code=args.reference_checksum,
        max_wheel_mm_s=max_wheel,
        quirks=parse_quirks(args.quirks),
    )


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    """Serve until a stop signal (or until `stop` is set, for callers in other threads)."""
    settings = settings_from_args(args)
    stop = stop if stop is not None else threading.Event()
    with SimServer.open(settings, pty=args.pty, listen=args.listen, port=args.port, baud=args.baud) as server:
        print(server.address, flush=True)
        with stop_on_signals(stop):
            serve(server.stack, server.link, stop_event=stop)
        counters = server.stack.counters()
    print(
        f"ctrlbus sim: stopped ({sum(counters.requests.values())} requests, "
        f"{sum(counters.errors_sent.values())} error answers, {counters.watchdog_trips} watchdog trips)",
        file=sys.stderr,
        flush=True,
    )
    return 0
