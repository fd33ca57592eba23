"""Every exception ctrlbus raises on purpose derives from CtrlbusError."""

from __future__ import annotations


class CtrlbusError(Exception):
    """Base class of all ctrlbus errors."""


class FrameError(CtrlbusError, ValueError):
    """Bytes that are not a valid frame (bad flag, length or checksum)."""


class MessageError(CtrlbusError, ValueError):
    """A frame whose payload cannot be read as the message its command names."""


class MessageFormatError(MessageError):
    """Wrong payload length or out-of-range value for the command (a base answers ERROR 0x8001)."""


class UnsupportedMessageError(MessageError):
    """Unknown command, control-bus request or sub-command (a base answers ERROR 0x8000/0x8002)."""


class LinkError(CtrlbusError, OSError):
    """A port could not be opened, was closed, or failed while reading or writing."""


class ProtocolTimeout(CtrlbusError, TimeoutError):
    """No (valid) answer arrived in time."""


class UsageError(CtrlbusError):
    """Bad command-line or API arguments; the CLI prints it on one line and exits 2."""
