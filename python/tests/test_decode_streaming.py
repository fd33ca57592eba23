# SPDX-License-Identifier: MIT
"""`ctrlbus decode` streams its input (issue 17, finding 5): a day-long capture decodes in bounded
memory. Each input kind (capture, raw bytes, hex text) of 4 MiB is decoded in process under
tracemalloc; the peak of Python allocations must stay at the bound docs/tools.md states (about
1 MiB whatever the input's size), half the input's size: reading the whole input fails it.
"""

from __future__ import annotations

import contextlib
import json
import os
import select
import subprocess
import sys
import tracemalloc
from collections.abc import Callable
from pathlib import Path

import pytest

from ctrlbus.annotate import FrameNote
from ctrlbus.capture import CaptureWriter, Direction
from ctrlbus.cli import decode_cmd, main
from ctrlbus.cli.common import parse_hex_text
from ctrlbus.errors import UsageError
from ctrlbus.frame import encode

INPUT_BYTES = 4 << 20
PEAK_LIMIT_BYTES = 2 << 20  # docs/tools.md promises about 1 MiB whatever the input's size
ECHO = 0x01
CTRL_BUS = 0xF8


def _exchange(index: int) -> tuple[bytes, bytes]:
    """A large ECHO (answered by the same bytes) and a status request with its answer."""
    echo = encode(ECHO, bytes((index + offset) & 0xFF for offset in range(4000)))
    status = encode(CTRL_BUS, bytes((0x30,)))
    answer = encode(0x02, bytes((80, 0)), long=True)
    return echo + status, echo + answer


def write_capture(path: Path) -> None:
    with CaptureWriter.create(path, flush=False) as writer:
        index, size, time = 0, 0, 0.0
        while size < INPUT_BYTES:
            request, answer = _exchange(index)
            writer.write(Direction.CORE_TO_BASE, request, time)
            writer.write(Direction.BASE_TO_CORE, answer, time + 0.002)
            size += len(request) + len(answer)
            index += 1
            time += 0.02


def write_binary(path: Path) -> None:
    with path.open("wb") as out:
        index, size = 0, 0
        while size < INPUT_BYTES:
            request, _answer = _exchange(index)
            chunk = request + b"\xaa\x55"  # and a little garbage between exchanges
            out.write(chunk)
            size += len(chunk)
            index += 1


def write_hex(path: Path) -> None:
    with path.open("w") as out:
        index, size = 0, 0
        while size < INPUT_BYTES:
            request, _answer = _exchange(index)
            line = request.hex() + f"  # exchange {index}, one token per frame\n"
            out.write(line)
            size += len(line)
            index += 1


@pytest.mark.parametrize("write", [write_capture, write_binary, write_hex], ids=["capture", "binary", "hex"])
def test_decode_holds_a_bounded_amount_of_memory(write: Callable[[Path], None], tmp_path: Path) -> None:
    path = tmp_path / "input"
    write(path)
    assert path.stat().st_size >= INPUT_BYTES
    warm_up = tmp_path / "first-exchanges"
    with path.open("rb") as whole:
        warm_up.write_bytes(whole.read(1 << 16))
    with open(os.devnull, "w") as sink, contextlib.redirect_stdout(sink):
        main(["decode", "--json", str(warm_up)])  # imports every module decode needs: not measured
        tracemalloc.start()
        try:
            status = main(["decode", "--json", str(path)])
            _current, peak = tracemalloc.get_traced_memory()
        finally:
            tracemalloc.stop()
    assert status == 0
    assert peak < PEAK_LIMIT_BYTES, f"decoding {path.stat().st_size >> 20} MiB peaked at {peak >> 20} MiB"


def test_decode_output_comes_before_the_input_ends() -> None:
    # Incremental consumption: the first exchange is printed while the input is still open.
    reader, writer = os.pipe()
    request, _answer = _exchange(0)
    os.write(writer, request)
    command = [sys.executable, "-m", "ctrlbus", "decode", "--format", "binary", "--json", "-"]
    process = subprocess.Popen(command, stdin=reader, stdout=subprocess.PIPE)
    os.close(reader)
    try:
        assert process.stdout is not None
        ready, _, _ = select.select([process.stdout], [], [], 20.0)
        assert ready, "decode printed nothing while its input stayed open"
        first = json.loads(process.stdout.readline())
        assert first["kind"] == "frame" and first["cmd"] == ECHO, first
    finally:
        os.close(writer)
        process.wait(timeout=30)


def test_pieces_cut_anywhere_decode_as_the_whole(monkeypatch: pytest.MonkeyPatch) -> None:
    # Tokens, comments, "0x" prefixes, multi-byte characters and one-digit bytes cut across
    # pieces of 7 bytes read as they do in one piece.
    text = (
        "# a comment with ünïcode that is longer than a piece\n"
        "10 02 F8 30 DA, 0x50,0x03:00 02 50 03 02\n"
        "1003f81001fa   # CONNECT_BASE in one token\n"
        "10 2 F8 30 DA\n"
    ).encode()
    whole = decode_cmd.decode_bytes(text, input_format="hex")
    monkeypatch.setattr(decode_cmd, "_READ_SIZE", 7)
    pieces = decode_cmd.decode_bytes(text, input_format="hex")
    assert [entry.to_json() for entry in pieces.entries] == [entry.to_json() for entry in whole.entries]
    assert sum(isinstance(entry, FrameNote) for entry in whole.entries) == 4
    as_bytes = decode_cmd.decode_bytes(parse_hex_text(text.decode()), input_format="binary")
    assert [entry.to_json() for entry in as_bytes.entries] == [entry.to_json() for entry in whole.entries]
    with pytest.raises(UsageError, match="not hex text: 'zz' at line 2 column 4"):
        decode_cmd.decode_bytes(b"10\n10 zz\n", input_format="hex")
