"""The radio interface: how ClarkLink packets leave one agent and reach the others.

The runtime is pure and speaks packets (:mod:`clark_engine.link.codec`); a
:class:`Radio` carries them over one medium: an XBee DigiMesh network
(:mod:`clark_engine.io.xbee`, through digi-xbee) or UDP datagrams on a LAN or
loopback (:mod:`clark_engine.io.udp_radio`). Every radio has the same small
interface, from thesis 3.2.1-3.2.7, so the real-time shell treats them alike and
waits on any of them with ``selectors``:

- ``open()`` then ``verify()``: connect to the device and check it answers as
  configured (raises :class:`RadioError` naming the radio and what to change).
- ``address``: the radio's own address, as the hardware profile writes it (a
  64-bit hexadecimal XBee address, ``host:port`` for UDP).
- ``send(data, destination)``: queue one packet to one address, or to every
  radio (``destination`` None: broadcast). Never blocks the loop; delivery
  failures are counted in :attr:`stats` (and, for XBee, learnt from transmit
  status frames), never raised.
- ``receive()``: the frames that arrived since the last call, never blocking.
- ``fileno()``: a descriptor that becomes readable when frames are waiting, for
  the shell's selector (None: poll ``receive`` every tick).
- ``close()``: release the device; idempotent.
- ``link_events()``: the losses and returns of the link that the radio handled
  itself since the last call (an XBee dongle pulled out and plugged back), for
  the shell to write in the interface log with their times. Radios that never
  reconnect on their own return none.

Every byte that arrives is hostile until the codec has checked it: a radio
hands frames up as they came, bounded in number (:data:`MAX_PENDING_FRAMES`),
with the sender's address as the medium reported it (never trusted for
identity: the packet's own authenticated header says who sent it).
"""

from __future__ import annotations

from abc import ABC, abstractmethod
from dataclasses import dataclass, field
from types import TracebackType
from typing import Final

from clark_engine.errors import ClarkError

MAX_PENDING_FRAMES: Final = 1024
"""Frames a radio holds for the loop before dropping the oldest (counted, never silent)."""


class RadioError(ClarkError):
    """The radio cannot be opened, does not answer as configured, or its link failed."""


@dataclass(frozen=True, slots=True)
class RadioFrame:
    """One packet as it arrived.

    Attributes:
        source: The sender's address as the medium reported it (not proof of identity).
        data: The packet's bytes, unchecked.
        broadcast: Whether it was sent to every radio rather than to this one.
    """

    source: str
    data: bytes
    broadcast: bool = False


@dataclass(frozen=True, slots=True)
class LinkEvent:
    """The radio's link went down or came back, on the radio's own supervision.

    Attributes:
        up: True when the link came back, False when it was lost.
        monotonic_s: When, on :func:`time.monotonic`'s clock (the shell converts it
            to its own time base for the log line).
        detail: What happened, in words: why it was lost, or how long it was down
            and after how many attempts it came back.
    """

    up: bool
    monotonic_s: float
    detail: str


@dataclass(slots=True)
class RadioStats:
    """What a radio counted since it was opened.

    Attributes:
        sent: Packets handed to the medium.
        delivered: Unicast packets the medium confirmed (XBee transmit status SUCCESS).
        send_failures: Packets the medium reported undelivered, per reason
            (``route not found``, ``no ack``...), or could not take.
        received: Frames handed to the loop.
        dropped: Frames lost before the loop read them (a full queue), per place.
        reconnects: Times the device was opened again after its link failed.
        library_lines: Lines the radio's library logged that were counted
            rather than written (a reader spinning on a dead port logs tens of
            thousands a second).
    """

    sent: int = 0
    delivered: int = 0
    send_failures: dict[str, int] = field(default_factory=dict)
    received: int = 0
    dropped: dict[str, int] = field(default_factory=dict)
    reconnects: int = 0
    library_lines: int = 0

    def fail(self, reason: str) -> None:
        """Count one undelivered packet under ``reason``."""
        self.send_failures[reason] = self.send_failures.get(reason, 0) + 1

    def drop(self, place: str, count: int = 1) -> None:
        """Count ``count`` frames lost at ``place`` (``receive queue``...)."""
        self.dropped[place] = self.dropped.get(place, 0) + count


class Radio(ABC):
    """One agent's radio; see the module docstring for the contract."""

    name: str
    """The radio in words, for errors and logs (``xbee /dev/ttyUSB0``, ``udp 127.0.0.1:15001``)."""

    stats: RadioStats
    """What it counted since it was opened."""

    @property
    @abstractmethod
    def address(self) -> str:
        """This radio's own address, as the hardware profile writes it."""

    @abstractmethod
    def open(self) -> None:
        """Connect to the device (thesis 3.2.1); raises :class:`RadioError`."""

    @abstractmethod
    def verify(self) -> None:
        """Check that the device answers and is configured as the profile says (3.2.7)."""

    @abstractmethod
    def send(self, data: bytes, destination: str | None) -> None:
        """Queue ``data`` to ``destination`` (None: every radio); never blocks (3.2.3-3.2.4)."""

    @abstractmethod
    def receive(self) -> list[RadioFrame]:
        """The frames that arrived since the last call, oldest first; never blocks (3.2.5)."""

    @abstractmethod
    def fileno(self) -> int | None:
        """A descriptor readable while frames wait, for the shell's selector; or None."""

    @abstractmethod
    def close(self) -> None:
        """Release the device (3.2.2); calling it again does nothing."""

    def link_events(self) -> list[LinkEvent]:
        """Losses and returns of the link the radio handled itself since the last call.

        The default: none (the radio reports a failure by raising, and the shell
        reopens it).
        """
        return []

    def __enter__(self) -> Radio:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.close()
