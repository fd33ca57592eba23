#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Write every table that comes from the protocol description (protocol/ctrlbus.json).

`make generate` runs this with no arguments: it rewrites the generated files and the blocks
between `BEGIN GENERATED <name>` / `END GENERATED <name>` markers in hand-written ones (C layout
tables, answer structs and decoders; Python tables; Wireshark and sigrok tables; protocol.md
tables). Standard library only, so that nothing but Python 3.10 is needed.

    python3 scripts/generate_protocol.py             # rewrite in place
    python3 scripts/generate_protocol.py --out DIR   # write the would-be files under DIR instead
    python3 scripts/generate_protocol.py --check     # exit 1 naming each file that is out of date

The description is reviewed by hand; this script never reads an implementation.
"""

from __future__ import annotations

import argparse
import ast
import json
import re
import sys
import textwrap
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

REPO = Path(__file__).resolve().parent.parent
DESCRIPTION = Path("protocol/ctrlbus.json")
COMMAND = "make generate"
WIDTHS = {"u8": 1, "u16": 2, "u32": 4, "s32": 4}
C_TYPES = {"u8": "uint8_t", "u16": "uint16_t", "u32": "uint32_t", "s32": "int32_t"}
C_KINDS = {1: "FIELD_U8", 2: "FIELD_U16", 4: "FIELD_U32"}


class DescriptionError(Exception):
    """The description breaks a rule of its own format."""


def number(value: int | str) -> int:
    """A number of the description: an int, or hexadecimal text like "0x10"."""
    return value if isinstance(value, int) else int(value, 0)


# --- the description, read once --------------------------------------------------------------


@dataclass(frozen=True)
class Field:
    """One field of a request or answer as the description gives it."""

    name: str
    type: str  # u8 u16 u32 s32 text bytes, or a struct name
    count: int  # array items (1: a scalar), text bytes, or 0 for bytes
    raw: dict[str, Any]
    struct_words: int = 0  # 32-bit words of one item of a struct type

    @property
    def optional(self) -> bool:
        return bool(self.raw.get("optional"))

    @property
    def is_array(self) -> bool:
        return "count" in self.raw and self.type != "text"

    @property
    def doc(self) -> str:
        return str(self.raw.get("doc", ""))

    @property
    def width(self) -> int:
        """Bytes of one wire item; 4 for a struct item's words; 0 for text and bytes."""
        return 4 if self.struct_words else WIDTHS.get(self.type, 0)

    @property
    def wire_size(self) -> int:
        if self.type == "bytes":
            return 0
        if self.type == "text":
            return self.count
        return self.count * (self.struct_words * 4 if self.struct_words else self.width)


@dataclass(frozen=True)
class Answer:
    message: str
    fields: tuple[Field, ...]
    raw: dict[str, Any]

    @property
    def custom(self) -> bool:
        return bool(self.raw.get("custom"))

    @property
    def base_size(self) -> int:
        """Wire bytes without the optional tail and the bytes field."""
        return sum(f.wire_size for f in self.fields if not f.optional)

    @property
    def full_size(self) -> int:
        return sum(f.wire_size for f in self.fields)

    @property
    def optional_field(self) -> Field | None:
        return next((f for f in self.fields if f.optional), None)

    @property
    def bytes_field(self) -> Field | None:
        return next((f for f in self.fields if f.type == "bytes"), None)


@dataclass(frozen=True)
class Message:
    name: str
    raw: dict[str, Any]
    request: tuple[Field, ...]
    answer: Answer | None  # None: empty OK, no layout, or none defined

    @property
    def lower(self) -> str:
        return self.name.lower()

    @property
    def anchor(self) -> str:
        return str(self.raw["anchor"])

    @property
    def code(self) -> int | None:
        return number(self.raw["code"]) if "code" in self.raw else None

    @property
    def subcommand(self) -> int | None:
        return number(self.raw["subcommand"]) if "subcommand" in self.raw else None

    @property
    def answer_kind(self) -> str:
        answer = self.raw["answer"]
        return "empty" if answer.get("empty") else "none" if answer.get("none") else "fields"

    @property
    def request_size(self) -> int:
        """The CTRL_BUS payload: code, sub-command, arguments (BASE_CMD: its one byte)."""
        head = 0 if self.code is None else 1 + (self.subcommand is not None)
        return head + sum(f.wire_size for f in self.request)


@dataclass
class Description:
    raw: dict[str, Any]
    messages: list[Message] = field(default_factory=list)

    def struct_fields(self, name: str) -> list[dict[str, Any]]:
        return list(self.raw["structs"][name]["fields"])


def _field(desc: dict[str, Any], raw: dict[str, Any], owner: str) -> Field:
    kind = str(raw["type"])
    count = int(raw.get("count", 0 if kind == "bytes" else 1))
    words = 0
    if kind in desc["structs"]:
        members = desc["structs"][kind]["fields"]
        if any(member["type"] not in ("u32", "s32") for member in members):
            raise DescriptionError(f"{owner}.{raw['name']}: struct {kind} must be 32-bit words")
        words = len(members)
    elif kind not in WIDTHS and kind not in ("text", "bytes"):
        raise DescriptionError(f"{owner}.{raw['name']}: unknown type {kind!r}")
    if "anchor" not in raw and owner == "":
        raise DescriptionError(f"{raw['name']}: no anchor")
    return Field(str(raw["name"]), kind, count, raw, words)


def load(repo: Path) -> Description:
    raw = json.loads((repo / DESCRIPTION).read_text(encoding="utf-8"))
    description = Description(raw)
    for item in raw["messages"]:
        name = str(item["name"])
        if "anchor" not in item:
            raise DescriptionError(f"{name}: every message cites its protocol.md anchor")
        request = tuple(_field(raw, f, name) for f in item["request"]["fields"])
        answer = None
        if "fields" in item["answer"]:
            fields = tuple(_field(raw, f, name) for f in item["answer"]["fields"])
            answer = Answer(name, fields, item["answer"])
            _check_answer(answer)
        description.messages.append(Message(name, item, request, answer))
    return description


def _check_answer(answer: Answer) -> None:
    optional = [f for f in answer.fields if f.optional]
    if len(optional) > 1 or (optional and answer.fields[-1] is not optional[0]):
        raise DescriptionError(f"{answer.message}: only the last field may be optional")
    bytes_fields = [f for f in answer.fields if f.type == "bytes"]
    if bytes_fields and answer.fields[-1] is not bytes_fields[0]:
        raise DescriptionError(f"{answer.message}: a bytes field must be the last one")
    counted = [f.raw["count_field"] for f in bytes_fields if "count_field" in f.raw]
    if counted and (
        len(answer.fields) < 2 or answer.fields[-2].name != counted[0] or answer.fields[-2].type != "u8"
    ):
        raise DescriptionError(f"{answer.message}: a bytes field's count must be the u8 field just before it")


# --- marker blocks ---------------------------------------------------------------------------


def replace_block(text: str, name: str, body: str, path: str) -> str:
    """`text` with the lines between the BEGIN/END GENERATED `name` markers replaced by `body`."""
    pattern = re.compile(
        rf"(^[^\n]*BEGIN GENERATED {re.escape(name)}\b[^\n]*\n)(.*?)"
        rf"(^[^\n]*END GENERATED {re.escape(name)}\b)",
        re.S | re.M,
    )
    found = pattern.search(text)
    if found is None:
        raise DescriptionError(f"{path}: no BEGIN/END GENERATED {name} markers")
    return text[: found.start(2)] + body + text[found.end(2) :]


# --- C -------------------------------------------------------------------------------------------


def c_struct(message: Message) -> str:
    return f"ctrlbus_{message.lower}_answer_t"


def c_count(f: Field) -> str:
    return f"CTRLBUS_{f.raw['count_name']}" if "count_name" in f.raw else f"{f.count}u"


def c_comment_block(text: str) -> str:
    """A C comment of at most 100 columns."""
    wrapped = textwrap.wrap(text, 94)
    return "\n".join(["/* " + wrapped[0]] + [" * " + rest for rest in wrapped[1:]]) + " */"


def c_member(declaration: str, comment: str) -> str:
    """`    declaration; /* comment */`, the comment above it when the line would pass 100 columns."""
    line = f"    {declaration};{comment}"
    if len(line) <= 100 or not comment:
        return line
    text = comment.strip()[3:-3].strip()
    wrapped = textwrap.wrap(text, 92)
    block = ["    /* " + wrapped[0]] + ["     * " + rest for rest in wrapped[1:]]
    block[-1] += " */"
    return "\n".join(block) + f"\n    {declaration};"


def c_members(answer: Answer, desc: Description) -> Iterator[str]:
    for f in answer.fields:
        doc = c_comment(f, desc)
        if f.optional:
            yield f"    bool has_{f.name}; /* false: the shorter form (the contract's null) */"
        if f.type == "text":
            extra = "" if f.raw.get("nul_in_field") else " + 1"
            yield c_member(f"char {f.name}[{c_count(f)}{extra}]", doc)
        elif f.type == "bytes":
            yield c_member(f"const uint8_t *{f.name}", doc)
            if "count_field" not in f.raw:
                yield f"    size_t {f.name}_len;"
        else:
            ctype = f"ctrlbus_{f.type}_t" if f.struct_words else C_TYPES[f.type]
            array = f"[{c_count(f)}]" if f.is_array else ""
            yield c_member(f"{ctype} {f.name}{array}", doc)
    if "size_field" in answer.raw:
        yield f"    uint8_t {answer.raw['size_field']}; /* bytes on the wire */"


def c_bits(desc: Description) -> str:
    lines: list[str] = []
    for group in desc.raw["bits"].values():
        if "c_prefix" not in group:
            continue
        lines.append(c_comment_block(f"{group['of']} ([{group['anchor']}])."))
        for bit in group["bits"]:
            lines.append(
                f"#define CTRLBUS_{group['c_prefix']}_{bit['name']} 0x{1 << bit['bit']:02X}u"
                f" /* {bit['meaning']} */"
            )
    return "\n".join(lines) + "\n"


def c_comment(f: Field, desc: Description | None = None) -> str:
    """A member's comment: unit and scale, bit names, the description's note."""
    parts = []
    if "unit" in f.raw:
        parts.append(f.raw["unit"] + (f", {f.raw['scale']}" if "scale" in f.raw else ""))
    bits = f.raw.get("bits")
    if desc is not None and bits and "c_prefix" in desc.raw["bits"][bits]:
        parts.append(f"CTRLBUS_{desc.raw['bits'][bits]['c_prefix']}_* bits")
    if f.doc:
        parts.append(f.doc)
    return f" /* {'; '.join(parts)} */" if parts else ""


def c_position_struct(desc: Description, name: str) -> str:
    struct = desc.raw["structs"][name]
    lines = [c_comment_block(f"{struct['doc'][0].upper()}{struct['doc'][1:]}."), "typedef struct {"]
    for member in struct["fields"]:
        lines.append(f"    {C_TYPES[member['type']]} {member['name']};")
    lines.append(f"}} ctrlbus_{name}_t;")
    return "\n".join(lines)


def c_answer_structs(desc: Description) -> str:
    blocks: list[str] = []
    emitted: set[str] = set()
    for message in desc.messages:
        answer = message.answer
        if answer is None or answer.custom:
            continue
        for f in answer.fields:
            if f.struct_words and f.type not in emitted:
                emitted.add(f.type)
                blocks.append(c_position_struct(desc, f.type))
        members = "\n".join(c_members(answer, desc))
        blocks.append(
            f"/* {message.name} (docs/protocol.md [{message.anchor}]) */\n"
            f"typedef struct {{\n{members}\n}} {c_struct(message)};"
        )
    return "\n\n".join(blocks) + "\n"


def c_size_macros(desc: Description) -> str:
    lines = ["/* Field counts. */"]
    counts: dict[str, tuple[int, str]] = {}
    for message in desc.messages:
        fields = list(message.request) + list(message.answer.fields if message.answer else ())
        for f in fields:
            if "count_name" in f.raw:
                counts.setdefault(f.raw["count_name"], (f.count, f"{message.name} {f.name}"))
    for name, (count, where) in counts.items():
        lines.append(f"#define CTRLBUS_{name} {count}u /* {where} */")
    lines.append("/* Request payloads (CMD 0xF8: request code and sub-command included). */")
    lines.append("#define CTRLBUS_PLAIN_REQUEST_SIZE 1u /* requests without argument: just the code */")
    for message in desc.messages:
        if message.request or message.subcommand is not None:
            lines.append(f"#define CTRLBUS_{message.name}_REQUEST_SIZE {message.request_size}u")
    lines.append(
        "/* OK answer payloads. Where the sources know two forms, both are accepted when decoding. */"
    )
    for message in desc.messages:
        answer = message.answer
        if answer is None:
            continue
        prefix = f"CTRLBUS_{message.name}_ANSWER"
        if answer.custom:
            lines.append(
                f"#define {prefix}_SIZE {max(answer.raw['sizes'])}u /* or {min(answer.raw['sizes'])} */"
            )
        elif answer.bytes_field is not None:
            if "count_field" in answer.bytes_field.raw:
                lines.append(
                    f"#define {prefix}_MIN {answer.base_size}u"
                    f" /* + {answer.bytes_field.raw['count_field']} */"
                )
        elif answer.optional_field is not None:
            tail = answer.optional_field
            lines.append(f"#define {prefix}_SIZE {answer.base_size}u /* without {tail.name} */")
            lines.append(f"#define {prefix}_SIZE_{tail.raw['form_name']} {answer.full_size}u")
            if tail.type in WIDTHS:
                lines.append(f"/* The form a {c_struct(message)} asks for (its has_{tail.name}). */")
                lines.append(
                    f"#define {prefix}_SIZE_OF(answer) \\\n"
                    f"    ((answer)->has_{tail.name} ? {prefix}_SIZE_{tail.raw['form_name']} \\\n"
                    f"                                 : {prefix}_SIZE)"
                )
        elif "min_size" in answer.raw:
            lines.append(
                f"#define {prefix}_SIZE {answer.full_size}u"
                f" /* {answer.raw['min_size']}..{answer.full_size} accepted */"
            )
        else:
            lines.append(f"#define {prefix}_SIZE {answer.full_size}u")
            lines.append(f"#define {prefix}_SIZE_OF(answer) {prefix}_SIZE")
    return "\n".join(lines) + "\n"


@dataclass
class LayoutEntry:
    first: Field
    kind: str
    count: str
    members: list[Field]


def layout_entries(answer: Answer) -> list[LayoutEntry]:
    """The layout table's rows: runs of integer fields of one width merged, as the struct keeps
    same-type neighbours contiguous (generated checks below prove it)."""
    entries: list[LayoutEntry] = []
    for f in answer.fields:
        if f.type == "text":
            entries.append(LayoutEntry(f, "FIELD_TEXT", c_count(f), [f]))
        elif f.type == "bytes":
            entries.append(LayoutEntry(f, "", "", [f]))
        elif f.struct_words:
            entries.append(LayoutEntry(f, "FIELD_U32", f"{c_count(f)} * {f.struct_words}u", [f]))
        else:
            last = entries[-1] if entries else None
            kind = C_KINDS[f.width]
            if (
                last is not None
                and last.kind == kind
                and not f.optional
                and not f.is_array
                and not last.first.struct_words
                and not any(m.is_array for m in last.members)
            ):
                last.members.append(f)
                last.count = f"{len(last.members)}"
            else:
                entries.append(LayoutEntry(f, kind, c_count(f) if f.is_array else "1", [f]))
    return entries


def c_layouts(desc: Description) -> str:
    blocks: list[str] = []
    checks: list[str] = []
    for message in desc.messages:
        answer = message.answer
        if answer is None or answer.custom:
            continue
        struct = c_struct(message)
        rows = []
        for entry in layout_entries(answer):
            if entry.kind == "":
                rows.append(f"    CODEC_FIELD_BYTES({struct}, {entry.first.name}),")
                continue
            names = " + ".join(m.name for m in entry.members[1:])
            note = f" /* + {names} */" if names else ""
            rows.append(f"    CODEC_FIELD({struct}, {entry.first.name}, {entry.kind}, {entry.count}),{note}")
            for before, after in zip(entry.members, entry.members[1:], strict=False):
                checks.append(f"FOLLOWS({struct}, {before.name}, {after.name}, {entry.first.width}u)")
            checks.append(f"offsetof({struct}, {entry.members[-1].name}) < 256u")
        table = "\n".join(rows)
        blocks.append(
            f"/* {message.name} (docs/protocol.md [{message.anchor}]) */\n"
            f"const ctrlbus_codec_field_t ctrlbus_codec_{message.lower}_layout[] CODEC_ROM = {{\n{table}\n}};"
        )
    joined = " &&\n             ".join(checks)
    check = (
        f"typedef char ctrlbus_codec_layouts_fit_their_structs\n    [{joined}\n         ? 1\n         : -1];"
    )
    return check + "\n\n" + "\n\n".join(blocks) + "\n"


def c_encoders(desc: Description) -> str:
    """The ANSWER_ENCODERS of messages.c: a fixed layout's check is fixed_size(); any other is the
    hand-written ctrlbus_<name>_answer_size() (text, forms, counts, limits to check)."""
    lines = []
    for m in desc.messages:
        a = m.answer
        if a is None or a.custom:
            continue
        checked = (
            any(f.type in ("text", "bytes") or f.raw.get("max_is_format_error") for f in a.fields)
            or "min_size" in a.raw
        )
        if checked:
            size = f"ctrlbus_{m.lower}_answer_size(a)"
        elif a.optional_field is not None:
            size = f"a != NULL ? (int32_t)CTRLBUS_{m.name}_ANSWER_SIZE_OF(a) : CTRLBUS_ERR_ARGUMENT"
        else:
            size = f"fixed_size(a, CTRLBUS_{m.name}_ANSWER_SIZE)"
        line = f"ANSWER_ENCODERS({m.lower}, {size})"
        lines.append(line if len(line) <= 100 else f"ANSWER_ENCODERS({m.lower},\n                {size})")
    return "\n".join(lines) + "\n"


def c_layout_declarations(desc: Description) -> str:
    return "".join(
        f"extern const ctrlbus_codec_field_t ctrlbus_codec_{m.lower}_layout[] CODEC_ROM;\n"
        for m in desc.messages
        if m.answer is not None and not m.answer.custom
    )


def c_decoding(message: Message) -> tuple[str, str]:
    """The answer's decoding row (messages_master.c's ctrlbus_codec_decoding_t) and its check."""
    answer = message.answer
    assert answer is not None
    struct = c_struct(message)
    prefix = f"CTRLBUS_{message.name}_ANSWER"
    tail = answer.optional_field
    blob = answer.bytes_field
    length_at = "NONE"
    if tail is not None:
        sizing, short, long = "DECODE_EXACT", f"{prefix}_SIZE", f"{prefix}_SIZE_{tail.raw['form_name']}"
        length_at = f"offsetof({struct}, has_{tail.name})"
    elif blob is not None and "count_field" in blob.raw:
        sizing, short, long = "DECODE_COUNTED", f"{prefix}_MIN", f"{prefix}_MIN"
    elif blob is not None:
        sizing, short, long = "DECODE_ANY", "0u", "0u"
    elif "min_size" in answer.raw:
        sizing, short, long = "DECODE_UP_TO", f"{answer.raw['min_size']}u", f"{prefix}_SIZE"
        length_at = f"offsetof({struct}, {answer.raw['size_field']})"
    else:
        sizing, short, long = "DECODE_EXACT", f"{prefix}_SIZE", f"{prefix}_SIZE"
    rest_at = "NONE"
    checks = []
    if blob is not None:
        rest_at = f"offsetof({struct}, {blob.name})"
        if "count_field" not in blob.raw:
            checks.append(f"offsetof({struct}, {blob.name}_len) == {rest_at} + sizeof(const uint8_t *)")
    limits = [
        (f"offsetof({struct}, {f.name})", f"{f.raw['max']}u")
        for f in answer.fields
        if f.raw.get("max_is_format_error")
    ]
    limits += [
        (f"offsetof({struct}, {f.name}) + {c_count(f)} - 1u", "0u")
        for f in answer.fields
        if f.raw.get("nul_in_field")
    ]
    if len(limits) > 2 or len({most for _, most in limits}) > 1:
        raise DescriptionError(f"{message.name}: at most two checked limits, of one value")
    limits += [("NONE", "0u")] * (2 - len(limits))
    members = [
        f".layout = ctrlbus_codec_{message.lower}_layout",
        f".out_size = sizeof({struct})",
        f".short_size = {short}",
        f".long_size = {long}",
        f".sizing = {sizing}",
        f".length_at = {length_at}",
        f".rest_at = {rest_at}",
        f".limit_max = {limits[0][1]}",
        f".limit_at = {{{limits[0][0]},\n{' ' * 25}{limits[1][0]}}}"
        if len(limits[0][0]) + len(limits[1][0]) > 60
        else f".limit_at = {{{limits[0][0]}, {limits[1][0]}}}",
    ]
    row = (
        f"    [DECODING_{message.name}] =\n        {{\n"
        + "".join(f"            {m},\n" for m in members)
        + "        },"
    )
    offsets = [o for o in (length_at, rest_at, limits[0][0], limits[1][0]) if o != "NONE"]
    return row, " &&\n             ".join([f"{o} < NONE" for o in offsets] + checks)


def c_decoders(desc: Description) -> str:
    messages = [m for m in desc.messages if m.answer is not None and not m.answer.custom]
    names = ",\n".join(f"    DECODING_{m.name}" for m in messages)
    rows, checks = zip(*(c_decoding(m) for m in messages), strict=True)
    out = [
        f"enum {{\n{names}\n}};",
        "",
        "/* Every offset of a decoding fits its byte (NONE, 0xFF, is none). */",
        "typedef char decoding_offsets_fit_a_byte\n    ["
        + " &&\n             ".join(c for c in checks if c)
        + " ? 1 : -1];",
        "",
        "static const ctrlbus_codec_decoding_t DECODINGS[] = {",
        *rows,
        "};",
    ]
    out.append("")
    out += [f"ANSWER_DECODER({m.lower}, DECODING_{m.name})" for m in messages]
    return "\n".join(out) + "\n"


def c_test_fields(desc: Description) -> str:
    """c/tests/answer_fields.h: each OK answer's fields by contract name, where its struct keeps
    them: what the C tests compare with the vectors' fields."""
    out = [
        "/* SPDX-License-Identifier: MIT */",
        f"/* {GENERATED_NOTE} */",
        "/* Test support: each OK answer's fields by their contract names (msg_fields.c walks them). */",
        "#ifndef CTRLBUS_TEST_ANSWER_FIELDS_H",
        "#define CTRLBUS_TEST_ANSWER_FIELDS_H",
        "",
        "#include <stdbool.h>",
        "#include <stddef.h>",
        "",
        '#include "ctrlbus/messages.h"',
        "",
        "#define ANSWER_FIELD_NONE ((size_t)-1)",
        "typedef enum { AF_U8, AF_U16, AF_U32, AF_S32, AF_TEXT, AF_BYTES, AF_POSITIONS }"
        " answer_field_kind_t;",
        "typedef struct {",
        "    const char *name;",
        "    size_t offset;   /* in the answer struct */",
        "    answer_field_kind_t kind;",
        "    size_t count;    /* array items (0: a scalar) */",
        "    size_t has_at;   /* the bool saying an optional field was sent, or NONE */",
        "    size_t len_at;   /* AF_BYTES: its size_t length, or NONE (then count_at) */",
        "    size_t count_at; /* AF_BYTES: the uint8_t count of its bytes, or NONE */",
        "} answer_field_t;",
        "typedef struct {",
        "    ctrlbus_req_kind_t to;",
        "    const answer_field_t *fields;",
        "    size_t count;",
        "} answer_fields_t;",
        "",
    ]
    tables = []
    for m in desc.messages:
        a = m.answer
        if a is None or a.custom:
            continue
        struct = c_struct(m)
        rows = []
        fields = list(a.fields)
        for f in fields:
            kind = {
                "u8": "AF_U8",
                "u16": "AF_U16",
                "u32": "AF_U32",
                "s32": "AF_S32",
                "text": "AF_TEXT",
                "bytes": "AF_BYTES",
            }.get(f.type, "AF_POSITIONS")
            count = f"{f.count}u" if (f.is_array or f.struct_words) else "0u"
            has_at = f"offsetof({struct}, has_{f.name})" if f.optional else "ANSWER_FIELD_NONE"
            len_at = count_at = "ANSWER_FIELD_NONE"
            if f.type == "bytes" and "count_field" in f.raw:
                count_at = f"offsetof({struct}, {f.raw['count_field']})"
            elif f.type == "bytes":
                len_at = f"offsetof({struct}, {f.name}_len)"
            rows.append(
                f'    {{"{f.name}", offsetof({struct}, {f.name}), {kind}, {count},'
                f" {has_at}, {len_at}, {count_at}}},"
            )
        if "size_field" in a.raw:
            name = a.raw["size_field"]
            rows.append(
                f'    {{"{name}", offsetof({struct}, {name}), AF_U8, 0u,'
                " ANSWER_FIELD_NONE, ANSWER_FIELD_NONE, ANSWER_FIELD_NONE},"
            )
        out.append(f"static const answer_field_t {m.name}_FIELDS[] = {{")
        out += rows
        out.append("};")
        tables.append(
            f"    {{CTRLBUS_REQ_{m.name}, {m.name}_FIELDS,"
            f" sizeof {m.name}_FIELDS / sizeof {m.name}_FIELDS[0]}},"
        )
    out.append("")
    out.append("/* The OK payload lengths the description allows (a counted answer: with a count of 3). */")
    out.append("static inline bool answer_length_allowed(ctrlbus_req_kind_t to, size_t len)")
    out.append("{")
    out.append("    switch (to) {")
    for m in desc.messages:
        a = m.answer
        if a is None or m.name == "GET_AUXILIARY_ANCHOR":
            continue
        if a.custom:
            rule = " || ".join(f"len == {s}u" for s in a.raw["sizes"])
        elif a.bytes_field is not None and "count_field" in a.bytes_field.raw:
            rule = f"len == {a.base_size}u + 3u"
        elif a.bytes_field is not None:
            rule = "true"
        elif "min_size" in a.raw:
            rule = f"len >= {a.raw['min_size']}u && len <= {a.full_size}u"
        else:
            rule = " || ".join(f"len == {s}u" for s in sorted({a.base_size, a.full_size}))
        out.append(f"    case CTRLBUS_REQ_{m.name}: return {rule};")
    out.append("    default: return len == 0u; /* the empty OK answers */")
    out.append("    }")
    out.append("}")
    out.append("")
    out.append("static const answer_fields_t ANSWER_FIELDS[] = {")
    out += tables
    out.append("};")
    out += ["", "#endif"]
    return "\n".join(out) + "\n"


# --- Python ----------------------------------------------------------------------------------

PY_FORMATS = {"u8": "B", "u16": "H", "u32": "I", "s32": "i"}
PY_RANGES = {"u8": "U8", "u16": "U16", "u32": "U32", "s32": "S32"}
GENERATED_NOTE = "Generated by scripts/generate_protocol.py from protocol/ctrlbus.json: run `make generate`."


def py_class(message: Message) -> str:
    return "".join(part.capitalize() for part in message.lower.split("_")) + "AnswerFields"


def py_format(fields: tuple[Field, ...], desc: Description) -> str:
    parts = []
    for f in fields:
        if f.type == "text":
            parts.append(f"{f.count}s")
        elif f.struct_words:
            item = "".join(PY_FORMATS[m["type"]] for m in desc.struct_fields(f.type))
            parts.append(item * f.count)
        else:
            parts.append(f"{f.count if f.is_array else ''}{PY_FORMATS[f.type]}")
    return "<" + "".join(parts)


def py_annotation(f: Field) -> str:
    if f.type == "text":
        kind = "str"
    elif f.type == "bytes":
        kind = "tuple[int, ...]" if "count_field" in f.raw else "bytes"
    elif f.struct_words:
        kind = f"tuple[{f.type.capitalize()}Fields, ...]"
    else:
        kind = "tuple[int, ...]" if f.is_array else "int"
    return (
        f"{kind} | None = None"
        if f.optional
        else kind + (f" = {json.dumps(f.raw['default'])}" if "default" in f.raw else "")
    )


def py_comment(f: Field) -> str:
    parts = []
    if "unit" in f.raw:
        parts.append(f.raw["unit"] + (f", {f.raw['scale']}" if "scale" in f.raw else ""))
    if "bits" in f.raw:
        parts.append(f"bits: {f.raw['bits'].upper()}_BITS")
    if f.doc:
        parts.append(f.doc)
    return py_wrapped_comment("; ".join(parts)) if parts else ""


def py_struct_class(name: str, struct: dict[str, Any]) -> str:
    lines = ["@dataclass(frozen=True)", f"class {name.capitalize()}Fields:"]
    lines.append(f'    """A {name} (docs/protocol.md [{struct["anchor"]}]): {struct["doc"]}."""')
    lines.append("")
    for member in struct["fields"]:
        f = Field(member["name"], member["type"], 1, member)
        lines.append(f"{py_comment(f)}    {f.name}: int = 0")
    return "\n".join(lines)


def py_fields_class(message: Message, desc: Description) -> str:
    answer = message.answer
    assert answer is not None
    lines = ["@dataclass(frozen=True)", f"class {py_class(message)}:"]
    lines.append(
        f'    """The fields of the {message.name} OK answer (docs/protocol.md [{message.anchor}])."""'
    )
    lines.append("")
    plain = [f for f in answer.fields if not f.optional]
    simple = all(f.type in PY_FORMATS for f in answer.fields) and "min_size" not in answer.raw
    if simple and answer.optional_field is None:
        lines.append(py_struct("_LAYOUT: ClassVar[struct.Struct | None]", py_format(answer.fields, desc)))
    if answer.optional_field is not None:
        lines.append(py_struct("_REFERENCE_FORM: ClassVar[struct.Struct]", py_format(tuple(plain), desc)))
        lines.append(py_struct("_SDK_FORM: ClassVar[struct.Struct]", py_format(answer.fields, desc)))
        lines.append(
            "    _FORMS: ClassVar[tuple[struct.Struct, struct.Struct] | None] = (_REFERENCE_FORM, _SDK_FORM)"
        )
        lines.append(f'    _TAIL: ClassVar[str | None] = "{answer.optional_field.name}"')
    elif not simple and answer.bytes_field is None and "min_size" not in answer.raw:
        lines.append(py_struct("_WIRE: ClassVar[struct.Struct]", py_format(answer.fields, desc)))
    ranges = []
    for f in answer.fields:
        if f.type in PY_RANGES and not f.is_array:
            limit = f"(0, {f.raw['max']})" if f.raw.get("max_is_format_error") else PY_RANGES[f.type]
            ranges.append(f'"{f.name}": {limit}')
    if "size_field" in answer.raw:
        ranges.append(f'"{answer.raw["size_field"]}": ({answer.raw["min_size"]}, {answer.full_size})')
    if ranges:
        lines.append(py_dict("    _RANGES: ClassVar[Mapping[str, tuple[int, int]]]", ranges))
    arrays = [
        f'"{f.name}": ({PY_RANGES[f.type]}, {f.count})' for f in plain if f.type in PY_RANGES and f.is_array
    ]
    if arrays:
        lines.append(py_dict("    _ARRAYS: ClassVar[Mapping[str, tuple[tuple[int, int], int]]]", arrays))
    if answer.bytes_field is not None and "count_field" not in answer.bytes_field.raw:
        lines.append(f'    _BYTES: ClassVar[tuple[str, ...]] = ("{answer.bytes_field.name}",)')
    lines.append("")
    for f in answer.fields:
        lines.append(f"{py_comment(f)}    {f.name}: {py_annotation(f)}")
    if "size_field" in answer.raw:
        lines.append(
            f"    # bytes on the wire\n    {answer.raw['size_field']}: int = {answer.raw['size_default']}"
        )
    return "\n".join(lines)


def q(text: str) -> str:
    """A Python string literal as ruff format writes it."""
    if text.count('"') > text.count("'"):
        return "'" + text.replace("'", "\\'") + "'"
    return json.dumps(text, ensure_ascii=False)


def py_dict(head: str, items: list[str]) -> str:
    """`head = {...}` with one item a line (ruff format keeps it so: the trailing comma)."""
    body = "".join(f"        {item},\n" for item in items)
    return f"{head} = {{\n{body}    }}"


def py_struct(head: str, fmt: str) -> str:
    line = f'    {head} = struct.Struct("{fmt}")'
    return line if len(line) <= 110 else f'    {head} = struct.Struct(\n        "{fmt}"\n    )'


def py_wrapped_comment(text: str) -> str:
    return "".join(f"    # {line}\n" for line in textwrap.wrap(text, 100))


def py_values(name: str, values: dict[str, str]) -> str:
    body = "".join(f"    0x{number(code):02X}: {q(text)},\n" for code, text in values.items())
    return f"{name}: Final[Mapping[int, str]] = {{\n{body}}}"


def python_tables(desc: Description) -> str:
    raw = desc.raw
    out = [
        "# SPDX-License-Identifier: MIT",
        f"# {GENERATED_NOTE}",
        "# ruff: noqa: E501, RUF022",  # __all__ in the description's order
        '"""The protocol description\'s tables for Python (docs/protocol.md): answer fields, bit meanings,',
        "error and health codes. ctrlbus.messages builds its answer classes on the *AnswerFields",
        "classes; the Core, the dashboard, decode and the checker read bit meanings from here.",
        '"""',
        "",
        "from __future__ import annotations",
        "",
        "import struct",
        "from collections.abc import Mapping",
        "from dataclasses import dataclass",
        "from typing import ClassVar, Final",
        "",
        "U8: Final = (0, 0xFF)",
        "U16: Final = (0, 0xFFFF)",
        "U32: Final = (0, 0xFFFFFFFF)",
        "S32: Final = (-0x80000000, 0x7FFFFFFF)",
        "",
        "# --- field counts",
        "",
    ]
    counts: dict[str, int] = {}
    for message in desc.messages:
        for f in list(message.request) + list(message.answer.fields if message.answer else ()):
            if "count_name" in f.raw:
                counts.setdefault(f.raw["count_name"], f.count)
    out += [f"{name}: Final = {count}" for name, count in counts.items()]
    out += ["", "# --- bit meanings: mask -> meaning", ""]
    for name, group in raw["bits"].items():
        if "bits" in group:
            body = "".join(f"    0x{1 << b['bit']:02X}: {q(b['meaning'])},\n" for b in group["bits"])
            out.append(f"# [{group['anchor']}]")
            out.append(f"{name.upper()}_BITS: Final[Mapping[int, str]] = {{\n{body}}}")
            out.append(f"{name.upper()}_DEFINED: Final = 0x{sum(1 << b['bit'] for b in group['bits']):02X}")
            out += [f"{name.upper()}_{b['name']}: Final = 0x{1 << b['bit']:02X}" for b in group["bits"]]
        for g in group.get("groups", ()):
            bits = tuple(range(g["first_bit"], g["first_bit"] + g["count"]))
            out.append(f"# [{group['anchor']}] {g['meaning']} bits where the reference puts them")
            out.append(f"REFERENCE_{g['name'].upper()}_BITS: Final = {bits!r}")
        if group.get("active_low"):
            out.append(f"{name.upper()}_ACTIVE_LOW: Final = True")
        if "below" in group:
            out.append(f"{name.upper()}_BELOW: Final = {group['below']}")
        out.append("")
    out += ["# --- OK payload sizes per request (answers are paired with requests by size)", ""]
    sizes = "".join(
        f"    {q(name)}: {q(s) if isinstance(s, str) else repr(s)},\n" for name, s in ok_sizes(desc).items()
    )
    out.append(f"OK_SIZES: Final[Mapping[str, tuple[int, ...] | str]] = {{\n{sizes}}}")
    heads = "".join(f"    {q(name)}: {head},\n" for name, head in ok_counted_heads(desc).items())
    out.append(f"OK_COUNTED_HEAD: Final[Mapping[str, int]] = {{\n{heads}}}")
    out += ["", "# --- codes", ""]
    errors = {e["code"]: e["name"] for e in raw["errors"]["codes"]}
    out.append(py_values("ERROR_CODE_NAMES", errors))
    out.append(py_values("ERROR_CODE_MEANINGS", {e["code"]: e["meaning"] for e in raw["errors"]["codes"]}))
    for name, group in raw["values"].items():
        out.append(py_values(name.upper(), group["values"]))
    out.append(py_values("HEALTH_LEVELS", raw["health"]["levels"]))
    out.append(py_values("HEALTH_COMPONENTS", raw["health"]["components"]))
    components = {v: number(k) for k, v in raw["health"]["components"].items()}
    body = "".join(
        f"    (0x{components[t['component']]:02X}, 0x{number(t['type']):02X}): {q(t['meaning'])},\n"
        for t in raw["health"]["types"]
    )
    out.append(f"HEALTH_TYPES: Final[Mapping[tuple[int, int], str]] = {{\n{body}}}")
    out += ["", "", "# --- answer fields", "", ""]
    classes = [py_struct_class(name, struct) for name, struct in raw["structs"].items()]
    classes += [
        py_fields_class(m, desc) for m in desc.messages if m.answer is not None and not m.answer.custom
    ]
    out.append("\n\n\n".join(classes))
    text = "\n".join(out) + "\n"
    return text + "\n\n" + python_all(text)


def python_all(module_text: str) -> str:
    """`__all__` naming every public name the generated module defines (its imports are not its own)."""
    names: list[str] = []
    for node in ast.parse(module_text).body:
        if isinstance(node, ast.ClassDef):
            names.append(node.name)
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            names += [t.id for t in targets if isinstance(t, ast.Name)]
    public = [name for name in names if not name.startswith("_")]
    body = "".join(f"    {q(name)},\n" for name in public)
    return f"__all__ = [\n{body}]\n"


# --- Wireshark (Lua) and sigrok (Python) tables --------------------------------------------------

LUA_TYPES = {
    "u8": "uint8",
    "u16": "uint16",
    "u32": "uint32",
    "s32": "int32",
    "text": "string",
    "bytes": "bytes",
}


def lua_string(text: str) -> str:
    return json.dumps(text, ensure_ascii=False)


def lua_names(values: dict[str, str] | dict[int, str]) -> str:
    items = ", ".join(f"[0x{number(code):02X}] = {lua_string(text)}" for code, text in values.items())
    return f"{{ {items} }}"


def request_code_names(desc: Description) -> dict[int, str]:
    """Control-bus request code -> name (the HEALTH_MGMT code names its group)."""
    return {
        number(m.raw["code"]): ("HEALTH_MGMT" if m.subcommand is not None else m.name)
        for m in desc.messages
        if m.code is not None
    }


def health_sub_names(desc: Description) -> dict[int, str]:
    return {number(m.raw["subcommand"]): m.name for m in desc.messages if m.subcommand is not None}


def cmd_names(raw: dict[str, Any], *sections: str) -> dict[int, str]:
    return {number(c["cmd"]): c["name"] for section in sections for c in raw[section]}


def ok_sizes(desc: Description) -> dict[str, tuple[int, ...] | str]:
    """Each request's OK payload sizes: a tuple, "any" (a bytes field takes the rest), or
    "counted" (the fixed part, then as many bytes as its last byte says: OK_COUNTED_HEAD)."""
    sizes: dict[str, tuple[int, ...] | str] = {}
    for m in desc.messages:
        a = m.answer
        if m.answer_kind == "empty":
            sizes[m.name] = (0,)
        elif a is None:
            continue
        elif a.custom:
            sizes[m.name] = tuple(a.raw["sizes"])
        elif a.bytes_field is not None:
            sizes[m.name] = "counted" if "count_field" in a.bytes_field.raw else "any"
        elif "min_size" in a.raw:
            sizes[m.name] = tuple(range(a.raw["min_size"], a.full_size + 1))
        else:
            sizes[m.name] = tuple(sorted({a.base_size, a.full_size}))
    return sizes


def ok_counted_heads(desc: Description) -> dict[str, int]:
    return {
        m.name: m.answer.base_size
        for m in desc.messages
        if m.answer is not None
        and m.answer.bytes_field is not None
        and "count_field" in m.answer.bytes_field.raw
    }


def bit_names(group: dict[str, Any]) -> dict[int, str]:
    return {b["bit"]: b["meaning"] for b in group["bits"]}


def contract_fields(desc: Description) -> Iterator[tuple[str, Field]]:
    """Every field of every request and answer once (a struct's members as parent.member), in
    the description's order: what the dissector registers."""
    seen: set[str] = set()
    for message in desc.messages:
        for f in list(message.request) + list(message.answer.fields if message.answer else ()):
            members = (
                [
                    (f"{f.name}.{m['name']}", Field(m["name"], m["type"], 1, m))
                    for m in desc.struct_fields(f.type)
                ]
                if f.struct_words
                else [(f.name, f)]
            )
            for name, member in members:
                if name not in seen:
                    seen.add(name)
                    yield name, member
        if message.answer is not None and "size_field" in message.answer.raw:
            name = message.answer.raw["size_field"]
            if name not in seen:
                seen.add(name)
                yield name, Field(name, "u8", 1, {"name": name})


def lua_field_spec(f: Field) -> str:
    kind = "position" if f.struct_words else f.type
    parts = [lua_string(f.name), lua_string(kind)]
    if f.count != 1 or f.type == "text":
        parts.append(str(f.count))
    extras = []
    if f.optional:
        extras.append("optional = true")
    if f.raw.get("nul_in_field"):
        extras.append("nul_required = true")
    if f.raw.get("truncatable"):
        extras.append("truncatable = true")
    if "bits" in f.raw:
        extras.append(f"bits = {lua_string(f.raw['bits'])}")
    if f.raw.get("layout") == "health_code":
        extras.append("health_code = true")
    return "{ " + ", ".join(parts + extras) + " }"


def lua_tables(desc: Description) -> str:
    raw = desc.raw
    out = [
        "-- SPDX-License-Identifier: MIT",
        f"-- {GENERATED_NOTE}",
        "-- The protocol description's tables for ctrlbus.lua, which loads this file from its own folder:",
        "-- names, bit meanings, the contract's fields, request arguments and OK answer layouts.",
        "return {",
        f"    CMD_NAMES = {lua_names(cmd_names(raw, 'request_cmds', 'response_cmds'))},",
        f"    REQUEST_NAMES = {lua_names(request_code_names(desc))},",
        f"    HEALTH_NAMES = {lua_names(health_sub_names(desc))},",
    ]
    for name, group in raw["values"].items():
        out.append(f"    {name.upper()} = {lua_names(group['values'])},")
    out.append(f"    HEALTH_LEVELS = {lua_names(raw['health']['levels'])},")
    out.append(f"    HEALTH_COMPONENTS = {lua_names(raw['health']['components'])},")
    out.append("    BITS = {")
    for name, group in raw["bits"].items():
        if "bits" in group:
            items = ", ".join(f"[{bit}] = {lua_string(text)}" for bit, text in bit_names(group).items())
            out.append(f"        {name} = {{ {items} }},")
    out.append("    },")
    out.append("    -- name, ProtoField type, display (DEC_HEX for codes and bit fields), value names")
    out.append("    FIELDS = {")
    for name, f in contract_fields(desc):
        ftype = LUA_TYPES.get(f.type, "bytes")
        if f.type == "bytes" and "count_field" in f.raw:
            ftype = "uint8"
        hexed = bool(f.raw.get("hex")) or "bits" in f.raw or "layout" in f.raw
        spec = [lua_string(name), lua_string(ftype)]
        if ftype.startswith("uint"):
            spec.append(lua_string("DEC_HEX" if hexed else "DEC"))
            if isinstance(f.raw.get("values"), str):
                spec.append(lua_string(f.raw["values"].upper()))
        out.append(f"        {{ {', '.join(spec)} }},")
    out.append("    },")
    out.append("    -- fixed-point shift and unit of the numeric fields, by name")
    out.append("    UNITS = {")
    units: set[str] = set()
    for name, f in contract_fields(desc):
        if "unit" in f.raw and name.split(".")[-1] not in units:
            units.add(name.split(".")[-1])
            shift = {"Q8": 8, "Q16": 16}.get(f.raw.get("scale", ""), 0)
            unit = {"degrees": "°"}.get(f.raw["unit"], f.raw["unit"])
            out.append(f"        {name.split('.')[-1]} = {{ {shift}, {lua_string(unit)} }},")
    out.append("    },")
    out.append(
        '    -- OK payload sizes per request: a list, "any", or "counted" (OK_COUNTED_HEAD, then its count)'
    )
    out.append("    OK_SIZES = {")
    for name, s in ok_sizes(desc).items():
        shown = lua_string(s) if isinstance(s, str) else "{ " + ", ".join(map(str, s)) + " }"
        out.append(f"        {name} = {shown},")
    out.append("    },")
    heads = ", ".join(f"{name} = {head}" for name, head in ok_counted_heads(desc).items())
    out.append(f"    OK_COUNTED_HEAD = {{ {heads} }},")
    out.append("    -- control-bus request arguments, after the request code (and the HEALTH sub-command)")
    out.append("    REQUEST_ARGS = {")
    for m in desc.messages:
        if m.request and m.code is not None:
            out.append(f"        {m.name} = {{ {', '.join(lua_field_spec(f) for f in m.request)} }},")
    out.append("    },")
    out.append("    -- OK answers: the sizes allowed and the fields in wire order")
    out.append("    ANSWERS = {")
    for m in desc.messages:
        a = m.answer
        if a is None or a.custom:
            continue
        size: list[str] = []
        if a.bytes_field is not None and "count_field" in a.bytes_field.raw:
            size.append(f"min = {a.base_size}, count_field = {lua_string(a.bytes_field.raw['count_field'])}")
        elif a.bytes_field is not None:
            size.append("min = 1")
        elif "min_size" in a.raw:
            size.append(f"min = {a.raw['min_size']}, max = {a.full_size}")
        else:
            sizes = sorted({a.base_size, a.full_size})
            size.append(f"sizes = {{ {', '.join(map(str, sizes))} }}")
        if "size_field" in a.raw:
            size.append(f"size_field = {lua_string(a.raw['size_field'])}")
        fields = ",\n            ".join(lua_field_spec(f) for f in a.fields)
        out.append(
            f"        {m.name} = {{ {', '.join(size)}, fields = {{\n            {fields},\n        }} }},"
        )
    out.append("    },")
    out.append("}")
    return "\n".join(out) + "\n"


def sigrok_field_spec(f: Field) -> str:
    kind = "position" if f.struct_words else f.type
    spec: dict[str, Any] = {"name": f.name, "type": kind, "size": f.width or f.count}
    if f.is_array or f.type == "text":
        spec["count"] = f.count
    for key in ("optional", "nul_in_field", "truncatable", "max_is_format_error"):
        if f.raw.get(key):
            spec[key] = True
    if f.raw.get("max_is_format_error"):
        spec["max"] = f.raw["max"]
    if "count_field" in f.raw:
        spec["count_field"] = f.raw["count_field"]
    return repr(spec)


def sigrok_tables(desc: Description) -> str:
    raw = desc.raw
    out = [
        "# SPDX-License-Identifier: MIT",
        f"# {GENERATED_NOTE}",
        "#",
        "# The protocol description's tables for pd.py (libsigrokdecode's Python has no ctrlbus",
        "# package, so the tables travel with the decoder): names, bit meanings, request arguments",
        "# and OK answer layouts.",
        "",
    ]

    def names(name: str, values: dict[Any, str]) -> None:
        body = "".join(f"    0x{number(code):02X}: {text!r},\n" for code, text in values.items())
        out.append(f"{name} = {{\n{body}}}")

    names("TOP_REQUESTS", cmd_names(raw, "request_cmds"))
    names("RESPONSES", cmd_names(raw, "response_cmds"))
    names("CTRL_REQUESTS", request_code_names(desc))
    names("HEALTH_SUBS", health_sub_names(desc))
    for name, group in raw["values"].items():
        names(name.upper(), group["values"])
    names("HEALTH_LEVELS", raw["health"]["levels"])
    names("HEALTH_COMPONENTS", raw["health"]["components"])
    for name, group in raw["bits"].items():
        if "bits" in group:
            body = "".join(f"    (0x{1 << b['bit']:02X}, {b['meaning']!r}),\n" for b in group["bits"])
            out.append(f"{name.upper()}_BITS = (\n{body})")
    out.append(
        "# OK payload sizes per request: a tuple, 'any', or 'counted' (OK_COUNTED_HEAD, then its count)"
    )
    out.append("OK_SIZES = {")
    out += [f"    {name!r}: {s!r}," for name, s in ok_sizes(desc).items()]
    out.append("}")
    out.append(f"OK_COUNTED_HEAD = {ok_counted_heads(desc)!r}")
    out.append("# request arguments after the code (and the HEALTH sub-command)")
    out.append("REQUEST_ARGS = {")
    for m in desc.messages:
        if m.code is not None:
            out.append(f"    {m.name!r}: ({''.join(sigrok_field_spec(f) + ', ' for f in m.request)}),")
    out.append("}")
    out.append("# OK answers with a layout: sizes allowed, fields in wire order")
    out.append("ANSWERS = {")
    for m in desc.messages:
        a = m.answer
        if m.answer_kind == "empty":
            out.append(f"    {m.name!r}: {{'sizes': (0,), 'fields': ()}},")
            continue
        if a is None or a.custom:
            continue
        size: dict[str, Any] = {}
        if a.bytes_field is not None and "count_field" in a.bytes_field.raw:
            size = {"min": a.base_size, "count_at": a.base_size - 1}
        elif a.bytes_field is not None:
            size = {"min": 0}
        elif "min_size" in a.raw:
            size = {"min": a.raw["min_size"], "max": a.full_size}
        else:
            size = {"sizes": tuple(sorted({a.base_size, a.full_size}))}
        if "size_field" in a.raw:
            size["size_field"] = a.raw["size_field"]
        fields = "".join(f"        {sigrok_field_spec(f)},\n" for f in a.fields)
        out.append(
            f"    {m.name!r}: dict({', '.join(f'{k}={v!r}' for k, v in size.items())},"
            f" fields=(\n{fields}    )),"
        )
    out.append("}")
    return "\n".join(out) + "\n"


# --- protocol.md -------------------------------------------------------------------------------

MD_HEADER = "| offset | size | type | unit | field |\n|---|---|---|---|---|\n"


def md_type(f: Field) -> str:
    if f.type == "text":
        return f"char[{f.count}]"
    if f.type == "bytes":
        return "u8[]" if "count_field" in f.raw else "bytes"
    if f.raw.get("truncatable"):
        return f"{f.type} (LE, truncated)"
    return f"{f.type}[{f.count}]" if f.is_array else f.type


def md_meaning(f: Field, desc: Description) -> str:
    parts = []
    values = f.raw.get("values")
    if (
        isinstance(values, str)
        and values in desc.raw["values"]
        and len(desc.raw["values"][values]["values"]) <= 3
    ):
        hexed = bool(f.raw.get("hex"))
        parts.append(
            ", ".join(
                f"0x{number(k):02X} {v}" if hexed else f"{number(k)} {v}"
                for k, v in desc.raw["values"][values]["values"].items()
            )
        )
    elif isinstance(values, str):
        parts.append(f"see [{desc.raw['values'][values]['anchor']}]")
    if "supported" in f.raw and not f.doc:
        parts.append(" or ".join(f"0x{number(v):02X}" for v in f.raw["supported"]))
    bits = f.raw.get("bits")
    group = desc.raw["bits"].get(bits) if bits else None
    if group is not None and "bits" in group:
        parts.append(
            ", ".join(
                f"bit{b['bit']} {b['meaning']}" + (" [2020 SDK]" if b["source"] == "sdk2020" else "")
                for b in group["bits"]
            )
        )
    if f.doc:
        parts.append(f.doc)
    return f"`{f.name}`" + (": " + "; ".join(parts).replace("|", "\\|") if parts else "")


def md_rows(
    fields: tuple[Field, ...], desc: Description, offset: int = 0, count_of: dict[str, str] | None = None
) -> list[str]:
    rows = []
    for f in fields:
        unit = f.raw.get("unit", "—") + (f", {f.raw['scale']}" if "scale" in f.raw else "")
        if f.type == "bytes":
            size = f.raw.get("count_field", "the rest")
        elif f.raw.get("truncatable"):
            size = f"1..{f.wire_size}"
        else:
            size = str(f.wire_size)
        kind = f"{f.type}[{f.count}]" if f.struct_words else md_type(f)
        rows.append(f"| {offset} | {size} | {kind} | {unit} | {md_meaning(f, desc)} |")
        offset += f.wire_size
    return rows


def md_request(message: Message, desc: Description) -> str:
    rows = []
    offset = 0
    if message.code is not None:
        rows.append(f"| 0 | 1 | u8 | — | request code 0x{message.code:02X} |")
        offset = 1
    if message.subcommand is not None:
        rows.append(f"| 1 | 1 | u8 | — | sub-command 0x{message.subcommand:02X} |")
        offset = 2
    return MD_HEADER + "\n".join(rows + md_rows(message.request, desc, offset)) + "\n"


def md_answer(message: Message, desc: Description) -> str:
    assert message.answer is not None
    return MD_HEADER + "\n".join(md_rows(message.answer.fields, desc)) + "\n"


def md_struct(name: str, desc: Description) -> str:
    fields = tuple(Field(m["name"], m["type"], 1, m) for m in desc.struct_fields(name))
    return MD_HEADER + "\n".join(md_rows(fields, desc)) + "\n"


def md_answer_sizes(message: Message) -> str:
    answer = message.answer
    if message.answer_kind == "empty":
        return "0"
    if answer is None:
        return "none defined"
    if answer.custom:
        return " or ".join(str(s) for s in answer.raw["sizes"])
    if answer.bytes_field is not None:
        count = answer.bytes_field.raw.get("count_field")
        return f"{answer.base_size} + `{count}`" if count else "any"
    if "min_size" in answer.raw:
        return f"{answer.raw['min_size']}..{answer.full_size}"
    if answer.optional_field is not None:
        return f"{answer.base_size} or {answer.full_size}"
    return str(answer.full_size)


def md_messages(desc: Description) -> str:
    rows = [
        "| code | sub | message | request | OK answer | every base | section |",
        "|---|---|---|---|---|---|---|",
    ]
    for m in desc.messages:
        if m.code is None:
            continue
        sub = f"0x{m.subcommand:02X}" if m.subcommand is not None else ""
        required = "yes" if m.raw.get("required") else ""
        rows.append(
            f"| 0x{m.code:02X} | {sub} | {m.name} | {m.request_size} | {md_answer_sizes(m)} | {required}"
            f" | [{m.anchor}](#{m.anchor}) |"
        )
    return "\n".join(rows) + "\n"


def protocol_md(desc: Description, text: str, path: str) -> str:
    text = replace_block(text, "messages", md_messages(desc), path)
    text = replace_block(text, "struct position", md_struct("position", desc), path)
    for m in desc.messages:
        if f"BEGIN GENERATED request {m.name} " in text:
            text = replace_block(text, f"request {m.name}", md_request(m, desc), path)
        if f"BEGIN GENERATED answer {m.name} " in text:
            text = replace_block(text, f"answer {m.name}", md_answer(m, desc), path)
    return text


# --- the generated outputs -----------------------------------------------------------------


Block = tuple[str, Callable[[Description], str]]
BLOCKS: dict[str, list[Block]] = {
    "c/include/ctrlbus/messages.h": [
        ("bits", c_bits),
        ("sizes", c_size_macros),
        ("answer structs", c_answer_structs),
    ],
    "c/src/codec.h": [("layout declarations", c_layout_declarations)],
    "c/src/messages.c": [("layouts", c_layouts), ("encoders", c_encoders)],
    "c/src/messages_master.c": [("decoders", c_decoders)],
}
# Files with many blocks, each named after a message: rewritten by one function.
REWRITES: dict[str, Callable[[Description, str, str], str]] = {"docs/protocol.md": protocol_md}
WHOLE_FILES: dict[str, Callable[[Description], str]] = {
    "c/tests/answer_fields.h": c_test_fields,
    "python/src/ctrlbus/protocol_tables.py": python_tables,
    "tools/wireshark/ctrlbus_protocol.lua": lua_tables,
    "tools/sigrok/ctrlbus/protocol.py": sigrok_tables,
}


def render(repo: Path) -> dict[str, str]:
    """Every generated file's would-be text, by its path in the repository."""
    desc = load(repo)
    out: dict[str, str] = {}
    for path, blocks in BLOCKS.items():
        text = (repo / path).read_text(encoding="utf-8")
        for name, make in blocks:
            text = replace_block(text, name, make(desc), path)
        out[path] = text
    for path, make in WHOLE_FILES.items():
        out[path] = make(desc)
    for path, rewrite in REWRITES.items():
        out[path] = rewrite(desc, (repo / path).read_text(encoding="utf-8"), path)
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--out", type=Path, help="write under this folder instead of the repository")
    parser.add_argument("--check", action="store_true", help="only say which files are out of date")
    parser.add_argument("--repo", type=Path, default=REPO, help=argparse.SUPPRESS)
    args = parser.parse_args(argv)
    try:
        files = render(args.repo)
    except (DescriptionError, KeyError, ValueError, OSError) as exc:
        print(f"generate_protocol: {exc}", file=sys.stderr)
        return 2
    if args.check:
        stale = [p for p, text in files.items() if _read(args.repo / p) != text]
        for path in stale:
            print(f"generate_protocol: {path} is out of date: run `{COMMAND}`", file=sys.stderr)
        return 1 if stale else 0
    target = args.out or args.repo
    for path, text in files.items():
        destination = target / path
        destination.parent.mkdir(parents=True, exist_ok=True)
        if _read(destination) != text:
            destination.write_text(text, encoding="utf-8")
    return 0


def _read(path: Path) -> str | None:
    try:
        return path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return None


if __name__ == "__main__":
    sys.exit(main())
