# SPDX-License-Identifier: MIT
"""The ros2 extra is optional: without cyclonedds, `import ctrlbus` and every other command work,
and `ctrlbus ros2` / `ctrlbus record` say in one line which extra is missing (exit code 2).

cyclonedds is hidden from a child interpreter (None in sys.modules makes its import fail), so the
test runs whether the extra is installed here or not.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

HIDE = "import sys; sys.modules['cyclonedds'] = None; sys.modules['rosbags'] = None\n"


def run_without_extra(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", HIDE + code], capture_output=True, text=True, timeout=60, check=False
    )


@pytest.mark.parametrize(
    "argv",
    [
        ["ros2", "--port", "loop://"],
        ["record", "--rosbag", "never-made", "--port", "loop://"],
        ["record", "--rosbag", "never-made", "--capture", "missing.pcap"],
    ],
)
def test_the_bridge_without_the_extra_is_one_line_and_exit_2(argv: list[str]) -> None:
    result = run_without_extra(f"from ctrlbus.cli import main; sys.exit(main({argv!r}))")
    assert result.returncode == 2, result.stderr
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1, result.stderr
    assert "ros2 extra" in lines[0] and "pip install 'ctrlbus[ros2]'" in lines[0]
    assert result.stdout == ""


def test_everything_else_works_without_the_extra() -> None:
    result = run_without_extra(
        "import ctrlbus, ctrlbus.core, ctrlbus.sim, ctrlbus.checker\n"
        "from ctrlbus.cli import main\n"
        "for command in ('core', 'sim', 'check', 'decode', 'ros2', 'record'):\n"
        "    try:\n"
        "        main([command, '--help'])\n"
        "    except SystemExit as exc:\n"
        "        assert exc.code == 0, (command, exc.code)\n"
        "print('ok')\n"
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.rstrip().endswith("ok")
    assert "usage: ctrlbus ros2" in result.stdout and "usage: ctrlbus record" in result.stdout
