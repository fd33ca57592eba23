# SPDX-License-Identifier: MIT
"""decode/spy pair answers with requests by order, timing and size on a noisy line.

A Core that timed out (or sent a flushing SYNC) has moved on when a late answer comes; pairing
that answer with the newest request read it with the wrong layout ("OK to GET_BASE_SENSOR_DATA:
13 payload bytes, expected 64", "OK to SYNC") and blamed the base. The faulted capture here is made
in the test: the Core emulator and the simulated base in virtual time, the fault injector on both
directions with fixed seeds, the bytes recorded as each end received them.
"""

from __future__ import annotations

from typing import Any

import pytest

from ctrlbus.annotate import OK_SIZES, Annotator, FrameNote, ok_size_fits
from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.capture import Direction
from ctrlbus.core import CoreSession
from ctrlbus.errors import MessageError
from ctrlbus.faults import FaultFilter, fault_models
from ctrlbus.frame import encode
from ctrlbus.messages import (
    GetBaseSensorData,
    GetBaseStatus,
    GetBaseStatusAnswer,
    Response,
    SetVAndGetDeadreckon,
    SetVAndGetDeadreckonAnswer,
    Sync,
    answer_frame,
    decode_answer,
    request_frame,
)
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.world import World
from ctrlbus.vtime import VirtualBus

C, B = Direction.CORE_TO_BASE, Direction.BASE_TO_CORE


class Recording:
    """Both ends of a VirtualBus, recording what each received: [(time, direction, bytes)]."""

    def __init__(self, core: CoreSession, base: BaseStack) -> None:
        self.core = core
        self.base = base
        self.records: list[tuple[float, Direction, bytes]] = []

    # the base's side
    def receive(self, data: bytes, now: float) -> bytes:
        self.records.append((now, C, data))
        return self.base.receive(data, now)

    def tick(self, now: float) -> bytes:
        return self.base.tick(now)


class RecordingCore:
    def __init__(self, recording: Recording) -> None:
        self._recording = recording
        self._core = recording.core

    def poll(self, now: float) -> bytes | None:
        return self._core.poll(now)

    def next_poll_time(self) -> float | None:
        return self._core.next_poll_time()

    def receive(self, data: bytes, now: float) -> None:
        self._recording.records.append((now, B, data))
        self._core.receive(data, now)


def faulted_capture(seed: int, seconds: float) -> list[tuple[float, Direction, bytes]]:
    core = CoreSession(port="fault")
    recording = Recording(core, BaseStack(SimulatedBase(World(seed=1)), BaseConfig()))
    to_base, to_core = fault_models("ber=3e-4,burst=3e-3:1-64", seed=seed)
    bus = VirtualBus(
        RecordingCore(recording),  # type: ignore[arg-type]
        recording,
        to_base=FaultFilter(to_base),
        to_core=FaultFilter(to_core),
    )
    bus.run_for(seconds)
    return recording.records


def annotate(records: list[tuple[float, Direction, bytes]]) -> list[FrameNote]:
    annotator = Annotator(timeout=0.1)
    notes: list[Any] = []
    for time, direction, data in records:
        notes += annotator.feed(data, direction, time)
    notes += annotator.finish()
    return [note for note in notes if isinstance(note, FrameNote)]


@pytest.mark.parametrize("seed", [1, 2, 3])
def test_no_answer_on_a_faulted_line_is_read_with_the_wrong_request(seed: int) -> None:
    answers = [note for note in annotate(faulted_capture(seed, 30.0)) if note.direction is B]
    assert len(answers) > 500
    # The simulated base sends no malformed answer: a format error would be a pairing mistake
    # (a damaged frame that passes the 8-bit XOR could make one, but not with these seeds).
    mistakes = [(note.to, note.error_message) for note in answers if note.error == "format"]
    assert mistakes == []
    late = [note for note in answers if any(text.startswith("a late answer") for text in note.notes)]
    unpaired = [note for note in answers if note.error == "unpaired"]
    assert late or unpaired  # the line did take answers away: the test is about something
    for note in unpaired:
        assert note.error_message is not None and "format" not in note.error_message


def frames(*items: tuple[float, Direction, bytes]) -> list[FrameNote]:
    return annotate(list(items))


def test_a_late_answer_pairs_with_the_request_it_fits_not_the_newer_one() -> None:
    set_v = request_frame(SetVAndGetDeadreckon(0, 0, 0))
    sensor = request_frame(GetBaseSensorData())
    deadreckon = answer_frame(SetVAndGetDeadreckonAnswer(0, 0, 0, 0), long=True)
    distances = encode(0x02, bytes(64), long=True)
    notes = frames((0.0, C, set_v), (0.25, C, sensor), (0.26, B, deadreckon), (0.27, B, distances))
    answers = [note for note in notes if note.direction is B]
    assert [(note.to, note.error) for note in answers] == [
        ("SET_V_AND_GET_DEADRECKON", None),
        ("GET_BASE_SENSOR_DATA", None),
    ]
    assert any("a late answer" in text for text in answers[0].notes)


def test_the_answer_held_behind_a_flushing_sync_is_not_read_as_the_sync_answer() -> None:
    status = request_frame(GetBaseStatus())
    flush = request_frame(Sync(bytes(507)), long=True)
    ok = answer_frame(GetBaseStatusAnswer(80, 0), long=True)
    notes = frames((0.0, C, status), (0.2, C, flush), (0.21, B, ok), (0.26, B, flush))
    answers = [note for note in notes if note.direction is B]
    assert [(note.name, note.to, note.error) for note in answers] == [
        ("OK", "GET_BASE_STATUS", None),
        ("SYNC", "SYNC", None),
    ]


def test_an_answer_that_fits_no_waiting_request_is_unpaired_not_a_format_error() -> None:
    status = request_frame(GetBaseStatus())
    notes = frames((0.0, C, status), (0.01, B, encode(0x02, bytes(64), long=True)))
    (answer,) = [note for note in notes if note.direction is B]
    assert answer.error == "unpaired" and answer.to is None
    assert answer.error_message is not None and "fits no outstanding request" in answer.error_message
    assert answer.guess == "GET_BASE_SENSOR_DATA"  # read by its size, marked as a guess
    assert "unpaired: it fits none of the waiting requests (GET_BASE_STATUS)" in answer.notes


def test_a_request_too_old_for_the_answer_is_not_paired() -> None:
    status = request_frame(GetBaseStatus())
    ok = answer_frame(GetBaseStatusAnswer(80, 0), long=True)
    notes = frames((0.0, C, status), (5.0, B, ok))
    (answer,) = [note for note in notes if note.direction is B]
    assert answer.to is None and answer.error == "unpaired"


@pytest.mark.parametrize("name", sorted(OK_SIZES))
def test_the_pairing_size_table_agrees_with_the_message_codec(name: str) -> None:
    """OK_SIZES (also in the dissector and the sigrok decoder) says a size fits exactly when the
    codec decodes an OK of that size (zero bytes: no content to refuse)."""
    for size in range(0, 520):
        payload = bytes(size)
        try:
            decode_answer(name, Response.OK, payload)
            decodes = True
        except MessageError:
            decodes = False
        assert ok_size_fits(name, payload) == decodes, (name, size)
