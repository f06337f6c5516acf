"""Everything that can be wrong with a byte string that arrives, as exceptions.

:meth:`clark_engine.link.codec.Codec.decode` raises only these, whatever the
input. Each carries what could be read of the header before the problem was
found, so the fleet table can count it against the claimed sender.
"""

from __future__ import annotations

from clark_engine.errors import ClarkError


class ClarkLinkError(ClarkError):
    """A packet that must not be acted on.

    Attributes:
        sender_id: The sender the header claims, when the header could be read.
        mission_id: The mission the header claims, when it could be read.
    """

    def __init__(
        self, message: str, *, sender_id: int | None = None, mission_id: int | None = None
    ) -> None:
        super().__init__(message)
        self.sender_id = sender_id
        self.mission_id = mission_id


class TruncatedPacket(ClarkLinkError):
    """Shorter than a header (or than its header and tag)."""


class MalformedPacket(ClarkLinkError):
    """The header or the message bundle cannot be parsed."""


class BadVersion(ClarkLinkError):
    """A ClarkLink protocol version this engine does not speak."""


class ForeignMission(ClarkLinkError):
    """From an agent running another mission: reported, never acted on."""


class BadTag(ClarkLinkError):
    """Authentication failed.

    Forged, corrupted, unauthenticated when a key is set, or keyed when none is.
    """


class ReplayedPacket(ClarkLinkError):
    """A counter already seen from this sender, or too old for its replay window."""


class OversizePacket(ClarkLinkError):
    """Too large for a packet.

    Larger than the radio's packet limit (on decode), or a single message that cannot fit
    any packet (on encode).
    """


class ReplayStoreError(ClarkLinkError):
    """The receiver's replay marks cannot be read or written.

    Raised by :class:`~clark_engine.link.codec.Codec` when it starts (the store is
    damaged: it cannot know what it accepted before, so it does not start) and by
    decode (the mark that must be on disk before a packet is accepted could not be
    written: the packet is refused, never acted on unrecorded). The message names
    the file, never its content.
    """
