# SPDX-License-Identifier: MIT
"""The byte links: every kind moves bytes both ways and fails with LinkError/UsageError, not a traceback."""

from __future__ import annotations

import os
import socket
import time

import pytest

from ctrlbus.errors import LinkError, UsageError
from ctrlbus.link import PtyLink, TcpServerLink, link_pair, parse_host_port
from ctrlbus.ports import open_link, serve_link


def read_exactly(read: object, count: int, limit_s: float = 5.0) -> bytes:
    """Collect `count` bytes from a link-like read(timeout) within a generous bound."""
    assert callable(read)
    data = b""
    deadline = time.monotonic() + limit_s
    while len(data) < count and time.monotonic() < deadline:
        data += read(0.05)
    return data


def test_pair_moves_bytes_both_ways_and_reports_close() -> None:
    a, b = link_pair()
    a.write(b"\x10\x01\x00\x11")
    assert b.read(1.0) == b"\x10\x01\x00\x11"
    b.write(b"xyz")
    assert a.read(1.0) == b"xyz"
    assert a.read(0.01) == b""
    a.close()
    with pytest.raises(LinkError):
        b.read(0.01)


def test_pty_link_talks_to_a_program_opening_its_path() -> None:
    link = PtyLink()
    try:
        peer = os.open(link.path, os.O_RDWR | os.O_NOCTTY)
        try:
            os.write(peer, bytes(range(256)))  # raw mode: every byte value passes unchanged
            assert read_exactly(link.read, 256) == bytes(range(256))
            link.write(b"\x0d\x0a\x03")
            got = b""
            deadline = time.monotonic() + 5
            while len(got) < 3 and time.monotonic() < deadline:
                got += os.read(peer, 16)
            assert got == b"\x0d\x0a\x03"
        finally:
            os.close(peer)
    finally:
        link.close()


def test_tcp_server_link_new_connection_replaces_old() -> None:
    link = TcpServerLink("127.0.0.1", 0)
    try:
        first = socket.create_connection((link.host, link.port))
        first.sendall(b"one")
        assert read_exactly(link.read, 3) == b"one"
        second = socket.create_connection((link.host, link.port))
        second.sendall(b"two")
        assert read_exactly(link.read, 3) == b"two"
        assert link.connections == 2
        link.write(b"back")
        second.settimeout(5)
        assert second.recv(16) == b"back"
        first.settimeout(5)
        assert first.recv(16) == b""  # the old connection was closed
        first.close()
        second.close()
    finally:
        link.close()


def test_tcp_server_link_without_client_drops_writes_and_times_out_reads() -> None:
    link = TcpServerLink("127.0.0.1", 0)
    try:
        link.write(b"nobody listens")
        assert link.read(0.01) == b""
        assert not link.connected
    finally:
        link.close()


def test_open_link_loop_url_and_socket_url() -> None:
    loop = open_link("loop://")
    loop.write(b"\x50\x01\x00\x02\x53")
    assert read_exactly(loop.read, 5) == b"\x50\x01\x00\x02\x53"
    loop.close()

    server = TcpServerLink("127.0.0.1", 0)
    try:
        client = open_link(f"socket://127.0.0.1:{server.port}")
        client.write(b"hi")
        assert read_exactly(server.read, 2) == b"hi"
        server.write(b"ho")
        assert read_exactly(client.read, 2) == b"ho"
        client.close()
    finally:
        server.close()


@pytest.mark.parametrize("url", ["/dev/does-not-exist", "nosuchscheme://x", "socket://127.0.0.1:1", ""])
def test_bad_urls_raise_one_line_errors(url: str) -> None:
    with pytest.raises((LinkError, UsageError)) as info:
        open_link(url)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize("text", ["nohost", ":80", "host:notaport", "host:70000"])
def test_parse_host_port_rejects_bad_text(text: str) -> None:
    with pytest.raises(UsageError):
        parse_host_port(text)


def test_serve_link_needs_exactly_one_choice() -> None:
    with pytest.raises(UsageError):
        serve_link()
    with pytest.raises(UsageError):
        serve_link(pty=True, listen="127.0.0.1:0")


def test_socket_url_reads_what_is_waiting_in_one_call() -> None:
    server = TcpServerLink("127.0.0.1", 0)
    try:
        client = open_link(f"socket://127.0.0.1:{server.port}")
        read_exactly(server.read, 0)  # accept the connection
        server.write(bytes(range(200)))
        time.sleep(0.2)  # let all 200 bytes arrive before the one read below
        assert client.read(1.0) == bytes(range(200))
        client.close()
    finally:
        server.close()


def test_loop_url_with_a_full_buffer_raises_link_error() -> None:
    loop = open_link("loop://")
    with pytest.raises(LinkError, match="buffer is full"):
        for _ in range(10_000):
            loop.write(b"x" * 4096)
    loop.close()
