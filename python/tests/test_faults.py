# SPDX-License-Identifier: MIT
"""The fault injector (ctrlbus.faults): the spec grammar, each fault on its own, determinism, the
vtime filter, the link wrapper (with a fake clock: no timed assertions) and the fault: URL."""

from __future__ import annotations

import importlib
import random
import struct
from pathlib import Path
from typing import Any

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctrlbus.errors import LinkError, UsageError
from ctrlbus.faults import (
    CutWindow,
    Delivery,
    Direction,
    DirectionFaults,
    FaultFilter,
    FaultModel,
    FaultSpec,
    FaultyLink,
    fault_models,
    split_fault_url,
)
from ctrlbus.frame import StreamDecoder, encode
from ctrlbus.link import link_pair
from ctrlbus.ports import open_link

REPO = Path(__file__).resolve().parents[2]
FRAME = encode(0xF8, bytes((0x41,)) + bytes(12))  # a SET_V_AND_GET_DEADRECKON request


def hamming(a: bytes, b: bytes) -> int:
    return sum(bin(x ^ y).count("1") for x, y in zip(a, b, strict=True))


def delivered(pieces: list[tuple[float, bytes]]) -> bytes:
    return b"".join(piece for _, piece in pieces)


# --- the spec grammar --------------------------------------------------------------------------


def test_the_example_spec_parses_into_both_directions() -> None:
    spec = FaultSpec.parse("ber=1e-4,burst=0.01:1-64,drop=0.001,delay=5ms,cut=2s@10s")
    expected = DirectionFaults(
        ber=1e-4,
        burst=0.01,
        burst_bytes=(1, 64),
        drop=0.001,
        delay_s=0.005,
        cuts=(CutWindow(2.0, 10.0),),
    )
    assert spec.tx == expected and spec.rx == expected
    assert spec.seed is None


def test_direction_prefixes_units_and_repeated_cuts() -> None:
    spec = FaultSpec.parse(
        " tx.ber=0.5 , rx.drop=0.1:2-3, dropchunk=0.2, split=1-4:250us, rx.delay=1s:20ms,"
        " cut=1.5s@1min/2min, tx.cut=100ms@0s, seed=42 "
    )
    assert spec.tx.ber == 0.5 and spec.rx.ber == 0.0
    assert spec.rx.drop == 0.1 and spec.rx.drop_run == (2, 3) and spec.tx.drop == 0.0
    assert spec.tx.drop_chunk == spec.rx.drop_chunk == 0.2
    assert spec.tx.split == (1, 4) and spec.tx.split_gap_s == pytest.approx(250e-6)
    assert spec.rx.delay_s == 1.0 and spec.rx.jitter_s == pytest.approx(0.02) and spec.tx.delay_s == 0.0
    assert spec.rx.cuts == (CutWindow(1.5, 60.0, 120.0),)
    assert spec.tx.cuts == (CutWindow(1.5, 60.0, 120.0), CutWindow(0.1, 0.0))
    assert spec.seed == 42


@pytest.mark.parametrize(
    "text",
    [
        "ber=1e-4,burst=0.01:1-64,drop=0.001,delay=5ms,cut=2s@10s",
        "tx.ber=0.5,rx.drop=0.1:2-3,dropchunk=0.2,split=1-4:250us,rx.delay=1s:20ms,cut=1.5s@1min/2min",
        "rx.cut=3s@0s,seed=7",
        "",
        "none",
    ],
)
def test_the_canonical_form_parses_back_to_the_same_spec(text: str) -> None:
    spec = FaultSpec.parse(text)
    assert FaultSpec.parse(str(spec)) == spec


def test_an_empty_spec_means_no_faults() -> None:
    for text in ("", "  ", "none", "NONE"):
        spec = FaultSpec.parse(text)
        assert not spec.tx.active and not spec.rx.active
        assert str(spec) == "none"


@pytest.mark.parametrize(
    ("text", "bad_part", "reason"),
    [
        ("ber=1e-4,bre=0.1", "bre=0.1", "unknown fault 'bre'"),
        ("ber=2", "ber=2", "between 0 and 1"),
        ("ber=nan", "ber=nan", "between 0 and 1"),
        ("ber=lots", "ber=lots", "not a number"),
        ("ber", "ber", "NAME=VALUE"),
        ("ber=", "ber=", "NAME=VALUE"),
        ("ber=0.1,,drop=0.1", "ber=0.1,,drop=0.1", "empty item"),
        ("up.ber=0.1", "up.ber=0.1", "tx or rx"),
        ("ber=0.1,tx.ber=0.2", "tx.ber=0.2", "given twice for tx"),
        ("burst=0.1:64-1", "burst=0.1:64-1", "runs backwards"),
        ("burst=0.1:0-4", "burst=0.1:0-4", "burst length must be 1..1048576"),
        ("burst=0.1:x", "burst=0.1:x", "not a whole number"),
        ("split=0", "split=0", "piece size"),
        ("delay=5", "delay=5", "not a duration"),
        ("delay=5ms:fast", "delay=5ms:fast", "jitter 'fast'"),
        ("cut=2s", "cut=2s", "DURATION@START"),
        ("cut=0s@1s", "cut=0s@1s", "longer than 0 s"),
        ("cut=2s@1s/2s", "cut=2s@1s/2s", "period must be longer"),
        ("cut=2s@-1s", "cut=2s@-1s", "cut start"),
        ("seed=x", "seed=x", "not a whole number"),
        ("tx.seed=1", "tx.seed=1", "both directions"),
        ("seed=1,seed=2", "seed=2", "seed given twice"),
    ],
)
def test_a_bad_spec_names_the_bad_part(text: str, bad_part: str, reason: str) -> None:
    with pytest.raises(UsageError) as caught:
        FaultSpec.parse(text)
    message = str(caught.value)
    assert repr(bad_part) in message and reason in message


def test_a_spec_that_is_not_text_is_refused() -> None:
    with pytest.raises(UsageError, match="must be text"):
        FaultSpec.parse(b"ber=0.1")  # type: ignore[arg-type]


def test_bad_model_arguments_are_refused() -> None:
    with pytest.raises(UsageError, match="direction"):
        FaultModel("ber=0.1", direction="sideways")
    with pytest.raises(UsageError, match="seed"):
        FaultModel("ber=0.1", seed="1")  # type: ignore[arg-type]
    model = FaultModel("ber=0.1")
    for now in (float("nan"), float("inf"), True):
        with pytest.raises(UsageError, match="time"):
            model.apply(b"x", now)


# --- the model, one fault at a time ------------------------------------------------------------


def test_no_faults_delivers_every_chunk_unchanged_at_once() -> None:
    model = FaultModel("")
    for k in range(5):
        assert model.apply(FRAME, k * 0.1) == [(k * 0.1, FRAME)]
    assert model.apply(b"", 1.0) == []
    assert model.counters.chunks == 5 and model.counters.bytes_in == model.counters.bytes_out == 5 * len(
        FRAME
    )


def test_bit_errors_flip_about_ber_of_the_bits_and_are_counted() -> None:
    model = FaultModel("ber=1e-3", seed=5)
    data = random.Random(1).randbytes(100_000)
    out = delivered(model.apply(data, 0.0))
    assert len(out) == len(data)
    flips = hamming(data, out)
    assert flips == model.counters.bits_flipped
    assert 640 <= flips <= 960  # 800 expected; the seed is fixed, so this cannot flap


def test_bit_errors_drops_and_bursts_do_not_depend_on_how_the_stream_is_chunked() -> None:
    data = random.Random(2).randbytes(20_000)
    spec = "ber=1e-3,drop=1e-3:1-3,burst=1e-3:1-8"
    whole = delivered(FaultModel(spec, seed=9).apply(data, 0.0))
    model = FaultModel(spec, seed=9)
    rng = random.Random(3)
    pieces = []
    at = 0
    while at < len(data):
        size = rng.randint(1, 50)
        pieces.append(delivered(model.apply(data[at : at + size], 0.0)))
        at += size
    assert b"".join(pieces) == whole


def test_the_same_seed_gives_the_same_faults_and_another_seed_others() -> None:
    spec = "ber=1e-3,burst=0.02:1-16,drop=0.01:1-4,dropchunk=0.05,split=1-5:1ms,delay=2ms:3ms"

    def run(seed: int) -> list[tuple[float, bytes]]:
        model = FaultModel(spec, seed=seed)
        return [piece for k in range(300) for piece in model.apply(FRAME, k * 0.01)]

    assert run(1) == run(1)  # bursts, splits, delays and all
    assert run(1) != run(2)
    assert FaultModel(spec + ",seed=1").seed == 1  # the spec's seed applies when none is given


def test_dropped_bytes_leave_a_subsequence_and_are_counted() -> None:
    model = FaultModel("drop=0.01:1-5", seed=3)
    data = bytes(range(256)) * 40
    out = delivered(model.apply(data, 0.0))
    assert model.counters.bytes_dropped == len(data) - len(out) > 0
    assert model.counters.drop_runs > 0
    remaining = iter(data)
    assert all(byte in remaining for byte in out)  # in order: a subsequence


def test_a_lost_chunk_delivers_nothing() -> None:
    model = FaultModel("dropchunk=1")
    delivery = model.apply_detailed(FRAME, 0.0)
    assert delivery.pieces == [] and not delivery.intact and delivery.dropped == len(FRAME)
    assert model.counters.chunks_dropped == 1 and model.counters.bytes_out == 0
    assert model.counters.bytes_dropped == len(FRAME)


def strip_garbage(delivery: Delivery) -> bytes:
    """The chunk's own bytes out of a delivery that lost none: the line minus its garbage."""
    line = delivered(delivery.pieces)
    own = bytearray()
    start = 0
    shift = 0
    for at, length in delivery.garbage:
        own += line[start + shift : at + shift]
        start = at
        shift += length
    own += line[start + shift :]
    return bytes(own)


def test_a_burst_before_a_byte_is_garbage_with_a_false_header() -> None:
    model = FaultModel("burst=1:6", seed=4)
    for k in range(50):
        delivery = model.apply_detailed(bytes((k,)), k * 0.1)
        out = delivered(delivery.pieces)
        assert delivery.garbage == ((0, 6),) and delivery.burst == 6 and delivery.intact
        assert len(out) == 7 and out[-1] == k
        garbage = out[:6]
        assert 0x10 in garbage[:5] or 0x50 in garbage[:4]  # with room for its bogus length
    assert model.counters.bursts == model.counters.false_flags == 50
    assert model.counters.burst_bytes == 300


def test_garbage_inside_a_chunk_breaks_it_but_keeps_its_bytes_in_order() -> None:
    model = FaultModel("burst=0.2:1-9", seed=5)
    hit = 0
    for k in range(200):
        delivery = model.apply_detailed(FRAME, k * 0.1)
        assert strip_garbage(delivery) == FRAME
        inside = any(0 < at < len(FRAME) for at, _ in delivery.garbage)
        assert delivery.intact == (not inside)
        hit += inside
    assert hit > 50


def test_the_decoder_finds_every_frame_behind_bursts_unless_a_false_frame_covers_it() -> None:
    """Bursts hold false headers; a base's decoder (512-byte buffer, 100 ms timeout) recovers
    every frame they did not land inside, except where garbage and real bytes happen to pass
    the 8-bit XOR as one false frame (protocol.md §7.4), which then covers the real ones."""
    model = FaultModel("burst=0.03:1-64", seed=3)
    decoder = StreamDecoder(timeout=0.1, max_frame=512)
    intact: list[tuple[int, bytes]] = []  # stream offset of each frame that arrived whole
    decoded = []
    offset = 0
    for k in range(400):
        frame = encode(0xF8, bytes((0x41,)) + struct.pack("<iii", k * 977, 0, -k * 31))
        delivery = model.apply_detailed(frame, k * 0.01)
        if delivery.intact:
            intact.append((offset + delivery.burst, frame))
        for when, piece in delivery.pieces:
            decoded += decoder.feed(piece, when)
            offset += len(piece)
    decoded += decoder.feed(b"", 5.0)
    assert model.counters.bursts > 100 and len(intact) > 200
    found = {(f.offset, f.raw) for f in decoded}
    false_spans = [(f.offset, f.offset + f.size) for f in decoded if (f.offset, f.raw) not in set(intact)]
    lost = [at for at, frame in intact if (at, frame) not in found]
    assert len(lost) < 20
    for at in lost:
        assert any(start <= at < end for start, end in false_spans), f"frame at {at} lost for no reason"


def test_split_delivers_pieces_in_order_with_the_gap_between_them() -> None:
    model = FaultModel("split=2-3:1ms")
    pieces = model.apply(FRAME, 5.0)
    assert delivered(pieces) == FRAME
    assert all(2 <= len(piece) <= 3 for _, piece in pieces[:-1]) and 1 <= len(pieces[-1][1]) <= 3
    assert [when for when, _ in pieces] == pytest.approx([5.0 + 0.001 * k for k in range(len(pieces))])


def test_delay_and_jitter_keep_the_order() -> None:
    model = FaultModel("delay=10ms:50ms", seed=6)
    times = []
    for k in range(200):
        ((when, piece),) = model.apply(bytes((k,)), k * 0.001)
        assert piece == bytes((k,))
        assert when >= k * 0.001 + 0.010
        times.append(when)
    assert times == sorted(times)
    assert max(t - k * 0.001 for k, t in enumerate(times)) > 0.040  # the jitter is used


def test_a_cut_silences_the_line_for_its_window_and_again_every_period() -> None:
    model = FaultModel("cut=1s@2s/10s", origin=100.0)
    arrived = [k * 0.5 for k in range(60) if model.apply(b"x", 100.0 + k * 0.5)]
    lost = {k * 0.5 for k in range(60)} - set(arrived)
    assert lost == {2.0, 2.5, 12.0, 12.5, 22.0, 22.5}
    assert model.counters.cuts == 3 and model.counters.bytes_cut == 6
    assert model.cut_windows(125.0) == [(102.0, 103.0), (112.0, 113.0), (122.0, 123.0)]


def test_a_cut_of_both_directions_hits_both_at_the_same_time() -> None:
    tx, rx = fault_models("cut=1s@1s")
    assert tx.apply(b"a", 50.0)  # the first time seen starts both clocks
    assert not rx.apply(b"b", 51.5)
    assert not tx.apply(b"c", 51.9)
    assert rx.apply(b"d", 52.0) and tx.apply(b"e", 52.1)
    assert tx.origin == rx.origin == 50.0


def test_a_one_way_cut_leaves_the_other_direction_alone() -> None:
    tx, rx = fault_models("rx.cut=1s@0s", origin=0.0)
    assert tx.apply(b"a", 0.5) == [(0.5, b"a")]
    assert rx.apply(b"b", 0.5) == []


def test_the_delivery_account_says_which_chunks_were_hit() -> None:
    model = FaultModel("ber=2e-3", seed=12)
    hit = intact = 0
    for k in range(500):
        delivery = model.apply_detailed(FRAME, k * 0.01)
        out = delivered(delivery.pieces)
        assert delivery.intact == (out == FRAME)
        assert delivery.flipped == hamming(out, FRAME)
        hit += not delivery.intact
        intact += delivery.intact
    assert hit > 0 and intact > 0


@settings(max_examples=200, deadline=None)
@given(
    st.lists(st.binary(max_size=80), max_size=20),
    st.sampled_from(
        ["ber=0.01", "drop=0.05:1-3", "dropchunk=0.2", "burst=0.05:1-9", "split=1-4:1ms", "delay=1ms:2ms", ""]
    ),
    st.integers(0, 2**32),
)
def test_times_never_run_backwards_and_the_counters_add_up(chunks: list[bytes], spec: str, seed: int) -> None:
    model = FaultModel(spec, seed=seed)
    last = float("-inf")
    out = 0
    for k, chunk in enumerate(chunks):
        for when, piece in model.apply(chunk, k * 0.001):
            assert when >= last and piece
            last = when
            out += len(piece)
    c = model.counters
    assert c.bytes_out == out
    assert c.bytes_in + c.burst_bytes - c.bytes_dropped - c.bytes_cut == out


# --- as a vtime filter -------------------------------------------------------------------------


def test_the_filter_holds_delayed_bytes_until_they_are_due() -> None:
    seen: list[tuple[bytes, float, bool]] = []
    filt = FaultFilter(FaultModel("delay=10ms"), observe=lambda c, t, d: seen.append((c, t, d.intact)))
    assert filt(FRAME, 1.0) == b""
    assert filt.held_bytes == len(FRAME)
    assert filt(b"", 1.005) == b""
    assert filt(b"", 1.010) == FRAME
    assert seen == [(FRAME, 1.0, True)]  # empty calls are not observed


# --- the link wrapper --------------------------------------------------------------------------


class FakeClock:
    def __init__(self) -> None:
        self.now = 1000.0

    def __call__(self) -> float:
        return self.now


def test_the_link_applies_tx_faults_to_writes_and_rx_faults_to_reads() -> None:
    ours, theirs = link_pair()
    link = FaultyLink(ours, "tx.burst=1:3,rx.dropchunk=1", seed=1)
    link.write(b"x")
    sent = theirs.read(1.0)
    assert len(sent) == 4 and sent.endswith(b"x")
    theirs.write(FRAME)
    assert link.read(0.0) == b""  # read, and lost on the way
    assert link.counters()["tx"]["bursts"] == 1 and link.counters()["rx"]["chunks_dropped"] == 1
    assert link.name.startswith("fault:") and link.name.endswith("|pair:a")
    link.close()
    with pytest.raises(LinkError):
        theirs.write(b"x")


def test_the_link_delays_in_both_directions_by_its_clock() -> None:
    clock = FakeClock()
    ours, theirs = link_pair()
    link = FaultyLink(ours, "delay=20ms", clock=clock)
    link.write(FRAME)
    assert theirs.read(0.0) == b""  # held back
    theirs.write(b"answer")
    assert link.read(0.0) == b""  # arrived, but not due yet
    clock.now += 0.020
    assert link.read(0.0) == b"answer"  # due now; the held write went out on this call too
    assert theirs.read(0.0) == FRAME


def test_a_cut_on_the_link_counts_from_its_creation() -> None:
    clock = FakeClock()
    ours, theirs = link_pair()
    link = FaultyLink(ours, "tx.cut=1s@2s", clock=clock)
    clock.now += 2.5
    link.write(b"lost")
    clock.now += 1.0
    link.write(b"kept")
    assert theirs.read(0.0) == b"kept"
    assert link.counters()["tx"]["cuts"] == 1


def test_fault_urls_open_through_open_link() -> None:
    link = open_link("fault:tx.burst=1:2-2|loop://")
    try:
        assert isinstance(link, FaultyLink)
        link.write(b"x")
        echoed = b""
        for _ in range(50):
            echoed += link.read(0.05)
            if len(echoed) >= 3:
                break
        assert echoed.endswith(b"x") and len(echoed) == 3
    finally:
        link.close()


def test_fault_urls_nest() -> None:
    link = open_link("fault:tx.ber=0.1|fault:rx.ber=0.2|loop://")
    try:
        assert isinstance(link, FaultyLink) and isinstance(link.inner, FaultyLink)
        assert link.spec.tx.ber == 0.1 and link.inner.spec.rx.ber == 0.2
    finally:
        link.close()


@pytest.mark.parametrize(
    ("url", "complaint"),
    [
        ("fault:ber=1e-4", "needs the port after a '|'"),
        ("fault:ber=1e-4|", "needs the port after a '|'"),
        ("fault:bre=1e-4|loop://", "'bre=1e-4'"),
    ],
)
def test_bad_fault_urls_say_what_is_wrong(url: str, complaint: str) -> None:
    with pytest.raises(UsageError, match=complaint.replace("|", r"\|")):
        open_link(url)


def test_split_fault_url() -> None:
    spec, inner = split_fault_url("fault:rx.cut=2s@10s|socket://127.0.0.1:5555")
    assert inner == "socket://127.0.0.1:5555"
    assert spec.rx.cuts == (CutWindow(2.0, 10.0),) and not spec.tx.cuts
    with pytest.raises(UsageError):
        split_fault_url("socket://127.0.0.1:5555")


def test_direction_names() -> None:
    assert [d.value for d in Direction] == ["tx", "rx"]


# --- end to end: the soak harness (bench/soak.py) in virtual time ------------------------------


@pytest.mark.slow  # a soak or long end-to-end run: make check leaves it out
def test_through_bursts_and_cuts_the_base_keeps_its_limits_and_stops_in_time(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The Core emulator drives the simulated base through faults on both directions (virtual
    time, so deterministic): no motion command beyond the limits reaches the robot, and every cut
    stops the wheels one watchdog time after the last request that got through."""
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    soak: Any = importlib.import_module("soak")
    result = soak.run_virtual("ber=1e-4,burst=1e-3:1-64,cut=2s@10s/30s", 1500)
    assert result["exchanges"] >= 1500
    assert result["faults_to_base"]["bursts"] > 0 and result["faults_to_core"]["bits_flipped"] > 0
    assert result["retries"] > 0  # the faults did cost something
    assert result["commands_clamped"] > 0 and result["commands_over_limits"] == 0
    assert len(result["cuts"]) == 2
    for cut in result["cuts"]:
        assert cut["stop_after_last_command_s"] == pytest.approx(1.0)
        assert 0.0 <= cut["stop_after_cut_s"] <= 1.0
        assert cut["first_exchange_after_s"] is not None
