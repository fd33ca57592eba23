# SPDX-License-Identifier: MIT
"""`ctrlbus config`: the binary configuration blob of GET_BASE_CONF_ADV (0x21) and its JSON form.

    ctrlbus config decode BLOB [-o FILE]   blob (binary or hex text; '-' = stdin) -> JSON
    ctrlbus config encode JSON [-o FILE]   JSON ('-' = stdin) -> hex text on stdout, or binary to
                                           FILE with -o ('-o -' writes binary to stdout)
    ctrlbus config example [-o FILE]       the documented example configuration (JSON)

The JSON mapping is in docs/binary-config.md.
"""

from __future__ import annotations

import argparse
import sys
from typing import Any

from ctrlbus import binconf
from ctrlbus.cli.common import format_hex, parse_hex_text, read_input_bytes, write_output

__all__ = [
    "DESCRIPTION",
    "blob_from_input",
    "register",
    "run",
]

DESCRIPTION = """\
Convert the binary configuration that a base serves for GET_BASE_CONF_ADV (0x21) to JSON and back.
decode then encode gives back the same bytes; encode then decode gives back the same JSON
(docs/binary-config.md describes the JSON form).
"""


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "config",
        help="binary configuration (0x21) blob <-> JSON",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    actions = parser.add_subparsers(dest="config_action", metavar="ACTION", required=True)

    decode = actions.add_parser(
        "decode",
        help="blob -> JSON",
        description="Print the JSON form of a blob. The blob is read as hex text if it is printable "
        "ASCII not starting with 'P' (spaces, newlines, 0x prefixes and # comments allowed), else "
        "as raw bytes.",
    )
    decode.add_argument("blob", metavar="BLOB", help="file holding the blob, or - for stdin")
    decode.add_argument("-o", "--output", metavar="FILE", help="write the JSON to FILE instead of stdout")

    encode = actions.add_parser(
        "encode",
        help="JSON -> blob",
        description="Encode a JSON configuration. Without -o the blob is printed as hex text; "
        "with -o FILE it is written as raw bytes (-o - writes raw bytes to stdout).",
    )
    encode.add_argument("json", metavar="JSON", help="file holding the JSON, or - for stdin")
    encode.add_argument("-o", "--output", metavar="FILE", help="write the raw blob to FILE ('-' = stdout)")

    example = actions.add_parser(
        "example",
        help="print the example configuration of the default simulated base",
        description="Print the documented example configuration (the simulated base serves its blob "
        "for 0x21); a starting point for your own.",
    )
    example.add_argument("-o", "--output", metavar="FILE", help="write it to FILE instead of stdout")

    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.config_action == "decode":
        blob = blob_from_input(read_input_bytes(args.blob))
        write_output(args.output, binconf.dump_json(binconf.decode(blob)))
    elif args.config_action == "encode":
        blob = binconf.encode(binconf.load_json(read_input_bytes(args.json)))
        if len(blob) > binconf.REFERENCE_MAX_BLOB:
            print(
                f"ctrlbus config: warning: the blob has {len(blob)} bytes; the reference base sends "
                f"at most {binconf.REFERENCE_MAX_BLOB}",
                file=sys.stderr,
            )
        write_output(args.output, blob if args.output is not None else format_hex(blob))
    else:
        write_output(args.output, binconf.example_config_text())
    return 0


def blob_from_input(data: bytes) -> bytes:
    """Hex text if the input is printable ASCII, else the raw bytes. A raw blob starts with 0x50
    ('P', its root object), which hex text never does, so a printable blob is still read raw."""
    printable = all(0x20 <= byte < 0x7F or byte in b"\t\r\n" for byte in data)
    if data and printable and not data.startswith(b"P"):
        return parse_hex_text(data.decode("ascii"))
    return data
