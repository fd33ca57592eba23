# SPDX-License-Identifier: MIT
"""Our side of the benchmarks: the one place that knows the ctrlbus decoder APIs (C and Python).

Each accessor returns the thing to measure, or raises Pending naming what is missing, so a
benchmark reports "pending" for our side instead of a made-up figure while the peer's side is
still measured.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable
from pathlib import Path
from typing import Any

from common import C_INCLUDE, C_SRC, ensure_ctrlbus_importable

FRAME_HEADER = C_INCLUDE / "ctrlbus" / "frame.h"
FRAME_SOURCE = C_SRC / "frame.c"


class Pending(Exception):
    """Our side of a benchmark cannot run yet; the message says what it waits for."""


def c_decoder_sources() -> list[Path]:
    """The C sources the decoder harness links against (frame.c and what it needs)."""
    if not FRAME_HEADER.is_file() or not FRAME_SOURCE.is_file():
        raise Pending(
            f"the C stream decoder ({FRAME_HEADER.relative_to(C_INCLUDE.parent.parent)}, "
            f"{FRAME_SOURCE.relative_to(C_SRC.parent.parent)}) is not written yet"
        )
    return [FRAME_SOURCE]


def ctrlbus_module(name: str) -> Any:
    """Import ctrlbus.<name> from the tree, or raise Pending if it does not exist yet.

    Imported by name so the benchmarks type-check and run before the module is written.
    """
    ensure_ctrlbus_importable()
    try:
        return importlib.import_module(f"ctrlbus.{name}")
    except ModuleNotFoundError as exc:
        if exc.name in (f"ctrlbus.{name}", "ctrlbus"):
            raise Pending(f"ctrlbus.{name} is not written yet") from None
        raise


def _frame_module() -> Any:
    frame = ctrlbus_module("frame")
    if not hasattr(frame, "StreamDecoder"):
        raise Pending("ctrlbus.frame has no StreamDecoder yet")
    return frame


# Takes a chunk and the time it arrived (seconds; None = no time, so no timeout).
FeedFrames = Callable[[bytes, float | None], list[bytes]]
FeedCount = Callable[[bytes], int]


def python_decoder_counting() -> Callable[[], FeedCount]:
    """A factory of fresh decoders that take a chunk and return how many frames it completed."""
    frame = _frame_module()

    def make() -> FeedCount:
        decoder = frame.StreamDecoder()

        def feed(chunk: bytes) -> int:
            return len(decoder.feed(chunk))

        return feed

    return make


def python_decoder_frames() -> tuple[Callable[[], FeedFrames], str]:
    """A factory of fresh decoders with the default settings, which take a chunk and its time and
    return the frames it completed as wire bytes; and a description of those settings."""
    frame = _frame_module()

    def make() -> FeedFrames:
        decoder = frame.StreamDecoder()

        def feed(chunk: bytes, now: float | None) -> list[bytes]:
            return [f.raw for f in decoder.feed(chunk, now)]

        return feed

    probe = frame.StreamDecoder()
    return make, f"ctrlbus.frame.StreamDecoder(), max_frame {probe.max_frame}, timeout {probe.timeout} s"
