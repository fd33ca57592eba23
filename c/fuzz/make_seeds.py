#!/usr/bin/env python3
# SPDX-License-Identifier: MIT
"""Writes the fuzz targets' seed corpora from the shared vectors (vectors/*.json).

    make_seeds.py --vectors DIR --out DIR

Creates OUT/decoder, OUT/base and OUT/fixup, one file per seed, in each target's input format (see
the comment at the top of fuzz_decoder.c, fuzz_base.c, fuzz_fixup.c and base_harness.h): the
settings bytes, then the vector's bytes. The vectors are the seeds; nothing generated here is
committed. Any file already in OUT/<target> is replaced.
"""

from __future__ import annotations

import argparse
import json
import shutil
from pathlib import Path

# Decoder settings byte: bits 0-2 buffer index (16, 64, 512, 65539 = 3, 4, 6, 7), bits 3-5
# timeout index (off, 20 ms = 0, 5), bits 6-7 cut style (3 = whole, 1 = 1..64 bytes).
DECODER_BUFFER_INDEX = {16: 3, 64: 4, 512: 6}
DECODER_TIMEOUT_INDEX = {20: 5}
# Base settings: byte 0 = frame buffer 512, reference profile, long answers; byte 1 = default
# timeout and watchdog, storage, a binary config, reboot handlers; bytes 2-3 = handler seed.
BASE_SETTINGS = bytes([0x04, 0x70, 0x00, 0x00])
BASE_CUT_WHOLE = 0x03
FIXUP_LONG, FIXUP_POLL = 0x01, 0x40


def unhex(text: str) -> bytes:
    return bytes.fromhex(text.replace(" ", ""))


def encode(cmd: int, payload: bytes, long: bool) -> bytes:
    """A frame, as docs/protocol.md §3 lays it out."""
    length = len(payload) + 1
    header = bytes([0x50, length & 0xFF, length >> 8]) if long else bytes([0x10, length])
    body = header + bytes([cmd]) + payload
    checksum = 0
    for byte in body:
        checksum ^= byte
    return body + bytes([checksum])


def record(cmd: int, payload: bytes, long: bool) -> bytes:
    ctl = (FIXUP_LONG if long else 0) | FIXUP_POLL | (0x20 if len(payload) > 255 else 0)
    return bytes([ctl, cmd, len(payload) & 0xFF]) + payload


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--vectors", type=Path, required=True)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()

    seeds: dict[str, dict[str, bytes]] = {"decoder": {}, "base": {}, "fixup": {}}

    def add_stream(name: str, data: bytes, max_frame: int | None = None, timeout: int | None = None) -> None:
        buffer_index = DECODER_BUFFER_INDEX.get(max_frame or 0, 7 if max_frame is None else 6)
        settings = buffer_index | DECODER_TIMEOUT_INDEX.get(timeout or 0, 0) << 3 | 3 << 6
        seeds["decoder"][name] = bytes([settings, 0, 0]) + data
        seeds["base"][name] = BASE_SETTINGS + bytes([BASE_CUT_WHOLE]) + data

    def add_record(name: str, cmd: int, payload: bytes, long: bool) -> None:
        seeds["fixup"][name] = BASE_SETTINGS + record(cmd, payload, long)

    frames = json.loads((args.vectors / "frames.json").read_text())["frames"]
    session = b""
    requests = b""
    for frame in frames:
        data = unhex(frame["hex"])
        add_stream(f"frame-{frame['name']}", data)
        add_record(f"frame-{frame['name']}", frame["cmd"], unhex(frame["payload"]), frame["long"])
        session += data
        if frame["message"]["kind"] == "request":
            requests += record(frame["cmd"], unhex(frame["payload"]), frame["long"])
    add_stream("all-frames", session)
    seeds["fixup"]["all-requests"] = BASE_SETTINGS + requests

    invalid = json.loads((args.vectors / "invalid.json").read_text())
    for case in invalid["frame_level"]:
        add_stream(f"invalid-{case['name']}", unhex(case["hex"]))
    for case in invalid["message_level"]:
        payload = unhex(case["payload"])
        add_record(f"invalid-{case['name']}", case["cmd"], payload, case["long"])
        add_stream(f"invalid-{case['name']}", encode(case["cmd"], payload, case["long"]))

    streams = json.loads((args.vectors / "streams.json").read_text())["streams"]
    for stream in streams:
        data = b"".join(unhex(chunk["hex"]) for chunk in stream["chunks"])
        add_stream(f"stream-{stream['name']}", data, stream.get("max_frame"), stream.get("timeout_ms"))

    for target, files in seeds.items():
        directory = args.out / target
        shutil.rmtree(directory, ignore_errors=True)
        directory.mkdir(parents=True)
        for name, data in files.items():
            (directory / name).write_bytes(data)
    print(f"make_seeds: {', '.join(f'{len(files)} {target}' for target, files in seeds.items())} seeds in {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
