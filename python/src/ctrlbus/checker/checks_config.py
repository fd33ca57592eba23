# SPDX-License-Identifier: MIT
"""Checks that the base's two descriptions of itself agree, as a Core would read them.

A Core reads GET_BASE_CONF_ADV (0x21) when the base serves a blob and GET_BASE_CONF (0x20) only
otherwise; a base maker usually fills in both. These checks read both the way the Core emulator
does (ctrlbus.core.geometry: the blob's `robot_size` is a diameter in metres, its poses metres
and radians) and say what a Core reading one of them gets wrong or misses.
"""

from __future__ import annotations

from ctrlbus import binconf
from ctrlbus.checker.framework import Check, CheckContext, Rule
from ctrlbus.core.geometry import BaseGeometry, compare_geometries, geometry_from_conf, geometry_from_tree
from ctrlbus.errors import BinaryConfigError
from ctrlbus.messages import (
    GetBaseConf,
    GetBaseConfAdv,
    GetBaseConfAdvAnswer,
    GetBaseConfAnswer,
    GetBaseSensorData,
    GetBaseSensorDataAnswer,
)

__all__ = ["CHECKS"]

SENSOR_SAMPLES = 3  # GET_BASE_SENSOR_DATA reads: a channel counts as reporting if any is non-zero
REFERENCE_SONARS = (
    "the reference firmware does this: its blob lists only bumpers and cliff sensors, its sonars "
    "are in GET_BASE_CONF alone"
)


def _both_geometries(ctx: CheckContext) -> tuple[BaseGeometry, BaseGeometry | None, str]:
    """(GET_BASE_CONF's geometry, the blob's or None, why there is no blob geometry)."""
    conf, _ = ctx.expect_ok(GetBaseConf(), GetBaseConfAnswer)
    answer, _ = ctx.ask(GetBaseConfAdv())
    if not isinstance(answer, GetBaseConfAdvAnswer):
        return geometry_from_conf(conf), None, "no binary configuration (0x21 refused): the Core uses 0x20"
    try:
        tree = binconf.decode(answer.blob)
    except BinaryConfigError:
        return geometry_from_conf(conf), None, "the blob does not decode (check 3): the Core uses 0x20"
    adv = geometry_from_tree(tree)
    if adv is None:
        return geometry_from_conf(conf), None, "the blob has no `base` object: the Core uses 0x20"
    return geometry_from_conf(conf), adv, ""


# --- 22 config-agreement ---------------------------------------------------------------------


def check_config_agreement(ctx: CheckContext) -> None:
    conf, adv, why = _both_geometries(ctx)
    if adv is None:
        ctx.summary = f"{why}; nothing to compare"
        return
    for problem in compare_geometries(adv, conf):
        if problem.kind in ("radius", "sensor_position"):
            ctx.fail(f"{problem}: a Core reading 0x21 gets the robot wrong (§12.4 [conf-agree])")
        elif problem.kind == "sensor_count" and problem.missing_slots:
            ctx.warn(
                f"{problem}: a Core reading 0x21 does not know them; {REFERENCE_SONARS} (§12.4 [conf-agree])"
            )
        else:
            ctx.note(f"{problem} (the blob may describe more than 0x20 can hold)")
    ctx.summary = (
        f"radius {adv.radius_mm:.0f} mm (robot_size/2) and {conf.radius_mm:.0f} mm; "
        f"{len(adv.sensors)} and {len(conf.sensors)} distance sensors (0x21 and 0x20)"
    )


# --- 23 sensor-list --------------------------------------------------------------------------


def check_sensor_list(ctx: CheckContext) -> None:
    conf, adv, why = _both_geometries(ctx)
    reporting: dict[int, float] = {}
    for _ in range(SENSOR_SAMPLES):
        answer, _ = ctx.expect_ok(GetBaseSensorData(), GetBaseSensorDataAnswer)
        for channel, distance in enumerate(answer.distances_mm):
            if distance:
                reporting.setdefault(channel, distance)
    conf_slots = {sensor.slot for sensor in conf.sensors}
    used = conf_slots if adv is None else {sensor.slot for sensor in adv.sensors}
    source = "GET_BASE_CONF" if adv is None else "the 0x21 blob"
    for channel, distance in sorted(reporting.items()):
        if channel in used:
            continue
        reading = f"channel {channel} reports readings ({distance:g} mm)"
        if channel in conf_slots:
            ctx.warn(
                f"{reading} and GET_BASE_CONF lists it, but the 0x21 blob does not: a Core reading 0x21 "
                f"ignores it; {REFERENCE_SONARS} (§12.4 [conf-sensor-list])"
            )
        else:
            ctx.fail(
                f"{reading} but no configuration lists it: a Core has no position for it and ignores "
                "it (§12.4 [conf-sensor-list]; a channel without a sensor reads 0)"
            )
    note = f" ({why})" if why else ""
    ctx.summary = (
        f"{len(reporting)} channels report readings; {source} lists {len(used)} distance sensors{note}"
    )


CHECKS = (
    Check(
        22,
        "config-agreement",
        "the 0x21 blob agrees with GET_BASE_CONF (radius = robot_size/2, distance sensors)",
        (Rule("§12.4", "conf-agree"), Rule("§5.2", "base-conf"), Rule("§5.3", "base-conf-adv")),
        check_config_agreement,
    ),
    Check(
        23,
        "sensor-list",
        "every distance channel with readings is in the configuration the Core reads",
        (Rule("§12.4", "conf-sensor-list"), Rule("§5.6", "sensor-data")),
        check_sensor_list,
    ),
)
