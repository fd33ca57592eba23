# SPDX-License-Identifier: MIT
"""A capture (ctrlbus capture, docs/capture-format.md) read back as the Core saw it, for the ROS 2
topics: `ctrlbus record --rosbag DIR --capture FILE`.

`CaptureModel` listens to both directions of a capture the way `ctrlbus decode` reads them
(ctrlbus.annotate pairs each answer with its request) and keeps what the Core would know: the
identity, the geometry from the configuration, the readings (ctrlbus.core.readings, as the
session applies them), the health list and the last SET_V. It never sends anything: it can only
know what was on the wire, so the link counters are the capture's (answers, line faults).
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

from ctrlbus import binconf
from ctrlbus.annotate import Annotator, FrameNote, Role
from ctrlbus.capture import CaptureReader
from ctrlbus.core.geometry import SOURCE_CONF_ADV, geometry_from_conf, geometry_from_tree
from ctrlbus.core.readings import apply_reading
from ctrlbus.core.telemetry import BaseIdentity, BaseTelemetry, CommandState, HealthError, HealthState
from ctrlbus.errors import CtrlbusError
from ctrlbus.messages import (
    AnswerMessage,
    ConnectBaseAnswer,
    ErrorAnswer,
    GetBaseConfAdvAnswer,
    GetBaseConfAnswer,
    HealthGetErrorAnswer,
    HealthGetHealthAnswer,
    SetVAndGetDeadreckon,
    from_q16,
)
from ctrlbus.ros2.topics import BaseState

__all__ = ["CaptureModel", "capture_moments"]


class CaptureModel:
    """What the Core knew at each point of a capture (see the module)."""

    def __init__(self) -> None:
        self.telemetry = BaseTelemetry()
        self.connects = 0
        self.answers = 0
        self.line_faults = 0
        self._command = CommandState(0.0, 0.0, False, "idle", None)
        self._health_flags: int | None = None
        self._health_expected = 0
        self._health_errors: list[HealthError] = []

    def note(self, note: FrameNote) -> None:
        """Take one decoded frame."""
        message = note.message
        if note.role is Role.REQUEST:
            if isinstance(message, SetVAndGetDeadreckon):
                vx, omega = from_q16(message.vx_mps_q16), from_q16(message.omega_radps_q16)
                mode = "teleop" if vx or omega else "idle"
                self._command = CommandState(vx, omega, False, mode, None)
            return
        if isinstance(message, ErrorAnswer) and note.to is None:
            self.line_faults += 1
            return
        if note.to is None or message is None:
            return
        self.answers += 1
        telemetry = self.telemetry
        if isinstance(message, ConnectBaseAnswer):
            telemetry.identity = BaseIdentity.from_answer(message)
            self.connects += 1
        elif isinstance(message, GetBaseConfAdvAnswer):
            try:
                geometry = geometry_from_tree(binconf.decode(message.blob))
            except CtrlbusError:
                geometry = None
            if geometry is not None:
                telemetry.use_geometry(geometry)
        elif isinstance(message, GetBaseConfAnswer):
            if telemetry.config_source != SOURCE_CONF_ADV:
                telemetry.use_geometry(geometry_from_conf(message))
        elif isinstance(message, HealthGetHealthAnswer):
            self._health_flags = message.flags
            self._health_expected = message.error_count
            self._health_errors = []
            if message.error_count == 0:
                telemetry.health = HealthState(message.flags, ())
        elif isinstance(message, HealthGetErrorAnswer):
            self._health_errors.append(HealthError(message.error_code, message.message))
            if len(self._health_errors) >= self._health_expected:
                telemetry.health = HealthState(self._health_flags, tuple(self._health_errors))
        elif isinstance(message, AnswerMessage):
            apply_reading(telemetry, None, message, note.time or 0.0)

    def state(self, stamp_s: float) -> BaseState:
        telemetry = self.telemetry
        identity = telemetry.identity
        connected = self.connects > 0
        return BaseState(
            stamp_s=stamp_s,
            connected=connected,
            pose=telemetry.pose,
            geometry=telemetry.geometry,
            battery_percent=telemetry.battery_percent,
            charging=telemetry.charging,
            dc_connected=telemetry.dc_connected,
            on_dock=telemetry.on_dock,
            bumper_bitmap=telemetry.bumper_bitmap,
            bumpers_pressed=telemetry.bumpers_pressed,
            cliffs_triggered=telemetry.cliffs_triggered,
            distances_mm=telemetry.distances_mm,
            health=telemetry.health,
            command=self._command,
            serial="" if identity is None else identity.serial,
            link={
                "connection": {
                    "state": "connected" if connected else "connecting",
                    "connects": self.connects,
                },
                "answers": self.answers,
                "line_faults_by_bit": {"any": self.line_faults},
                "source": "capture",
            },
        )


def capture_moments(path: str | Path, model: CaptureModel) -> Iterator[float]:
    """Feed the capture's records into `model`, yielding each record's time (seconds) after it."""
    annotator = Annotator()
    with CaptureReader.open(path) as reader:
        for record in reader:
            for annotation in annotator.feed(record.data, record.direction, record.time):
                if isinstance(annotation, FrameNote):
                    model.note(annotation)
            yield record.time
    for annotation in annotator.finish():
        if isinstance(annotation, FrameNote):
            model.note(annotation)
