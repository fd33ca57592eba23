# SPDX-License-Identifier: MIT
"""The `ctrlbus` command as a whole: usage errors are one line and exit 2, help works."""

from __future__ import annotations

import argparse
import subprocess
import sys

import pytest

from ctrlbus.cli import SUBCOMMANDS, build_parser, main


def run_cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "ctrlbus", *args], capture_output=True, text=True, timeout=60, check=False
    )


@pytest.mark.parametrize(
    "args",
    [
        ("nosuchcommand",),
        ("sim",),  # missing --pty/--listen/--port
        ("sim", "--pty", "--listen", "127.0.0.1:0"),  # mutually exclusive
        ("sim", "--listen", "notanaddress"),
        ("config", "decode", "/nonexistent/blob.bin"),
    ],
)
def test_usage_errors_are_one_line_with_exit_code_2(args: tuple[str, ...]) -> None:
    result = run_cli(*args)
    assert result.returncode == 2, result
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1, result.stderr
    assert "error" in lines[0]
    assert "Traceback" not in result.stderr


def test_every_registered_subcommand_has_help() -> None:
    parser = build_parser()
    actions = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    registered = list(actions[0].choices)
    assert set(registered) <= set(SUBCOMMANDS)
    for name in registered:
        with pytest.raises(SystemExit) as info:
            main([name, "--help"])
        assert info.value.code == 0


def test_no_command_prints_help_and_exits_2(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().out
