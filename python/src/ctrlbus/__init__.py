# SPDX-License-Identifier: MIT
"""ctrlbus: the SLAMWARE Control Bus, byte-exact, in Python.

The everyday names are here; each lives in its layer (docs/architecture.md):

    from ctrlbus import StreamDecoder, encode, open_link, CoreSession, Base

- frames: `encode`, `StreamDecoder`, `Frame`, `checksum` (ctrlbus.frame);
- messages: the request and answer types, `Cmd`, `Request`, `ErrorCode`, ... and
  `decode_request` / `decode_answer` (ctrlbus.messages);
- ports: `open_link`, `serve_link` (ctrlbus.ports), `Link`, `link_pair` (ctrlbus.link);
- the two peers: `Base` and `BaseRunner` (ctrlbus.base), `CoreSession` and `CoreRunner`
  (ctrlbus.core); `Profile` (ctrlbus.constants);
- every error, all derived from `CtrlbusError` (ctrlbus.errors).

They are imported when first used (module `__getattr__`), so `import ctrlbus` costs only this
file: a CLI command or a test loads the layers it needs, not every layer. Type checkers see the
plain imports under TYPE_CHECKING.
"""

import importlib
import os
import sys

# typing.TYPE_CHECKING without importing typing (mypy takes any TYPE_CHECKING as true)
TYPE_CHECKING = False
if TYPE_CHECKING:
    from ctrlbus.base import (
        Base,
        BaseConfig,
        BaseRunner,
        VelocityLimits,
    )
    from ctrlbus.constants import (
        Profile,
    )
    from ctrlbus.core import (
        CoreConfig,
        CoreRunner,
        CoreSession,
    )
    from ctrlbus.errors import (
        BinaryConfigError,
        CaptureError,
        CtrlbusError,
        FrameError,
        LinkError,
        MessageError,
        MessageFormatError,
        PortOpenError,
        PortURLError,
        ProtocolTimeout,
        SimConfigError,
        UnsupportedMessageError,
        UnsupportedSubcommandError,
        UsageError,
    )
    from ctrlbus.frame import (
        Frame,
        StreamDecoder,
        checksum,
        encode,
    )
    from ctrlbus.link import (
        Link,
        link_pair,
    )
    from ctrlbus.messages import (
        AnswerMessage,
        BaseCommand,
        BaseSubcommand,
        Cmd,
        ConnectBase,
        ConnectBaseAnswer,
        Echo,
        EchoAnswer,
        EmptyAnswer,
        ErrorAnswer,
        ErrorCode,
        Event,
        ExternalCommand,
        GetAuxiliaryAnchor,
        GetBaseBumperData,
        GetBaseBumperDataAnswer,
        GetBaseConf,
        GetBaseConfAdv,
        GetBaseConfAdvAnswer,
        GetBaseConfAnswer,
        GetBaseMotorData,
        GetBaseMotorDataAnswer,
        GetBaseSensorData,
        GetBaseSensorDataAnswer,
        GetBaseStatus,
        GetBaseStatusAnswer,
        GetChargerData,
        GetChargerDataAnswer,
        HealthClrError,
        HealthGetError,
        HealthGetErrorAnswer,
        HealthGetHealth,
        HealthGetHealthAnswer,
        HealthSub,
        InvalidAnswer,
        Message,
        OkAnswer,
        PollBaseAnsCmd,
        PollBaseCmd,
        PollBaseCmdAnswer,
        Position,
        Request,
        RequestMessage,
        Response,
        SendEvent,
        SetBaseMotor,
        SetVAndGetDeadreckon,
        SetVAndGetDeadreckonAnswer,
        Sync,
        SyncAnswer,
        answer_frame,
        decode_answer,
        decode_request,
        encode_answer,
        encode_request,
        request_frame,
    )
    from ctrlbus.ports import (
        open_link,
        serve_link,
    )

    __version__: str

# name -> the module that defines it
_EXPORTS = {
    # ctrlbus.base
    "Base": "ctrlbus.base",
    "BaseConfig": "ctrlbus.base",
    "BaseRunner": "ctrlbus.base",
    "VelocityLimits": "ctrlbus.base",
    # ctrlbus.constants
    "Profile": "ctrlbus.constants",
    # ctrlbus.core
    "CoreConfig": "ctrlbus.core",
    "CoreRunner": "ctrlbus.core",
    "CoreSession": "ctrlbus.core",
    # ctrlbus.errors
    "BinaryConfigError": "ctrlbus.errors",
    "CaptureError": "ctrlbus.errors",
    "CtrlbusError": "ctrlbus.errors",
    "FrameError": "ctrlbus.errors",
    "LinkError": "ctrlbus.errors",
    "MessageError": "ctrlbus.errors",
    "MessageFormatError": "ctrlbus.errors",
    "PortOpenError": "ctrlbus.errors",
    "PortURLError": "ctrlbus.errors",
    "ProtocolTimeout": "ctrlbus.errors",
    "SimConfigError": "ctrlbus.errors",
    "UnsupportedMessageError": "ctrlbus.errors",
    "UnsupportedSubcommandError": "ctrlbus.errors",
    "UsageError": "ctrlbus.errors",
    # ctrlbus.frame
    "Frame": "ctrlbus.frame",
    "StreamDecoder": "ctrlbus.frame",
    "checksum": "ctrlbus.frame",
    "encode": "ctrlbus.frame",
    # ctrlbus.link
    "Link": "ctrlbus.link",
    "link_pair": "ctrlbus.link",
    # ctrlbus.messages
    "AnswerMessage": "ctrlbus.messages",
    "BaseCommand": "ctrlbus.messages",
    "BaseSubcommand": "ctrlbus.messages",
    "Cmd": "ctrlbus.messages",
    "ConnectBase": "ctrlbus.messages",
    "ConnectBaseAnswer": "ctrlbus.messages",
    "Echo": "ctrlbus.messages",
    "EchoAnswer": "ctrlbus.messages",
    "EmptyAnswer": "ctrlbus.messages",
    "ErrorAnswer": "ctrlbus.messages",
    "ErrorCode": "ctrlbus.messages",
    "Event": "ctrlbus.messages",
    "ExternalCommand": "ctrlbus.messages",
    "GetAuxiliaryAnchor": "ctrlbus.messages",
    "GetBaseBumperData": "ctrlbus.messages",
    "GetBaseBumperDataAnswer": "ctrlbus.messages",
    "GetBaseConf": "ctrlbus.messages",
    "GetBaseConfAdv": "ctrlbus.messages",
    "GetBaseConfAdvAnswer": "ctrlbus.messages",
    "GetBaseConfAnswer": "ctrlbus.messages",
    "GetBaseMotorData": "ctrlbus.messages",
    "GetBaseMotorDataAnswer": "ctrlbus.messages",
    "GetBaseSensorData": "ctrlbus.messages",
    "GetBaseSensorDataAnswer": "ctrlbus.messages",
    "GetBaseStatus": "ctrlbus.messages",
    "GetBaseStatusAnswer": "ctrlbus.messages",
    "GetChargerData": "ctrlbus.messages",
    "GetChargerDataAnswer": "ctrlbus.messages",
    "HealthClrError": "ctrlbus.messages",
    "HealthGetError": "ctrlbus.messages",
    "HealthGetErrorAnswer": "ctrlbus.messages",
    "HealthGetHealth": "ctrlbus.messages",
    "HealthGetHealthAnswer": "ctrlbus.messages",
    "HealthSub": "ctrlbus.messages",
    "InvalidAnswer": "ctrlbus.messages",
    "Message": "ctrlbus.messages",
    "OkAnswer": "ctrlbus.messages",
    "PollBaseAnsCmd": "ctrlbus.messages",
    "PollBaseCmd": "ctrlbus.messages",
    "PollBaseCmdAnswer": "ctrlbus.messages",
    "Position": "ctrlbus.messages",
    "Request": "ctrlbus.messages",
    "RequestMessage": "ctrlbus.messages",
    "Response": "ctrlbus.messages",
    "SendEvent": "ctrlbus.messages",
    "SetBaseMotor": "ctrlbus.messages",
    "SetVAndGetDeadreckon": "ctrlbus.messages",
    "SetVAndGetDeadreckonAnswer": "ctrlbus.messages",
    "Sync": "ctrlbus.messages",
    "SyncAnswer": "ctrlbus.messages",
    "answer_frame": "ctrlbus.messages",
    "decode_answer": "ctrlbus.messages",
    "decode_request": "ctrlbus.messages",
    "encode_answer": "ctrlbus.messages",
    "encode_request": "ctrlbus.messages",
    "request_frame": "ctrlbus.messages",
    # ctrlbus.ports
    "open_link": "ctrlbus.ports",
    "serve_link": "ctrlbus.ports",
}


def _installed_version() -> str:
    """The installed package's version, which is the C library's (python/setup.py reads it from
    c/include/ctrlbus/ctrlbus.h): there is no second copy to keep in step. Read from the name of
    the installed distribution's `ctrlbus-<version>.dist-info` directory (the wheel format fixes
    that name), found on sys.path in import order as importlib.metadata would, without importing
    importlib.metadata (a tenth of a second, paid by every CLI command); importlib.metadata
    remains the fallback for other installers' layouts."""
    for entry in sys.path:
        try:
            names = os.listdir(entry or ".")
        except OSError:  # not a directory (a zip file) or gone
            continue
        found = sorted(n for n in names if n.startswith("ctrlbus-") and n.endswith(".dist-info"))
        if found:
            return found[0].removeprefix("ctrlbus-").removesuffix(".dist-info")
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("ctrlbus")
    except PackageNotFoundError:  # imported from a source tree that was never installed
        return "0+unknown"


def __getattr__(name: str) -> object:
    if name == "__version__":
        value: object = _installed_version()
    elif name in _EXPORTS:
        value = getattr(importlib.import_module(_EXPORTS[name]), name)
    else:
        raise AttributeError(f"module 'ctrlbus' has no attribute {name!r}")
    globals()[name] = value  # later lookups find it without calling __getattr__
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})


__all__ = [
    "AnswerMessage",
    "Base",
    "BaseCommand",
    "BaseConfig",
    "BaseRunner",
    "BaseSubcommand",
    "BinaryConfigError",
    "CaptureError",
    "Cmd",
    "ConnectBase",
    "ConnectBaseAnswer",
    "CoreConfig",
    "CoreRunner",
    "CoreSession",
    "CtrlbusError",
    "Echo",
    "EchoAnswer",
    "EmptyAnswer",
    "ErrorAnswer",
    "ErrorCode",
    "Event",
    "ExternalCommand",
    "Frame",
    "FrameError",
    "GetAuxiliaryAnchor",
    "GetBaseBumperData",
    "GetBaseBumperDataAnswer",
    "GetBaseConf",
    "GetBaseConfAdv",
    "GetBaseConfAdvAnswer",
    "GetBaseConfAnswer",
    "GetBaseMotorData",
    "GetBaseMotorDataAnswer",
    "GetBaseSensorData",
    "GetBaseSensorDataAnswer",
    "GetBaseStatus",
    "GetBaseStatusAnswer",
    "GetChargerData",
    "GetChargerDataAnswer",
    "HealthClrError",
    "HealthGetError",
    "HealthGetErrorAnswer",
    "HealthGetHealth",
    "HealthGetHealthAnswer",
    "HealthSub",
    "InvalidAnswer",
    "Link",
    "LinkError",
    "Message",
    "MessageError",
    "MessageFormatError",
    "OkAnswer",
    "PollBaseAnsCmd",
    "PollBaseCmd",
    "PollBaseCmdAnswer",
    "PortOpenError",
    "PortURLError",
    "Position",
    "Profile",
    "ProtocolTimeout",
    "Request",
    "RequestMessage",
    "Response",
    "SendEvent",
    "SetBaseMotor",
    "SetVAndGetDeadreckon",
    "SetVAndGetDeadreckonAnswer",
    "SimConfigError",
    "StreamDecoder",
    "Sync",
    "SyncAnswer",
    "UnsupportedMessageError",
    "UnsupportedSubcommandError",
    "UsageError",
    "VelocityLimits",
    "__version__",
    "answer_frame",
    "checksum",
    "decode_answer",
    "decode_request",
    "encode",
    "encode_answer",
    "encode_request",
    "link_pair",
    "open_link",
    "request_frame",
    "serve_link",
]
