# SPDX-License-Identifier: MIT
"""One home per protocol fact: the health codes, status bits, profiles and profile answer sizes
are defined in ctrlbus.constants and nowhere else in the package (found by reading the sources:
a copy that drifts would not show in any behaviour test until a base disagreed)."""

from __future__ import annotations

import functools
import io
import re
import tokenize
from pathlib import Path

import pytest

from ctrlbus import constants
from ctrlbus.messages import ConnectBaseAnswer, SetVAndGetDeadreckonAnswer

SRC = Path(__file__).resolve().parent.parent / "src" / "ctrlbus"
HOME = SRC / "constants.py"
# The bit meanings' own home: generated from protocol/ctrlbus.json (scripts/generate_protocol.py).
DESCRIBED = SRC / "protocol_tables.py"

# The facts issue 15 found copied: each must be defined once, in ctrlbus/constants.py.
LISTED = [
    "WATCHDOG_TRIPPED_CODE",
    "WATCHDOG_TRIPPED_MESSAGE",
    "HEALTH_WARNING",
    "HEALTH_ERROR",
    "HEALTH_FATAL",
    "COMPONENT_POWER",
    "COMPONENT_MOTION",
    "TYPE_WATCHDOG_TRIPPED",
    "health_code",
    "POWER_CHARGING",
    "POWER_DC_CONNECTED",
    "POWER_ON_DOCK",
    "POWER_DEFINED_BITS",
    "MOTION_STALL",
    "MOTION_TRACTION_LOST",
    "MOTION_DEFINED_BITS",
    "POWER_BIT_NAMES",
    "MOTION_BIT_NAMES",
    "Profile",
    "parse_profile",
    "PROFILE_ANSWER_SIZES",
]


# The sources are read, and tokenized, once per session: every test here searches all of them.
@functools.cache
def sources() -> tuple[Path, ...]:
    return tuple(sorted(SRC.rglob("*.py")))


@functools.cache
def text_of(path: Path) -> str:
    return path.read_text(encoding="utf-8")


@functools.cache
def lines_of(path: Path) -> tuple[str, ...]:
    return tuple(text_of(path).splitlines())


def definitions(name: str) -> list[str]:
    """Where `name` is bound by an assignment (also in a tuple), a def or a class."""
    assigned = re.compile(rf"^\s*(?:\w+\s*,\s*)*{name}\s*(?:,\s*\w+\s*)*(?::[^=\n]+)?=(?!=)")
    defined = re.compile(rf"^\s*(?:class|def)\s+{name}\b")
    found = []
    for path in sources():
        for number, line in enumerate(lines_of(path), start=1):
            if assigned.match(line) or defined.match(line):
                found.append(f"{path.relative_to(SRC)}:{number}")
    return found


@functools.cache
def code_tokens(path: Path) -> tuple[tokenize.TokenInfo, ...]:
    return tuple(tokenize.generate_tokens(io.StringIO(text_of(path)).readline))


@pytest.mark.parametrize("name", LISTED)
def test_each_fact_is_defined_once_in_constants(name: str) -> None:
    assert hasattr(constants, name) and name in constants.__all__
    assert definitions(name) == [f"{HOME.relative_to(SRC)}:{_line_of(name)}"]


def _line_of(name: str) -> int:
    found = definitions(name)
    assert found, f"{name} is not defined anywhere"
    return int(found[0].rsplit(":", 1)[1])


def test_the_grep_finds_every_form_of_definition(tmp_path: Path) -> None:
    lines = ["X = 1", "A, X = 1, 2", "X: int = 3", "class X(Enum):", "def X(a):", "  X = 4"]
    pattern_hits = 0
    for line in lines:
        assigned = re.compile(r"^\s*(?:\w+\s*,\s*)*X\s*(?:,\s*\w+\s*)*(?::[^=\n]+)?=(?!=)")
        defined = re.compile(r"^\s*(?:class|def)\s+X\b")
        pattern_hits += bool(assigned.match(line) or defined.match(line))
    assert pattern_hits == len(lines)
    assert not re.match(r"^\s*(?:\w+\s*,\s*)*X\s*(?:,\s*\w+\s*)*(?::[^=\n]+)?=(?!=)", "if X == 1:")


def test_no_literal_copy_of_the_watchdog_code() -> None:
    copies = [
        f"{path.relative_to(SRC)}:{token.start[0]}"
        for path in sources()
        for token in code_tokens(path)
        if token.type == tokenize.NUMBER
        and token.string.lower().startswith("0x")
        and int(token.string, 16) == 0x01038000
    ]
    assert copies == []
    assert constants.WATCHDOG_TRIPPED_CODE == 0x01038000


@pytest.mark.parametrize(
    "text", ["reference", "sdk2020", "DC connected", "on the dock", "wheel stall", "traction lost"]
)
def test_no_string_copy_of_a_profile_or_bit_name(text: str) -> None:
    copies = [
        f"{path.relative_to(SRC)}:{token.start[0]}"
        for path in sources()
        if path not in (HOME, DESCRIBED)
        for token in code_tokens(path)
        if token.type == tokenize.STRING and token.string.strip("\"'") == text
    ]
    assert copies == []


def test_no_size_table_outside_constants() -> None:
    copies = [
        f"{path.relative_to(SRC)}"
        for path in sources()
        if path != HOME and re.search(r"\"CONNECT_BASE\":\s*\d", text_of(path))
    ]
    assert copies == []


def test_the_profile_sizes_are_the_layouts_sizes() -> None:
    sizes = constants.PROFILE_ANSWER_SIZES
    assert sizes[constants.Profile.REFERENCE] == {
        "CONNECT_BASE": 28,
        "SET_V_AND_GET_DEADRECKON": 13,
        "POLL_BASE_CMD": 0,
    }
    assert sizes[constants.Profile.SDK2020] == {
        "CONNECT_BASE": 39,
        "SET_V_AND_GET_DEADRECKON": 17,
        "POLL_BASE_CMD": 2,
    }
    assert ConnectBaseAnswer._REFERENCE_FORM.size == 28 and SetVAndGetDeadreckonAnswer._SDK_FORM.size == 17
