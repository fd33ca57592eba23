# SPDX-License-Identifier: MIT
"""The reference base's own configuration blob and bumper/cliff bitmaps, read as protocol §5.7 says.

The bytes are the real firmware's answers, recorded once (tests/data/refbase_answers.json says
how); no test here runs the firmware. §5.7: bumpers in bits 0-1, cliff sensors in bits 2-5, active
low. The reference's blob lists its two bumpers with ids 0-1 and its four cliffs with ids 2-5.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from core_fakes import FakeBase

from ctrlbus import binconf
from ctrlbus.cli.core_status import json_status, render_screen
from ctrlbus.core import CoreSession
from ctrlbus.core.geometry import geometry_from_conf, geometry_from_tree, shared_bits
from ctrlbus.frame import StreamDecoder
from ctrlbus.messages import GetBaseConf, decode_answer
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.schema import check_snapshot
from ctrlbus.web.snapshot import dashboard_snapshot

RECORDED = json.loads((Path(__file__).parent / "data" / "refbase_answers.json").read_text())

# protocol.md §5.7, for the reference base: what each input of the firmware sets (a 0 bit).
BUMPER_BITS = {"bump L": 0, "bump R": 1}
CLIFF_BITS = {"cliff 0": 2, "cliff 1": 3, "cliff 2": 4, "cliff 3": 5}


def recorded_payload(name: str) -> bytes:
    (frame,) = StreamDecoder().feed(bytes.fromhex(RECORDED["answers"][name]))
    return frame.payload


def recorded_bitmap_payload(label: str) -> bytes:
    (frame,) = StreamDecoder().feed(bytes.fromhex(RECORDED["bumper_data_by_input"][label]))
    return frame.payload


def reference_blob() -> bytes:
    # The OK payload of GET_BASE_CONF_ADV is the blob itself.
    return recorded_payload("GET_BASE_CONF_ADV")


def test_the_reference_blob_numbers_its_cliffs_as_bitmap_bits() -> None:
    tree: Any = binconf.decode(reference_blob())
    entries = tree["base"]["sensors"]
    ids = {
        kind: [int(e["id"]["u8"]) for e in entries if e["type"] == {"dict": kind}]
        for kind in ("bumper", "cliff")
    }
    assert ids == {"bumper": [0, 1], "cliff": [2, 3, 4, 5]}  # the recorded data is what we think it is
    geometry = geometry_from_tree(tree)
    assert geometry is not None
    assert [bumper.bit for bumper in geometry.bumpers] == sorted(BUMPER_BITS.values())
    assert list(geometry.cliff_bits) == sorted(CLIFF_BITS.values())


def test_both_configuration_sources_agree_on_the_reference_bits() -> None:
    conf = decode_answer(GetBaseConf(), 0x02, recorded_payload("GET_BASE_CONF"))
    from_conf = geometry_from_conf(conf)  # type: ignore[arg-type]
    tree: Any = binconf.decode(reference_blob())
    from_blob = geometry_from_tree(tree)
    assert from_blob is not None
    assert from_blob.cliff_bits == from_conf.cliff_bits
    assert [b.bit for b in from_blob.bumpers] == [b.bit for b in from_conf.bumpers]


@pytest.mark.parametrize("label", list(RECORDED["bumper_data_by_input"]))
def test_every_reference_input_shows_on_its_own_bumper_or_cliff(label: str) -> None:
    """The Core fed the reference's blob and one recorded bitmap shows exactly the input that the
    firmware had set, in the session, the dashboard's snapshot and `ctrlbus core`'s JSON and
    screen."""
    base = FakeBase(
        raw_ok={
            "GET_BASE_CONF_ADV": reference_blob(),
            "GET_BASE_CONF": recorded_payload("GET_BASE_CONF"),
            "GET_BASE_BUMPER_DATA": recorded_bitmap_payload(label),
        }
    )
    core = CoreSession(port="fake")
    bus = VirtualBus(core, base)
    assert bus.run_until(lambda: core.connected and core.bumper_bitmap is not None, 5.0), core.events()
    assert core.telemetry.config_source == "GET_BASE_CONF_ADV"

    want_bumpers = [BUMPER_BITS.get(label) == bit for bit in (0, 1)]
    want_cliffs = [CLIFF_BITS.get(label) == bit for bit in (2, 3, 4, 5)]
    assert list(core.bumpers_pressed) == want_bumpers
    assert list(core.telemetry.cliffs_triggered) == want_cliffs

    snap = dashboard_snapshot(core)
    assert check_snapshot(snap) == []
    assert [(b["bit"], b["pressed"]) for b in snap["bumpers"]] == list(zip((0, 1), want_bumpers, strict=True))
    assert [(c["bit"], c["triggered"]) for c in snap["cliffs"]] == list(
        zip((2, 3, 4, 5), want_cliffs, strict=True)
    )
    status = json.loads(json.dumps(json_status(core)))
    assert status["bumpers_pressed"] == want_bumpers
    assert status["cliffs_triggered"] == want_cliffs
    screen = render_screen(core)
    triggered = [str(bit) for bit, on in zip((2, 3, 4, 5), want_cliffs, strict=True) if on]
    assert f"cliff bits {', '.join(triggered) or 'none'}" in screen


def test_a_blob_numbering_its_cliffs_from_0_is_read_by_bits_and_logged() -> None:
    """Cliff ids 0-3 beside bumpers 0-1 (how ctrlbus's own example numbered them before): the ids
    are bits, so two cliffs share the bumpers' bits, and the Core says so."""
    tree: Any = json.loads(binconf.example_config_text())
    cliffs = [entry for entry in tree["base"]["sensors"] if entry["type"] == {"dict": "cliff"}]
    for index, entry in enumerate(cliffs):
        entry["id"] = {"u8": index}
    blob = binconf.encode(tree)
    geometry = geometry_from_tree(binconf.decode(blob))
    assert geometry is not None and geometry.cliff_bits == (0, 1, 2, 3)
    assert shared_bits(geometry) == (0, 1)
    core = CoreSession(port="fake")
    bus = VirtualBus(core, FakeBase(blob=blob))
    assert bus.run_until(lambda: core.connected, 5.0)
    assert any("the same bit (0, 1)" in event.text for event in core.events())
