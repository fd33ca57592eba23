# SPDX-License-Identifier: MIT
"""Getting the base's configuration: on a harsh line, without a blob, and what a Core ignores.

- A harsh line (BER 1e-3, the fault injector, virtual time): the 313-byte 0x21 answer rarely
  arrives intact; the Core falls back to GET_BASE_CONF, asks for the blob again while polling, and
  counts no disconnect for a base that answers (protocol §11.2 [core-config-retry]).
- The simulated base serves a blob made from its description by default; without one, the
  Core's fallback is "not supported", not an error.
- The reference's blob lists no sonars: their readings are shown as ignored, with one warning.
"""

from __future__ import annotations

import json
import statistics
from pathlib import Path

import pytest
from core_fakes import FakeBase

from ctrlbus import binconf
from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.cli import main
from ctrlbus.cli.core_status import json_status, render_screen
from ctrlbus.core import CoreSession
from ctrlbus.core.session import ConnectionState
from ctrlbus.errors import UsageError
from ctrlbus.faults import FaultFilter, fault_models
from ctrlbus.frame import StreamDecoder
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.server import SimSettings, build_simulated_stack
from ctrlbus.sim.world import World
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.schema import check_snapshot
from ctrlbus.web.snapshot import dashboard_snapshot

RECORDED = json.loads((Path(__file__).parent / "data" / "refbase_answers.json").read_text())


def recorded_payload(name: str) -> bytes:
    (frame,) = StreamDecoder().feed(bytes.fromhex(RECORDED["answers"][name]))
    return frame.payload


REFERENCE_BLOB = recorded_payload("GET_BASE_CONF_ADV")  # 308 bytes, a 313-byte answer frame


def harsh_run(seed: int, seconds: float) -> tuple[float | None, CoreSession]:
    """The simulated base serving the reference's blob behind `ber=1e-3` both ways: when the
    Core was first configured and polling (None: not within `seconds`), and the Core after
    `seconds` of virtual time."""
    stack = BaseStack(SimulatedBase(World(seed=1), binary_config=REFERENCE_BLOB), BaseConfig())
    core = CoreSession(port="fault")
    to_base, to_core = fault_models("ber=1e-3", seed=seed)
    bus = VirtualBus(core, stack, to_base=FaultFilter(to_base), to_core=FaultFilter(to_core))
    configured = bus.run_until(lambda: core.state is ConnectionState.CONNECTED, seconds, 0.01)
    at = bus.now if configured else None
    bus.run_for(max(0.0, seconds - bus.now))
    return at, core


def test_a_harsh_line_configures_quickly_and_never_disconnects_a_base_that_answers() -> None:
    """Before the fallback, seed 5 lost the connection once while asking for the blob over and
    over (16 damaged answers in a row), and the median of these 7 seeds was 4.5 s (now 1.2 s)."""
    runs = [harsh_run(seed, 15.0) for seed in range(1, 8)]
    times = [at for at, _ in runs]
    assert None not in times, times
    assert statistics.median(t for t in times if t is not None) < 5.0, times  # a loose bound
    for _, core in runs:
        stats = core.link_stats()
        assert stats["disconnects"] == 0, [event.text for event in core.events()]
        assert stats["lost_requests"] == 0
        assert core.telemetry.geometry is not None
        assert core.telemetry.blob_status in ("used", "pending")


class DamageFirstLongAnswers:
    """A to-Core filter that flips one byte in the middle of the first `count` long writes (the
    0x21 answers), so that their checksum fails."""

    def __init__(self, count: int) -> None:
        self.left = count

    def __call__(self, data: bytes, now: float) -> bytes:
        if self.left and len(data) > 300:
            self.left -= 1
            middle = len(data) // 2
            return data[:middle] + bytes([data[middle] ^ 0x01]) + data[middle + 1 :]
        return data


def test_damaged_blob_falls_back_to_get_base_conf_then_the_blob_is_used_when_it_arrives() -> None:
    base = FakeBase(blob=REFERENCE_BLOB)
    core = CoreSession(port="fake")
    bus = VirtualBus(core, base, to_core=DamageFirstLongAnswers(2))
    assert bus.run_until(lambda: core.connected, 5.0)
    names = base.names()
    assert names[:5] == [
        "CONNECT_BASE",
        "GET_BASE_CONF_ADV",
        "GET_BASE_CONF_ADV",
        "GET_BASE_CONF",
        "SEND_EVENT:0x63",
    ]
    assert core.telemetry.config_source == "GET_BASE_CONF"
    assert dashboard_snapshot(core)["base"]["blob"] == "pending"
    # Asked again while polling, and used once it arrives intact; GET_BASE_CONF stays as a view.
    assert bus.run_until(lambda: core.telemetry.config_source == "GET_BASE_CONF_ADV", 5.0)
    snap = dashboard_snapshot(core)
    assert check_snapshot(snap) == []
    assert snap["base"]["blob"] == "used"
    assert set(snap["base"]["views"]) == {"GET_BASE_CONF", "GET_BASE_CONF_ADV"}
    assert [cliff["bit"] for cliff in snap["cliffs"]] == [2, 3, 4, 5]
    stats = core.link_stats()
    assert stats["disconnects"] == 0 and stats["lost_requests"] == 0
    assert stats["errors_by_code"] == {}


def test_the_simulated_base_serves_a_blob_made_from_its_description_by_default() -> None:
    sim, stack = build_simulated_stack(SimSettings())
    core = CoreSession(port="sim")
    bus = VirtualBus(core, stack)
    assert bus.run_until(lambda: core.connected and core.distances_mm is not None, 5.0)
    snap = dashboard_snapshot(core)
    assert snap["base"]["config_source"] == "GET_BASE_CONF_ADV" and snap["base"]["blob"] == "used"
    robot = sim.world.base
    assert len(snap["sensors"]) == len(robot.distance_sensors)  # every sensor, IR included
    assert len(snap["bumpers"]) == len(robot.bumpers)
    assert [cliff["bit"] for cliff in snap["cliffs"]] == [
        len(robot.bumpers) + index for index in range(len(robot.cliff_sensors))
    ]
    assert snap["link"]["errors_by_code"] == {}
    assert snap["ignored_sensors"] == [] and snap["warnings"] == []
    # Both views describe the same robot: nothing disagrees.
    assert not [event.text for event in core.events() if "disagree" in event.text]


def test_without_a_blob_the_fallback_is_shown_as_not_supported_apart_from_errors() -> None:
    _, stack = build_simulated_stack(SimSettings(serve_binary_config=False))
    core = CoreSession(port="sim")
    bus = VirtualBus(core, stack)
    assert bus.run_until(lambda: core.connected, 5.0)
    snap = dashboard_snapshot(core)
    assert snap["base"]["config_source"] == "GET_BASE_CONF"
    assert snap["base"]["blob"] == "not_supported"
    assert snap["link"]["errors_by_code"] == {}  # was {"0x8000": 1} on every start
    assert json_status(core)["link"]["errors_by_code"] == {}
    screen = render_screen(core)
    assert "0x21 not supported: fallback, not an error" in screen
    assert "errors none" in screen


def test_the_sim_cli_takes_no_binary_config_and_refuses_it_with_a_file(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "base.json"
    config.write_text(binconf.example_config_text())
    assert main(["sim", "--pty", "--no-binary-config", "--binary-config", str(config)]) == 2
    error = capsys.readouterr().err.strip().splitlines()
    assert len(error) == 1 and "--binary-config and --no-binary-config exclude each other" in error[0]
    with pytest.raises(UsageError):
        build_simulated_stack(SimSettings(binary_config=config, serve_binary_config=False))


def test_readings_a_real_core_ignores_are_shown_marked_with_one_warning() -> None:
    """The reference's blob lists no sonars, its 0x32 answers report 999-2,499 mm on channels 0-3."""
    base = FakeBase(
        raw_ok={
            "GET_BASE_CONF_ADV": REFERENCE_BLOB,
            "GET_BASE_CONF": recorded_payload("GET_BASE_CONF"),
            "GET_BASE_SENSOR_DATA": recorded_payload("GET_BASE_SENSOR_DATA"),
        }
    )
    core = CoreSession(port="fake")
    bus = VirtualBus(core, base)
    assert bus.run_until(lambda: core.connected and core.distances_mm is not None, 5.0)
    snap = dashboard_snapshot(core)
    assert check_snapshot(snap) == []
    assert snap["sensors"] == []  # the real Core's view: the blob has no distance sensor
    ignored = snap["ignored_sensors"]
    assert [(item["slot"], item["distance_mm"]) for item in ignored] == [
        (0, 999.0),
        (1, 1499.0),
        (2, 2000.0),
        (3, 2499.0),
    ]
    assert {item["mount_source"] for item in ignored} == {"GET_BASE_CONF"}
    assert ignored[0]["mount"]["x_mm"] > 0  # where GET_BASE_CONF puts that sonar
    assert len(snap["warnings"]) == 1 and "0, 1, 2, 3" in snap["warnings"][0]
    status = json_status(core)
    assert status["ignored_sensors"] == ignored and status["warnings"] == snap["warnings"]
    screen = render_screen(core)
    assert "ignored   0: 999, 1: 1499, 2: 2000, 3: 2499 mm" in screen
    assert screen.count("WARNING") == 1
