# SPDX-License-Identifier: MIT
"""The binary configuration tree of GET_BASE_CONF_ADV (0x21): blob <-> JSON, losslessly.

The blob is a typed tree (reference §5, 0x21): each entry is `key (u8 dictionary id), type (u8),
value`, and the root is an object written without a key. The JSON form keeps everything the bytes
say, so that `encode(decode(blob)) == blob` for every valid blob and `decode(encode(tree)) == tree`
for every accepted tree (floats excepted: see below). docs/binary-config.md is the user's manual of
the mapping; in short:

| wire type            | JSON                                                             |
|----------------------|------------------------------------------------------------------|
| 0x50 object          | JSON object; keys are dictionary names, `0x99` for unknown ids,  |
|                      | `name#2`, `name#3`... for repeated keys; member order is kept    |
| 0x40 array           | JSON array                                                       |
| 0x60 / 0x61          | `true` / `false`                                                 |
| 0x20 float32         | a JSON number written with a point or exponent (`0.35`, `1.0`);  |
|                      | non-finite values `{"f32_bits": "0x7fc00000"}`                   |
| 0x10 / 0x11 / 0x1A   | `{"u8": 5}` / `{"u16": 600}` / `{"s32": -1}`                     |
| 0x30 string          | JSON string (UTF-8); bytes that are not UTF-8 `{"bytes": "C3 28"}` |
| 0x31 dictionary id   | `{"dict": "sonar"}`, `{"dict": "0x99"}` for unknown ids          |

Floats: decode prints the shortest decimal that gives the same float32 bits back; encode rounds any
decimal to the nearest float32. A decimal with more digits than a float32 holds therefore comes
back shortened (`3.14159265` -> `3.1415927`); every other accepted spelling comes back unchanged,
because the encoder accepts only the spellings decode produces.
"""

from __future__ import annotations

import json
import math
import re
import struct
from collections.abc import Mapping
from importlib import resources
from typing import TypeAlias

from ctrlbus.errors import BinaryConfigError

__all__ = [
    "DICTIONARY",
    "DICTIONARY_IDS",
    "EXAMPLE_CONFIG_FILE",
    "INT_TAGS",
    "MAX_DEPTH",
    "REFERENCE_MAX_BLOB",
    "SCALAR_TAGS",
    "TAG_BYTES",
    "TAG_DICT",
    "TAG_F32_BITS",
    "TYPE_ARRAY",
    "TYPE_DICT_STRING",
    "TYPE_F32",
    "TYPE_FALSE",
    "TYPE_OBJECT",
    "TYPE_S32",
    "TYPE_STRING",
    "TYPE_TRUE",
    "TYPE_U8",
    "TYPE_U16",
    "JsonValue",
    "decode",
    "dump_json",
    "encode",
    "example_blob",
    "example_config",
    "example_config_text",
    "float32_bits",
    "id_spelling",
    "load_json",
    "parse_id_spelling",
    "shortest_float32",
]

JsonValue: TypeAlias = "bool | int | float | str | list[JsonValue] | dict[str, JsonValue] | None"

TYPE_U8 = 0x10
TYPE_U16 = 0x11
TYPE_S32 = 0x1A
TYPE_F32 = 0x20
TYPE_STRING = 0x30
TYPE_DICT_STRING = 0x31
TYPE_ARRAY = 0x40
TYPE_OBJECT = 0x50
TYPE_TRUE = 0x60
TYPE_FALSE = 0x61

# Deepest nesting of objects and arrays (the root object counts as 1). Real configurations nest
# about 4 deep; the bound keeps a hostile blob or JSON file from exhausting the stack.
MAX_DEPTH = 32
# Largest blob the reference base can send: its 512-byte transmit buffer minus the long-frame
# header, CMD and checksum (reference §4).
REFERENCE_MAX_BLOB = 507

# Dictionary ids with the names of reference §5 (names of medium confidence).
DICTIONARY: Mapping[int, str] = {
    0x00: "base",
    0x01: "manufacture_id",
    0x02: "manufacture_name",
    0x03: "model_id",
    0x04: "model_name",
    0x05: "hardware_version",
    0x06: "robot_size",
    0x07: "low_battery_percentage_for_charging",
    0x08: "high_battery_percentage_for_charging",
    0x09: "low_battery_auto_homing",
    0x0A: "sensors",
    0x0B: "type",
    0x0C: "bumper",
    0x0D: "installation_pose",
    0x0E: "x",
    0x0F: "y",
    0x10: "z",
    0x11: "yaw",
    0x14: "cliff",
    0x15: "sonar",
    0x16: "feature",
    0x17: "has_ir_docking_tower",
    0x18: "lidar",
    0x19: "id",
    0x1A: "motion_plan",
    0x1B: "bump_handle_strategy",
    0x1C: "default",
    0x1E: "side_margin",
    0x1F: "docking",
    0x21: "backward_docking",
    0x22: "docking_method",
    0x23: "landing_offset",
    0x24: "laserpattern",
    0x26: "head_up",
    0x27: "slamware_core_pose",
    0x28: "wheel_span",
    0x29: "reverse_installation",
    0x2E: "dock_center_line_length",
    0x2F: "hibernate_time",
    0x30: "dock_depth",
    0x31: "dock_inner_line_length",
    0x32: "dock_side_line_length",
    0x3A: "depth_camera",
    0x3B: "driver",
    0x3C: "max_distance",
    0x3D: "min_distance",
    0x44: "enable_use_filter",
    0x45: "enable_use_morphology_filter",
    0x46: "inversion",
    0x47: "min_filter_height",
    0x48: "max_filter_height",
}
DICTIONARY_IDS: Mapping[str, int] = {name: ident for ident, name in DICTIONARY.items()}

# Tags of the one-member JSON objects that stand for a scalar. None of them may be a dictionary
# name, or a one-member object would be ambiguous (checked below and in the tests).
INT_TAGS: Mapping[str, tuple[int, int, int, str]] = {
    # tag: (type code, lowest, highest, struct format)
    "u8": (TYPE_U8, 0, 0xFF, "<B"),
    "u16": (TYPE_U16, 0, 0xFFFF, "<H"),
    "s32": (TYPE_S32, -(2**31), 2**31 - 1, "<i"),
}
TAG_DICT = "dict"
TAG_F32_BITS = "f32_bits"
TAG_BYTES = "bytes"
SCALAR_TAGS = frozenset([*INT_TAGS, TAG_DICT, TAG_F32_BITS, TAG_BYTES])
assert not SCALAR_TAGS & set(DICTIONARY_IDS), "a scalar tag must never be a dictionary name"

_INT_TAG_BY_TYPE = {code: tag for tag, (code, _, _, _) in INT_TAGS.items()}
_UNKNOWN_ID = re.compile(r"0x[0-9a-f]{2}")
_KEY = re.compile(r"(?P<name>[^#]+)(?:#(?P<occurrence>[1-9][0-9]*))?")
_F32_BITS = re.compile(r"0x[0-9a-f]{8}")
_HEX_PAIRS = re.compile(r"[0-9A-F]{2}(?: [0-9A-F]{2})*")

# Inside the ctrlbus package (data/ is a plain directory, not a package of its own).
EXAMPLE_CONFIG_FILE = "base-config.json"


# ---------------------------------------------------------------------------------------------
# Shared helpers


def id_spelling(ident: int) -> str:
    """The JSON spelling of a dictionary id: its name if known, else `0x99`."""
    return DICTIONARY.get(ident, f"0x{ident:02x}")


def parse_id_spelling(spelling: str) -> int | None:
    """The dictionary id a JSON spelling stands for, or None if it is neither a name nor `0x99`
    for an unknown id (a known id spelled as a number is refused: decode would print its name)."""
    ident = DICTIONARY_IDS.get(spelling)
    if ident is not None:
        return ident
    if _UNKNOWN_ID.fullmatch(spelling):
        number = int(spelling, 16)
        if number not in DICTIONARY:
            return number
    return None


def _id_spelling_hint(spelling: str) -> str:
    if _UNKNOWN_ID.fullmatch(spelling.lower()) and int(spelling, 16) in DICTIONARY:
        return f"; {spelling} is the id of {DICTIONARY[int(spelling, 16)]!r}, write that name"
    if spelling.lower().startswith("0x"):
        return "; write unknown ids as 0x and two lowercase hex digits, like 0x9a"
    return ""


def float32_bits(value: float) -> int:
    """The bits of the float32 nearest to `value` (OverflowError beyond the float32 range)."""
    packed: int = struct.unpack("<I", struct.pack("<f", value))[0]
    return packed


def shortest_float32(bits: int) -> float:
    """The float with the shortest decimal repr that rounds to the float32 `bits` (finite only)."""
    value: float = struct.unpack("<f", struct.pack("<I", bits))[0]
    for digits in range(1, 10):
        candidate = float(f"{value:.{digits}g}")
        if float32_bits(candidate) == bits:
            return candidate
    return value  # the exact value always round-trips


def _is_finite_bits(bits: int) -> bool:
    return (bits >> 23) & 0xFF != 0xFF


# ---------------------------------------------------------------------------------------------
# Decoding


class _Reader:
    def __init__(self, blob: bytes) -> None:
        self.blob = blob
        self.pos = 0

    def remaining(self) -> int:
        return len(self.blob) - self.pos

    def take(self, count: int, what: str) -> bytes:
        if self.remaining() < count:
            raise BinaryConfigError(
                f"blob truncated at offset {self.pos}: {what} needs {count} byte(s), {self.remaining()} left",
                offset=self.pos,
            )
        chunk = self.blob[self.pos : self.pos + count]
        self.pos += count
        return chunk

    def byte(self, what: str) -> int:
        return self.take(1, what)[0]


def decode(blob: bytes) -> dict[str, JsonValue]:
    """Decode a binary configuration blob into its JSON tree (see the module doc).

    Raises BinaryConfigError (with the byte offset) for an empty or truncated blob, an unknown
    type code, a count larger than the remaining bytes can hold, nesting deeper than MAX_DEPTH,
    a root that is not an object, or bytes after the root object.
    """
    reader = _Reader(bytes(blob))
    if not blob:
        raise BinaryConfigError("empty blob (offset 0): a configuration is an object (type 0x50)", offset=0)
    root_type = reader.byte("the root type")
    if root_type != TYPE_OBJECT:
        raise BinaryConfigError(
            f"the root must be an object (type 0x50), found type 0x{root_type:02x} at offset 0",
            offset=0,
        )
    root = _decode_object(reader, depth=1, start=0)
    if reader.remaining():
        raise BinaryConfigError(
            f"{reader.remaining()} trailing byte(s) after the root object, at offset {reader.pos}",
            offset=reader.pos,
        )
    return root


def _decode_value(reader: _Reader, type_code: int, depth: int, start: int) -> JsonValue:
    """The value of type `type_code` (its type byte at `start` already read)."""
    if type_code in _INT_TAG_BY_TYPE:
        tag = _INT_TAG_BY_TYPE[type_code]
        fmt = INT_TAGS[tag][3]
        number: int = struct.unpack(fmt, reader.take(struct.calcsize(fmt), f"a {tag}"))[0]
        return {tag: number}
    if type_code == TYPE_F32:
        bits: int = struct.unpack("<I", reader.take(4, "a float32"))[0]
        if _is_finite_bits(bits):
            return shortest_float32(bits)
        return {TAG_F32_BITS: f"0x{bits:08x}"}
    if type_code == TYPE_STRING:
        length = reader.byte("a string length")
        raw = reader.take(length, f"a string of {length} bytes")
        try:
            return raw.decode("utf-8")
        except UnicodeDecodeError:
            return {TAG_BYTES: raw.hex(" ").upper()}
    if type_code == TYPE_DICT_STRING:
        return {TAG_DICT: id_spelling(reader.byte("a dictionary id"))}
    if type_code == TYPE_TRUE:
        return True
    if type_code == TYPE_FALSE:
        return False
    if type_code in (TYPE_ARRAY, TYPE_OBJECT):
        if depth + 1 > MAX_DEPTH:
            raise BinaryConfigError(f"nesting deeper than {MAX_DEPTH} levels at offset {start}", offset=start)
        if type_code == TYPE_ARRAY:
            return _decode_array(reader, depth + 1, start)
        return _decode_object(reader, depth + 1, start)
    raise BinaryConfigError(f"unknown type code 0x{type_code:02x} at offset {start}", offset=start)


def _check_count(reader: _Reader, count: int, min_size: int, what: str, start: int) -> None:
    if count * min_size > reader.remaining():
        raise BinaryConfigError(
            f"{what} at offset {start} claims {count} entries but only {reader.remaining()} "
            f"byte(s) remain (each needs at least {min_size})",
            offset=start,
        )


def _decode_array(reader: _Reader, depth: int, start: int) -> list[JsonValue]:
    count = reader.byte("an array count")
    _check_count(reader, count, 1, "array", start)
    values: list[JsonValue] = []
    for _ in range(count):
        value_start = reader.pos
        type_code = reader.byte("a value type")
        values.append(_decode_value(reader, type_code, depth, value_start))
    return values


def _decode_object(reader: _Reader, depth: int, start: int) -> dict[str, JsonValue]:
    count = reader.byte("an object count")
    _check_count(reader, count, 2, "object", start)
    members: dict[str, JsonValue] = {}
    occurrences: dict[str, int] = {}
    for _ in range(count):
        name = id_spelling(reader.byte("a key"))
        seen = occurrences.get(name, 0) + 1
        occurrences[name] = seen
        key = name if seen == 1 else f"{name}#{seen}"
        value_start = reader.pos
        type_code = reader.byte("a value type")
        members[key] = _decode_value(reader, type_code, depth, value_start)
    return members


# ---------------------------------------------------------------------------------------------
# Encoding


def encode(tree: object) -> bytes:
    """Encode a JSON tree (as decode returns it, see the module doc) into a blob.

    Raises BinaryConfigError naming the place in the tree (`base.sensors[2].id`) for anything that
    has no binary form: a bare integer (its wire type must be given), null, a key that is not a
    dictionary name, a value out of range, a container of more than 255 entries, a string of more
    than 255 bytes, nesting deeper than MAX_DEPTH, or a root that is not an object.
    """
    if not isinstance(tree, dict) or _scalar_tag(tree) is not None:
        raise BinaryConfigError("the root of a configuration must be a JSON object", path="(root)")
    out = bytearray([TYPE_OBJECT])
    _encode_object(tree, out, depth=1, path="")
    return bytes(out)


def _where(path: str) -> str:
    return path or "(root)"


def _fail(path: str, message: str) -> BinaryConfigError:
    return BinaryConfigError(f"at {_where(path)}: {message}", path=_where(path))


def _scalar_tag(value: dict[object, object]) -> str | None:
    if len(value) == 1:
        (key,) = value
        if isinstance(key, str) and key in SCALAR_TAGS:
            return key
    return None


def _encode_value(value: object, out: bytearray, depth: int, path: str) -> None:
    """Append the type byte and the value."""
    if isinstance(value, bool):
        out.append(TYPE_TRUE if value else TYPE_FALSE)
    elif isinstance(value, float):
        if not math.isfinite(value):
            raise _fail(path, 'write a non-finite float32 as {"f32_bits": "0x7f800000"}')
        try:
            bits = float32_bits(value)
        except OverflowError:
            raise _fail(path, f"{value!r} is outside the float32 range") from None
        out.append(TYPE_F32)
        out += struct.pack("<I", bits)
    elif isinstance(value, int):
        raise _fail(
            path,
            f'a bare integer has no wire type: write {{"u8": {value}}}, {{"u16": {value}}}, '
            f'{{"s32": {value}}}, or {value}.0 for a float32',
        )
    elif isinstance(value, str):
        raw = _utf8(value, path)
        out.append(TYPE_STRING)
        _append_string(raw, out, path)
    elif isinstance(value, list):
        _check_depth(depth + 1, path)
        if len(value) > 0xFF:
            raise _fail(path, f"an array holds at most 255 values, this one has {len(value)}")
        out += bytes([TYPE_ARRAY, len(value)])
        for index, item in enumerate(value):
            _encode_value(item, out, depth + 1, f"{path}[{index}]")
    elif isinstance(value, dict):
        tag = _scalar_tag(value)
        if tag is not None:
            _encode_tagged(tag, value[tag], out, path)
        else:
            _check_depth(depth + 1, path)
            out.append(TYPE_OBJECT)
            _encode_object(value, out, depth + 1, path)
    elif value is None:
        raise _fail(path, "null has no binary form")
    else:
        raise _fail(path, f"a {type(value).__name__} has no binary form")


def _check_depth(depth: int, path: str) -> None:
    if depth > MAX_DEPTH:
        raise _fail(path, f"nesting deeper than {MAX_DEPTH} levels")


def _utf8(text: str, path: str) -> bytes:
    try:
        return text.encode("utf-8")
    except UnicodeEncodeError:
        raise _fail(path, "the string is not valid Unicode (lone surrogate)") from None


def _append_string(raw: bytes, out: bytearray, path: str) -> None:
    if len(raw) > 0xFF:
        raise _fail(path, f"a string holds at most 255 bytes, this one has {len(raw)}")
    out.append(len(raw))
    out += raw


def _encode_tagged(tag: str, inner: object, out: bytearray, path: str) -> None:
    if tag in INT_TAGS:
        type_code, lowest, highest, fmt = INT_TAGS[tag]
        if isinstance(inner, bool) or not isinstance(inner, int):
            raise _fail(path, f"{tag} needs an integer, not {json.dumps(inner)}")
        if not lowest <= inner <= highest:
            raise _fail(path, f"{inner} is out of the {tag} range {lowest}..{highest}")
        out.append(type_code)
        out += struct.pack(fmt, inner)
    elif tag == TAG_DICT:
        ident = parse_id_spelling(inner) if isinstance(inner, str) else None
        if ident is None:
            hint = _id_spelling_hint(inner) if isinstance(inner, str) else ""
            raise _fail(
                path, f"{json.dumps(inner)} is not a dictionary name (or 0x99 for an unknown id){hint}"
            )
        out += bytes([TYPE_DICT_STRING, ident])
    elif tag == TAG_F32_BITS:
        if not isinstance(inner, str) or not _F32_BITS.fullmatch(inner):
            raise _fail(path, 'f32_bits needs 0x and 8 lowercase hex digits, like "0x7fc00000"')
        bits = int(inner, 16)
        if _is_finite_bits(bits):
            raise _fail(
                path, f"{inner} is a finite float32: write it as the number {shortest_float32(bits)!r}"
            )
        out.append(TYPE_F32)
        out += struct.pack("<I", bits)
    else:  # TAG_BYTES
        if not isinstance(inner, str) or not (inner == "" or _HEX_PAIRS.fullmatch(inner)):
            raise _fail(path, 'bytes needs uppercase hex pairs separated by spaces, like "C3 28"')
        raw = bytes.fromhex(inner)
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError:
            out.append(TYPE_STRING)
            _append_string(raw, out, path)
        else:
            raise _fail(path, f"these bytes are valid UTF-8: write them as the string {json.dumps(text)}")


def _encode_object(members: dict[object, object], out: bytearray, depth: int, path: str) -> None:
    if len(members) > 0xFF:
        raise _fail(path, f"an object holds at most 255 members, this one has {len(members)}")
    out.append(len(members))
    occurrences: dict[str, int] = {}
    for key, value in members.items():
        member_path = f"{path}.{key}" if path else str(key)
        ident, name = _parse_key(key, occurrences, member_path)
        out.append(ident)
        _encode_value(value, out, depth, member_path)
        occurrences[name] = occurrences.get(name, 0) + 1


def _parse_key(key: object, occurrences: dict[str, int], path: str) -> tuple[int, str]:
    """The dictionary id of an object key, and its name without the `#n` occurrence suffix."""
    match = _KEY.fullmatch(key) if isinstance(key, str) else None
    if match is None:
        raise _fail(path, f"{json.dumps(key)} is not a valid key")
    name = match["name"]
    ident = parse_id_spelling(name)
    if ident is None:
        raise _fail(
            path,
            f"{json.dumps(name)} is not a dictionary name (or 0x99 for an unknown id)"
            f"{_id_spelling_hint(name)}; docs/binary-config.md lists the names",
        )
    expected = occurrences.get(name, 0) + 1
    occurrence = int(match["occurrence"]) if match["occurrence"] else 1
    if occurrence != expected or match["occurrence"] == "1":
        right = name if expected == 1 else f"{name}#{expected}"
        raise _fail(path, f"repeated keys are numbered in order: this key must be spelled {right!r}")
    return ident, name


# ---------------------------------------------------------------------------------------------
# JSON text


def load_json(text: str | bytes) -> JsonValue:
    """Parse JSON text strictly: repeated keys, NaN/Infinity and absurd nesting are errors."""

    def no_repeats(pairs: list[tuple[str, JsonValue]]) -> dict[str, JsonValue]:
        members: dict[str, JsonValue] = {}
        for key, value in pairs:
            if key in members:
                raise BinaryConfigError(
                    f"key {key!r} appears twice in one JSON object; spell the second {key + '#2'!r}"
                )
            members[key] = value
        return members

    def no_constants(name: str) -> JsonValue:
        raise BinaryConfigError(f"{name} is not JSON; write a non-finite float32 with f32_bits")

    try:
        parsed: JsonValue = json.loads(text, object_pairs_hook=no_repeats, parse_constant=no_constants)
    except json.JSONDecodeError as exc:
        raise BinaryConfigError(f"invalid JSON at line {exc.lineno} column {exc.colno}: {exc.msg}") from None
    except UnicodeDecodeError:
        raise BinaryConfigError("the JSON text is not UTF-8") from None
    except RecursionError:
        raise BinaryConfigError(f"the JSON nests too deeply (at most {MAX_DEPTH} levels)") from None
    return parsed


def dump_json(tree: JsonValue, width: int = 100) -> str:
    """JSON text of a tree with a final newline: a container that fits in `width` columns stays on
    one line (so `{"u8": 5}` and a pose read at a glance), larger ones get one member per line."""
    return _dump_value(tree, 0, 0, width) + "\n"


def _dump_value(value: JsonValue, indent: int, column: int, width: int) -> str:
    flat = json.dumps(value, ensure_ascii=False)
    if not isinstance(value, dict | list) or not value or column + len(flat) <= width:
        return flat
    inner = " " * (indent + 2)
    if isinstance(value, list):
        lines = [inner + _dump_value(item, indent + 2, indent + 2, width) for item in value]
        opening, closing = "[", "]"
    else:
        lines = []
        for key, member in value.items():
            prefix = f"{json.dumps(key, ensure_ascii=False)}: "
            lines.append(inner + prefix + _dump_value(member, indent + 2, indent + 2 + len(prefix), width))
        opening, closing = "{", "}"
    return opening + "\n" + ",\n".join(lines) + "\n" + " " * indent + closing


# ---------------------------------------------------------------------------------------------
# The example configuration of the default simulated base (documented in docs/binary-config.md)


def example_config_text() -> str:
    """The text of data/base-config.json."""
    return (resources.files("ctrlbus") / "data" / EXAMPLE_CONFIG_FILE).read_text(encoding="utf-8")


def example_config() -> dict[str, JsonValue]:
    """The example configuration of the default simulated base, as a JSON tree."""
    tree = load_json(example_config_text())
    assert isinstance(tree, dict)
    return tree


def example_blob() -> bytes:
    """The blob of the example configuration (what `ctrlbus sim --binary-config` is typically given)."""
    return encode(example_config())
