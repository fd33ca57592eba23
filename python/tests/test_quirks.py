# SPDX-License-Identifier: MIT
"""The simulated base's reference-quirks mode (ctrlbus.quirks, docs/simulator.md), and the Core
emulator against it: the reference firmware's behaviours stay tested without the vendor's code."""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

import pytest

from ctrlbus import binconf
from ctrlbus.base import BaseConfig, BaseStack
from ctrlbus.constants import REFERENCE_LOW_BATTERY_CODE
from ctrlbus.core import CoreSession
from ctrlbus.errors import UsageError
from ctrlbus.faults import FaultFilter, FaultSpec, fault_models
from ctrlbus.frame import Frame, StreamDecoder, encode
from ctrlbus.messages import SetVAndGetDeadreckonAnswer
from ctrlbus.quirks import BOOT_SILENCE_S, STARTUP_BATTERY_S, Quirks, parse_quirks
from ctrlbus.sim.base import SimulatedBase
from ctrlbus.sim.description import default_base_description
from ctrlbus.sim.world import World
from ctrlbus.vtime import VirtualBus
from ctrlbus.web.snapshot import dashboard_snapshot

STATUS = bytes.fromhex("10 02 F8 30 DA")
STATUS_ANSWER_CMD_OK = 0x02
ERROR = 0x03
BOOTED = BOOT_SILENCE_S + 0.1
AFTER_STARTUP = STARTUP_BATTERY_S + 0.5


class RecordingSim(SimulatedBase):
    """The simulated base, noting each velocity the stack hands it."""

    def __init__(self, world: World, blob: bytes | None = None) -> None:
        super().__init__(world, binary_config=blob)
        self.velocities: list[tuple[float, float]] = []

    def set_velocity(self, vx_mps: float, vy_mps: float, omega_radps: float) -> SetVAndGetDeadreckonAnswer:
        self.velocities.append((vx_mps, omega_radps))
        return super().set_velocity(vx_mps, vy_mps, omega_radps)


def quirky(blob: bytes | None = None) -> tuple[BaseStack, RecordingSim]:
    sim = RecordingSim(World(seed=1), blob)
    return BaseStack(sim, BaseConfig(quirks=Quirks.REFERENCE)), sim


def frames(data: bytes) -> list[Frame]:
    return StreamDecoder().feed(data, 0.0)


def error_codes(data: bytes) -> list[int | None]:
    """Each answer frame: its ERROR code, or None for any other answer."""
    return [struct.unpack("<H", frame.payload)[0] if frame.cmd == ERROR else None for frame in frames(data)]


def booted_stack(blob: bytes | None = None) -> tuple[BaseStack, RecordingSim]:
    stack, sim = quirky(blob)
    assert stack.tick(0.0) == b""
    stack.tick(AFTER_STARTUP)
    return stack, sim


def test_quirks_names() -> None:
    assert parse_quirks("Reference") is Quirks.REFERENCE
    with pytest.raises(UsageError, match="unknown quirks mode 'nope'"):
        BaseConfig(quirks="nope")  # type: ignore[arg-type]


def test_garbage_then_a_request_gives_not_synced_reports_then_0090_and_no_answer() -> None:
    stack, _ = booted_stack()
    out = stack.receive(bytes(range(1, 9)) + STATUS, 5.0) + stack.tick(5.1)
    codes = error_codes(out)
    # Reference §2: ERROR 0x0010 reports, then the combined 0x0090, and the status is never answered.
    assert codes[-1] == 0x0090 and set(codes[:-1]) == {0x0010} and len(codes) >= 2
    # The resend is what recovers.
    assert error_codes(stack.receive(STATUS, 5.2)) == [None]


def test_checksum_mismatch_is_00c0_and_the_frame_is_not_executed() -> None:
    stack, sim = booted_stack()
    set_v = encode(0xF8, bytes([0x41]) + struct.pack("<iii", 0x3333, 0, 0))
    broken = set_v[:-1] + bytes([set_v[-1] ^ 1])
    assert error_codes(stack.receive(broken, 5.0)) == [0x00C0]
    assert sim.velocities == []


def test_len0_runs_the_previous_request_again() -> None:
    stack, sim = booted_stack()
    set_v = encode(0xF8, bytes([0x41]) + struct.pack("<iii", 0x3333, 0, 0))
    assert error_codes(stack.receive(set_v, 5.0)) == [None]
    assert error_codes(stack.receive(bytes.fromhex("10 00 10"), 5.5)) == [None]
    assert [round(vx, 3) for vx, _ in sim.velocities] == [0.2, 0.2]
    # It fed the watchdog too: 1.2 s after the first SET_V the wheels still turn.
    stack.tick(6.2)
    assert sim.world.commanded_wheel_speeds != (0.0, 0.0)


def test_no_inter_byte_timeout_a_partial_frame_waits() -> None:
    stack, _ = booted_stack()
    assert stack.receive(STATUS[:2], 5.0) == b""
    assert stack.tick(60.0) == b""
    assert error_codes(stack.receive(STATUS[2:], 61.0)) == [None]


def test_power_on_silence_then_only_the_last_complete_request_is_answered() -> None:
    stack, _ = quirky()
    connect = encode(0xF8, bytes([0x10, 0x01]))
    assert stack.receive(STATUS, 0.0) == b""
    assert stack.receive(connect, 0.5) == b""
    assert stack.tick(BOOT_SILENCE_S - 0.05) == b""
    answers = frames(stack.tick(BOOTED))
    assert len(answers) == 1 and answers[0].cmd == STATUS_ANSWER_CMD_OK
    assert len(answers[0].payload) == 28  # CONNECT_BASE, the last one; the status is forgotten


def test_no_battery_reading_and_a_low_battery_error_for_the_first_seconds() -> None:
    stack, _ = quirky()
    stack.tick(0.0)
    first = frames(stack.tick(BOOTED) + stack.receive(STATUS, BOOTED + 0.1))
    assert first[-1].payload[0] == 0  # 0 %
    assert REFERENCE_LOW_BATTERY_CODE in stack.health
    later = frames(stack.receive(STATUS, AFTER_STARTUP))
    assert later[-1].payload[0] > 0
    assert REFERENCE_LOW_BATTERY_CODE not in stack.health


# --- the Core emulator against it ---------------------------------------------------------------


def test_core_tolerates_the_booting_base_and_its_transient_low_battery_error() -> None:
    stack, _ = quirky()
    core = CoreSession(port="quirks")
    bus = VirtualBus(core, stack)
    assert bus.run_until(lambda: core.connected, 5.0), core.events()
    assert core.time_s > BOOT_SILENCE_S  # nothing answered before its main loop ran
    bus.run_for(AFTER_STARTUP)
    texts = [event.text for event in core.events()]
    assert any(text.startswith(f"health: 0x{REFERENCE_LOW_BATTERY_CODE:08X}") for text in texts), texts
    assert f"health: 0x{REFERENCE_LOW_BATTERY_CODE:08X} cleared" in texts
    assert core.health.errors == ()
    stats = core.link_stats()
    assert stats["disconnects"] == 0 and stats["lost_requests"] == 0


def test_core_soak_through_the_fault_injector_loses_no_request() -> None:
    """A small version of `bench/soak.py --quirks` (docs/reliability.md has the 100,000-exchange
    figures): every request is answered, superseded by its next period, or resent."""
    spec = FaultSpec.parse("ber=1e-4,burst=1e-3:1-64")
    stack, _ = quirky()
    core = CoreSession(port="quirks")
    to_base, to_core = fault_models(spec, 7, origin=0.0)
    bus = VirtualBus(core, stack, to_base=FaultFilter(to_base), to_core=FaultFilter(to_core))
    bus.run_for(120.0)
    stats = core.link_stats()
    assert stats["answers"] > 2500
    assert stats["lost_requests"] == 0
    assert stats["disconnects"] == 0
    settled = sum(
        stats[key] for key in ("requests_answered", "superseded", "abandoned_at_disconnect", "lost_requests")
    )
    assert stats["requests_tracked"] - settled in (0, 1)  # 1: the one in flight
    # Combined codes occurred, and each line fault is counted by its bits.
    line_faults = {int(code, 16): n for code, n in stats["errors_by_code"].items() if int(code, 16) < 0x100}
    assert any(bin(code).count("1") > 1 for code in line_faults), line_faults
    for bit in (0x10, 0x20, 0x40, 0x80):
        expected = sum(n for code, n in line_faults.items() if code & bit)
        assert stats["line_faults_by_bit"][f"0x{bit:02X}"] == expected


# --- the 0x21 units -------------------------------------------------------------------------------


def reference_like_blob(robot_size_m: float) -> bytes:
    """A blob laid out as the reference's: robot_size a diameter, bumpers and cliffs only."""
    tree: dict[str, Any] = json.loads(binconf.example_config_text())
    base = tree["base"]
    base["robot_size"] = robot_size_m
    base["sensors"] = [entry for entry in base["sensors"] if entry["type"]["dict"] in ("bumper", "cliff")]
    return binconf.encode(binconf.load_json(json.dumps(tree).encode()))


def test_robot_size_is_a_diameter_and_both_views_are_shown() -> None:
    description = default_base_description()
    blob = reference_like_blob(2 * description.radius_mm / 1000)
    stack = BaseStack(SimulatedBase(World(seed=1), binary_config=blob), BaseConfig())
    core = CoreSession(port="vtime")
    bus = VirtualBus(core, stack)
    assert bus.run_until(lambda: core.connected, 5.0)
    base = dashboard_snapshot(core)["base"]
    assert base["config_source"] == "GET_BASE_CONF_ADV"
    assert base["radius_mm"] == pytest.approx(description.radius_mm, abs=0.01)
    views = base["views"]
    assert views["GET_BASE_CONF_ADV"]["distance_sensors"] == 0
    assert views["GET_BASE_CONF"]["distance_sensors"] == len(description.distance_sensors)
    texts = [event.text for event in core.events()]
    assert any("the two configurations disagree: distance sensors" in text for text in texts), texts


def test_ctrlbus_core_shows_radius_180_for_a_blob_whose_robot_size_is_036(tmp_path: Path) -> None:
    from test_core_cli import LIMIT_S, child, ctrlbus_command

    blob_json = tmp_path / "reference.json"
    blob_json.write_text(binconf.dump_json(binconf.decode(reference_like_blob(0.36))), encoding="utf-8")
    sim_args = ["sim", "--pty", "--quirks", "reference", "--binary-config", str(blob_json)]
    with child(ctrlbus_command(*sim_args)) as sim:
        line = sim.read_line()
        assert line is not None and line.startswith("pty: "), line
        pty = line.removeprefix("pty: ").strip()
        core_args = ["core", "--port", pty, "--json", "--interval", "0.25", "--duration", "4"]
        with child(ctrlbus_command(*core_args)) as core:
            statuses = [json.loads(text) for text in core.lines()]
            assert core.process.wait(LIMIT_S) == 0
    bases = [status["base"] for status in statuses if status["base"] is not None]
    assert bases, statuses[-1]
    assert bases[-1]["radius_mm"] == pytest.approx(180.0)
    assert bases[-1]["config_source"] == "GET_BASE_CONF_ADV"
    assert statuses[-1]["link"]["lost_requests"] == 0
