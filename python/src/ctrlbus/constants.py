# SPDX-License-Identifier: MIT
"""Protocol facts that more than one layer needs, each defined here once.

The message layouts live in ctrlbus.messages; this module holds the facts about what the fields
mean and which variant a base sends, which the base framework, the simulator, the Core emulator,
the checker and the annotator all need:

- health error codes (HEALTH_GET_ERROR): their four bytes, and the motor watchdog's code;
- the bits of GET_BASE_STATUS: power and motion;
- the answer profiles (`Profile`) and the answer sizes that tell them apart.

tests/test_constants.py proves by grep that none of these is defined anywhere else. The bit
meanings themselves come from the protocol description (protocol/ctrlbus.json, generated into
ctrlbus.protocol_tables), as the C, Wireshark and sigrok tables do.
"""

from __future__ import annotations

from ctrlbus import protocol_tables
from ctrlbus.compat import StrEnum
from ctrlbus.errors import UsageError
from ctrlbus.messages import ConnectBaseAnswer, SetVAndGetDeadreckonAnswer

__all__ = [
    "COMPONENT_MOTION",
    "COMPONENT_POWER",
    "COMPONENT_SENSOR",
    "COMPONENT_SYSTEM",
    "COMPONENT_USER",
    "HEALTH_ERROR",
    "HEALTH_FATAL",
    "HEALTH_WARNING",
    "LINE_FAULT_BIT_NAMES",
    "LINE_FAULT_LIMIT",
    "MOTION_BIT_NAMES",
    "MOTION_DEFINED_BITS",
    "MOTION_STALL",
    "MOTION_TRACTION_LOST",
    "POWER_BIT_NAMES",
    "POWER_CHARGING",
    "POWER_DC_CONNECTED",
    "POWER_DEFINED_BITS",
    "POWER_ON_DOCK",
    "PROFILE_ANSWER_SIZES",
    "REFERENCE_LOW_BATTERY_CODE",
    "REFERENCE_LOW_BATTERY_MESSAGE",
    "TYPE_WATCHDOG_TRIPPED",
    "WATCHDOG_TRIPPED_CODE",
    "WATCHDOG_TRIPPED_MESSAGE",
    "Profile",
    "health_code",
    "parse_profile",
]

# --- health error codes: bits 31..24 level, 23..16 component, 15..8 type, 7..0 index (reference §5)

HEALTH_WARNING = 0x01
HEALTH_ERROR = 0x02
HEALTH_FATAL = 0x04
COMPONENT_USER = 0
COMPONENT_SYSTEM = 1
COMPONENT_POWER = 2
COMPONENT_MOTION = 3
COMPONENT_SENSOR = 4
# Types from 0x80 up are ctrlbus's own (the reference's types are all small numbers).
TYPE_WATCHDOG_TRIPPED = 0x80


def health_code(level: int, component: int, error_type: int, index: int = 0) -> int:
    """The u32 health error code of its four bytes (each 0..255)."""
    for name, value in (
        ("level", level),
        ("component", component),
        ("error_type", error_type),
        ("index", index),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= 0xFF:
            raise UsageError(f"health code {name} must be an integer 0..255, got {value!r}")
    return (level << 24) | (component << 16) | (error_type << 8) | index


# protocol.md §10.3: what a base lists once its motor watchdog stopped the wheels (0x01038000).
WATCHDOG_TRIPPED_CODE = health_code(HEALTH_WARNING, COMPONENT_MOTION, TYPE_WATCHDOG_TRIPPED)
WATCHDOG_TRIPPED_MESSAGE = "motor watchdog tripped"
# The reference's low-battery error (power, type 0x01, index 0), which its quirks mode shows at start.
REFERENCE_LOW_BATTERY_CODE = health_code(HEALTH_ERROR, COMPONENT_POWER, 0x01)  # 0x02020100
REFERENCE_LOW_BATTERY_MESSAGE = "low battery"

# --- line faults (protocol §11.6): an ERROR code below LINE_FAULT_LIMIT is the base receiver's
# state, bits ORed together by the reference; never an answer, the request is sent again.

LINE_FAULT_LIMIT = protocol_tables.LINE_FAULTS_BELOW
LINE_FAULT_BIT_NAMES = protocol_tables.LINE_FAULTS_BITS

# --- GET_BASE_STATUS bits (protocol.md §5.4, §5.5) ---------------------------------------------

POWER_CHARGING = protocol_tables.POWER_STATUS_CHARGING
POWER_DC_CONNECTED = protocol_tables.POWER_STATUS_DC_CONNECTED
POWER_ON_DOCK = protocol_tables.POWER_STATUS_ON_DOCK
POWER_DEFINED_BITS = protocol_tables.POWER_STATUS_DEFINED  # 0-2 from the reference, 3-5 the 2020 SDK
MOTION_STALL = protocol_tables.MOTOR_STATUS_STALL
MOTION_TRACTION_LOST = protocol_tables.MOTOR_STATUS_TRACTION_LOST
MOTION_DEFINED_BITS = protocol_tables.MOTOR_STATUS_DEFINED

POWER_BIT_NAMES = protocol_tables.POWER_STATUS_BITS
MOTION_BIT_NAMES = protocol_tables.MOTOR_STATUS_BITS

# --- answer profiles (protocol.md §6.2) -------------------------------------------------------


class Profile(StrEnum):
    """Which answer variants a base sends where the sources know two (reference §4-5).

    reference: the 2018/v4 reference firmware (CONNECT 28 bytes, deadreckon 13 bytes, POLL with
    nothing pending = OK 0). sdk2020: the sizes the vendor's 2020 master SDK reads (CONNECT 39,
    deadreckon 17 with timestamp_ms, BUMPER 4, POLL with nothing pending = OK 2 `FF 00`).
    """

    REFERENCE = "reference"
    SDK2020 = "sdk2020"


def parse_profile(value: Profile | str) -> Profile:
    """The Profile named `value` ("reference" or "sdk2020"); UsageError otherwise."""
    try:
        return Profile(value)
    except ValueError:
        choices = " or ".join(profile.value for profile in Profile)
        raise UsageError(f"unknown profile {value!r} (choose {choices})") from None


# Payload sizes of the OK answers that differ between the profiles, from the layouts themselves.
PROFILE_ANSWER_SIZES: dict[Profile, dict[str, int]] = {
    Profile.REFERENCE: {
        "CONNECT_BASE": ConnectBaseAnswer._REFERENCE_FORM.size,
        "SET_V_AND_GET_DEADRECKON": SetVAndGetDeadreckonAnswer._REFERENCE_FORM.size,
        "POLL_BASE_CMD": 0,  # nothing pending: OK with no payload
    },
    Profile.SDK2020: {
        "CONNECT_BASE": ConnectBaseAnswer._SDK_FORM.size,
        "SET_V_AND_GET_DEADRECKON": SetVAndGetDeadreckonAnswer._SDK_FORM.size,
        "POLL_BASE_CMD": 2,  # nothing pending: `FF 00`
    },
}
