# SPDX-License-Identifier: MIT
"""`ctrlbus ros2` and `ctrlbus record` refuse bad options in one line (exit code 2) before they
open anything, and `ctrlbus record --port` records a live base."""

from __future__ import annotations

from pathlib import Path

import pytest
from ros2_support import sim_port, start_sim
from test_ros2_record import read_bag

from ctrlbus.cli import main


@pytest.mark.parametrize(
    ("argv", "problem"),
    [
        (["ros2", "--port", "loop://", "--domain", "233"], "--domain wants 0..232"),
        (["ros2", "--port", "loop://", "--domain", "x"], "whole number"),
        (["ros2", "--port", "loop://", "--namespace", "9lives"], "bad ROS 2 name"),
        (["ros2", "--port", "loop://", "--rates", "odom=fast"], "not NAME=HZ"),
        (["ros2", "--port", "loop://", "--rates", "lidar=5"], "unknown topic 'lidar'"),
        (["ros2", "--port", "loop://", "--range", "0=radar:30:0.1:2"], "sonar or ir"),
        (["ros2", "--port", "loop://", "--range", "0=ir:30:2:1"], "MIN < MAX"),
        (["ros2", "--port", "loop://", "--cmd-vel-timeout", "-1"], "--cmd-vel-timeout"),
        (["ros2", "--port", "/dev/no-such-port"], "no-such-port"),
        (["record", "--rosbag", "EXISTS", "--port", "loop://"], "exists already"),
        (["record", "--rosbag", "NEW", "--capture", "missing.pcap"], "missing.pcap"),
    ],
)
def test_bad_options_are_one_line_and_exit_2(
    argv: list[str], problem: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    (tmp_path / "EXISTS").mkdir()
    argv = [str(tmp_path / arg) if arg in ("EXISTS", "NEW", "missing.pcap") else arg for arg in argv]
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and problem in err[0], err


def test_record_a_live_base(tmp_path: Path) -> None:
    sim = start_sim(seed=1)
    try:
        bag = tmp_path / "live"
        argv = ["record", "--rosbag", str(bag), "--port", f"socket://127.0.0.1:{sim_port(sim)}"]
        assert main([*argv, "--duration", "2", "--rates", "odom=10"]) == 0
    finally:
        sim.close()
    topics = read_bag(bag)
    # 10 Hz for the ~2 s after the connection
    assert 5 <= len(topics["/odom"]) <= 25
    assert {"/tf_static", "/battery_state", "/diagnostics", "/range/sensor_0"} <= set(topics)
