# SPDX-License-Identifier: MIT
"""The port scheme table (ctrlbus.ports): every URL goes to one opener, and every failure to open
is one typed error naming the URL, which each command turns into one line and exit 2."""

from __future__ import annotations

from pathlib import Path

import pytest

from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.cli import main
from ctrlbus.errors import LinkError, PortOpenError, PortURLError, UsageError
from ctrlbus.faults import FaultyLink
from ctrlbus.link import PtyLink, SerialLink, TcpServerLink
from ctrlbus.ports import SCHEMES, PortScheme, open_link, register_scheme, scheme_for, serve_link

# URLs pyserial's handlers used to reject with a bare KeyError / re.error (issue 17, finding 1),
# a scheme nobody knows, a device that is not there, and a port nobody listens on.
BAD_URLS = [
    "loop://?logging=bogus",
    "loop://?bogus=1",
    "hwgrep://[",
    "nosuchscheme://x",
    "/dev/ctrlbus-no-such-port",
    "fault:bre=1|loop://",
    "fault:ber=1e-4|hwgrep://[",
]


@pytest.mark.parametrize("url", BAD_URLS)
def test_open_failures_are_typed_and_name_the_url(url: str) -> None:
    with pytest.raises(PortOpenError) as info:
        open_link(url)
    error = info.value
    assert isinstance(error, LinkError)
    # A nested fault URL names the part that failed.
    assert error.url == url or (url.startswith("fault:") and url.endswith("|" + error.url))
    assert error.url in str(error) and "\n" not in str(error)


@pytest.mark.parametrize(
    "url", ["loop://?logging=bogus", "hwgrep://[", "nosuchscheme://x", "fault:bre=1|loop://"]
)
def test_a_wrong_url_is_a_usage_error(url: str) -> None:
    with pytest.raises(PortURLError) as info:
        open_link(url)
    assert isinstance(info.value, UsageError)


def test_an_absent_device_is_not_a_usage_error() -> None:
    with pytest.raises(PortOpenError) as info:
        open_link("/dev/ctrlbus-no-such-port")
    assert not isinstance(info.value, UsageError)
    assert str(info.value) == "cannot open /dev/ctrlbus-no-such-port: No such file or directory"


def test_each_kind_of_url_has_one_scheme() -> None:
    expected = {
        "fault:ber=0|loop://": "fault:",
        "socket://127.0.0.1:1": "socket://",
        "loop://": "loop://",
        "rfc2217://127.0.0.1:1": "rfc2217://",
        "hwgrep://x": "hwgrep://",
        "spy://loop://": "spy://",
        "pty": "pty",
        "listen:127.0.0.1:0": "listen:",
        "/dev/ttyUSB0": "device path",
        "COM3": "device path",
    }
    for url, name in expected.items():
        assert scheme_for(url).name == name, url
        assert sum(scheme.matches(url) for scheme in SCHEMES) == 1, url


def test_the_table_opens_what_each_scheme_names() -> None:
    loop = open_link("loop://")
    assert isinstance(loop, SerialLink)
    loop.close()
    faulty = open_link("fault:ber=0|loop://")
    assert isinstance(faulty, FaultyLink) and isinstance(faulty.inner, SerialLink)
    faulty.close()
    pty = open_link("pty", serving=True)
    assert isinstance(pty, PtyLink)
    pty.close()
    listener = serve_link(listen="127.0.0.1:0")
    assert isinstance(listener, TcpServerLink) and listener.port > 0
    listener.close()


def test_serving_schemes_need_a_serving_caller() -> None:
    with pytest.raises(PortURLError, match="creates a port for the peer"):
        open_link("pty")
    with pytest.raises(PortURLError, match="creates a port for the peer"):
        open_link("listen:127.0.0.1:0")


def test_a_new_scheme_is_one_registration(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("ctrlbus.ports.SCHEMES", list(SCHEMES))
    opened: list[str] = []

    def open_test(url: str, baud: int) -> SerialLink:
        opened.append(url)
        return SerialLink("loop://", baud)

    register_scheme(PortScheme("test://", lambda url: url.startswith("test://"), open_test), first=True)
    link = open_link("test://anything")
    link.close()
    assert opened == ["test://anything"]
    with pytest.raises(ValueError, match="registered already"):
        register_scheme(PortScheme("test://", lambda url: False, open_test))


def _capture_file(tmp_path: Path) -> Path:
    path = tmp_path / "one.pcap"
    with CaptureWriter.create(path) as writer:
        writer.write(Direction.CORE_TO_BASE, b"\x10\x00\x10", 0.0)
    return path


# One regression per command that opens a port (issue 17, finding 1): a traceback and exit 1 before.
COMMANDS = {
    "core": ["core", "--port", "{url}", "--duration", "0.1"],
    "check": ["check", "--port", "{url}"],
    "sim": ["sim", "--port", "{url}"],
    "capture": ["capture", "--port", "{url}", "-o", "{tmp}/out.pcap", "--duration", "0.1"],
    "replay": ["replay", "--port", "{url}", "{capture}"],
    "spy": ["spy", "--core", "{url}", "--base", "loop://", "--duration", "0.1"],
}


@pytest.mark.parametrize("url", ["loop://?logging=bogus", "loop://?bogus=1", "hwgrep://["])
@pytest.mark.parametrize("command", sorted(COMMANDS))
def test_every_command_says_a_bad_port_in_one_line_and_exits_2(
    command: str, url: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capture = _capture_file(tmp_path)
    argv = [word.format(url=url, tmp=tmp_path, capture=capture) for word in COMMANDS[command]]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1, err
    assert err.startswith(f"ctrlbus {command}: error: cannot open {url}: "), err
    assert "Traceback" not in err
