# SPDX-License-Identifier: MIT
"""One conversation from two tapped lines: the merge behind `ctrlbus capture --tap`.

A passive tap is two serial ports whose RX pins listen to the Core's TX line and to the base's TX
line. Each port hands over bytes when it likes (a USB adapter holds them for its latency timer,
16 ms by default on common FTDI chips, and the OS schedules the two reading threads as it likes), so
the times at which chunks are read are only roughly the times their bytes were on the wire, and a
chunk may hold several frames. Sorting chunks by read time alone can put an answer after the next
request, and the conversation then reads wrong (answers paired with the wrong request).

`TapMerger` merges by time and lets the protocol settle what the clocks cannot:

- each chunk is cut after every complete frame (one `StreamDecoder` per line finds them), so that
  the pieces of one read can go to different places in the conversation;
- pieces go out oldest first (a piece the protocol puts after a piece read later gets that later
  time, so that times never go back), except when the oldest piece of each line was read within `skew`
  seconds of the other's: then the order of the protocol decides. The Core has one request
  outstanding at a time (docs/protocol.md [core-one-outstanding]): while a request it sent is
  unanswered, the base's bytes go first (they are the answer, on the wire before the Core's next
  request); otherwise the Core's bytes go first (the base speaks when asked). A request counts as
  unanswered for `answer_limit` seconds at most: after that the Core has given up on it and may
  send again without an answer.

A line's decoder only cuts pieces: the annotator downstream decodes them again, as always.
No clock is read here; times are passed in.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, replace

from ctrlbus.capture import Direction
from ctrlbus.core.config import CoreConfig
from ctrlbus.frame import MAX_FRAME, Frame, StreamDecoder

# Read times of the two lines closer than this are not trusted to order them: a USB adapter's
# latency timer plus scheduling on a loaded machine.
__all__ = ["DEFAULT_ANSWER_LIMIT_S", "DEFAULT_SKEW_S", "Piece", "TapMerger"]

DEFAULT_SKEW_S = 0.05
# How long a Core waits for an answer before it may send without one (our emulator's §11.6 value;
# the real Core's is not published).
DEFAULT_ANSWER_LIMIT_S = CoreConfig().request_timeout_s


@dataclass(frozen=True)
class Piece:
    """Bytes of one line read at `time` (seconds); `ends_frame` if they end a complete frame."""

    direction: Direction
    data: bytes
    time: float
    ends_frame: bool


class TapMerger:
    """Takes the chunks of both lines as they are read (`add`) and hands them on as pieces in
    conversation order (`release`)."""

    def __init__(
        self,
        *,
        skew: float = DEFAULT_SKEW_S,
        answer_limit: float = DEFAULT_ANSWER_LIMIT_S,
        max_frame: int = MAX_FRAME,
    ) -> None:
        self.skew = skew
        self.answer_limit = answer_limit
        self._held: dict[Direction, deque[Piece]] = {direction: deque() for direction in Direction}
        # No times fed: a line's decoder never times out, it only finds where frames end.
        self._decoders = {direction: StreamDecoder(max_frame=max_frame) for direction in Direction}
        self._fed = dict.fromkeys(Direction, 0)
        self._request_time: float | None = None  # when the unanswered request ended, if any
        self._last_time = float("-inf")  # time of the last piece released

    @property
    def held(self) -> int:
        """Pieces waiting to be released."""
        return sum(len(pieces) for pieces in self._held.values())

    @property
    def oldest(self) -> float | None:
        """The read time of the oldest piece waiting, or None."""
        times = [pieces[0].time for pieces in self._held.values() if pieces]
        return min(times) if times else None

    def add(self, direction: Direction, data: bytes, time: float) -> None:
        """A chunk of `direction`'s line, read at `time` (each line's chunks in read order)."""
        start = self._fed[direction]
        self._fed[direction] += len(data)
        cut = 0
        for item in self._decoders[direction].feed_items(data):
            if isinstance(item, Frame):
                end = item.offset + item.size - start
                self._held[direction].append(Piece(direction, data[cut:end], time, True))
                cut = end
        if cut < len(data):
            self._held[direction].append(Piece(direction, data[cut:], time, False))

    def release(self, until: float | None) -> list[Piece]:
        """The pieces to hand on now, in conversation order: those read up to `until` (and any of
        the other line that the order puts before them); all of them if `until` is None (the end)."""
        out: list[Piece] = []
        core, base = self._held[Direction.CORE_TO_BASE], self._held[Direction.BASE_TO_CORE]
        while core or base:
            pieces = self._held[self._next_line(core[0], base[0])] if core and base else core or base
            piece = pieces[0]
            if until is not None and min(piece.time, self.oldest or piece.time) > until:
                break
            pieces.popleft()
            if piece.time < self._last_time:  # put after a later-read piece: keep time order
                piece = replace(piece, time=self._last_time)
            self._last_time = piece.time
            out.append(piece)
            if piece.ends_frame:
                self._request_time = piece.time if piece.direction is Direction.CORE_TO_BASE else None
        return out

    def _next_line(self, core: Piece, base: Piece) -> Direction:
        if abs(core.time - base.time) > self.skew:
            return core.direction if core.time < base.time else base.direction
        waiting = self._request_time is not None and core.time - self._request_time < self.answer_limit
        return Direction.BASE_TO_CORE if waiting else Direction.CORE_TO_BASE
