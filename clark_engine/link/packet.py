"""A decoded ClarkLink packet.

Wire format (big-endian), fixed by golden-byte tests:

====== ==== =========================================================
offset size field
====== ==== =========================================================
0      1    protocol version (1)
1      1    flags: bit 0 set when a tag follows; other bits zero
2      4    mission id
6      2    sender agent id
8      2    destination agent id (0 = every agent)
10     6    counter, 48 bits, never reused by a sender
16     n    the message bundle (Protocol Buffers ``Bundle``)
16+n   12   tag: HMAC-SHA256 over bytes 0..16+n, truncated (authenticated only)
====== ==== =========================================================

The radio frame (XBee API frame, UDP datagram) delimits the packet, so it has
no length field.
"""

from __future__ import annotations

from dataclasses import dataclass

from clark_engine.link.messages import Message

PROTOCOL_VERSION = 1
HEADER_BYTES = 16
TAG_BYTES = 12
FLAG_AUTHENTICATED = 0x01
BROADCAST = 0
MAX_COUNTER = (1 << 48) - 1


@dataclass(frozen=True, slots=True)
class Packet:
    """One packet as received: its header and every message it bundles.

    Attributes:
        mission_id: The mission the sender runs (equal to ours, or decode raised).
        sender_id: Agent id of the sender.
        destination_id: Agent it is for; 0 for every agent.
        counter: The sender's packet counter.
        authenticated: True when its tag was checked against the mission key.
        messages: The messages, in the order they were bundled.
        size_bytes: Length of the packet on the wire (header, bundle, tag).
    """

    mission_id: int
    sender_id: int
    destination_id: int
    counter: int
    authenticated: bool
    messages: tuple[Message, ...]
    size_bytes: int
