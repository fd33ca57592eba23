# SPDX-License-Identifier: MIT
"""The command-line tools on the inputs a black-box campaign found them wrong on (issue 25).

Each test is one row of the issue's table (docs/reliability.md, "Tools under hostile input"):
hex text that was silently re-paired or not recognised, a tap whose stdout reader went away, a
duplicate Host header, shell completion, a demo on another loopback address, a replay with an
absurd time gap, a full disk and a capture cut inside its last record. The Wireshark dissector and
the sigrok decoder have their own files (test_wireshark_hostile.py, test_sigrok_hostile.py).
"""

from __future__ import annotations

import contextlib
import errno
import io
import json
import logging
import os
import resource
import shlex
import shutil
import signal
import subprocess
import sys
import time
import tty
import urllib.request
from pathlib import Path
from typing import Any

import pytest
from test_spy import LIMIT_S, wait_until
from test_web import FakeSimSource, serve
from test_web_edges import MAX_LINES_PER_PATH, raw_get

from ctrlbus.annotate import Annotator
from ctrlbus.capture import CaptureWriter, Direction, read_capture
from ctrlbus.cli import main
from ctrlbus.cli.replay_cmd import DEFAULT_MAX_GAP_S, cap_gaps
from ctrlbus.cli.spy_cmd import Chunk, Printer, show_chunks
from ctrlbus.errors import CaptureError, UsageError

GET_BASE_STATUS = "10 02 F8 30 DA"
CTRLBUS = [sys.executable, "-m", "ctrlbus"]


def decode_json(
    capsys: pytest.CaptureFixture[str], path: Path, *options: str
) -> tuple[int, list[dict[str, Any]], str]:
    code = main(["decode", "--json", *options, str(path)])
    out, err = capsys.readouterr()
    return code, [json.loads(line) for line in out.splitlines()], err


def frames(records: list[dict[str, Any]]) -> list[str]:
    return [record["hex"] for record in records if record["kind"] == "frame"]


# --- row 3: 0x-prefixed and one-digit bytes ------------------------------------------------------


@pytest.mark.parametrize("form", ["hex", "auto"])
def test_prefixed_one_digit_bytes_are_bytes_not_re_paired(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], form: str
) -> None:
    path = tmp_path / "sync.txt"
    path.write_text("0x10 0x1 0x0 0x11\n")  # SYNC, LEN 1, CMD 0, checksum 0x11
    code, records, _ = decode_json(capsys, path, "--format", form)
    assert code == 0
    assert frames(records) == ["10 01 00 11"]
    path.write_text("10 1 0 11\n")
    code, records, _ = decode_json(capsys, path, "--format", form)
    assert frames(records) == ["10 01 00 11"]


def test_a_token_with_an_odd_number_of_digits_is_a_one_line_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "odd.txt"
    path.write_text("0x10 0x100 0x11\n")
    code = main(["decode", str(path)])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""
    assert err.count("\n") == 1
    assert "'0x100' has an odd number of digits" in err and "line 1 column 6" in err


# --- row 8: a byte order mark, a no-break space ---------------------------------------------------


@pytest.mark.parametrize(
    "text", ["\ufeff" + GET_BASE_STATUS + "\n", GET_BASE_STATUS.replace(" ", "\u00a0", 1) + "\n"]
)
def test_hex_text_with_a_bom_or_a_no_break_space_is_read_as_hex(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], text: str
) -> None:
    path = tmp_path / "pasted.txt"
    path.write_text(text, encoding="utf-8")
    for form in ("auto", "hex"):
        code, records, _ = decode_json(capsys, path, "--format", form)
        assert code == 0
        assert frames(records) == [GET_BASE_STATUS], form


# --- row 4: the tap's stdout reader goes away ---------------------------------------------------


def _raw_pty() -> tuple[int, str]:
    """A pty as a tapped line: (master fd to write the line's bytes to, the slave's path)."""
    master, slave = os.openpty()
    tty.setraw(slave)
    path = os.ttyname(slave)
    os.close(slave)
    return master, path


def test_tap_keeps_recording_when_its_stdout_is_closed(tmp_path: Path) -> None:
    core_line, core_path = _raw_pty()
    base_line, base_path = _raw_pty()
    capture = tmp_path / "tap.pcap"
    command = [*CTRLBUS, "capture", "--tap", f"core={core_path}", "--tap", f"base={base_path}"]
    command += ["-o", str(capture)]
    tool = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
    try:
        assert tool.stdout is not None and tool.stderr is not None
        assert tool.stdout.readline().startswith(b"core: ")  # the ports are open: it listens
        tool.stdout.close()  # the reader goes away, as `| head -1` does
        pairs = 7
        for _ in range(pairs):
            os.write(core_line, bytes.fromhex(GET_BASE_STATUS))
            os.write(base_line, bytes.fromhex("50 03 00 02 50 03 02"))

        def recorded() -> int:
            try:
                return len(read_capture(capture))
            except (OSError, CaptureError):
                return 0

        assert wait_until(lambda: recorded() >= 2 * pairs or tool.poll() is not None)
        assert tool.poll() is None, tool.stderr.read().decode()
        tool.send_signal(signal.SIGINT)
        assert tool.wait(timeout=LIMIT_S) == 0
        err = tool.stderr.read().decode()
    finally:
        if tool.poll() is None:
            tool.kill()
            tool.wait()
        os.close(core_line)
        os.close(base_line)
    assert f"stdout was closed; still recording to {capture}" in err
    records = read_capture(capture)
    core = b"".join(r.data for r in records if r.direction is Direction.CORE_TO_BASE)
    assert core == bytes.fromhex(GET_BASE_STATUS) * pairs


# --- row 12: a full disk, and a capture cut inside its last record ---------------------------------


def _limit_file_size() -> None:
    # Writes past 210 bytes fail as on a full disk (EFBIG; Python ignores SIGXFSZ).
    resource.setrlimit(resource.RLIMIT_FSIZE, (210, 210))


def test_a_failed_capture_write_names_the_file_and_decode_says_the_record_is_cut(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    capture = tmp_path / "full.pcap"
    command = [*CTRLBUS, "capture", "--port", "pty", "-o", str(capture)]
    tool = subprocess.Popen(
        command,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        stdin=subprocess.DEVNULL,
        preexec_fn=_limit_file_size,
    )
    try:
        assert tool.stdout is not None and tool.stderr is not None
        pty_path = tool.stdout.readline().decode().removeprefix("pty: ").strip()
        port = os.open(pty_path, os.O_WRONLY | os.O_NOCTTY)
        try:
            # 24 header bytes, then 22 bytes a record: the 9th record does not fit in 210 bytes.
            deadline = time.monotonic() + LIMIT_S
            while tool.poll() is None and time.monotonic() < deadline:
                try:
                    os.write(port, bytes.fromhex(GET_BASE_STATUS))
                except OSError:  # EIO: the tool has just stopped, its end of the pty is gone
                    break
                wait_until(lambda: tool.poll() is not None, limit_s=0.05)  # one record each, mostly
        finally:
            os.close(port)
        assert tool.wait(timeout=LIMIT_S) == 2
        err = tool.stderr.read().decode()
    finally:
        if tool.poll() is None:
            tool.kill()
            tool.wait()
    assert err.count("\n") == 1 and f"cannot write {capture}: File too large" in err, err
    assert capture.stat().st_size == 210  # cut inside a record

    code = main(["decode", str(capture)])
    out, err = capsys.readouterr()
    assert code == 0 and out.count("GET_BASE_STATUS") >= 1
    assert "warning:" in err and "the last record is cut short" in err
    code = main(["decode", "--strict", str(capture)])
    out, err = capsys.readouterr()
    assert code == 2 and "error:" in err and "the last record is cut short" in err


# --- row 10: a replay whose capture's clock jumps by 136 years ------------------------------------


def test_replay_caps_a_time_jump_at_max_gap(tmp_path: Path) -> None:
    capture = tmp_path / "jump.pcap"
    with CaptureWriter.create(capture) as writer:
        writer.write(Direction.CORE_TO_BASE, b"\x10\x01\x00\x11", 100.0)
        writer.write(Direction.CORE_TO_BASE, bytes.fromhex(GET_BASE_STATUS), 4_294_967_295.0)
    # --linger: the port stays open until the test has read it all (then Ctrl-C ends the replay)
    command = [*CTRLBUS, "replay", str(capture), "--port", "pty", "--max-gap", "0.2", "--linger", "600"]
    tool = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=subprocess.PIPE, stdin=subprocess.DEVNULL)
    played = b""
    try:
        assert tool.stdout is not None and tool.stderr is not None
        line = tool.stdout.readline().decode()
        assert line.startswith("pty: "), line + tool.stderr.read().decode()
        # (the tool has put the pty in raw mode; setting it again here would flush what it wrote)
        port = os.open(line.removeprefix("pty: ").strip(), os.O_RDONLY | os.O_NOCTTY | os.O_NONBLOCK)
        expected = b"\x10\x01\x00\x11" + bytes.fromhex(GET_BASE_STATUS)

        def read_some() -> bool:
            nonlocal played
            with contextlib.suppress(OSError):  # nothing there yet (EAGAIN)
                played += os.read(port, 64)
            return played == expected

        try:
            assert wait_until(read_some), played
        finally:
            os.close(port)
        tool.send_signal(signal.SIGINT)
        assert tool.wait(timeout=LIMIT_S) == 0
        err = tool.stderr.read().decode()
    finally:
        if tool.poll() is None:
            tool.kill()
            tool.wait()
    assert "1 pause(s) longer than --max-gap 0.2 s (the longest 4.29497e+09 s) shortened to 0.2 s" in err


def test_replay_pauses_are_capped_at_a_minute_by_default() -> None:
    schedule = [(0.0, b"a"), (30.0, b"b"), (4_294_967_195.0, b"c"), (4_294_967_196.0, b"d")]
    capped, shortened = cap_gaps(schedule, DEFAULT_MAX_GAP_S)
    assert DEFAULT_MAX_GAP_S == 60.0
    assert capped == [(0.0, b"a"), (30.0, b"b"), (90.0, b"c"), (91.0, b"d")]
    assert shortened == [4_294_967_165.0]


# --- row 5: a duplicate Host header, 200 times -----------------------------------------------------


def test_a_duplicate_host_header_is_one_throttled_line(caplog: pytest.LogCaptureFixture) -> None:
    caplog.set_level(logging.DEBUG)
    srv = serve(FakeSimSource())
    try:
        statuses = {
            raw_get(srv, "GET /api/snapshot HTTP/1.1\r\nHost: 127.0.0.1\r\nHost: evil.example\r\n\r\n")[0]
            for _ in range(200)
        }
    finally:
        srv.stop()
    assert statuses == {400}
    lines = [record for record in caplog.records if record.levelno >= logging.WARNING]
    assert 1 <= len(lines) <= MAX_LINES_PER_PATH, f"{len(lines)} lines"
    assert not any(record.exc_info for record in lines)  # one line each, no traceback
    assert "refused a malformed request from 127.0.0.1: Duplicate 'Host' header" in lines[0].getMessage()
    assert srv.counters.malformed_requests == 200  # every one counted, logged or not


# --- row 9: the demo on another loopback address ---------------------------------------------------


def test_demo_on_another_loopback_address_works_at_the_url_it_prints() -> None:
    demo = subprocess.Popen(
        [*CTRLBUS, "demo", "--http", "127.0.0.2:0"],
        stdout=subprocess.PIPE,
        stderr=subprocess.STDOUT,
        stdin=subprocess.DEVNULL,
        text=True,
    )
    try:
        assert demo.stdout is not None
        output = []
        url = None
        for line in demo.stdout:
            output.append(line)
            if "dashboard at " in line:
                url = line.split("dashboard at ", 1)[1].strip()
                break
        assert url is not None and url.startswith("http://127.0.0.2:"), "".join(output)
        with urllib.request.urlopen(url + "api/snapshot", timeout=LIMIT_S) as response:
            assert response.status == 200
            assert json.load(response)["type"] == "snapshot"
    finally:
        demo.send_signal(signal.SIGINT)
        try:
            demo.wait(LIMIT_S)
        finally:
            if demo.poll() is None:
                demo.kill()
                demo.wait()


# --- rows 6 and 7: shell completion -------------------------------------------------------------


def completion_script(shell: str, capsys: pytest.CaptureFixture[str]) -> str:
    assert main(["completion", shell]) == 0
    return capsys.readouterr().out


def bash_offers(script: str, words: list[str], cwd: Path) -> list[str]:
    """What bash offers with COMP_WORDS = `words` (as bash splits the line: `--color=al` is
    `--color`, `=`, `al`), the last one being typed; one candidate a line, so spaces stay."""
    bash = shutil.which("bash")
    assert bash, "bash is needed to test the bash completion"
    quoted = " ".join(shlex.quote(word) for word in words)
    probe = (
        f"set -u; source /dev/stdin; COMP_WORDS=({quoted}); COMP_CWORD={len(words) - 1}; "
        '_ctrlbus_complete; printf "%s\\n" "${COMPREPLY[@]}"'
    )
    done = subprocess.run(
        [bash, "--norc", "-c", probe], input=script, capture_output=True, text=True, cwd=cwd, check=False
    )
    assert done.returncode == 0 and not done.stderr, done.stderr
    return [line for line in done.stdout.split("\n") if line]


def test_bash_completion_keeps_names_whole_and_knows_every_choice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = completion_script("bash", capsys)
    (tmp_path / "a b.pcap").write_bytes(b"")
    assert bash_offers(script, ["ctrlbus", "decode", "a"], tmp_path) == ["a b.pcap"]
    assert bash_offers(script, ["ctrlbus", "decode", "--color", "="], tmp_path) == ["auto", "always", "never"]
    assert bash_offers(script, ["ctrlbus", "decode", "--color", "=", "al"], tmp_path) == ["always"]
    assert bash_offers(script, ["ctrlbus", "sim", "--profile", ""], tmp_path) == ["reference", "sdk2020"]
    assert bash_offers(script, ["ctrlbus", "sim", "--quirks", ""], tmp_path) == ["none", "reference"]
    only = bash_offers(script, ["ctrlbus", "check", "--only", ""], tmp_path)
    assert {"link", "connect", "1", "2"} <= set(only) and "a b.pcap" not in only


def zsh_offers(script: str, words: list[str], cwd: Path) -> list[str]:
    """What zsh offers: the script sourced in zsh, the completion function called the way zsh's
    bashcompinit calls a bash completion function (compgen -F, in its emulation)."""
    zsh = shutil.which("zsh")
    assert zsh, "zsh is needed to test the zsh completion: scripts/setup.sh full installs it"
    probe = (
        'source "$1"; shift; words=("$@"); CURRENT=$#; COMP_WORDS=("${words[@]}"); '
        'COMP_CWORD=$((CURRENT - 1)); compgen -F _ctrlbus_complete -o filenames -- "${words[CURRENT]}"'
    )
    (cwd / "completion.zsh").write_text(script)
    done = subprocess.run(
        [zsh, "-f", "-c", probe, "zsh", str(cwd / "completion.zsh"), *words],
        capture_output=True,
        text=True,
        cwd=cwd,
        env={**os.environ, "HOME": str(cwd), "ZDOTDIR": str(cwd)},
        check=False,
    )
    assert done.returncode == 0, done.stderr
    return [line for line in done.stdout.split("\n") if line]


def test_zsh_completion_offers_the_choices_of_an_option(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    script = completion_script("zsh", capsys)
    (tmp_path / "a b.pcap").write_bytes(b"")
    assert zsh_offers(script, ["ctrlbus", "decode", "--color", ""], tmp_path) == ["auto", "always", "never"]
    # (zsh's compgen leaves matching the typed prefix to zsh itself: an empty word shows all)
    assert zsh_offers(script, ["ctrlbus", "sim", "--quirks", ""], tmp_path) == ["none", "reference"]
    assert "a b.pcap" in zsh_offers(script, ["ctrlbus", "decode", ""], tmp_path)


class _FillingDisk(io.BytesIO):
    """A file on a disk that fills up after `room` bytes (as ENOSPC does: the write fails)."""

    name = "/media/full/tap.pcap"

    def __init__(self, room: int) -> None:
        super().__init__()
        self.room = room

    def write(self, data: Any) -> int:
        if self.tell() + len(data) > self.room:
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))
        return super().write(data)


def test_a_full_disk_under_the_tap_names_the_file() -> None:
    # The tap and the spy write through show_chunks; 24 bytes of header fit, the first record not.
    capture = CaptureWriter(_FillingDisk(room=30), owns_stream=True)
    chunk = Chunk(Direction.CORE_TO_BASE, bytes.fromhex(GET_BASE_STATUS), 1.0, bytes.fromhex(GET_BASE_STATUS))
    printer = Printer(as_json=True, color=False, time_origin=0.0)
    with pytest.raises(UsageError) as raised:
        show_chunks([chunk], Annotator(timeout=0.1), capture, printer)
    assert str(raised.value) == "cannot write /media/full/tap.pcap: No space left on device"
    capture.close()  # the failed bytes are not written again (no second error from close)
