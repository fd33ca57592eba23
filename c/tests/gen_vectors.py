#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Write the shared JSON test vectors (vectors/*.json) as a C header for the C tests.

The C tests never carry copies of the vectors: CMake runs this at build time, whenever a vector
file or this script changes, and test_vectors.c includes the result. The shapes are declared in
vector_types.h. The three files are required: one that is missing, or that does not match the
schema of vectors/README.md, stops the build with a message naming the file or the vector.

Usage: gen_vectors.py --vectors DIR --output FILE
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

# Message fields that the contract writes as hex text; every other string field is text.
HEX_FIELDS = frozenset({"filler", "data", "blob"})
DEFAULT_MAX_FRAME = 65539


class VectorError(Exception):
    """A vector that does not follow the schema."""


def parse_hex(text: Any, where: str) -> bytes:
    if not isinstance(text, str):
        raise VectorError(f"{where}: expected hex text, got {text!r}")
    try:
        return bytes.fromhex(text.replace(" ", "").replace("\n", ""))
    except ValueError as exc:
        raise VectorError(f"{where}: bad hex {text!r} ({exc})") from None


def require(obj: dict[str, Any], key: str, kind: type | tuple[type, ...], where: str) -> Any:
    if key not in obj:
        raise VectorError(f"{where}: missing {key!r}")
    value = obj[key]
    if not isinstance(value, kind) or (kind is int and isinstance(value, bool)):
        raise VectorError(f"{where}: {key!r} has the wrong type ({value!r})")
    return value


def optional_int(obj: dict[str, Any], key: str, default: int, where: str) -> int:
    if obj.get(key) is None:
        return default
    return int(require(obj, key, int, where))


def c_string(text: str) -> str:
    out = []
    for byte in text.encode("utf-8"):
        char = chr(byte)
        if char in '"\\?' or not 0x20 <= byte < 0x7F:
            out.append(f"\\{byte:03o}")  # octal: never swallows the next character, no trigraphs
        else:
            out.append(char)
    return '"' + "".join(out) + '"'


def c_opt_string(text: str | None) -> str:
    return "NULL" if text is None else c_string(text)


def c_bool(value: bool) -> str:
    return "true" if value else "false"


class Emitter:
    """Collects static arrays and returns the C expressions that refer to them."""

    def __init__(self) -> None:
        self.lines: list[str] = []
        self.count = 0

    def _name(self, prefix: str) -> str:
        self.count += 1
        return f"{prefix}_{self.count}"

    def bytes(self, data: bytes) -> str:
        if not data:
            return "{NULL, 0}"
        name = self._name("vec_bytes")
        body = ", ".join(f"0x{b:02X}" for b in data)
        self.lines.append(f"static const uint8_t {name}[{len(data)}] = {{{body}}};")
        return f"{{{name}, {len(data)}}}"

    def array(self, ctype: str, items: list[str]) -> tuple[str, int]:
        if not items:
            return "NULL", 0
        name = self._name("vec_items")
        self.lines.append(f"static const {ctype} {name}[{len(items)}] = {{")
        self.lines.extend(f"    {item}," for item in items)
        self.lines.append("};")
        return name, len(items)


def flatten(path: str, value: Any, out: list[tuple[str, Any]]) -> None:
    if isinstance(value, dict):
        for key, item in value.items():
            flatten(f"{path}.{key}" if path else key, item, out)
    elif isinstance(value, list):
        for index, item in enumerate(value):
            flatten(f"{path}[{index}]", item, out)
    else:
        out.append((path, value))


def leaf_name(path: str) -> str:
    return path.rsplit(".", 1)[-1].split("[", 1)[0]


def emit_fields(em: Emitter, fields: Any, where: str) -> tuple[str, int]:
    if fields is None:
        return "NULL", 0
    if not isinstance(fields, dict):
        raise VectorError(f"{where}: 'fields' must be an object")
    leaves: list[tuple[str, Any]] = []
    flatten("", fields, leaves)
    items = []
    for path, value in leaves:
        if value is None:
            items.append(f"{{{c_string(path)}, VEC_NULL, 0, NULL, {{NULL, 0}}}}")
        elif isinstance(value, int):  # bool included
            items.append(f"{{{c_string(path)}, VEC_INT, {int(value)}LL, NULL, {{NULL, 0}}}}")
        elif isinstance(value, str) and leaf_name(path) in HEX_FIELDS:
            data = em.bytes(parse_hex(value, f"{where}: field {path}"))
            items.append(f"{{{c_string(path)}, VEC_BYTES, 0, NULL, {data}}}")
        elif isinstance(value, str):
            items.append(f"{{{c_string(path)}, VEC_TEXT, 0, {c_string(value)}, {{NULL, 0}}}}")
        else:
            raise VectorError(f"{where}: field {path} has an unsupported value {value!r}")
    return em.array("vec_field_t", items)


def emit_expected_frames(em: Emitter, frames: Any, where: str) -> tuple[str, int]:
    if frames is None:
        return "NULL", 0
    if not isinstance(frames, list):
        raise VectorError(f"{where}: frames must be a list")
    items = []
    for i, frame in enumerate(frames):
        at = f"{where} frame {i}"
        is_long = require(frame, "long", bool, at)
        cmd = require(frame, "cmd", int, at)
        payload = em.bytes(parse_hex(frame.get("payload", ""), f"{at} payload"))
        items.append(f"{{{c_bool(is_long)}, {cmd}, {payload}}}")
    return em.array("vec_expected_frame_t", items)


def emit_expect(em: Emitter, frames: Any, events: Any, counters: Any, where: str) -> str:
    frames_ref, frame_count = emit_expected_frames(em, frames, where)
    events_given = events is not None
    if events_given and not (isinstance(events, list) and all(isinstance(e, str) for e in events)):
        raise VectorError(f"{where}: events must be a list of names")
    events_ref, event_count = em.array("char *const", [c_string(e) for e in events] if events_given else [])
    if counters is None:
        counters = {}
    if not isinstance(counters, dict) or not all(
        isinstance(v, int) and not isinstance(v, bool) for v in counters.values()
    ):
        raise VectorError(f"{where}: counters must map names to integers")
    counters_ref, counter_count = em.array(
        "vec_counter_t", [f"{{{c_string(k)}, {v}LL}}" for k, v in counters.items()]
    )
    return (
        f"{{{frames_ref}, {frame_count}, {c_bool(events_given)}, {events_ref}, {event_count}, "
        f"{counters_ref}, {counter_count}}}"
    )


def optional_bytes(em: Emitter, case: dict[str, Any], key: str, where: str) -> tuple[bool, str]:
    """Whether case has hex text under key, and the C expression of its bytes."""
    if case.get(key) is None:
        return False, "{NULL, 0}"
    return True, em.bytes(parse_hex(case[key], f"{where} {key}"))


def load(path: Path) -> Any:
    try:
        with path.open(encoding="utf-8") as handle:
            return json.load(handle)
    except json.JSONDecodeError as exc:
        raise VectorError(f"{path}: not valid JSON ({exc})") from None


def cases(doc: Any, key: str, path: Path) -> list[dict[str, Any]]:
    items = doc.get(key, []) if isinstance(doc, dict) else None
    if not isinstance(items, list) or not all(isinstance(item, dict) for item in items):
        raise VectorError(f"{path}: {key!r} must be a list of objects")
    return items


def vector_name(case: dict[str, Any], where: str) -> str:
    return str(require(case, "name", str, where))


def gen_frames(em: Emitter, path: Path) -> list[str]:
    items = []
    for index, case in enumerate(cases(load(path), "frames", path)):
        where = f"{path.name} frames[{index}]"
        name = vector_name(case, where)
        where = f"{path.name} {name}"
        wire = em.bytes(parse_hex(require(case, "hex", str, where), f"{where} hex"))
        is_long = require(case, "long", bool, where)
        cmd = require(case, "cmd", int, where)
        payload = em.bytes(parse_hex(case.get("payload", ""), f"{where} payload"))
        message = case.get("message")
        kind = msg_name = to = None
        fields_ref, field_count = "NULL", 0
        if message is not None:
            if not isinstance(message, dict):
                raise VectorError(f"{where}: message must be an object")
            kind = require(message, "kind", str, where)
            msg_name = require(message, "name", str, where)
            to = message.get("to")
            if kind == "answer" and not isinstance(to, str):
                raise VectorError(f"{where}: an answer needs 'to'")
            fields_ref, field_count = emit_fields(em, message.get("fields", {}), where)
        items.append(
            f"{{{c_string(name)}, {wire}, {c_bool(is_long)}, {cmd}, {payload}, "
            f"{c_opt_string(kind)}, {c_opt_string(msg_name)}, {c_opt_string(to)}, "
            f"{fields_ref}, {field_count}}}"
        )
    return items


def gen_invalid(em: Emitter, path: Path) -> tuple[list[str], list[str]]:
    doc = load(path)
    frame_items = []
    for index, case in enumerate(cases(doc, "frame_level", path)):
        name = vector_name(case, f"{path.name} frame_level[{index}]")
        where = f"{path.name} {name}"
        data = em.bytes(parse_hex(require(case, "hex", str, where), f"{where} hex"))
        expect = require(case, "expect", dict, where)
        expect_ref = emit_expect(
            em, expect.get("frames", []), expect.get("events"), expect.get("counters"), where
        )
        has_answer, answer = optional_bytes(em, case, "base_answer", where)
        frame_items.append(
            f"{{{c_string(name)}, {data}, {optional_int(case, 'timeout_ms', 0, where)}u, "
            f"{optional_int(case, 'max_frame', DEFAULT_MAX_FRAME, where)}u, {expect_ref}, "
            f"{c_bool(has_answer)}, {answer}}}"
        )
    message_items = []
    for index, case in enumerate(cases(doc, "message_level", path)):
        name = vector_name(case, f"{path.name} message_level[{index}]")
        where = f"{path.name} {name}"
        direction = require(case, "direction", str, where)
        to = case.get("to")
        if direction == "answer" and not isinstance(to, str):
            raise VectorError(f"{where}: an answer needs 'to'")
        payload = em.bytes(parse_hex(case.get("payload", ""), f"{where} payload"))
        has_answer, answer = optional_bytes(em, case, "base_answer", where)
        message_items.append(
            f"{{{c_string(name)}, {c_string(direction)}, {c_opt_string(to)}, "
            f"{c_bool(bool(case.get('long', False)))}, {require(case, 'cmd', int, where)}, "
            f"{payload}, {c_string(require(case, 'expect_error', str, where))}, "
            f"{c_bool(has_answer)}, {answer}}}"
        )
    return frame_items, message_items


def gen_streams(em: Emitter, path: Path) -> list[str]:
    items = []
    for index, case in enumerate(cases(load(path), "streams", path)):
        name = vector_name(case, f"{path.name} streams[{index}]")
        where = f"{path.name} {name}"
        chunks = require(case, "chunks", list, where)
        chunk_items = []
        for i, chunk in enumerate(chunks):
            at = f"{where} chunk {i}"
            if not isinstance(chunk, dict):
                raise VectorError(f"{at}: must be an object")
            data = em.bytes(parse_hex(require(chunk, "hex", str, at), at))
            chunk_items.append(f"{{{optional_int(chunk, 't_ms', 0, at)}u, {data}}}")
        chunks_ref, chunk_count = em.array("vec_chunk_t", chunk_items)
        expect_ref = emit_expect(
            em,
            require(case, "expect_frames", list, where),
            case.get("expect_events"),
            case.get("expect_counters"),
            where,
        )
        has_idle = case.get("final_idle_ms") is not None
        items.append(
            f"{{{c_string(name)}, {optional_int(case, 'max_frame', DEFAULT_MAX_FRAME, where)}u, "
            f"{optional_int(case, 'timeout_ms', 0, where)}u, {chunks_ref}, {chunk_count}, "
            f"{c_bool(has_idle)}, {optional_int(case, 'final_idle_ms', 0, where)}u, {expect_ref}}}"
        )
    return items


def table(em: Emitter, ctype: str, name: str, items: list[str]) -> None:
    ref, count = em.array(ctype, items)
    em.lines.append(f"static const {ctype} *const {name} = {ref};")
    em.lines.append(f"static const size_t {name}_COUNT = {count};")


def generate(vectors: Path) -> str:
    em = Emitter()
    for name in ("frames.json", "invalid.json", "streams.json"):
        if not (vectors / name).is_file():
            raise VectorError(f"{vectors / name} is missing: the C tests need every shared vector file")
    frames = gen_frames(em, vectors / "frames.json")
    frame_level, message_level = gen_invalid(em, vectors / "invalid.json")
    streams = gen_streams(em, vectors / "streams.json")
    sources = ["frames.json", "invalid.json", "streams.json"]
    table(em, "vec_frame_t", "VEC_FRAMES", frames)
    table(em, "vec_frame_level_t", "VEC_FRAME_LEVEL", frame_level)
    table(em, "vec_message_level_t", "VEC_MESSAGE_LEVEL", message_level)
    table(em, "vec_stream_t", "VEC_STREAMS", streams)
    header = [
        "/* Generated by c/tests/gen_vectors.py from "
        + ", ".join(sources)
        + ". Do not edit. */",
        "#ifndef CTRLBUS_VECTORS_H",
        "#define CTRLBUS_VECTORS_H",
        '#include "vector_types.h"',
        "",
    ]
    return "\n".join(header + em.lines + ["", "#endif", ""])


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vectors", required=True, type=Path, help="directory of the JSON files")
    parser.add_argument("--output", required=True, type=Path, help="header to write")
    args = parser.parse_args()
    try:
        text = generate(args.vectors)
    except VectorError as exc:
        print(f"gen_vectors.py: {exc}", file=sys.stderr)
        return 2
    args.output.parent.mkdir(parents=True, exist_ok=True)
    if not args.output.exists() or args.output.read_text(encoding="utf-8") != text:
        args.output.write_text(text, encoding="utf-8")
    else:
        args.output.touch()  # up to date for the build tool even when nothing changed
    return 0


if __name__ == "__main__":
    sys.exit(main())
