# SPDX-License-Identifier: MIT
"""The package's face: the everyday names import from `ctrlbus`, and every module says what it
exports (`__all__`) and exports only what it has."""

from __future__ import annotations

import ast
import importlib
from pathlib import Path

import pytest

import ctrlbus

SRC = Path(__file__).resolve().parent.parent / "src"
MODULES = sorted(
    ".".join(path.relative_to(SRC).with_suffix("").parts).removesuffix(".__init__")
    for path in (SRC / "ctrlbus").rglob("*.py")
    if path.name != "__main__.py"
)

EVERYDAY = [
    "encode",
    "StreamDecoder",
    "Frame",
    "open_link",
    "serve_link",
    "Link",
    "Base",
    "BaseRunner",
    "CoreSession",
    "CoreRunner",
    "Profile",
    "CtrlbusError",
    "FrameError",
    "MessageError",
    "LinkError",
    "PortOpenError",
    "ProtocolTimeout",
    "UsageError",
    "Cmd",
    "Request",
    "ErrorCode",
    "ConnectBase",
    "GetBaseStatus",
    "GetBaseStatusAnswer",
    "SetVAndGetDeadreckon",
    "decode_request",
    "decode_answer",
]


def test_the_everyday_names_are_on_the_package() -> None:
    for name in EVERYDAY:
        assert name in ctrlbus.__all__, name
        assert getattr(ctrlbus, name) is not None


def test_the_package_names_are_the_layers_own() -> None:
    from ctrlbus import frame, ports
    from ctrlbus.core import CoreSession

    assert ctrlbus.encode is frame.encode  # the frame encoder, not messages.encode
    assert ctrlbus.open_link is ports.open_link
    assert ctrlbus.CoreSession is CoreSession


def test_a_frame_round_trip_with_the_package_names_only() -> None:
    wire = ctrlbus.encode(ctrlbus.Cmd.CTRL_BUS, bytes([ctrlbus.Request.GET_BASE_STATUS]))
    frames = ctrlbus.StreamDecoder().feed(wire, 0.0)
    assert len(frames) == 1 and frames[0].cmd == ctrlbus.Cmd.CTRL_BUS
    assert isinstance(ctrlbus.decode_request(frames[0].cmd, frames[0].payload), ctrlbus.GetBaseStatus)


@pytest.mark.parametrize("name", MODULES)
def test_every_module_has_an_all_naming_only_what_it_has(name: str) -> None:
    path = SRC / Path(*name.split("."))
    path = path / "__init__.py" if path.is_dir() else path.with_suffix(".py")
    tree = ast.parse(path.read_text(encoding="utf-8"))
    targets = [
        target
        for node in tree.body
        for target in (node.targets if isinstance(node, ast.Assign) else [getattr(node, "target", None)])
    ]
    assert any(isinstance(target, ast.Name) and target.id == "__all__" for target in targets), (
        f"{name} has no __all__"
    )
    module = importlib.import_module(name)
    exported = module.__all__
    assert len(exported) == len(set(exported)), f"{name}: __all__ repeats a name"
    missing = [item for item in exported if not hasattr(module, item)]
    assert missing == [], f"{name}.__all__ names what it does not have: {missing}"
