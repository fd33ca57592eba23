# SPDX-License-Identifier: MIT
"""posix_base (c/examples/posix_base): the C base stack serving the simulated base on TCP or a pty.

Process-level tests: the real program, the real link, frames built and read with ctrlbus.frame.
Everything listens on 127.0.0.1 with a port the program picks itself (--listen 127.0.0.1:0) and
prints, so no port can collide. Every process is stopped in the fixtures' teardown.

`make c-build` builds the program into build/c/examples/posix_base/; CTRLBUS_POSIX_BASE may name
another build of it (an ASan build, say).
"""

from __future__ import annotations

import os
import re
import signal
import socket
import struct
import subprocess
import termios
import time
import tty
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest
from support.base_harness import REPO, FramePeer, Process, connect_tcp

from ctrlbus import binconf
from ctrlbus.frame import Frame, encode

DEFAULT_BINARY = REPO / "build" / "c" / "examples" / "posix_base" / "posix_base"
BINARY = Path(os.environ.get("CTRLBUS_POSIX_BASE", DEFAULT_BINARY))

CMD_SYNC, CMD_ECHO, CMD_OK, CMD_ERROR, CMD_CTRL_BUS = 0x00, 0x01, 0x02, 0x03, 0xF8
CONNECT_BASE_V1 = bytes((0x10, 0x01))
GET_BASE_CONF = bytes((0x20,))
GET_BASE_STATUS = bytes((0x30,))
GET_BASE_MOTOR_DATA = bytes((0x31,))
GET_BASE_SENSOR_DATA = bytes((0x32,))
GET_BASE_BUMPER_DATA = bytes((0x33,))
GET_CHARGER_BEACONS = bytes((0x34, 0x00))
HEALTH_GET_HEALTH = bytes((0x90, 0x01))
HEALTH_WARNING = 0x01


def set_velocity(vx_mps: float, omega_radps: float) -> bytes:
    return bytes((0x41,)) + struct.pack("<iii", round(vx_mps * 65536), 0, round(omega_radps * 65536))


def set_wheels(left_mm_s: int, right_mm_s: int) -> bytes:
    return bytes((0x40,)) + struct.pack("<iiii", left_mm_s, right_mm_s, 0, 0)


def ok_payload(answer: Frame, size: int | None = None) -> bytes:
    """The payload of an OK answer (of `size` bytes if given); fails the test on anything else."""
    assert answer.cmd == CMD_OK, f"expected OK, got CMD 0x{answer.cmd:02X} payload {answer.payload.hex(' ')}"
    if size is not None:
        assert len(answer.payload) == size, f"OK payload of {len(answer.payload)} bytes, expected {size}"
    return answer.payload


@pytest.fixture(scope="module")
def binary() -> Path:
    if not BINARY.exists():
        pytest.fail(f"{BINARY} is missing: build it with `make c-build`")
    return BINARY


class TcpBase:
    """A running posix_base on 127.0.0.1 and the test's connection(s) to it."""

    def __init__(self, process: Process) -> None:
        self.process = process
        self.sockets: list[socket.socket] = []
        line = process.read_line()
        match = re.fullmatch(r"listen: 127\.0\.0\.1:(\d+)", line)
        assert match, f"unexpected first line {line!r} from {process.describe()}"
        self.port = int(match.group(1))
        self.peer = self.connect("posix_base over TCP")

    def connect(self, name: str) -> FramePeer:
        sock = connect_tcp("127.0.0.1", self.port)
        self.sockets.append(sock)
        return FramePeer.over_socket(sock, name)

    def stop(self) -> None:
        for sock in self.sockets:
            sock.close()
        self.process.stop()


StartBase = Callable[..., TcpBase]


@pytest.fixture
def start_tcp_base(binary: Path, tmp_path: Path) -> Iterator[StartBase]:
    """start(*options) runs posix_base --listen 127.0.0.1:0 and connects to the port it prints."""
    processes: list[Process] = []
    bases: list[TcpBase] = []

    def start(*options: str) -> TcpBase:
        process = Process(
            [str(binary), "--listen", "127.0.0.1:0", *options], tmp_path / f"base{len(processes)}.log"
        )
        processes.append(process)
        bases.append(TcpBase(process))
        return bases[-1]

    yield start
    for running in bases:
        running.stop()
    for process in processes:  # also those whose start failed half-way
        process.stop()


@pytest.fixture
def base(start_tcp_base: StartBase) -> FramePeer:
    """posix_base with default options, connected over TCP."""
    return start_tcp_base().peer


def test_help_describes_both_links_and_exits_0(binary: Path) -> None:
    result = subprocess.run([str(binary), "--help"], capture_output=True, text=True, timeout=30)
    assert result.returncode == 0
    assert "--pty" in result.stdout and "--listen HOST:PORT" in result.stdout


@pytest.mark.parametrize(
    ("args", "complaint"),
    [
        ([], "choose one link"),
        (["--pty", "--listen", "127.0.0.1:0"], "choose one link"),
        (["--listen", "127.0.0.1"], "--listen wants HOST:PORT"),
        (["--pty", "--profile", "fancy"], "--profile wants reference or sdk2020"),
        (["--pty", "--watchdog-ms", "-5"], "--watchdog-ms"),
        (["--pty", "--frame-timeout-ms", "60001"], "--frame-timeout-ms wants 0 to 60000"),
        (
            ["--pty", "--binary-config", "/nonexistent/blob.bin"],
            "cannot read --binary-config /nonexistent/blob.bin",
        ),
        (["--pty", "--binary-config", "/dev/null"], "is empty"),
        (["--pty", "--frobnicate"], "unknown argument: --frobnicate"),
    ],
)
def test_a_bad_command_line_gets_one_line_and_exit_2(binary: Path, args: list[str], complaint: str) -> None:
    result = subprocess.run([str(binary), *args], capture_output=True, text=True, timeout=30)
    assert result.returncode == 2
    assert result.stdout == ""
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("posix_base: error: ") and complaint in lines[0], (
        result.stderr
    )


def test_a_taken_port_is_a_clean_error(binary: Path) -> None:
    with socket.socket() as holder:
        holder.bind(("127.0.0.1", 0))
        holder.listen(1)
        port = holder.getsockname()[1]
        result = subprocess.run(
            [str(binary), "--listen", f"127.0.0.1:{port}"], capture_output=True, text=True, timeout=30
        )
    assert result.returncode == 2
    assert result.stderr.startswith(f"posix_base: error: cannot listen on 127.0.0.1:{port}"), result.stderr
    assert len(result.stderr.splitlines()) == 1


def test_sync_and_echo_come_back_verbatim(base: FramePeer) -> None:
    base.send(bytes.fromhex("10 01 00 11"))  # SYNC without filler, the reference's example
    assert base.read_bytes(4) == bytes.fromhex("10 01 00 11")
    for request in (
        encode(CMD_SYNC, b"\x55" * 40, long=True),
        encode(CMD_ECHO, bytes.fromhex("AA 55")),
        encode(CMD_ECHO, bytes(range(256)) + bytes(range(44))),  # 300 bytes: a long frame
    ):
        base.send(request)
        assert base.read_bytes(len(request)) == request


def test_a_burst_longer_than_the_receive_ring_loses_nothing(base: FramePeer) -> None:
    # 9 kB of requests in one write: many times the stack's 1 kB receive ring.
    requests = b"".join(encode(CMD_ECHO, bytes((i % 256,)) * (i % 60)) for i in range(300))
    base.send(requests)
    assert base.read_bytes(len(requests)) == requests


def test_connect_and_configuration(base: FramePeer) -> None:
    connect = ok_payload(base.request(CMD_CTRL_BUS, CONNECT_BASE_V1), 28)
    assert connect[:12].rstrip(b"\0") == b"ctrlbus sim"

    answer = base.request(CMD_CTRL_BUS, GET_BASE_CONF)
    assert answer.long
    conf = ok_payload(answer, 264)
    base_type, radius_q8, motor_type, sensor_num = struct.unpack_from("<BIBB", conf)
    assert (base_type, radius_q8, motor_type, sensor_num) == (0, 170 * 256, 0, 5)
    sensors = [struct.unpack_from("<iiiI", conf, 7 + 16 * i) for i in range(8)]
    assert [angle // 256 for _, _, _, angle in sensors[:5]] == [0, 40, 320, 90, 270]
    assert sensors[5:] == [(0, 0, 0, 0)] * 3
    assert conf[135] == 2  # bumper_num
    bumpers = [struct.unpack_from("<iiiI", conf, 136 + 16 * i) for i in range(2)]
    assert [angle // 256 for _, _, _, angle in bumpers] == [45, 315]


def test_binary_configuration_is_served_only_when_given(start_tcp_base: StartBase, tmp_path: Path) -> None:
    without = start_tcp_base().peer
    refused = without.request(CMD_CTRL_BUS, bytes((0x21,)))
    assert (refused.cmd, refused.payload) == (CMD_ERROR, struct.pack("<H", 0x8000))
    blob = binconf.example_blob()  # what `ctrlbus config encode` writes for the example
    path = tmp_path / "base.bin"
    path.write_bytes(blob)
    served = start_tcp_base("--binary-config", str(path)).peer.request(CMD_CTRL_BUS, bytes((0x21,)))
    assert served.long and ok_payload(served) == blob
    assert binconf.decode(served.payload) == binconf.decode(blob)


def test_frame_timeout_option(start_tcp_base: StartBase) -> None:
    # A false header claiming 32 bytes, then silence, then a real request.
    false_header = bytes.fromhex("10 20")
    quick = start_tcp_base("--frame-timeout-ms", "20").peer
    quick.send(false_header)
    time.sleep(0.1)  # five times the timeout: the partial frame is dropped
    assert len(ok_payload(quick.request(CMD_CTRL_BUS, CONNECT_BASE_V1))) == 28
    # With the timeout off, the request's bytes go into the waiting candidate: no answer yet.
    patient = start_tcp_base("--frame-timeout-ms", "0").peer
    patient.send(false_header)
    time.sleep(0.1)
    patient.send(encode(CMD_CTRL_BUS, CONNECT_BASE_V1))
    with pytest.raises(AssertionError, match="no frame within"):
        patient.read_frame(limit_s=0.3)


def test_telemetry_of_the_robot_at_its_start(start_tcp_base: StartBase) -> None:
    base = start_tcp_base("--battery", "55").peer
    assert ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_STATUS), 2) == bytes((55, 0))
    distances = struct.unpack("<16I", ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_SENSOR_DATA), 64))
    # 1.2 m from the dock wall, facing it: the front sensor sees it 1 m away; 1.5 m to the side walls.
    assert distances[0] == 1000 * 65536
    assert distances[3] == distances[4] == 1330 * 65536
    assert distances[5:] == (0,) * 11
    assert ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_BUMPER_DATA), 4) == b"\xff" * 4
    # Facing the dock: the main probe sees the main beacon.
    assert ok_payload(base.request(CMD_CTRL_BUS, GET_CHARGER_BEACONS), 5) == bytes((3, 3, 0, 0x02, 0))
    left, right, status = struct.unpack(
        "<iiB", ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_MOTOR_DATA), 9)
    )
    assert (left, right, status) == (0, 0, 0)


def drive(base: FramePeer, command: bytes, until_mm: float) -> tuple[float, float, float]:
    """Repeat a 0x41 command (keeping the watchdog fed) until the summed dx passes until_mm."""
    dx_sum = dy_sum = dtheta_sum = 0.0
    for _ in range(200):  # 200 x 50 ms: ample for a few centimetres at 0.2 m/s
        payload = ok_payload(base.request(CMD_CTRL_BUS, command))
        assert len(payload) in (13, 17)
        dx, dy, dtheta, _ = struct.unpack_from("<iiiB", payload)
        dx_sum += dx / 65536
        dy_sum += dy / 65536
        dtheta_sum += dtheta / 65536
        if abs(dx_sum) >= until_mm:
            return dx_sum, dy_sum, dtheta_sum
        time.sleep(0.05)
    raise AssertionError(f"the robot did not move {until_mm} mm: dx {dx_sum:.1f} mm")


def test_deadreckon_follows_the_velocity_command(base: FramePeer) -> None:
    dx, dy, dtheta = drive(base, set_velocity(0.2, 0.0), until_mm=50.0)
    assert dx >= 50.0 and abs(dy) < 0.01 and abs(dtheta) < 0.001
    stopped = ok_payload(base.request(CMD_CTRL_BUS, set_velocity(0.0, 0.0)))
    assert len(stopped) == 13  # the reference profile: no timestamp
    left, right, _ = struct.unpack("<iiB", ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_MOTOR_DATA), 9))
    assert left == right and left >= 50


def test_sdk2020_profile_answers_the_sizes_that_sdk_reads(start_tcp_base: StartBase) -> None:
    base = start_tcp_base("--profile", "sdk2020").peer
    for request, size in ((CONNECT_BASE_V1, 39), (set_velocity(0.0, 0.0), 17), (GET_BASE_STATUS, 2)):
        answer = base.request(CMD_CTRL_BUS, request)
        assert answer.long
        ok_payload(answer, size)


def test_checksum_error_is_answered_and_nothing_is_executed(base: FramePeer) -> None:
    # SET_BASE_MOTOR forward with its checksum byte flipped.
    request = bytearray(encode(CMD_CTRL_BUS, set_wheels(300, 300)))
    request[-1] ^= 0xFF
    base.send(bytes(request))
    answer = base.read_frame()
    assert (answer.cmd, answer.payload) == (CMD_ERROR, struct.pack("<H", 0x0040))
    time.sleep(0.3)
    left, right, _ = struct.unpack("<iiB", ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_MOTOR_DATA), 9))
    assert (left, right) == (0, 0)


def test_motor_watchdog_stops_the_wheels_and_shows_in_health(start_tcp_base: StartBase) -> None:
    base = start_tcp_base("--watchdog-ms", "200").peer
    health = ok_payload(base.request(CMD_CTRL_BUS, HEALTH_GET_HEALTH), 2)
    assert health[0] & HEALTH_WARNING == 0
    ok_payload(base.request(CMD_CTRL_BUS, set_wheels(-150, -150)), 0)  # backwards: 2.6 m of room
    # Only SYNC for a while: it does not feed the motor watchdog.
    for _ in range(8):
        base.send(bytes.fromhex("10 01 00 11"))
        base.read_bytes(4)
        time.sleep(0.1)
    flags, error_count = ok_payload(base.request(CMD_CTRL_BUS, HEALTH_GET_HEALTH), 2)
    assert flags & HEALTH_WARNING and error_count >= 1
    first = ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_MOTOR_DATA), 9)
    time.sleep(0.3)
    second = ok_payload(base.request(CMD_CTRL_BUS, GET_BASE_MOTOR_DATA), 9)
    left, right, _ = struct.unpack("<iiB", second)
    assert left < 0 and right < 0, "the wheels never moved before the watchdog stopped them"
    assert first[:8] == second[:8], "the wheels kept turning after the watchdog tripped"


def test_a_new_connection_replaces_the_old_one(start_tcp_base: StartBase) -> None:
    running = start_tcp_base()
    first = running.peer
    first.send(bytes.fromhex("10 01 00 11"))
    assert first.read_bytes(4) == bytes.fromhex("10 01 00 11")
    second = running.connect("second connection")
    second.send(bytes.fromhex("10 03 01 AA 55 ED"))
    assert second.read_bytes(6) == bytes.fromhex("10 03 01 AA 55 ED")
    with pytest.raises(ConnectionError):  # the base closed the first connection
        first.read_bytes(1)


@pytest.mark.parametrize("stop_signal", [signal.SIGTERM, signal.SIGINT])
def test_a_stop_signal_ends_it_cleanly(start_tcp_base: StartBase, stop_signal: signal.Signals) -> None:
    running = start_tcp_base()
    base, process = running.peer, running.process
    base.send(bytes.fromhex("10 01 00 11"))
    assert base.read_bytes(4) == bytes.fromhex("10 01 00 11")
    process.popen.send_signal(stop_signal)
    assert process.wait_exit() == 0


def test_pty_link(binary: Path, tmp_path: Path) -> None:
    process = Process([str(binary), "--pty"], tmp_path / "pty.log")
    fd = -1
    try:
        line = process.read_line()
        match = re.fullmatch(r"pty: (/dev/\S+)", line)
        assert match, f"unexpected first line {line!r} from {process.describe()}"
        fd = os.open(match.group(1), os.O_RDWR | os.O_NOCTTY)
        tty.setraw(fd, termios.TCSANOW)
        base = FramePeer.over_fd(fd, f"posix_base on {match.group(1)}")
        base.send(bytes.fromhex("10 01 00 11"))
        assert base.read_bytes(4) == bytes.fromhex("10 01 00 11")
        answer = base.request(CMD_CTRL_BUS, CONNECT_BASE_V1)
        assert ok_payload(answer, 28)[:11] == b"ctrlbus sim"
    finally:
        if fd >= 0:
            os.close(fd)
        process.stop()
