# SPDX-License-Identifier: MIT
"""Build a simulated base from its files and serve it on a link: what `ctrlbus sim` and the demo
share.

    settings = SimSettings(config="robot.json", time_scale=2.0)
    served = SimServer.open(settings, pty=True)       # or listen="127.0.0.1:5555", port=URL
    print(served.link.name)
    served.start()  ...  served.close()

Everything that can be refused (files, numbers, the link) is refused before anything runs, with
a CtrlbusError naming the problem.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import TYPE_CHECKING

from ctrlbus import binconf
from ctrlbus.base import (
    DEFAULT_FRAME_TIMEOUT_S,
    DEFAULT_WATCHDOG_S,
    BaseConfig,
    BaseRunner,
    BaseStack,
    Profile,
    VelocityLimits,
    parse_profile,
)
from ctrlbus.errors import BinaryConfigError, UsageError
from ctrlbus.link import DEFAULT_BAUD, Link, PtyLink, TcpServerLink
from ctrlbus.ports import serve_link
from ctrlbus.quirks import Quirks, parse_quirks
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.blob import blob_from_description
from ctrlbus.sim.description import load_base_description
from ctrlbus.sim.room import load_room
from ctrlbus.sim.world import World

if TYPE_CHECKING:
    from typing_extensions import Self  # typing.Self from Python 3.11; annotations only

__all__ = ["SimServer", "SimSettings", "build_simulated_stack", "read_binary_config", "robot_limits"]

MAX_TIME_SCALE = 1000.0


@dataclass(frozen=True)
class SimSettings:
    """What `ctrlbus sim` takes: file paths (None = the packaged defaults) and numbers."""

    config: str | Path | None = None  # base description (docs/simulator.md)
    room: str | Path | None = None
    binary_config: str | Path | None = None  # JSON configuration served for GET_BASE_CONF_ADV
    # Without a file, serve the blob made from the base description (ctrlbus.sim.blob); False:
    # none, ERROR 0x8000 to GET_BASE_CONF_ADV, to exercise the Core's fallback to GET_BASE_CONF.
    serve_binary_config: bool = True
    profile: Profile | str = Profile.REFERENCE
    time_scale: float = 1.0
    seed: int | None = None
    watchdog_s: float | None = DEFAULT_WATCHDOG_S
    frame_timeout_s: float = DEFAULT_FRAME_TIMEOUT_S  # inter-byte timeout; 0 switches it off
    reference_checksum_code: bool = False
    # The stack's wheel-speed limit (mm/s), applied with the robot's wheel track so that a limited
    # command keeps its curvature. None: the description's max_wheel_speed_mm_s; 0: no limit.
    max_wheel_mm_s: float | None = None
    quirks: Quirks | str = Quirks.NONE  # "reference": imitate the reference firmware (ctrlbus.quirks)


def read_binary_config(path: str | Path) -> bytes:
    """The blob of a JSON binary configuration file (docs/binary-config.md); BinaryConfigError
    naming the file if it cannot be read or encoded."""
    try:
        text = Path(path).read_bytes()
    except OSError as exc:
        raise BinaryConfigError(f"cannot read {path}: {exc.strerror or exc}") from None
    try:
        return binconf.encode(binconf.load_json(text))
    except BinaryConfigError as exc:
        raise BinaryConfigError(f"{path}: {exc}", offset=exc.offset, path=exc.path) from None


def robot_limits(world: World, max_wheel_mm_s: float | None = None) -> VelocityLimits:
    """The stack's limits for the simulated robot: its top wheel speed (or `max_wheel_mm_s`; 0
    for none) with its wheel track, so that an extreme (vx, omega) is scaled as a whole and a turn
    stays the same turn (the world alone would clamp each wheel and straighten it)."""
    limit = world.base.max_wheel_speed_mm_s if max_wheel_mm_s is None else max_wheel_mm_s
    if limit == 0:
        return VelocityLimits()
    return VelocityLimits(max_wheel_mm_s=limit, wheel_track_mm=world.base.wheel_track_mm)


def build_simulated_stack(settings: SimSettings) -> tuple[SimulatedBase, BaseStack]:
    """Load the files and make the simulated base and its stack (nothing runs yet)."""
    scale = settings.time_scale
    if not (math.isfinite(scale) and 0 < scale <= MAX_TIME_SCALE):
        raise UsageError(f"time scale must be a number > 0 and at most {MAX_TIME_SCALE:g}, got {scale:g}")
    if settings.seed is not None and settings.seed < 0:
        raise UsageError(f"seed must be an integer >= 0, got {settings.seed}")
    limit = settings.max_wheel_mm_s
    if limit is not None and not (math.isfinite(limit) and limit >= 0):
        raise UsageError(f"the wheel-speed limit must be a number of mm/s >= 0, got {limit:g}")
    if settings.binary_config is not None and not settings.serve_binary_config:
        raise UsageError("a binary configuration file and serving none contradict each other")
    blob = None if settings.binary_config is None else read_binary_config(settings.binary_config)
    world = World(load_base_description(settings.config), load_room(settings.room), seed=settings.seed)
    if blob is None and settings.serve_binary_config:
        blob = blob_from_description(world.base)
    config = BaseConfig(
        profile=parse_profile(settings.profile),
        watchdog_s=settings.watchdog_s,
        frame_timeout_s=settings.frame_timeout_s,
        reference_checksum_code=settings.reference_checksum_code,
        limits=robot_limits(world, limit),
        quirks=parse_quirks(settings.quirks),
    )
    sim = SimulatedBase(world, binary_config=blob, time_scale=scale, seed=settings.seed)
    return sim, BaseStack(sim, config)


class SimServer:
    """A simulated base, its stack, the link it serves and the runner thread."""

    def __init__(self, sim: SimulatedBase, stack: BaseStack, link: Link) -> None:
        self.sim = sim
        self.stack = stack
        self.link = link
        self.runner = BaseRunner(stack, link, name="ctrlbus-sim")

    @classmethod
    def open(
        cls,
        settings: SimSettings,
        *,
        pty: bool = False,
        listen: str | None = None,
        port: str | None = None,
        baud: int = DEFAULT_BAUD,
    ) -> Self:
        """Build the base, then open the link (so a bad file never leaves a port open)."""
        sim, stack = build_simulated_stack(settings)
        link = serve_link(pty=pty, listen=listen, port=port, baud=baud)
        return cls(sim, stack, link)

    @property
    def address(self) -> str:
        """What to print: `pty: /dev/pts/N`, `listen: HOST:PORT` or `port: URL`."""
        link = self.link
        if isinstance(link, PtyLink):
            return f"pty: {link.path}"
        if isinstance(link, TcpServerLink):
            host = f"[{link.host}]" if ":" in str(link.host) else link.host
            return f"listen: {host}:{link.port}"
        return f"port: {link.name}"

    def start(self) -> Self:
        self.runner.start()
        return self

    def close(self) -> None:
        """Stop the runner and close the link. Idempotent."""
        self.runner.stop()
        self.link.close()

    def __enter__(self) -> Self:
        return self

    def __exit__(
        self, exc_type: type[BaseException] | None, exc: BaseException | None, tb: TracebackType | None
    ) -> None:
        self.close()
