# SPDX-License-Identifier: MIT
"""Byte links: what a master or a base reads from and writes to.

A link moves bytes and nothing else; framing lives in ctrlbus.frame and sessions one layer up.
Every link has the same small interface (`Link`), so the Core emulator, the bases, the spy and the
fault injector do not care whether the other end is a USB adapter, a pty, a TCP socket or an
in-process pipe.

- `SerialLink` is a pyserial port opened from a URL (`/dev/ttyUSB0`, `socket://127.0.0.1:5555`,
  `loop://`). Open ports by URL with `ctrlbus.ports.open_link`, which knows every scheme
  (`fault:`, `pty`, `listen:` too) and turns any failure into one typed error naming the URL.
- `PtyLink` creates a pseudo-terminal and serves on its master side; `path` is what the other
  program opens.
- `TcpServerLink` listens on HOST:PORT; each accepted connection is one serial link and a new
  connection replaces the old one (the old one is closed), like replugging a cable.
- `link_pair()` gives two connected in-process links, for tests and for running a Core and a base
  in one process.
"""

from __future__ import annotations

import contextlib
import errno
import os
import queue
import select
import socket
import threading
import time
from typing import Protocol

from ctrlbus.errors import LinkError, UsageError

__all__ = [
    "DEFAULT_BAUD",
    "READ_CHUNK",
    "FdLink",
    "Link",
    "PipeLink",
    "PtyLink",
    "SerialLink",
    "TcpServerLink",
    "link_pair",
    "parse_host_port",
]

DEFAULT_BAUD = 115200
READ_CHUNK = 4096


class Link(Protocol):
    """The interface every link offers."""

    def read(self, timeout: float) -> bytes:
        """Return the bytes available now, waiting up to `timeout` s for the first; b"" if none."""
        ...

    def write(self, data: bytes) -> None:
        """Send all of `data`; raises LinkError if the link is closed or failed."""
        ...

    def close(self) -> None:
        """Release the link; idempotent."""
        ...

    @property
    def name(self) -> str:
        """What to show a person: the URL, pty path or listening address."""
        ...


class SerialLink:
    """A pyserial port opened from a URL."""

    def __init__(self, url: str, baud: int = DEFAULT_BAUD) -> None:
        import serial  # imported here so that a missing pyserial only hurts users of real ports

        if not url:
            raise UsageError("empty port URL")
        if baud <= 0:
            raise UsageError(f"baud rate must be positive, got {baud}")
        self._url = url
        # Failures propagate as pyserial raises them; ctrlbus.ports.open_link types them.
        self._port = serial.serial_for_url(url, baudrate=baud, timeout=0, write_timeout=5)
        self._lock = threading.Lock()

    @property
    def name(self) -> str:
        return self._url

    def read(self, timeout: float) -> bytes:
        import serial

        deadline = time.monotonic() + max(0.0, timeout)
        try:
            while True:
                waiting = self._port.in_waiting
                if waiting:
                    # socket:// reports 1 waiting byte whatever is there; the port is
                    # non-blocking (timeout=0), so ask for a chunk and take what is ready.
                    data: bytes = self._port.read(max(waiting, READ_CHUNK))
                    return data
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    return b""
                fileno = _fileno_of(self._port)
                if fileno is not None:
                    select.select([fileno], [], [], remaining)
                else:
                    # loop:// and friends have no descriptor: poll briefly.
                    time.sleep(min(remaining, 0.0005))
        except serial.SerialException as exc:
            if "returned no data" in str(exc):
                # pyserial's word for a readiness report with nothing behind it (a pty whose
                # other side is not open yet, or was just closed): no data now, not a failure.
                time.sleep(max(0.0, min(deadline - time.monotonic(), 0.01)))
                return b""
            raise LinkError(f"{self._url}: read failed: {_first_line(exc)}") from None
        except OSError as exc:
            raise LinkError(f"{self._url}: read failed: {_first_line(exc)}") from None

    def write(self, data: bytes) -> None:
        import serial

        try:
            with self._lock:
                self._port.write(data)
                self._port.flush()
        except (serial.SerialException, OSError) as exc:
            raise LinkError(f"{self._url}: write failed: {_first_line(exc)}") from None
        except queue.Full:  # loop:// holds a bounded queue nobody is reading
            raise LinkError(f"{self._url}: write failed: the port's buffer is full") from None

    def close(self) -> None:
        self._port.close()


def _fileno_of(port: object) -> int | None:
    fileno = getattr(port, "fileno", None)
    if fileno is None:
        sock = getattr(port, "_socket", None)  # socket:// ports keep their socket here
        return sock.fileno() if sock is not None else None
    try:
        value = fileno()
    except Exception:  # pyserial raises a bare Exception for ports without one
        sock = getattr(port, "_socket", None)
        return sock.fileno() if sock is not None else None
    return value if isinstance(value, int) else None


def _first_line(exc: BaseException) -> str:
    text = (str(exc).strip() or type(exc).__name__).splitlines()[0]
    # pyserial's socket ports already say "read failed: ..."; we add our own prefix.
    for prefix in ("read failed: ", "write failed: "):
        text = text.removeprefix(prefix)
    return text


class FdLink:
    """A link over a raw file descriptor (a pty master or a connected socket)."""

    def __init__(self, fd: int, name: str) -> None:
        self._fd = fd
        self._name = name
        self._closed = False
        self._lock = threading.Lock()

    @property
    def name(self) -> str:
        return self._name

    def read(self, timeout: float) -> bytes:
        if self._closed:
            raise LinkError(f"{self._name}: link is closed")
        ready, _, _ = select.select([self._fd], [], [], max(0.0, timeout))
        if not ready:
            return b""
        try:
            data = os.read(self._fd, READ_CHUNK)
        except BlockingIOError:
            return b""
        except OSError as exc:
            if exc.errno == errno.EIO:  # pty with no program on the other side yet
                time.sleep(min(timeout, 0.01))
                return b""
            raise LinkError(f"{self._name}: read failed: {exc.strerror}") from None
        return data

    def write(self, data: bytes) -> None:
        view = memoryview(data)
        with self._lock:
            while view:
                if self._closed:
                    raise LinkError(f"{self._name}: link is closed")
                try:
                    written = os.write(self._fd, view)
                except BlockingIOError:
                    select.select([], [self._fd], [], 0.05)
                    continue
                except OSError as exc:
                    raise LinkError(f"{self._name}: write failed: {exc.strerror}") from None
                view = view[written:]

    def close(self) -> None:
        if not self._closed:
            self._closed = True
            os.close(self._fd)


class PtyLink(FdLink):
    """Serve on a new pseudo-terminal; the peer opens `path` (e.g. /dev/pts/5)."""

    def __init__(self) -> None:
        import tty

        master_fd, slave_fd = os.openpty()
        # Raw mode on the slave: no echo, no line editing, no CR/LF translation; these are bytes.
        tty.setraw(slave_fd)
        self.path = os.ttyname(slave_fd)
        # Keep the slave open ourselves so the master never sees EIO before the peer opens it.
        self._slave_fd = slave_fd
        os.set_blocking(master_fd, False)
        super().__init__(master_fd, self.path)

    def close(self) -> None:
        super().close()
        with contextlib.suppress(OSError):
            os.close(self._slave_fd)


class TcpServerLink:
    """Listen on HOST:PORT; the latest accepted connection is the link, replacing older ones.

    While no client is connected, reads return b"" after the timeout and writes are dropped,
    as bytes sent down an unplugged cable are.
    """

    def __init__(self, host: str, port: int) -> None:
        self._server = socket.socket(socket.AF_INET6 if ":" in host else socket.AF_INET, socket.SOCK_STREAM)
        self._server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            self._server.bind((host, port))
        except OSError as exc:
            self._server.close()
            raise LinkError(f"cannot listen on {host}:{port}: {exc.strerror or exc}") from None
        self._server.listen(1)
        self._server.setblocking(False)
        self.host, self.port = self._server.getsockname()[:2]
        self._client: socket.socket | None = None
        self._lock = threading.Lock()
        self.connections = 0

    @property
    def name(self) -> str:
        return f"tcp://{self.host}:{self.port}"

    @property
    def connected(self) -> bool:
        return self._client is not None

    def _accept_pending(self) -> None:
        while True:
            try:
                client, _ = self._server.accept()
            except (BlockingIOError, InterruptedError):
                return
            client.setblocking(False)
            client.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            with self._lock:
                if self._client is not None:
                    self._client.close()
                self._client = client
                self.connections += 1

    def read(self, timeout: float) -> bytes:
        deadline = time.monotonic() + max(0.0, timeout)
        while True:
            self._accept_pending()
            watch: list[socket.socket] = [self._server]
            client = self._client
            if client is not None:
                watch.append(client)
            remaining = deadline - time.monotonic()
            ready, _, _ = select.select(watch, [], [], max(0.0, remaining))
            if client is not None and client in ready:
                try:
                    data = client.recv(READ_CHUNK)
                except (BlockingIOError, InterruptedError):
                    data = None
                except OSError:
                    data = b""
                if data:
                    return data
                if data == b"":  # peer closed: unplugged
                    self._drop(client)
            if not ready and remaining <= 0:
                return b""
            if remaining <= 0:
                return b""

    def _drop(self, client: socket.socket) -> None:
        with self._lock:
            if self._client is client:
                self._client = None
        client.close()

    def write(self, data: bytes) -> None:
        self._accept_pending()
        client = self._client
        if client is None:
            return
        view = memoryview(data)
        while view:
            try:
                sent = client.send(view)
            except BlockingIOError:
                select.select([], [client], [], 0.05)
                continue
            except OSError:
                self._drop(client)
                return
            view = view[sent:]

    def close(self) -> None:
        with self._lock:
            if self._client is not None:
                self._client.close()
                self._client = None
        self._server.close()


class PipeLink:
    """One end of an in-process pair (see `link_pair`)."""

    def __init__(self, name: str, inbox: _Pipe, outbox: _Pipe) -> None:
        self._name = name
        self._inbox = inbox
        self._outbox = outbox

    @property
    def name(self) -> str:
        return self._name

    def read(self, timeout: float) -> bytes:
        return self._inbox.take(timeout)

    def write(self, data: bytes) -> None:
        self._outbox.put(data)

    def close(self) -> None:
        self._inbox.close()
        self._outbox.close()


class _Pipe:
    def __init__(self) -> None:
        self._data = bytearray()
        self._closed = False
        self._ready = threading.Condition()

    def put(self, data: bytes) -> None:
        with self._ready:
            if self._closed:
                raise LinkError("in-process link is closed")
            self._data += data
            self._ready.notify_all()

    def take(self, timeout: float) -> bytes:
        with self._ready:
            if not self._data and not self._closed:
                self._ready.wait(max(0.0, timeout))
            if self._closed and not self._data:
                raise LinkError("in-process link is closed")
            data = bytes(self._data)
            self._data.clear()
            return data

    def close(self) -> None:
        with self._ready:
            self._closed = True
            self._ready.notify_all()


def parse_host_port(text: str) -> tuple[str, int]:
    """'127.0.0.1:5555' -> ('127.0.0.1', 5555); UsageError with a clear message otherwise."""
    host, sep, port_text = text.rpartition(":")
    if not sep or not host:
        raise UsageError(f"expected HOST:PORT, got {text!r}")
    try:
        port = int(port_text)
    except ValueError:
        raise UsageError(f"port must be a number in {text!r}") from None
    if not 0 <= port <= 65535:
        raise UsageError(f"port out of range in {text!r}")
    return host.strip("[]"), port


def link_pair(names: tuple[str, str] = ("pair:a", "pair:b")) -> tuple[PipeLink, PipeLink]:
    """Two in-process links wired back to back: what one writes, the other reads."""
    a_to_b, b_to_a = _Pipe(), _Pipe()
    return PipeLink(names[0], b_to_a, a_to_b), PipeLink(names[1], a_to_b, b_to_a)
