# SPDX-License-Identifier: MIT
"""The command's face: `ctrlbus demo`, shell completion, NO_COLOR and --color."""

from __future__ import annotations

import io
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ctrlbus.cli import SUBCOMMANDS, main
from ctrlbus.cli.common import use_color


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_demo_is_a_subcommand_with_the_demo_options(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as info:
        main(["demo", "--help"])
    assert info.value.code == 0
    out = capsys.readouterr().out
    for option in ("--base {sim,c,qemu}", "--speed", "--http", "--token"):
        assert option in out


def test_demo_refuses_bad_options_in_one_line(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["demo", "--base", "c", "--speed", "2"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("ctrlbus demo: error: --speed applies to --base sim only") and err.count("\n") == 1


def completions(script: str, *words: str, cwd: Path) -> list[str]:
    """What bash offers after `words` (the last one is being typed)."""
    bash = shutil.which("bash")
    assert bash, "bash is needed to test the bash completion"
    quoted = " ".join(f"'{word}'" for word in words)
    probe = (
        f"set -u; source /dev/stdin; COMP_WORDS=({quoted}); COMP_CWORD={len(words) - 1}; "
        '_ctrlbus_complete; printf "%s\\n" "${COMPREPLY[@]}"'
    )
    proc = subprocess.run(
        [bash, "--norc", "-c", probe], input=script, capture_output=True, text=True, cwd=cwd, check=False
    )
    assert proc.returncode == 0 and not proc.stderr, proc.stderr
    return proc.stdout.split()


def test_bash_completion_knows_commands_options_and_choices(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["completion", "bash"]) == 0
    script = capsys.readouterr().out
    (tmp_path / "session.pcap").write_bytes(b"")
    assert set(completions(script, "ctrlbus", "", cwd=tmp_path)) >= set(SUBCOMMANDS)
    assert completions(script, "ctrlbus", "co", cwd=tmp_path) == ["completion", "config", "core"]
    colours = completions(script, "ctrlbus", "decode", "--color", "", cwd=tmp_path)
    assert colours == ["auto", "always", "never"]
    assert completions(script, "ctrlbus", "demo", "--base", "q", cwd=tmp_path) == ["qemu"]
    assert completions(script, "ctrlbus", "config", "e", cwd=tmp_path) == ["encode", "example"]
    assert "--time-scale" in completions(script, "ctrlbus", "sim", "--ti", cwd=tmp_path)
    assert completions(script, "ctrlbus", "decode", "sess", cwd=tmp_path) == ["session.pcap"]
    assert completions(script, "ctrlbus", "check", "--port", "sess", cwd=tmp_path) == ["session.pcap"]


def test_zsh_completion_is_the_bash_one_behind_bashcompinit(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["completion", "zsh"]) == 0
    script = capsys.readouterr().out
    assert "bashcompinit" in script and "complete -o filenames -F _ctrlbus_complete ctrlbus" in script


def test_an_unknown_shell_is_a_usage_error() -> None:
    proc = subprocess.run(
        [sys.executable, "-m", "ctrlbus", "completion", "tcsh"], capture_output=True, text=True, check=False
    )
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1


def test_no_color_turns_auto_colour_off(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("NO_COLOR", raising=False)
    assert use_color("auto", Terminal()) is True
    assert use_color("auto", io.StringIO()) is False
    monkeypatch.setenv("NO_COLOR", "1")
    assert use_color("auto", Terminal()) is False
    assert use_color("never", Terminal()) is False
    assert use_color("always", io.StringIO()) is True  # an explicit --color always wins
    monkeypatch.setenv("NO_COLOR", "")  # empty means unset (no-color.org)
    assert use_color("auto", Terminal()) is True


def test_decode_honours_no_color_and_color_always(tmp_path: Path) -> None:
    blob = tmp_path / "frame.hex"
    blob.write_text("10 00 10\n")  # one CONNECT request
    env = {**os.environ, "NO_COLOR": "1"}
    for args, coloured in ((["--color", "always"], True), ([], False)):
        proc = subprocess.run(
            [sys.executable, "-m", "ctrlbus", "decode", *args, str(blob)],
            capture_output=True,
            text=True,
            env=env,
            check=False,
        )
        assert proc.returncode == 0, proc.stderr
        assert ("\x1b[" in proc.stdout) is coloured
