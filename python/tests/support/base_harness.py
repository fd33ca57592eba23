# SPDX-License-Identifier: MIT
"""Test harness for base processes (posix_base, the QEMU firmware): start and always stop them,
and talk to them over their serial link with bounded waits and clear failure messages.

Not a test module itself; test_posix_base.py and test_firmware.py import it.
"""

from __future__ import annotations

import collections
import contextlib
import fcntl
import os
import select
import signal
import socket
import subprocess
import time
from collections.abc import Callable, Iterator, Sequence
from pathlib import Path

from ctrlbus.frame import Frame, StreamDecoder, encode

REPO = Path(__file__).resolve().parents[3]
LOCKS = REPO / "build" / "test-locks"
ANSWER_LIMIT_S = 10.0  # generous: QEMU on a busy 2-core machine can be slow to start answering


class Process:
    """A child process whose stderr goes to a log file (so a full pipe never blocks it)."""

    def __init__(self, args: Sequence[str], log_path: Path, stdout_pipe: bool = True) -> None:
        self.args = list(args)
        self.log_path = log_path
        self._log = open(log_path, "wb")  # noqa: SIM115  # closed in stop()
        self.popen = subprocess.Popen(
            self.args,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE if stdout_pipe else self._log,
            stderr=self._log,
        )
        self._stdout_buffer = b""

    def log(self) -> str:
        """What the process wrote to stderr so far (for failure messages)."""
        self._log.flush()
        return self.log_path.read_text(errors="replace")

    def describe(self) -> str:
        status = self.popen.poll()
        state = "running" if status is None else f"exited with {status}"
        return f"{' '.join(self.args)} ({state}); its stderr:\n{self.log()}"

    def read_line(self, limit_s: float = ANSWER_LIMIT_S) -> str:
        """The next line of stdout, waiting at most limit_s; fails the test if none comes."""
        assert self.popen.stdout is not None
        fd = self.popen.stdout.fileno()
        deadline = time.monotonic() + limit_s
        while b"\n" not in self._stdout_buffer:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(f"no line on stdout within {limit_s} s from {self.describe()}")
            ready, _, _ = select.select([fd], [], [], remaining)
            if ready:
                chunk = os.read(fd, 4096)
                if not chunk:
                    raise AssertionError(f"stdout closed before a line came from {self.describe()}")
                self._stdout_buffer += chunk
        line, _, self._stdout_buffer = self._stdout_buffer.partition(b"\n")
        return line.decode(errors="replace")

    def wait_exit(self, limit_s: float = ANSWER_LIMIT_S) -> int:
        """Wait for the process to end on its own; fails the test if it does not within limit_s."""
        try:
            return self.popen.wait(timeout=limit_s)
        except subprocess.TimeoutExpired:
            raise AssertionError(f"still running after {limit_s} s: {self.describe()}") from None

    def stop(self) -> None:
        """SIGTERM, then SIGKILL if it lingers; always reaps it. Idempotent."""
        if self.popen.poll() is None:
            self.popen.send_signal(signal.SIGTERM)
            try:
                self.popen.wait(timeout=5)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(timeout=5)
        if self.popen.stdout is not None:
            self.popen.stdout.close()
        self._log.close()


class FramePeer:
    """The test's end of a serial link: raw bytes, or frames decoded with ctrlbus.frame."""

    def __init__(self, read: Callable[[float], bytes], write: Callable[[bytes], None], name: str) -> None:
        self._read = read
        self._write = write
        self.name = name
        self._decoder = StreamDecoder(timeout=0)
        self._frames: collections.deque[Frame] = collections.deque()
        self._raw = b""

    @classmethod
    def over_socket(cls, sock: socket.socket, name: str) -> FramePeer:
        def read(timeout: float) -> bytes:
            ready, _, _ = select.select([sock], [], [], timeout)
            if not ready:
                return b""
            data = sock.recv(65536)
            if not data:
                raise ConnectionError(f"{name}: the other end closed the connection")
            return data

        return cls(read, sock.sendall, name)

    @classmethod
    def over_fd(cls, fd: int, name: str) -> FramePeer:
        def read(timeout: float) -> bytes:
            ready, _, _ = select.select([fd], [], [], timeout)
            return os.read(fd, 65536) if ready else b""

        def write(data: bytes) -> None:
            view = memoryview(data)
            while view:
                view = view[os.write(fd, view) :]

        return cls(read, write, name)

    def send(self, data: bytes) -> None:
        self._write(data)

    def read_bytes(self, count: int, limit_s: float = ANSWER_LIMIT_S) -> bytes:
        """Exactly `count` raw bytes; fails the test (showing what came) if they do not come."""
        deadline = time.monotonic() + limit_s
        while len(self._raw) < count:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                raise AssertionError(
                    f"{self.name}: {len(self._raw)} of {count} bytes within {limit_s} s: "
                    f"{self._raw[:64].hex(' ')}{' ...' if len(self._raw) > 64 else ''}"
                )
            self._raw += self._read(min(remaining, 0.2))
        data, self._raw = self._raw[:count], self._raw[count:]
        return data

    def read_frame(self, limit_s: float = ANSWER_LIMIT_S) -> Frame:
        """The next whole frame; fails the test if none comes within limit_s."""
        if self._raw:  # bytes read ahead by read_bytes belong to the frame stream too
            self._frames.extend(self._decoder.feed(self._raw))
            self._raw = b""
        deadline = time.monotonic() + limit_s
        while not self._frames:
            remaining = deadline - time.monotonic()
            if remaining <= 0:
                stats = self._decoder.stats
                raise AssertionError(f"{self.name}: no frame within {limit_s} s (decoder: {stats})")
            self._frames.extend(self._decoder.feed(self._read(min(remaining, 0.2))))
        return self._frames.popleft()

    def request(self, cmd: int, payload: bytes, *, long: bool = False) -> Frame:
        """Send one frame and return the next frame that comes back."""
        self.send(encode(cmd, payload, long=long))
        return self.read_frame()


def connect_unix(path: Path, process: Process, limit_s: float = ANSWER_LIMIT_S) -> socket.socket:
    """Connect to a Unix socket that `process` creates; fails the test if it never appears."""
    deadline = time.monotonic() + limit_s
    while True:
        sock = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        try:
            sock.connect(str(path))
            return sock
        except (FileNotFoundError, ConnectionRefusedError):
            sock.close()
            if process.popen.poll() is not None or time.monotonic() > deadline:
                raise AssertionError(
                    f"no socket at {path} within {limit_s} s: {process.describe()}"
                ) from None
            time.sleep(0.05)


def connect_tcp(host: str, port: int, limit_s: float = ANSWER_LIMIT_S) -> socket.socket:
    sock = socket.create_connection((host, port), timeout=limit_s)
    sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
    sock.settimeout(None)
    return sock


@contextlib.contextmanager
def exclusive(name: str) -> Iterator[None]:
    """Hold the lock `name` across processes while the block runs: pytest-xdist's workers (and
    a second pytest) that build into the same directory (make -C c/firmware, c/ports, ...) take
    turns instead of racing. The lock is the kernel's (flock): a killed holder releases it."""
    LOCKS.mkdir(parents=True, exist_ok=True)
    with open(LOCKS / f"{name}.lock", "w") as handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
