# SPDX-License-Identifier: MIT
"""The ROS 2 bridge's goals (docs/ros2.md): cmd_vel -> SET_V latency and the bridge's CPU.

    .venv/bin/python bench/ros2.py [--samples N] [--seconds S] [--out FILE]

1. Latency: a Cyclone DDS writer in this process publishes cmd_vel to `ctrlbus ros2` (its own
   process), which drives the simulated base served in this process over TCP on 127.0.0.1. The
   base's `set_velocity` is wrapped to note when each SET_V_AND_GET_DEADRECKON carrying the new
   speed arrives: latency = that time - the time of the write (one clock, this process). Commands
   are written at random phases to the Core's 20 Hz schedule, so the figure includes the wait
   for the next SET_V: the goal is p99 <= one SET_V period (50 ms) + 5 ms.
2. CPU: `ctrlbus core` alone, then `ctrlbus ros2` (default rates: odom 20 Hz, ranges 10 Hz, with a
   subscriber to every topic in this process), each against the simulated base for S seconds;
   user + system time of the process from /proc. The bridge's cost is the difference; the goal is
   under 5 % of one core.

DDS stays on loopback (lo only, no multicast, the peer 127.0.0.1) in this process and in the
bridge (--loopback), on a domain id of its own. Needs the ros2 extra. Not part of `make bench`'s
table (bench/run.py): run it on its own; it writes bench/results/ros2.json.
"""

from __future__ import annotations

import argparse
import json
import os
import random
import statistics
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

from common import REPO, ensure_ctrlbus_importable, git_revision, machine_facts, stop_process

ensure_ctrlbus_importable()

from ctrlbus.ros2.dds import DEFAULT_QOS, LOOPBACK_CONFIG, SENSOR_QOS, TF_QOS, qos_for  # noqa: E402

os.environ["CYCLONEDDS_URI"] = LOOPBACK_CONFIG  # before any participant exists

from ctrlbus.messages import SetVAndGetDeadreckonAnswer  # noqa: E402
from ctrlbus.ros2 import msgs  # noqa: E402
from ctrlbus.sim.server import SimServer, SimSettings  # noqa: E402
from cyclonedds.core import Listener  # noqa: E402
from cyclonedds.domain import Domain, DomainParticipant  # noqa: E402
from cyclonedds.pub import DataWriter  # noqa: E402
from cyclonedds.sub import DataReader  # noqa: E402
from cyclonedds.topic import Topic  # noqa: E402

SET_V_PERIOD_MS = 50.0
GOAL_LATENCY_P99_MS = SET_V_PERIOD_MS + 5.0
GOAL_CPU_PERCENT = 5.0
WATCHDOG_S = 0.5  # ctrlbus ros2's default --cmd-vel-timeout
CLOCK_TICKS = os.sysconf("SC_CLK_TCK")


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / CLOCK_TICKS  # utime, stime


def start(argv: list[str], ready: str) -> subprocess.Popen[bytes]:
    """A ctrlbus process; returns once it printed its `ready` line (bounded)."""
    process = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.DEVNULL)
    assert process.stdout is not None
    deadline = time.monotonic() + 30
    while time.monotonic() < deadline:
        line = process.stdout.readline().decode(errors="replace")
        if ready in line:
            return process
        if not line and process.poll() is not None:
            break
    stop_process(process)
    raise RuntimeError(f"{' '.join(argv)} did not say {ready!r}")


class SetVLog:
    """The times at which the simulated base was given each velocity (wraps its set_velocity)."""

    def __init__(self, server: SimServer) -> None:
        self.lock = threading.Lock()
        self.seen: list[tuple[float, float]] = []
        base = server.sim
        original = base.set_velocity

        def noted(vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
            with self.lock:
                self.seen.append((time.monotonic(), vx_mps))
            return original(vx_mps, vy_mps, omega_radps)

        base.set_velocity = noted  # type: ignore[method-assign]

    def first_after(self, since: float, vx: float) -> float | None:
        with self.lock:
            for when, value in self.seen:
                if when >= since and abs(value - vx) < 1e-3:
                    return when
        return None


def measure_latency(server: SimServer, port: int, domain: int, samples: int) -> dict[str, Any]:
    log = SetVLog(server)
    participant = DomainParticipant(domain)
    qos = qos_for(DEFAULT_QOS)
    writer = DataWriter(participant, Topic(participant, "rt/cmd_vel", msgs.Twist, qos=qos), qos=qos)
    odom = DataReader(participant, Topic(participant, "rt/odom", msgs.Odometry, qos=qos), qos=qos)
    argv = [sys.executable, "-m", "ctrlbus", "ros2", "--port", f"socket://127.0.0.1:{port}"]
    argv += ["--domain", str(domain), "--loopback"]
    bridge = start(argv, "bridging")
    latencies: list[float] = []
    lost = 0
    try:
        deadline = time.monotonic() + 30
        while not odom.take(N=10):  # discovery done, base connected
            if time.monotonic() > deadline:
                raise RuntimeError("no odometry from the bridge within 30 s")
            time.sleep(0.05)
        rng = random.Random(29)
        for index in range(samples + 5):
            vx = 0.10 + 0.01 * (index % 10)
            time.sleep(rng.uniform(0.10, 0.20))  # a random phase to the Core's schedule
            written = time.monotonic()
            writer.write(msgs.Twist(msgs.Vector3(vx, 0.0, 0.0), msgs.Vector3()))
            end = written + 1.0
            seen = None
            while seen is None and time.monotonic() < end:
                time.sleep(0.0005)
                seen = log.first_after(written, vx)
            if index < 5:
                continue  # warm-up
            if seen is None:
                lost += 1
            else:
                latencies.append((seen - written) * 1000.0)
        writer.write(msgs.Twist())
        watchdog = measure_watchdog(log, writer, max(3, samples // 15))
    finally:
        stop_process(bridge)
    latencies.sort()
    p99 = latencies[min(len(latencies) - 1, int(0.99 * len(latencies)))]
    return {
        "watchdog_stop": watchdog,
        "samples": len(latencies),
        "not_seen_within_1s": lost,
        "p50_ms": round(statistics.median(latencies), 2),
        "p99_ms": round(p99, 2),
        "max_ms": round(latencies[-1], 2),
        "goal_p99_ms": GOAL_LATENCY_P99_MS,
        "met": p99 <= GOAL_LATENCY_P99_MS and lost == 0 and watchdog["met"],
    }


def measure_watchdog(log: SetVLog, writer: DataWriter[Any], samples: int) -> dict[str, Any]:
    """Drive, go silent: the time from the last cmd_vel written to the SET_V with zero speed."""
    delays: list[float] = []
    for _ in range(samples):
        last = 0.0
        for _ in range(5):
            last = time.monotonic()
            writer.write(msgs.Twist(msgs.Vector3(0.1, 0.0, 0.0), msgs.Vector3()))
            time.sleep(0.1)
        end = last + 3.0
        seen = None
        while seen is None and time.monotonic() < end:
            time.sleep(0.001)
            seen = log.first_after(last + 0.2, 0.0)
        if seen is not None:
            delays.append((seen - last) * 1000.0)
    bound = (WATCHDOG_S * 1000.0) + SET_V_PERIOD_MS
    return {
        "samples": len(delays),
        "of": samples,
        "min_ms": round(min(delays), 1) if delays else None,
        "max_ms": round(max(delays), 1) if delays else None,
        "goal_max_ms": bound,
        "met": len(delays) == samples and max(delays) <= bound + 5.0,
    }


def measure_cpu(argv: list[str], ready: str, seconds: float) -> float:
    """Percent of one core the process used over `seconds`, after a 3 s warm-up."""
    process = start(argv, ready)
    try:
        time.sleep(3.0)
        begin_cpu, begin = cpu_seconds(process.pid), time.monotonic()
        time.sleep(seconds)
        used, elapsed = cpu_seconds(process.pid) - begin_cpu, time.monotonic() - begin
    finally:
        stop_process(process)
    return 100.0 * used / elapsed


def measure_cpu_pair(port: int, domain: int, seconds: float) -> dict[str, Any]:
    participant = DomainParticipant(domain)
    received = [0]

    def count(reader: DataReader[Any]) -> None:
        received[0] += len(reader.take(N=1000))

    listener = Listener(on_data_available=count)  # type: ignore[no-untyped-call]
    readers = [
        DataReader(
            participant, Topic(participant, name, kind, qos=qos_for(qos)), qos=qos_for(qos), listener=listener
        )
        for name, kind, qos in (
            ("rt/odom", msgs.Odometry, DEFAULT_QOS),
            ("rt/tf", msgs.TFMessage, TF_QOS),
            ("rt/range/sensor_0", msgs.RangeJazzy, SENSOR_QOS),
            ("rt/bumper_cloud", msgs.PointCloud2, SENSOR_QOS),
            ("rt/diagnostics", msgs.DiagnosticArray, DEFAULT_QOS),
        )
    ]
    url = f"socket://127.0.0.1:{port}"
    core = measure_cpu(
        [sys.executable, "-m", "ctrlbus", "core", "--port", url, "--json", "--interval", "1"],
        '"state"',
        seconds,
    )
    bridge = measure_cpu(
        [sys.executable, "-m", "ctrlbus", "ros2", "--port", url, "--domain", str(domain), "--loopback"],
        "bridging",
        seconds,
    )
    del readers
    return {
        "seconds": seconds,
        "core_alone_percent": round(core, 2),
        "ros2_percent": round(bridge, 2),
        "bridge_cost_percent": round(bridge - core, 2),
        "samples_received_by_subscriber": received[0],
        "goal_percent": GOAL_CPU_PERCENT,
        "met": bridge - core < GOAL_CPU_PERCENT,
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    parser.add_argument("--samples", type=int, default=300, help="cmd_vel latency samples (default 300)")
    parser.add_argument("--seconds", type=float, default=30.0, help="CPU measuring window (default 30)")
    parser.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "ros2.json")
    args = parser.parse_args()
    domain = 1 + os.getpid() % 101  # ports below the ephemeral range
    Domain(domain, LOOPBACK_CONFIG)
    with SimServer.open(SimSettings(seed=1), listen="127.0.0.1:0") as server:
        server.start()
        port = int(server.address.rsplit(":", 1)[1])
        latency = measure_latency(server, port, domain, args.samples)
        print(f"cmd_vel -> SET_V: {json.dumps(latency)}", flush=True)
    with SimServer.open(SimSettings(seed=1), listen="127.0.0.1:0") as server:
        server.start()
        port = int(server.address.rsplit(":", 1)[1])
        cpu = measure_cpu_pair(port, domain, args.seconds)
        print(f"CPU: {json.dumps(cpu)}", flush=True)
    result = {
        "command": " ".join([".venv/bin/python", "bench/ros2.py", *sys.argv[1:]]),
        "machine": machine_facts(),
        "revision": git_revision(),
        "cmd_vel_to_set_v": latency,
        "cpu": cpu,
    }
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text(json.dumps(result, indent=2) + "\n")
    return 0 if latency["met"] and cpu["met"] else 1


if __name__ == "__main__":
    sys.exit(main())
