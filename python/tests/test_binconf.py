# SPDX-License-Identifier: MIT
"""The 0x21 binary configuration codec: hand-written blobs, malformed input, random round trips."""

from __future__ import annotations

import io
import json
import math
import struct
import subprocess
import sys
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ctrlbus import binconf
from ctrlbus.binconf import JsonValue
from ctrlbus.cli import main
from ctrlbus.errors import BinaryConfigError, CtrlbusError


def blob(hex_text: str) -> bytes:
    return bytes.fromhex(hex_text)


def exact(tree: JsonValue) -> str:
    """Text that tells -0.0 from 0.0 and 1 from 1.0, which == on trees does not."""
    return json.dumps(tree, sort_keys=False)


def assert_round_trips(data: bytes, expected: JsonValue) -> None:
    decoded = binconf.decode(data)
    assert exact(decoded) == exact(expected)
    assert binconf.encode(decoded) == data
    # ...and through the JSON text, as the CLI does it
    assert binconf.encode(binconf.load_json(binconf.dump_json(decoded))) == data


# Every type code, a nested object and array, an unknown key and an unknown dictionary value.
EVERY_TYPE = """
50 0A
   02 30 05 68 65 6C 6C 6F
   01 10 07
   03 11 58 02
   0E 1A FF FF FF FF
   06 20 00 00 C0 3F
   0B 31 15
   09 60
   29 61
   0A 40 02
      50 02
         19 10 00
         0D 50 01
            11 20 CD CC CC 3D
      10 2A
   99 31 9A
"""
EVERY_TYPE_JSON: JsonValue = {
    "manufacture_name": "hello",
    "manufacture_id": {"u8": 7},
    "model_id": {"u16": 600},
    "x": {"s32": -1},
    "robot_size": 1.5,
    "type": {"dict": "sonar"},
    "low_battery_auto_homing": True,
    "reverse_installation": False,
    "sensors": [{"id": {"u8": 0}, "installation_pose": {"yaw": 0.1}}, {"u8": 42}],
    "0x99": {"dict": "0x9a"},
}


def test_every_type_code_round_trips() -> None:
    assert_round_trips(blob(EVERY_TYPE), EVERY_TYPE_JSON)


def test_repeated_keys_are_numbered_and_keep_their_order() -> None:
    data = blob("50 04  0E 20 00 00 80 3F  0F 10 01  0E 20 00 00 00 40  0E 40 01 40 00")
    expected: JsonValue = {"x": 1.0, "y": {"u8": 1}, "x#2": 2.0, "x#3": [[]]}
    assert_round_trips(data, expected)
    assert list(binconf.decode(data)) == ["x", "y", "x#2", "x#3"]


def test_unknown_ids_repeat_too() -> None:
    data = blob("50 03  77 60  77 61  13 31 1D")
    assert_round_trips(data, {"0x77": True, "0x77#2": False, "0x13": {"dict": "0x1d"}})


def test_extreme_numbers_and_odd_floats() -> None:
    data = blob(
        """
        50 09
           01 10 FF
           03 11 FF FF
           0E 1A 00 00 00 80
           0F 1A FF FF FF 7F
           10 20 00 00 00 80
           11 20 00 00 C0 7F
           06 20 00 00 80 FF
           28 20 01 00 00 00
           23 20 AB AA AA 3E
        """
    )
    expected: JsonValue = {
        "manufacture_id": {"u8": 255},
        "model_id": {"u16": 65535},
        "x": {"s32": -(2**31)},
        "y": {"s32": 2**31 - 1},
        "z": -0.0,
        "yaw": {"f32_bits": "0x7fc00000"},
        "robot_size": {"f32_bits": "0xff800000"},
        "wheel_span": 1e-45,
        "landing_offset": 0.33333334,
    }
    assert_round_trips(data, expected)


def test_strings_empty_utf8_and_not_utf8() -> None:
    data = blob("50 03  02 30 00  04 30 03 C3 A9 21  02 30 02 C3 28")
    assert_round_trips(
        data, {"manufacture_name": "", "model_name": "é!", "manufacture_name#2": {"bytes": "C3 28"}}
    )


def test_empty_containers_and_deep_but_allowed_nesting() -> None:
    assert_round_trips(blob("50 00"), {})
    # root object + 31 nested arrays = MAX_DEPTH levels
    depth = binconf.MAX_DEPTH - 1
    data = bytes([0x50, 0x01, 0x0A]) + bytes([0x40, 0x01]) * (depth - 1) + bytes([0x40, 0x00])
    tree: JsonValue = []
    for _ in range(depth - 1):
        tree = [tree]
    assert_round_trips(data, {"sensors": tree})


@pytest.mark.parametrize(
    ("hex_text", "offset", "words"),
    [
        ("", 0, "empty"),
        ("10 05", 0, "root must be an object"),
        ("50", 1, "truncated"),
        ("50 01 0E 10", 4, "truncated"),
        ("50 01 0E 11 01", 4, "u16"),
        ("50 01 0E 1A 01 02 03", 4, "s32"),
        ("50 01 0E 20 00 00", 4, "float32"),
        ("50 01 02 30 05 41 42", 5, "string of 5 bytes"),
        ("50 01 0E 31", 4, "dictionary id"),
        ("50 01 0E 77 00", 3, "unknown type code 0x77"),
        ("50 02 0E 1A 01 02 03 04 0F", 9, "value type"),
        ("50 05 0E 60", 0, "claims 5 entries"),
        ("50 01 0A 40 03 10 01", 3, "claims 3 entries"),
        ("50 01 0A 40 01 50 01 0E", 5, "claims 1 entries"),
        ("50 00 00", 2, "trailing"),
        ("50 01 0E 60 61 61", 4, "2 trailing"),
    ],
)
def test_malformed_blobs_name_the_offset(hex_text: str, offset: int, words: str) -> None:
    with pytest.raises(BinaryConfigError) as caught:
        binconf.decode(blob(hex_text))
    assert caught.value.offset == offset
    assert words in str(caught.value)
    assert f"offset {offset}" in str(caught.value)


def test_nesting_too_deep_is_refused_both_ways() -> None:
    levels = binconf.MAX_DEPTH
    data = bytes([0x50, 0x01, 0x0A]) + bytes([0x40, 0x01]) * (levels - 1) + bytes([0x40, 0x00])
    with pytest.raises(BinaryConfigError, match="nesting deeper than 32") as caught:
        binconf.decode(data)
    assert caught.value.offset == 3 + 2 * (levels - 1)
    tree: JsonValue = []
    for _ in range(levels):
        tree = [tree]
    with pytest.raises(BinaryConfigError, match="nesting deeper"):
        binconf.encode({"sensors": tree})
    # a hostile blob of 60 000 nested arrays fails cleanly, not with RecursionError
    with pytest.raises(BinaryConfigError):
        binconf.decode(bytes([0x50, 0x01, 0x0A]) + bytes([0x40, 0x01]) * 30000)


@pytest.mark.parametrize(
    ("tree", "path", "words"),
    [
        ({"x": 5}, "x", "bare integer"),
        ({"x": None}, "x", "null"),
        ({"bogus": True}, "bogus", "not a dictionary name"),
        ({"0x15": True}, "0x15", "write that name"),
        ({"0X9A": True}, "0X9A", "lowercase"),
        ({"x#1": True}, "x#1", "spelled 'x'"),
        ({"x": True, "x#3": True}, "x#3", "spelled 'x#2'"),
        ({"x#2": True}, "x#2", "spelled 'x'"),
        ({"x#": True}, "x#", "not a valid key"),
        ({"x": {"u8": 256}}, "x", "out of the u8 range"),
        ({"x": {"u16": -1}}, "x", "out of the u16 range"),
        ({"x": {"s32": 2**31}}, "x", "out of the s32 range"),
        ({"x": {"u8": True}}, "x", "needs an integer"),
        ({"x": {"u8": 1.0}}, "x", "needs an integer"),
        ({"x": 1e39}, "x", "outside the float32 range"),
        ({"x": float("inf")}, "x", "f32_bits"),
        ({"x": {"f32_bits": "0x3f800000"}}, "x", "write it as the number 1.0"),
        ({"x": {"f32_bits": "7fc00000"}}, "x", "8 lowercase hex digits"),
        ({"x": {"bytes": "41 42"}}, "x", 'the string "AB"'),
        ({"x": {"bytes": "c3 28"}}, "x", "uppercase hex pairs"),
        ({"x": {"dict": "nope"}}, "x", "not a dictionary name"),
        ({"x": {"dict": "0x15"}}, "x", "'sonar'"),
        ({"x": {"dict": 21}}, "x", "not a dictionary name"),
        ({"x": "é" * 128}, "x", "at most 255 bytes"),
        ({"x": "\ud800"}, "x", "surrogate"),
        ({"x": [True] * 256}, "x", "at most 255 values"),
        ({"sensors": [{"id": 3}]}, "sensors[0].id", "bare integer"),
        ({"x": (1, 2)}, "x", "tuple"),
        ({"u8": 5}, "(root)", "root"),
    ],
)
def test_encode_refuses_what_has_no_exact_binary_form(tree: object, path: str, words: str) -> None:
    with pytest.raises(BinaryConfigError) as caught:
        binconf.encode(tree)
    assert caught.value.path == path
    assert words in str(caught.value)


def test_encode_refuses_a_non_object_root_and_too_many_members() -> None:
    roots: list[object] = [[], "x", 1.0, None]
    for root in roots:
        with pytest.raises(BinaryConfigError, match="root"):
            binconf.encode(root)
    members: dict[str, JsonValue] = {"x": True}
    members.update({f"x#{n}": True for n in range(2, 257)})
    with pytest.raises(BinaryConfigError, match="at most 255 members"):
        binconf.encode(members)


def test_floats_are_rounded_to_float32_and_print_shortest() -> None:
    data = binconf.encode({"yaw": 3.14159265358979})
    assert data == blob("50 01 11 20 DB 0F 49 40")
    assert binconf.decode(data) == {"yaw": 3.1415927}
    assert binconf.shortest_float32(0x3DCCCCCD) == 0.1
    assert binconf.shortest_float32(0x4B800001) == 16777218.0
    assert binconf.shortest_float32(0x00000001) == 1e-45


def test_load_json_is_strict() -> None:
    with pytest.raises(BinaryConfigError, match="'x#2'"):
        binconf.load_json('{"x": 1.0, "x": 2.0}')
    with pytest.raises(BinaryConfigError, match="NaN"):
        binconf.load_json('{"x": NaN}')
    with pytest.raises(BinaryConfigError, match="line 1 column 7"):
        binconf.load_json('{"x": }')
    with pytest.raises(BinaryConfigError, match="nests too deeply"):
        binconf.load_json("[" * 100000 + "]" * 100000)
    with pytest.raises(BinaryConfigError, match="UTF-8"):
        binconf.load_json(b'{"x": "\xff"}')


def test_tags_never_collide_with_dictionary_names() -> None:
    assert not binconf.SCALAR_TAGS & set(binconf.DICTIONARY.values())
    assert all(binconf.parse_id_spelling(name) == ident for ident, name in binconf.DICTIONARY.items())


def test_every_error_is_a_ctrlbus_error() -> None:
    assert issubclass(BinaryConfigError, CtrlbusError)


def test_example_configuration_round_trips_and_fits_the_reference_base() -> None:
    tree = binconf.example_config()
    data = binconf.example_blob()
    assert exact(binconf.decode(data)) == exact(tree)
    assert binconf.encode(binconf.decode(data)) == data
    assert len(data) <= binconf.REFERENCE_MAX_BLOB
    base = tree["base"]
    assert isinstance(base, dict)
    sensors = base["sensors"]
    assert isinstance(sensors, list)
    kinds = [sensor["type"] for sensor in sensors if isinstance(sensor, dict)]
    for kind in ("sonar", "bumper", "cliff"):
        assert {"dict": kind} in kinds
    assert isinstance(base["docking"], dict)
    # the file is kept in the printer's layout, so decode of its blob prints the file
    assert binconf.dump_json(binconf.decode(data)) == binconf.example_config_text()


# ---------------------------------------------------------------------------------------------
# Random trees. Blobs are written by a writer local to this test, so that the codec's encoder is
# checked against an independent spelling of the format.

KEY_IDS = st.sampled_from([0x0E, 0x0F, 0x0A, 0x19, 0x02, 0x77, 0xFF, 0x00])


@st.composite
def blob_values(draw: st.DrawFn, depth: int = 0) -> bytes:
    kinds = ["u8", "u16", "s32", "f32", "str", "dict", "true", "false"]
    if depth < 4:
        kinds += ["array", "object"]
    kind = draw(st.sampled_from(kinds))
    if kind == "u8":
        return bytes([0x10, draw(st.integers(0, 255))])
    if kind == "u16":
        return b"\x11" + struct.pack("<H", draw(st.integers(0, 0xFFFF)))
    if kind == "s32":
        return b"\x1a" + struct.pack("<i", draw(st.integers(-(2**31), 2**31 - 1)))
    if kind == "f32":
        return b"\x20" + struct.pack("<I", draw(st.integers(0, 2**32 - 1)))
    if kind == "str":
        raw = draw(st.one_of(st.binary(max_size=40), st.text(max_size=20).map(lambda t: t.encode()[:255])))
        return bytes([0x30, len(raw)]) + raw
    if kind == "dict":
        return bytes([0x31, draw(st.integers(0, 255))])
    if kind == "true":
        return b"\x60"
    if kind == "false":
        return b"\x61"
    if kind == "array":
        items = draw(st.lists(blob_values(depth + 1), max_size=5))
        return bytes([0x40, len(items)]) + b"".join(items)
    members = draw(st.lists(st.tuples(KEY_IDS, blob_values(depth + 1)), max_size=5))
    return bytes([0x50, len(members)]) + b"".join(bytes([key]) + value for key, value in members)


@st.composite
def blobs(draw: st.DrawFn) -> bytes:
    members = draw(st.lists(st.tuples(KEY_IDS, blob_values(1)), max_size=6))
    return bytes([0x50, len(members)]) + b"".join(bytes([key]) + value for key, value in members)


@settings(max_examples=300, deadline=None)
@given(blobs())
def test_random_blobs_round_trip(data: bytes) -> None:
    tree = binconf.decode(data)
    assert binconf.encode(tree) == data
    text = binconf.dump_json(tree)
    assert exact(binconf.decode(binconf.encode(binconf.load_json(text)))) == exact(tree)


float32s = st.integers(0, 2**32 - 1).filter(lambda bits: (bits >> 23) & 0xFF != 0xFF)
NAMES = st.sampled_from(["x", "y", "sensors", "id", "type", "0x77", "0xff"])


@st.composite
def json_values(draw: st.DrawFn, depth: int = 0) -> JsonValue:
    kinds = ["u8", "u16", "s32", "float", "str", "dict", "bool", "bytes", "nan"]
    if depth < 4:
        kinds += ["array", "object"]
    kind = draw(st.sampled_from(kinds))
    if kind in binconf.INT_TAGS:
        _, low, high, _ = binconf.INT_TAGS[kind]
        return {kind: draw(st.integers(low, high))}
    if kind == "float":
        return binconf.shortest_float32(draw(float32s))
    if kind == "str":
        return draw(st.text(alphabet=st.characters(exclude_categories=["Cs"]), max_size=20))
    if kind == "dict":
        return {"dict": binconf.id_spelling(draw(st.integers(0, 255)))}
    if kind == "bool":
        return draw(st.booleans())
    if kind == "bytes":
        return {"bytes": (b"\xff" + draw(st.binary(max_size=8))).hex(" ").upper()}
    if kind == "nan":
        return {
            "f32_bits": f"0x{draw(st.sampled_from([0x7F800000, 0xFF800000, 0x7FC00001, 0xFFFFFFFF])):08x}"
        }
    if kind == "array":
        return draw(st.lists(json_values(depth + 1), max_size=5))
    return json_objects(draw(st.lists(st.tuples(NAMES, json_values(depth + 1)), max_size=5)))


def json_objects(members: list[tuple[str, JsonValue]]) -> dict[str, JsonValue]:
    """Members with repeated names spelled name#2, name#3... in order."""
    tree: dict[str, JsonValue] = {}
    seen: dict[str, int] = {}
    for name, value in members:
        seen[name] = seen.get(name, 0) + 1
        tree[name if seen[name] == 1 else f"{name}#{seen[name]}"] = value
    return tree


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(NAMES, json_values(1)), max_size=6))
def test_random_json_trees_round_trip(members: list[tuple[str, JsonValue]]) -> None:
    tree = json_objects(members)
    data = binconf.encode(tree)
    assert exact(binconf.decode(data)) == exact(tree)
    assert binconf.encode(binconf.load_json(binconf.dump_json(tree))) == data


@settings(max_examples=500, deadline=None)
@given(st.one_of(st.binary(max_size=64), st.binary(max_size=64).map(lambda tail: b"\x50" + tail)))
def test_random_bytes_decode_or_fail_cleanly(data: bytes) -> None:
    try:
        tree = binconf.decode(data)
    except BinaryConfigError as exc:
        assert exc.offset is not None and 0 <= exc.offset <= len(data)
    else:
        assert binconf.encode(tree) == data


# ---------------------------------------------------------------------------------------------
# The `ctrlbus config` command


def run_cli(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str, str]:
    code = main(argv)
    out, err = capsys.readouterr()
    return code, out, err


def test_cli_encode_prints_hex_and_decode_reads_it_back(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    source = tmp_path / "every.json"
    source.write_text(json.dumps(EVERY_TYPE_JSON), encoding="utf-8")
    code, out, err = run_cli(["config", "encode", str(source)], capsys)
    assert (code, err) == (0, "")
    assert bytes.fromhex(out) == blob(EVERY_TYPE)
    hex_file = tmp_path / "every.hex"
    hex_file.write_text("# a comment\n" + out.replace(" ", ", 0x"), encoding="ascii")
    code, out, err = run_cli(["config", "decode", str(hex_file)], capsys)
    assert (code, err) == (0, "")
    assert exact(binconf.load_json(out)) == exact(EVERY_TYPE_JSON)


def test_cli_binary_files_and_stdin(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    raw = tmp_path / "example.bin"
    code, _, _ = run_cli(["config", "example", "-o", str(tmp_path / "example.json")], capsys)
    assert code == 0
    code, out, _ = run_cli(["config", "encode", str(tmp_path / "example.json"), "-o", str(raw)], capsys)
    assert (code, out) == (0, "")
    assert raw.read_bytes() == binconf.example_blob()
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(raw.read_bytes())))
    code, out, _ = run_cli(["config", "decode", "-", "-o", str(tmp_path / "back.json")], capsys)
    assert (code, out) == (0, "")
    assert (tmp_path / "back.json").read_text(encoding="utf-8") == binconf.example_config_text()


@pytest.mark.parametrize(
    ("argv", "stdin", "words"),
    [
        (["config", "decode", "-"], b"50 01 0E 10", "offset 4"),
        (["config", "decode", "-"], b"50 01 0G", "not hex text: '0G' at line 1 column 7"),
        (["config", "decode", "-"], b"\x50\x01\x0e\x77\x00", "unknown type code 0x77"),
        (["config", "encode", "-"], b'{"x": 5}', "at x: a bare integer"),
        (["config", "encode", "-"], b'{"x": ', "invalid JSON"),
        (["config", "decode", "/nonexistent/blob.bin"], b"", "No such file"),
    ],
)
def test_cli_errors_are_one_line_and_exit_2(
    argv: list[str],
    stdin: bytes,
    words: str,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(stdin)))
    code, out, err = run_cli(argv, capsys)
    assert code == 2
    assert out == ""
    assert err.count("\n") == 1 and err.startswith("ctrlbus config: error: ")
    assert words in err


def test_cli_warns_about_blobs_the_reference_base_cannot_send(
    capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    big = {"model_name": "x" * 250, "model_name#2": "y" * 250, "model_name#3": "z" * 10}
    monkeypatch.setattr(sys, "stdin", io.TextIOWrapper(io.BytesIO(json.dumps(big).encode())))
    code, out, err = run_cli(["config", "encode", "-"], capsys)
    assert code == 0
    assert len(bytes.fromhex(out)) == 2 + 3 * 3 + 510
    assert "warning: the blob has 521 bytes" in err


def test_cli_in_a_subprocess(tmp_path: Path) -> None:
    command = [sys.executable, "-m", "ctrlbus", "config"]
    example = subprocess.run([*command, "example"], capture_output=True, check=True)
    blob_file = tmp_path / "b.bin"
    subprocess.run([*command, "encode", "-", "-o", str(blob_file)], input=example.stdout, check=True)
    decoded = subprocess.run([*command, "decode", str(blob_file)], capture_output=True, check=True)
    assert decoded.stdout == example.stdout
    bad = subprocess.run([*command, "decode", "-"], input=b"50 05", capture_output=True)
    assert bad.returncode == 2
    assert bad.stderr.decode().strip() == (
        "ctrlbus config: error: object at offset 0 claims 5 entries but only 0 byte(s) remain "
        "(each needs at least 2)"
    )


def test_example_configuration_describes_the_default_simulated_base() -> None:
    """base-config.json and the simulator's data/sim-base.json describe the same robot (metres
    and radians here, millimetres and degrees there); sonar ids are GET_BASE_SENSOR_DATA channels,
    bumper and cliff ids are the bumper bitmap's bits."""
    from ctrlbus.sim.description import default_base_description

    robot = default_base_description()
    base = binconf.decode(binconf.example_blob())["base"]
    assert isinstance(base, dict)
    assert base["robot_size"] == pytest.approx(2 * robot.radius_mm / 1000, abs=1e-6)  # a diameter
    assert base["wheel_span"] == pytest.approx(robot.wheel_track_mm / 1000, abs=1e-6)

    def yaw_rad(degrees: float) -> float:
        return math.remainder(math.radians(degrees), math.tau)

    expected: dict[tuple[str, int], tuple[float, float, float, float]] = {}
    for channel, distance_sensor in enumerate(robot.distance_sensors):
        if distance_sensor.kind == "sonar":
            expected["sonar", channel] = distance_sensor.mount
    for index, mount in enumerate(robot.bumper_mounts()):
        expected["bumper", index] = mount
    for index, cliff in enumerate(robot.cliff_sensors):
        # A cliff's id is its bitmap bit, after the bumpers' (protocol §5.7).
        expected["cliff", len(robot.bumper_mounts()) + index] = (cliff.x_mm, cliff.y_mm, cliff.z_mm, 0.0)
    described: dict[tuple[str, int], dict[str, JsonValue]] = {}
    sensors = base["sensors"]
    assert isinstance(sensors, list)
    for sensor in sensors:
        assert isinstance(sensor, dict)
        kind, ident, pose = sensor["type"], sensor["id"], sensor["installation_pose"]
        assert isinstance(kind, dict) and isinstance(ident, dict) and isinstance(pose, dict)
        described[str(kind["dict"]), int(str(ident["u8"]))] = pose
    assert set(described) == set(expected)
    for key, (x_mm, y_mm, z_mm, yaw_deg) in expected.items():
        pose = described[key]
        assert [pose["x"], pose["y"], pose["z"]] == pytest.approx(
            [x_mm / 1000, y_mm / 1000, z_mm / 1000], abs=5e-4
        )
        assert pose["yaw"] == pytest.approx(yaw_rad(yaw_deg), abs=1e-4), key
