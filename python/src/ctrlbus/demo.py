# SPDX-License-Identifier: MIT
"""`ctrlbus demo` (what `make demo` runs): a base, the Core emulator and the dashboard.

    ctrlbus demo [--base sim|c|qemu] [--http HOST[:PORT]] [--token T] [--speed X]

(`python -m ctrlbus.demo` is the same.)

- `--base sim` (default): the Python simulated base, in this process, serving a real pty; the
  dashboard also shows the simulator's ground truth (room, dock, beacons, true pose).
- `--base c`: the C host base, build/c/examples/posix_base/posix_base --pty, as a child process.
- `--base qemu`: the Cortex-M3 firmware (c/ports/mps2_an385) under qemu-system-arm, its UART0 on a pty.

The Core emulator opens the base's pty like any serial port and talks the real protocol over it.
Ctrl-C or SIGTERM stops everything: the Core, the dashboard, the base; child processes run in
their own process group, which is terminated (then killed if it lingers) and waited for.
"""

from __future__ import annotations

import argparse
import contextlib
import os
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any

from ctrlbus.cli.common import add_dashboard_arguments, stop_on_signals
from ctrlbus.errors import CtrlbusError, LinkError, UsageError
from ctrlbus.web.options import DashboardOptions
from ctrlbus.web.source import DashboardSource

if TYPE_CHECKING:
    from ctrlbus.sim.base import SimulatedBase

__all__ = [
    "CHILD_START_TIMEOUT_S",
    "CHILD_STOP_TIMEOUT_S",
    "DEFAULT_C_BASE",
    "DEFAULT_FIRMWARE",
    "DESCRIPTION",
    "PTY_PATTERN",
    "REPO_ROOT",
    "ChildProcess",
    "RunningBase",
    "SimulatorAttached",
    "add_demo_arguments",
    "build_parser",
    "main",
    "run",
]

REPO_ROOT = Path(__file__).resolve().parents[3]
DEFAULT_C_BASE = REPO_ROOT / "build" / "c" / "examples" / "posix_base" / "posix_base"
DEFAULT_FIRMWARE = REPO_ROOT / "build" / "ports" / "mps2_an385" / "simbase-qemu.elf"
PTY_PATTERN = re.compile(r"(/dev/(?:pts/\d+|tty[A-Za-z0-9]+))")
CHILD_START_TIMEOUT_S = 15.0
CHILD_STOP_TIMEOUT_S = 3.0


DESCRIPTION = "Run a base, the Core emulator talking to it over a pty, and the browser dashboard."


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="python -m ctrlbus.demo", description=DESCRIPTION)
    add_demo_arguments(parser)
    return parser


def add_demo_arguments(parser: argparse.ArgumentParser) -> None:
    """The demo's options, for `python -m ctrlbus.demo` and `ctrlbus demo` alike."""
    parser.add_argument(
        "--base",
        choices=("sim", "c", "qemu"),
        default="sim",
        help="sim: the Python simulated base (default); c: the C host base; qemu: the Cortex-M3 firmware",
    )
    parser.add_argument(
        "--speed",
        type=float,
        default=1.0,
        metavar="X",
        help="simulated time per real second (--base sim only; default 1)",
    )
    parser.add_argument(
        "--base-binary",
        type=Path,
        default=None,
        metavar="PATH",
        help=f"the posix_base program (--base c, default {DEFAULT_C_BASE.relative_to(REPO_ROOT)}) "
        f"or firmware image (--base qemu, default {DEFAULT_FIRMWARE.relative_to(REPO_ROOT)})",
    )
    add_dashboard_arguments(parser)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return run(args)
    except (CtrlbusError, OSError) as exc:
        print(f"ctrlbus demo: error: {exc}", file=sys.stderr)
        return 2


def run(args: argparse.Namespace) -> int:
    # Everything that can be refused is refused before anything starts.
    options = DashboardOptions.from_args(args)
    if args.base != "sim" and args.speed != 1.0:
        raise UsageError("--speed applies to --base sim only (the C base and the firmware run in real time)")
    if not 0.1 <= args.speed <= 100.0:
        raise UsageError(f"--speed must be between 0.1 and 100, got {args.speed}")

    stop = threading.Event()
    with stop_on_signals(stop), contextlib.ExitStack() as cleanup:
        base = _start_base(args, cleanup)
        source = _start_core(base, cleanup)
        from ctrlbus.web import start_dashboard

        server = start_dashboard(source, options)
        cleanup.callback(server.stop)
        print(f"ctrlbus demo: base {base.description}", flush=True)
        print(f"ctrlbus demo: dashboard at {server.display_url}", flush=True)
        print("ctrlbus demo: Ctrl-C to stop", flush=True)
        while not stop.wait(0.25):
            failure = base.failure()
            if failure is not None:
                print(f"ctrlbus demo: error: {failure}", file=sys.stderr, flush=True)
                return 1
    print("ctrlbus demo: stopped", flush=True)
    return 0


# -- bases ------------------------------------------------------------------------------------


@dataclass
class RunningBase:
    """A base the Core can open: `port` is its pyserial URL (a pty path)."""

    port: str
    description: str
    failure: Callable[[], str | None]
    # The simulated base when it runs in this process (for ground truth), else None.
    simulator: SimulatedBase | None = None


def _start_base(args: argparse.Namespace, cleanup: contextlib.ExitStack) -> RunningBase:
    if args.base == "sim":
        return _start_sim_base(args, cleanup)
    if args.base == "c":
        program = args.base_binary or DEFAULT_C_BASE
        _require_file(program, "the C host base", 'make demo DEMO_ARGS="--base c" or make c-build')
        child = ChildProcess("posix_base", [str(program), "--pty"])
    else:
        qemu = shutil.which("qemu-system-arm")
        if qemu is None:
            raise UsageError("qemu-system-arm is not installed (scripts/setup.sh qemu installs it)")
        firmware = args.base_binary or DEFAULT_FIRMWARE
        _require_file(firmware, "the firmware image", 'make demo DEMO_ARGS="--base qemu" or make firmware')
        command = [qemu, "-M", "mps2-an385", "-display", "none", "-monitor", "none"]
        command += ["-serial", "pty", "-kernel", str(firmware)]
        child = ChildProcess("qemu", command)
    cleanup.callback(child.stop)
    port = child.start()
    return RunningBase(port=port, description=f"{args.base}: {child.name} on {port}", failure=child.failure)


def _start_sim_base(args: argparse.Namespace, cleanup: contextlib.ExitStack) -> RunningBase:
    from ctrlbus.link import PtyLink
    from ctrlbus.sim.server import SimServer, SimSettings

    served = SimServer.open(SimSettings(time_scale=args.speed), pty=True)
    cleanup.callback(served.close)
    served.start()
    link = served.link
    assert isinstance(link, PtyLink)

    def failure() -> str | None:
        runner = served.runner
        if runner.failure is not None:
            return f"the simulated base stopped: {runner.failure}"
        return None

    return RunningBase(
        port=link.path,
        description=f"sim: simulated base on {link.path} (time x{args.speed:g})",
        failure=failure,
        simulator=served.sim,
    )


class SimulatorAttached:
    """The Core's dashboard source plus the simulator's ground truth and external-command queue.

    The Core knows nothing of the simulator; only this process, which runs both, can put the two
    pictures side by side. The Core's dead-reckoned frame starts where the robot stood when the
    Core started: the room's start pose (the robot does not move before the Core drives it).
    """

    def __init__(self, core: DashboardSource, simulator: SimulatedBase) -> None:
        self.core = core
        self.simulator = simulator
        start = simulator.world.room.start_pose
        self.odometry_origin = {"x_mm": start.x_mm, "y_mm": start.y_mm, "theta_deg": start.theta_deg}

    def snapshot(self) -> dict[str, Any]:
        data = self.core.snapshot()
        data["sim"] = {**self.simulator.snapshot(), "odometry_origin": dict(self.odometry_origin)}
        return data

    def set_velocity(self, vx_mps: float, omega_radps: float) -> None:
        self.core.set_velocity(vx_mps, omega_radps)

    def emergency_stop(self) -> None:
        self.core.emergency_stop()

    def release_stop(self) -> None:
        self.core.release_stop()

    def go_home(self) -> None:
        self.core.go_home()

    def limits(self) -> tuple[float, float]:
        return self.core.limits()

    def queue_external_command(self, code: int) -> None:
        self.simulator.queue_external_command(code)


def _start_core(base: RunningBase, cleanup: contextlib.ExitStack) -> DashboardSource:
    """The Core emulator on the base's pty, in real time; the source the dashboard shows."""
    from ctrlbus.core import CoreRunner, CoreSession
    from ctrlbus.ports import open_link
    from ctrlbus.web.source import CoreSource

    session = CoreSession(port=base.port)
    runner = CoreRunner(session, open_link(base.port), reopen=lambda: open_link(base.port))
    runner.start()
    cleanup.callback(runner.stop)
    base_failure = base.failure

    def failure() -> str | None:
        if runner.failure is not None:
            return f"the Core emulator stopped: {runner.failure}"
        return base_failure()

    base.failure = failure
    source = CoreSource.for_runner(runner)  # the dashboard reads the session under the runner's lock
    if base.simulator is not None:
        return SimulatorAttached(source, base.simulator)
    return source


def _require_file(path: Path, what: str, how: str) -> None:
    if not path.is_file():
        raise UsageError(f"{what} is not built: {path} is missing (run `{how}`)")


class ChildProcess:
    """A base program in its own process group, whose output names the pty it serves."""

    def __init__(self, name: str, command: list[str]) -> None:
        self.name = name
        self.command = command
        self._process: subprocess.Popen[str] | None = None
        self._pty: str | None = None
        self._found = threading.Event()
        self._readers: list[threading.Thread] = []
        self._stopping = False

    def start(self) -> str:
        """Start it and return the pty path it prints; LinkError if it fails or never says."""
        try:
            self._process = subprocess.Popen(
                self.command,
                stdin=subprocess.DEVNULL,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                text=True,
                errors="replace",
                start_new_session=True,  # Ctrl-C reaches only us; we stop the child in order
            )
        except OSError as exc:
            raise LinkError(f"cannot start {self.name}: {exc.strerror or exc}") from None
        assert self._process.stdout is not None and self._process.stderr is not None
        for stream in (self._process.stdout, self._process.stderr):
            name = f"{self.name}-output"
            reader = threading.Thread(target=self._read, args=(stream,), name=name, daemon=True)
            reader.start()
            self._readers.append(reader)
        deadline = time.monotonic() + CHILD_START_TIMEOUT_S
        while not self._found.wait(0.05):
            if self._process.poll() is not None:
                status = self._process.returncode
                raise LinkError(f"{self.name} exited with status {status} before serving a pty")
            if time.monotonic() > deadline:
                raise LinkError(f"{self.name} did not name its pty within {CHILD_START_TIMEOUT_S:g} s")
        assert self._pty is not None
        return self._pty

    def _read(self, stream: IO[str]) -> None:
        for line in stream:
            if self._pty is None:
                match = PTY_PATTERN.search(line)
                if match:
                    self._pty = match.group(1)
                    self._found.set()
            text = line.rstrip()
            if text:
                print(f"[{self.name}] {text}", file=sys.stderr, flush=True)

    def failure(self) -> str | None:
        process = self._process
        if process is None or self._stopping or process.poll() is None:
            return None
        return f"{self.name} exited unexpectedly with status {process.returncode}"

    def stop(self) -> None:
        """Terminate the whole process group, kill it if it lingers, and reap it."""
        process = self._process
        if process is None:
            return
        self._stopping = True
        for sig, wait_s in ((signal.SIGTERM, CHILD_STOP_TIMEOUT_S), (signal.SIGKILL, CHILD_STOP_TIMEOUT_S)):
            with contextlib.suppress(ProcessLookupError, PermissionError):
                os.killpg(process.pid, sig)
            try:
                process.wait(wait_s)
                break
            except subprocess.TimeoutExpired:
                continue
        # The group may outlive its leader (a grandchild); make sure nothing of it is left.
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(process.pid, signal.SIGKILL)
        for reader in self._readers:
            reader.join(1.0)


if __name__ == "__main__":
    sys.exit(main())
