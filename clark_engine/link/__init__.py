"""ClarkLink: the messages agents exchange, their packets, and their authentication.

The public API is here: :class:`Codec` (encode and decode packets), :class:`Packet`,
the message dataclasses, the errors decoding raises, and key and counter files.
The message classes and errors are plain Python and import at once; :class:`Codec`
and the key and counter helpers load on first use, so that importing this package
(for example to name message types in mission checks) does not pull in Protocol
Buffers.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from clark_engine.link.errors import (
    BadTag,
    BadVersion,
    ClarkLinkError,
    ForeignMission,
    MalformedPacket,
    OversizePacket,
    ReplayedPacket,
    ReplayStoreError,
    TruncatedPacket,
)
from clark_engine.link.messages import (
    CLARKLINK_VERSION,
    COMMANDS,
    MESSAGE_NAMES,
    ActivateController,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    Condition,
    Heartbeat,
    Message,
    ModeChangeRequest,
    PictureData,
    PrearmState,
    Terminate,
    VehicleHealth,
)
from clark_engine.link.packet import Packet

if TYPE_CHECKING:
    from clark_engine.link.auth import (
        CounterStore,
        CounterStoreError,
        KeyFileError,
        ReplayStore,
        generate_key_file,
        load_key,
    )
    from clark_engine.link.codec import Codec

# Name -> module that defines it, imported on first access (PEP 562).
_LAZY = {
    "Codec": "clark_engine.link.codec",
    "CounterStore": "clark_engine.link.auth",
    "CounterStoreError": "clark_engine.link.auth",
    "KeyFileError": "clark_engine.link.auth",
    "ReplayStore": "clark_engine.link.auth",
    "generate_key_file": "clark_engine.link.auth",
    "load_key": "clark_engine.link.auth",
}

__all__ = [
    "CLARKLINK_VERSION",
    "COMMANDS",
    "MESSAGE_NAMES",
    "ActivateController",
    "AgentAttitude",
    "AgentStatus",
    "AgentType",
    "BadTag",
    "BadVersion",
    "BehaviorState",
    "ClarkLinkError",
    "Codec",
    "Condition",
    "CounterStore",
    "CounterStoreError",
    "ForeignMission",
    "Heartbeat",
    "KeyFileError",
    "MalformedPacket",
    "Message",
    "ModeChangeRequest",
    "OversizePacket",
    "Packet",
    "PictureData",
    "PrearmState",
    "ReplayStore",
    "ReplayStoreError",
    "ReplayedPacket",
    "Terminate",
    "TruncatedPacket",
    "VehicleHealth",
    "generate_key_file",
    "load_key",
]


def __getattr__(name: str) -> Any:
    """Import the heavier parts of the API on first use."""
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted(__all__)
