# SPDX-License-Identifier: MIT
"""Every exception ctrlbus raises on purpose derives from CtrlbusError."""

from __future__ import annotations

__all__ = [
    "BinaryConfigError",
    "CaptureError",
    "CtrlbusError",
    "FrameError",
    "LinkError",
    "MessageError",
    "MessageFormatError",
    "PortOpenError",
    "PortURLError",
    "ProtocolTimeout",
    "SimConfigError",
    "UnsupportedMessageError",
    "UnsupportedSubcommandError",
    "UsageError",
]


class CtrlbusError(Exception):
    """Base class of all ctrlbus errors."""


class FrameError(CtrlbusError, ValueError):
    """Bytes that are not a valid frame (bad flag, length or checksum)."""


class MessageError(CtrlbusError, ValueError):
    """A frame whose payload cannot be read as the message its command names."""


class MessageFormatError(MessageError):
    """Wrong payload length or out-of-range value for the command (a base answers ERROR 0x8001)."""

    error_code = 0x8001  # the ERROR code a base answers with


class UnsupportedMessageError(MessageError):
    """Unknown command, control-bus request or sub-command (a base answers ERROR 0x8000/0x8002)."""

    error_code = 0x8000  # the ERROR code a base answers with


class UnsupportedSubcommandError(UnsupportedMessageError):
    """Unknown HEALTH_MGMT sub-command: the reference answers ERROR 0x8002 here, not 0x8000."""

    error_code = 0x8002


class LinkError(CtrlbusError, OSError):
    """A port could not be opened, was closed, or failed while reading or writing."""


class ProtocolTimeout(CtrlbusError, TimeoutError):
    """No (valid) answer arrived in time."""


class UsageError(CtrlbusError):
    """Bad command-line or API arguments; the CLI prints it on one line and exits 2."""


class PortOpenError(LinkError):
    """A port could not be opened (absent, busy, refused); `url` names it, `reason` says why."""

    def __init__(self, url: str, reason: str, *, message: str | None = None) -> None:
        shown = url if url.isprintable() else repr(url)
        super().__init__(message or f"cannot open {shown}: {reason}")
        self.url = url
        self.reason = reason


class PortURLError(PortOpenError, UsageError):
    """A port URL that is wrong in itself: unknown scheme, bad option, bad fault spec."""


class BinaryConfigError(CtrlbusError, ValueError):
    """A binary configuration blob (0x21) or its JSON form that cannot be decoded or encoded.

    `offset` is the byte offset in the blob where decoding failed; `path` is where in the JSON tree
    encoding failed (like `base.sensors[2].id`). Either may be None.
    """

    def __init__(self, message: str, *, offset: int | None = None, path: str | None = None) -> None:
        super().__init__(message)
        self.offset = offset
        self.path = path


class CaptureError(CtrlbusError, ValueError):
    """A capture file that is not a ctrlbus pcap, or is damaged."""


class SimConfigError(CtrlbusError, ValueError):
    """A simulator base or room description that cannot be used; the message names the file and key."""
