# SPDX-License-Identifier: MIT
"""The command-line tools on the inputs a black-box campaign found them wrong on (issue 25).

Each test is one row of the issue's table (docs/reliability.md, "Tools under hostile input"):
hex text that was silently re-paired or not recognised, a tap whose stdout reader went away, a
duplicate Host header, shell completion, a demo on another loopback address, a replay with an
absurd time gap, a full disk and a capture cut inside its last record. The Wireshark dissector and
the sigrok decoder have their own files (test_wireshark_hostile.py, test_sigrok_hostile.py).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from ctrlbus.cli import main

GET_BASE_STATUS = "10 02 F8 30 DA"


def decode_json(capsys: pytest.CaptureFixture[str], path: Path, *options: str) -> tuple[int, list[dict], str]:
    code = main(["decode", "--json", *options, str(path)])
    out, err = capsys.readouterr()
    return code, [json.loads(line) for line in out.splitlines()], err


def frames(records: list[dict]) -> list[str]:
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
