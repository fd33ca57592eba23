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
"""

from importlib.metadata import PackageNotFoundError, version

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

# The installed package's version, which is the C library's (python/setup.py reads it from
# c/include/ctrlbus/ctrlbus.h): there is no second copy to keep in step.
try:
    __version__ = version("ctrlbus")
except PackageNotFoundError:  # imported from a source tree that was never installed
    __version__ = "0+unknown"

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
