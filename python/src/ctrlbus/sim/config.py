# SPDX-License-Identifier: MIT
"""Reading the simulator's JSON description files, with errors that name the file and the key.

Every reader method takes the key, checks presence, type and range, and remembers the key as used;
`finish()` then rejects keys nobody asked for, so a typo ("radius_m") is an error rather than a
silently ignored setting. Keys starting with "_" are comments and are skipped.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

from ctrlbus.errors import SimConfigError
from ctrlbus.sim.geometry import Point

__all__ = [
    "ConfigReader",
    "load_json_file",
    "parse_json_text",
    "unique_names",
]

_MISSING = object()


def load_json_file(path: str | Path) -> tuple[Any, str]:
    """Parse a JSON file; returns (data, name to use in error messages)."""
    source = str(path)
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise SimConfigError(f"cannot read {source}: {exc}") from None
    return parse_json_text(text, source), source


def parse_json_text(text: str, source: str) -> Any:
    def reject_constant(name: str) -> Any:
        raise SimConfigError(f"{source}: {name} is not a valid number in a description")

    try:
        return json.loads(text, parse_constant=reject_constant)
    except json.JSONDecodeError as exc:
        raise SimConfigError(
            f"{source}: not valid JSON: {exc.msg} (line {exc.lineno} column {exc.colno})"
        ) from None


def _describe(value: object) -> str:
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, dict):
        return "an object"
    if isinstance(value, list):
        return "a list"
    if isinstance(value, str):
        return repr(value)
    return str(value)


class ConfigReader:
    """One JSON object of a description, read key by key."""

    def __init__(self, data: object, path: str, source: str) -> None:
        if not isinstance(data, dict):
            where = path or "top level"
            raise SimConfigError(f"{source}: {where}: expected an object, got {_describe(data)}")
        self._data: dict[str, Any] = data
        self._path = path
        self._source = source
        self._used: set[str] = set()

    @property
    def source(self) -> str:
        return self._source

    def key_path(self, key: str) -> str:
        return f"{self._path}.{key}" if self._path else key

    def error(self, key: str, message: str) -> SimConfigError:
        """An error about `key` of this object (use "" for the object itself)."""
        where = self.key_path(key) if key else (self._path or "top level")
        return SimConfigError(f"{self._source}: {where}: {message}")

    def has(self, key: str) -> bool:
        return key in self._data

    def _get(self, key: str, default: object) -> object:
        self._used.add(key)
        if key in self._data:
            return self._data[key]
        if default is _MISSING:
            raise self.error(key, "missing required key")
        return default

    def number(
        self,
        key: str,
        default: float | None = None,
        *,
        minimum: float | None = None,
        maximum: float | None = None,
        positive: bool = False,
    ) -> float:
        value = self._get(key, _MISSING if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int | float):
            raise self.error(key, f"expected a number, got {_describe(value)}")
        number = float(value)
        if not math.isfinite(number):
            raise self.error(key, "expected a finite number")
        if positive and number <= 0.0:
            raise self.error(key, f"must be greater than 0, got {_describe(value)}")
        if minimum is not None and number < minimum:
            raise self.error(key, f"must be at least {minimum:g}, got {_describe(value)}")
        if maximum is not None and number > maximum:
            raise self.error(key, f"must be at most {maximum:g}, got {_describe(value)}")
        return number

    def angle(self, key: str, default: float | None = None) -> float:
        """An angle in degrees, anticlockwise, 0..360 as the wire's positions are."""
        return self.number(key, default, minimum=0.0, maximum=360.0)

    def integer(
        self, key: str, default: int | None = None, *, minimum: int | None = None, maximum: int | None = None
    ) -> int:
        value = self._get(key, _MISSING if default is None else default)
        if isinstance(value, bool) or not isinstance(value, int):
            raise self.error(key, f"expected an integer, got {_describe(value)}")
        if minimum is not None and value < minimum:
            raise self.error(key, f"must be at least {minimum}, got {value}")
        if maximum is not None and value > maximum:
            raise self.error(key, f"must be at most {maximum}, got {value}")
        return value

    def string(self, key: str, default: str | None = None, *, choices: tuple[str, ...] = ()) -> str:
        value = self._get(key, _MISSING if default is None else default)
        if not isinstance(value, str):
            raise self.error(key, f"expected a string, got {_describe(value)}")
        if choices and value not in choices:
            raise self.error(key, f"must be one of {', '.join(choices)}; got {value!r}")
        return value

    def boolean(self, key: str, default: bool | None = None) -> bool:
        value = self._get(key, _MISSING if default is None else default)
        if not isinstance(value, bool):
            raise self.error(key, f"expected true or false, got {_describe(value)}")
        return value

    def child(self, key: str) -> ConfigReader:
        """The object under `key` (required)."""
        return ConfigReader(self._get(key, _MISSING), self.key_path(key), self._source)

    def optional_child(self, key: str) -> ConfigReader | None:
        """The object under `key`, or None when it is absent or null."""
        value = self._get(key, None)
        return None if value is None else ConfigReader(value, self.key_path(key), self._source)

    def children(self, key: str, *, max_count: int, required: bool = False) -> list[ConfigReader]:
        """The objects of the list under `key` (an empty list when optional and absent)."""
        value = self._get(key, _MISSING if required else [])
        if not isinstance(value, list):
            raise self.error(key, f"expected a list, got {_describe(value)}")
        if len(value) > max_count:
            raise self.error(key, f"at most {max_count} entries, got {len(value)}")
        return [
            ConfigReader(item, f"{self.key_path(key)}[{index}]", self._source)
            for index, item in enumerate(value)
        ]

    def points(self, key: str, *, min_count: int) -> tuple[Point, ...]:
        """A list of [x_mm, y_mm] pairs."""
        value = self._get(key, _MISSING)
        if not isinstance(value, list):
            raise self.error(key, f"expected a list of [x, y] points, got {_describe(value)}")
        if len(value) < min_count:
            raise self.error(key, f"needs at least {min_count} points, got {len(value)}")
        points: list[Point] = []
        for index, item in enumerate(value):
            valid = (
                isinstance(item, list)
                and len(item) == 2
                and all(
                    isinstance(c, int | float) and not isinstance(c, bool) and math.isfinite(c) for c in item
                )
            )
            if not valid:
                raise self.error(f"{key}[{index}]", f"expected [x_mm, y_mm], got {_describe(item)}")
            points.append((float(item[0]), float(item[1])))
        return tuple(points)

    def finish(self) -> None:
        """Reject keys that were never read (typos, settings this version does not know)."""
        for key in self._data:
            if key not in self._used and not key.startswith("_"):
                raise self.error(key, "unknown key")


def unique_names(readers: list[ConfigReader], names: list[str], key: str = "name") -> None:
    """Reject two entries of one list with the same name."""
    seen: set[str] = set()
    for reader, name in zip(readers, names, strict=True):
        if name in seen:
            raise reader.error(key, f"duplicate name {name!r}")
        seen.add(name)
