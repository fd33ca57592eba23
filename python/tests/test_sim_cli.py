# SPDX-License-Identifier: MIT
"""`ctrlbus sim`: the simulated base as a program, over a real pty and over TCP on 127.0.0.1.

The program runs as a child process (base_harness.Process: stderr to a log, bounded waits,
always stopped); bad command lines run in-process through ctrlbus.cli.main.
"""

from __future__ import annotations

import os
import re
import signal
import socket
import struct
import sys
import termios
import tty
from collections.abc import Iterator
from pathlib import Path

import pytest
from support.base_harness import FramePeer, Process, connect_tcp

from ctrlbus import binconf
from ctrlbus.base import DEFAULT_FRAME_TIMEOUT_S
from ctrlbus.cli import build_parser, main, sim_cmd
from ctrlbus.frame import encode
from ctrlbus.sim.server import build_simulated_stack

CTRL_BUS, OK = 0xF8, 0x02
SIM = [sys.executable, "-m", "ctrlbus", "sim"]


@pytest.fixture
def processes(tmp_path: Path) -> Iterator[list[Process]]:
    """Every process a test starts is stopped (SIGTERM, then SIGKILL) at teardown."""
    started: list[Process] = []
    yield started
    for process in started:
        process.stop()


def start(processes: list[Process], tmp_path: Path, *options: str) -> Process:
    process = Process([*SIM, *options], tmp_path / f"sim{len(processes)}.log")
    processes.append(process)
    return process


def open_pty(path: str) -> int:
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY)
    tty.setraw(fd, termios.TCSANOW)
    return fd


def test_pty_serves_the_protocol_and_ctrl_c_exits_0(processes: list[Process], tmp_path: Path) -> None:
    process = start(processes, tmp_path, "--pty")
    line = process.read_line()
    match = re.fullmatch(r"pty: (/dev/pts/\d+)", line)
    assert match, f"unexpected first line {line!r} from {process.describe()}"
    fd = open_pty(match.group(1))
    try:
        peer = FramePeer.over_fd(fd, "ctrlbus sim over a pty")
        peer.send(bytes.fromhex("10 01 00 11"))
        assert peer.read_bytes(4) == bytes.fromhex("10 01 00 11")
        connect = peer.request(CTRL_BUS, b"\x10\x01")
        assert (connect.cmd, connect.long, len(connect.payload)) == (OK, True, 28)
        assert connect.payload[:12] == b"ctrlbus sim\0"
        status = peer.request(CTRL_BUS, b"\x30")
        assert (status.cmd, status.payload) == (OK, bytes((80, 0)))
        motion = peer.request(CTRL_BUS, b"\x41" + struct.pack("<3i", 0, 0, 0))
        assert (motion.cmd, len(motion.payload)) == (OK, 13)
    finally:
        os.close(fd)
    process.popen.send_signal(signal.SIGINT)
    assert process.wait_exit() == 0
    assert "ctrlbus sim: stopped" in process.log()


def test_listen_with_options_and_sigterm_exits_0(processes: list[Process], tmp_path: Path) -> None:
    config = tmp_path / "binary-config.json"
    config.write_text(binconf.example_config_text(), encoding="utf-8")
    process = start(
        processes,
        tmp_path,
        "--listen",
        "127.0.0.1:0",
        "--profile",
        "sdk2020",
        "--binary-config",
        str(config),
        "--time-scale",
        "4",
        "--seed",
        "7",
    )
    line = process.read_line()
    match = re.fullmatch(r"listen: 127\.0\.0\.1:(\d+)", line)
    assert match, f"unexpected first line {line!r} from {process.describe()}"
    with connect_tcp("127.0.0.1", int(match.group(1))) as sock:
        peer = FramePeer.over_socket(sock, "ctrlbus sim over TCP")
        connect = peer.request(CTRL_BUS, b"\x10\x01")
        assert (connect.cmd, len(connect.payload)) == (OK, 39)
        blob = peer.request(CTRL_BUS, b"\x21")
        assert (blob.cmd, blob.payload) == (OK, binconf.example_blob())
        poll = peer.request(CTRL_BUS, b"\x50")
        assert (poll.cmd, poll.payload) == (OK, b"\xff\x00")
        echo = encode(0x01, bytes(range(256)) + bytes(range(44)))
        peer.send(echo)
        assert peer.read_bytes(len(echo)) == echo
    process.popen.send_signal(signal.SIGTERM)
    assert process.wait_exit() == 0


@pytest.mark.parametrize(
    ("options", "complaint"),
    [
        (["--pty", "--time-scale", "fast"], "--time-scale wants a number"),
        (["--pty", "--time-scale", "0"], "time scale must be"),
        (["--pty", "--time-scale", "nan"], "time scale must be"),
        (["--pty", "--profile", "fancy"], "unknown profile 'fancy'"),
        (["--pty", "--seed", "-3"], "--seed wants an integer >= 0"),
        (["--pty", "--seed", "x"], "--seed wants an integer"),
        (["--pty", "--watchdog-ms", "-5"], "--watchdog-ms"),
        (["--pty", "--frame-timeout-ms", "-1"], "--frame-timeout-ms wants a number of milliseconds from 0"),
        (["--pty", "--frame-timeout-ms", "nan"], "--frame-timeout-ms wants a number of milliseconds from 0"),
        (["--pty", "--frame-timeout-ms", "soon"], "--frame-timeout-ms wants a number"),
        (["--pty", "--config", "/nonexistent/robot.json"], "cannot read /nonexistent/robot.json"),
        (["--pty", "--room", "/nonexistent/room.json"], "cannot read /nonexistent/room.json"),
        (["--pty", "--binary-config", "/nonexistent/conf.json"], "cannot read /nonexistent/conf.json"),
        (["--listen", "127.0.0.1"], "HOST:PORT"),
        (["--port", "/nonexistent/ttyUSB9"], "cannot open /nonexistent/ttyUSB9"),
    ],
)
def test_bad_options_get_one_line_and_exit_2(
    options: list[str], complaint: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["sim", *options]) == 2
    out, err = capsys.readouterr()
    assert out == ""
    lines = err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("ctrlbus sim: error: ") and complaint in lines[0], err


def test_bad_files_are_named_in_the_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    robot = tmp_path / "robot.json"
    robot.write_text('{"radius_mm": 170, "wheel_track_mm": 500}', encoding="utf-8")
    conf = tmp_path / "conf.json"
    conf.write_text('{"base": {"x": NaN}}', encoding="utf-8")
    for options, complaint in (
        (["--config", str(robot)], f"{robot}: wheel_track_mm"),
        (["--binary-config", str(conf)], f"{conf}: "),
    ):
        assert main(["sim", "--pty", *options]) == 2
        out, err = capsys.readouterr()
        assert out == "" and len(err.splitlines()) == 1 and complaint in err, err


def test_a_taken_port_is_a_one_line_error(capsys: pytest.CaptureFixture[str]) -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen(1)
        port = holder.getsockname()[1]
        assert main(["sim", "--listen", f"127.0.0.1:{port}"]) == 2
    out, err = capsys.readouterr()
    assert out == "" and err.startswith(f"ctrlbus sim: error: cannot listen on 127.0.0.1:{port}")
    assert len(err.splitlines()) == 1


def test_a_link_must_be_chosen() -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["sim"])
    assert exit_info.value.code == 2


def test_frame_timeout_option_reaches_the_base_stack() -> None:
    parser = build_parser()
    settings = sim_cmd.settings_from_args(parser.parse_args(["sim", "--pty", "--frame-timeout-ms", "20"]))
    _, stack = build_simulated_stack(settings)
    assert stack.config.frame_timeout_s == pytest.approx(0.02)
    default = sim_cmd.settings_from_args(parser.parse_args(["sim", "--pty"]))
    assert build_simulated_stack(default)[1].config.frame_timeout_s == DEFAULT_FRAME_TIMEOUT_S
    off = sim_cmd.settings_from_args(parser.parse_args(["sim", "--pty", "--frame-timeout-ms", "0"]))
    assert build_simulated_stack(off)[1].config.frame_timeout_s == 0
