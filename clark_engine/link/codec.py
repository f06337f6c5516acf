"""ClarkLink packets: framing, bundling, splitting, authentication and replay protection.

One :class:`Codec` per agent turns the messages due to one destination into
packets (:meth:`Codec.encode`) and turns whatever bytes arrive into a
:class:`~clark_engine.link.packet.Packet` or a
:class:`~clark_engine.link.errors.ClarkLinkError` (:meth:`Codec.decode`). It is
pure: no socket, and its only I/O is the optional counter and replay stores (its
clock is read only with a replay store, to size the replay reservations).

Decisions, each pinned by tests:

* **Decode checks in a fixed order** and stops at the first failure: size
  (``OversizePacket``), length (``TruncatedPacket``), protocol version
  (``BadVersion``), flags and sender id (``MalformedPacket``), mission id
  (``ForeignMission``), tag (``BadTag``), bundle (``MalformedPacket``), replay
  window (``ReplayedPacket``). Only a packet that passed all of them updates the
  sender's replay window, so a forged or garbled packet changes nothing: not
  even a forged packet with a huge counter can push the window past the
  genuine traffic.
* **With a key, every packet is authenticated**, telemetry included; a packet
  without a tag is ``BadTag``, and so is a tagged packet when this codec has no
  key (a keyed peer in an unkeyed mission is misconfigured; acting on its
  packets unchecked would hide that).
* **Every message in a packet must carry the header's sender as its agent_id**,
  and a Heartbeat the header's mission id, or the packet is ``MalformedPacket``.
  ClarkLink has no relaying, so a mismatch is either a bug or an attempt to speak
  for another agent; the header's sender is the one the tag and the replay
  window vouch for.
* **Which destination a packet is for is the caller's business**: decode returns
  ``destination_id`` and does not drop packets addressed to another agent (on a
  broadcast medium the runtime may still want to see them).
"""

from __future__ import annotations

import functools
import math
import struct
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass

from clark_engine.link.auth import (
    CounterStore,
    CounterStoreError,
    ReplayStore,
    ReplayWindow,
    Tagger,
)
from clark_engine.link.errors import (
    BadTag,
    BadVersion,
    ForeignMission,
    MalformedPacket,
    OversizePacket,
    ReplayedPacket,
    TruncatedPacket,
)
from clark_engine.link.messages import MESSAGE_NAMES, Heartbeat, Message
from clark_engine.link.packet import (
    FLAG_AUTHENTICATED,
    HEADER_BYTES,
    MAX_COUNTER,
    PROTOCOL_VERSION,
    TAG_BYTES,
    Packet,
)
from clark_engine.link.wire import AGENT_ID_MAX, canonical_order, encode_entry, parse_bundle

# version, flags, mission id, sender, destination, counter high 16 bits, counter low 32 bits
_HEADER = struct.Struct(">BBIHHHI")  # HEADER_BYTES long
_MISSION_ID_MAX = (1 << 32) - 1
#: The span over which a sender's slowest packet interval is kept (one to two of them).
_PACE_SPAN_S = 1.0
#: The span over which a sender's counters' mean advance is measured (the latest whole one).
_MEAN_SPAN_S = 5.0


class _Tier:
    """One set of replay marks a codec keeps on disk: how it writes them, what it reserves."""

    __slots__ = ("by_mean", "marks", "reserve_s", "write")

    def __init__(
        self,
        write: Callable[[dict[int, int]], None],
        reserve_s: float,
        marks: dict[int, int],
        *,
        by_mean: bool,
    ) -> None:
        self.write = write
        self.reserve_s = reserve_s
        self.by_mean = by_mean  # also reserve at the counters' mean rate (see _Pace)
        self.marks = marks  # sender -> the mark on disk, above every counter of it accepted


class _Pace:
    """How fast a sender's packets come, which sizes its replay reservations.

    Two measures (kept per span: constant memory and time per packet):

    * its slowest packet interval over the last one to two spans of ``span_s``,
      for the reservations that decide how long a crash makes the receiver refuse
      it: the longest, not the mean, so that a burst (a split bundle, packets
      queued behind a radio) does not make a slow sender look fast;
    * its counters' mean advance per second over the latest whole span of
      ``mean_span_s``, bursts and packets to others included, for the
      reservations that should rarely run out (the fsynced ones). A step above
      the replay window's 64 (a sender that restarted and jumped its counter)
      counts as 64.
    """

    __slots__ = (
        "_advance",
        "_current_s",
        "_mean_start_s",
        "_previous_s",
        "_span_start_s",
        "last_counter",
        "last_s",
        "rate_per_s",
    )

    def __init__(self, now_s: float, counter: int) -> None:
        self.last_s = now_s
        self.last_counter = counter
        self._span_start_s = now_s
        self._current_s = -1.0  # -1: no interval yet
        self._previous_s = -1.0
        self._mean_start_s = now_s
        self._advance = 0
        self.rate_per_s = 0.0  # over the latest whole mean span; 0 before one

    def arrived(self, now_s: float, counter: int, span_s: float, mean_span_s: float) -> None:
        """Record a packet accepted at ``now_s``."""
        interval_s = max(now_s - self.last_s, 0.0)
        self.last_s = now_s
        step = counter - self.last_counter
        if step > 0:
            self._advance += min(step, ReplayWindow.SIZE)
            self.last_counter = counter
        if now_s - self._span_start_s >= span_s:
            self._previous_s, self._current_s = self._current_s, interval_s
            self._span_start_s = now_s
        else:
            self._current_s = max(self._current_s, interval_s)
        elapsed_s = now_s - self._mean_start_s
        if elapsed_s >= mean_span_s:
            self.rate_per_s = self._advance / elapsed_s
            self._advance = 0
            self._mean_start_s = now_s

    def longest_s(self, now_s: float) -> float:
        """The longest recent interval, counting the silence since the latest packet.

        -1 before a second packet.
        """
        if self._current_s < 0.0:
            return -1.0
        return max(self._previous_s, self._current_s, now_s - self.last_s)


@dataclass(frozen=True, slots=True)
class SentPacket:
    """One packet :meth:`Codec.encode_packets` made: its bytes, counter and messages."""

    data: bytes
    counter: int
    messages: tuple[Message, ...]


class Codec:
    """Encodes and decodes one agent's ClarkLink packets.

    Holds the agent's packet counter and a replay window per sender, so it must
    live as long as the agent (one per agent, never shared between agents).
    """

    def __init__(
        self,
        mission_id: int,
        agent_id: int,
        key: bytes | None = None,
        *,
        counter_store: CounterStore | None = None,
        replay_store: ReplayStore | None = None,
        max_packet_bytes: int = 1400,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        """Set up a codec; reads the counter store, if any, to resume above its mark.

        Args:
            mission_id: This mission's id (1 to 2**32 - 1); packets of other missions
                are refused.
            agent_id: This agent's id (1 to 65535), the sender of what it encodes.
            key: The mission key (from :func:`~clark_engine.link.auth.load_key`), or
                None for an unauthenticated mission.
            counter_store: Where the packet counter's high-water mark persists. Without
                one the counter restarts at 1 with the process, and peers that remember
                the old counter drop this agent's packets as replays until it passes it.
            replay_store: Where the receiver's replay marks persist (authenticated
                missions only; ignored without a key, where counters prove nothing).
                With one, nothing accepted before a restart is accepted after it.
                Without one, a restarted receiver accepts every recorded packet of a
                sender until that sender's first newer packet.
            max_packet_bytes: The largest packet decoded, and the default limit of
                :meth:`encode` (the radio's packet size limit).
            clock: Seconds on a clock that never goes back (the runtime's), read when a
                packet is accepted with a replay store: packet intervals size each
                sender's reservation (see :class:`~clark_engine.link.auth.ReplayStore`).

        Raises:
            ValueError: An id or size is out of range, or the key is too short.
            CounterStoreError: The counter store cannot be read.
            ReplayStoreError: The replay store cannot be read or is damaged.
        """
        if not 1 <= mission_id <= _MISSION_ID_MAX:
            raise ValueError(f"mission_id {mission_id} is outside 1..{_MISSION_ID_MAX}")
        if not 1 <= agent_id <= AGENT_ID_MAX:
            raise ValueError(f"agent_id {agent_id} is outside 1..{AGENT_ID_MAX}")
        if max_packet_bytes < HEADER_BYTES + TAG_BYTES + 2:
            raise ValueError(f"max_packet_bytes {max_packet_bytes} cannot hold a header and a tag")
        self.mission_id = mission_id
        self.agent_id = agent_id
        self.max_packet_bytes = max_packet_bytes
        self._tagger = Tagger(key) if key is not None else None
        self._store = counter_store
        if counter_store is None:
            self._next_counter = 1
            self._reserved_through = MAX_COUNTER
        else:
            self._next_counter = counter_store.load() + 1
            self._reserved_through = self._next_counter - 1  # reserve before the first use
        self._windows: dict[int, ReplayWindow] = {}
        self._replay_store = replay_store if self._tagger is not None else None
        self._clock = clock
        # sender -> the pace of its accepted packets (with a replay store only)
        self._paces: dict[int, _Pace] = {}
        # the marks kept on disk, durable first (empty: no store)
        self._tiers: list[_Tier] = []
        store = self._replay_store
        if store is not None and self._tagger is not None:
            marks = store.load(f"{mission_id} {self._tagger.fingerprint()}")
            for sender, mark in marks.items():
                self._windows[sender] = ReplayWindow.resumed(mark)
            durable = _Tier(
                store.write_durable,
                store.durable_reserve_s,
                dict(store.durable_marks),
                by_mean=store.live,  # without live marks, the durable ones decide a restart
            )
            if store.live:
                live_marks = dict(store.live_marks or {})
                live = _Tier(store.write_live, store.reserve_s, live_marks, by_mean=False)
                self._tiers = [durable, live]  # live last: it names the durable file
            else:
                self._tiers = [durable]

    def __repr__(self) -> str:
        # Never the key: reprs end up in logs and tracebacks.
        return (
            f"Codec(mission_id={self.mission_id}, agent_id={self.agent_id}, "
            f"authenticated={self.authenticated}, max_packet_bytes={self.max_packet_bytes}, "
            f"next_counter={self._next_counter})"
        )

    @property
    def authenticated(self) -> bool:
        """True when this codec tags what it sends and demands tags on what it receives."""
        return self._tagger is not None

    @property
    def next_counter(self) -> int:
        """The counter the next packet will carry."""
        return self._next_counter

    # ------------------------------------------------------------------ encode

    def encode(
        self, messages: Sequence[Message], destination: int, max_packet_bytes: int | None = None
    ) -> list[bytes]:
        """Bundle every message due to one destination into as few packets as fit.

        Messages go in bundle order (by type, then as given; see
        :mod:`clark_engine.link.wire`). When they do not fit one packet, they are
        split across packets by whole messages in that order, never truncated.
        Each packet takes the next counter. No messages, no packets.

        Args:
            messages: What is due; every one must have this agent's agent_id.
            destination: The agent they are for, or 0 for every agent.
            max_packet_bytes: The radio's packet limit; the codec's by default.

        Returns:
            The packets, ready for the radio, in order.

        Raises:
            OversizePacket: One message alone cannot fit a packet (nothing is sent).
            ValueError: A message is not from this agent (or a Heartbeat not of this
                mission), a field is out of range, or the destination is not an id.
            CounterStoreError: The counter store cannot be written.
        """
        return [sent.data for sent in self.encode_packets(messages, destination, max_packet_bytes)]

    def encode_packets(
        self, messages: Sequence[Message], destination: int, max_packet_bytes: int | None = None
    ) -> list[SentPacket]:
        """:meth:`encode`, telling which messages each packet carries and its counter.

        The message log records every message with the packet that carries it, so a
        split bundle is logged packet by packet.
        """
        limit = self.max_packet_bytes if max_packet_bytes is None else max_packet_bytes
        if not 0 <= destination <= AGENT_ID_MAX:
            raise ValueError(f"destination {destination} is outside 0..{AGENT_ID_MAX}")
        room = limit - HEADER_BYTES - (TAG_BYTES if self._tagger else 0)
        groups: list[list[bytes]] = []
        carried: list[list[Message]] = []
        used = room + 1  # forces a first group
        for message in canonical_order(messages):
            self._check_own(message)
            entry = encode_entry(message)
            if len(entry) > room:
                name = MESSAGE_NAMES[type(message)]
                raise OversizePacket(
                    f"a {name} message encodes to {len(entry)} bytes, but a {limit}-byte packet "
                    f"has room for {max(room, 0)} after its header and tag; shorten it",
                    sender_id=self.agent_id,
                    mission_id=self.mission_id,
                )
            if used + len(entry) > room:
                groups.append([])
                carried.append([])
                used = 0
            groups[-1].append(entry)
            carried[-1].append(message)
            used += len(entry)
        flags = FLAG_AUTHENTICATED if self._tagger else 0
        packets: list[SentPacket] = []
        for group, inside in zip(groups, carried, strict=True):
            counter = self._take_counter()
            head = _HEADER.pack(
                PROTOCOL_VERSION,
                flags,
                self.mission_id,
                self.agent_id,
                destination,
                counter >> 32,
                counter & 0xFFFFFFFF,
            )
            packet = head + b"".join(group)
            if self._tagger is not None:
                packet += self._tagger.tag(packet)
            packets.append(SentPacket(packet, counter, tuple(inside)))
        return packets

    def _check_own(self, message: Message) -> None:
        if message.agent_id != self.agent_id:
            raise ValueError(
                f"{MESSAGE_NAMES[type(message)]} has agent_id {message.agent_id}, but this codec "
                f"sends as agent {self.agent_id}"
            )
        if isinstance(message, Heartbeat) and message.mission_id != self.mission_id:
            raise ValueError(
                f"heartbeat has mission_id {message.mission_id}, but this codec sends in mission "
                f"{self.mission_id}"
            )

    def _take_counter(self) -> int:
        counter = self._next_counter
        if counter > self._reserved_through:
            if self._store is None:
                raise CounterStoreError("the 48-bit packet counter is exhausted")
            self._reserved_through = self._store.reserve(counter)  # on disk before use
        self._next_counter = counter + 1
        return counter

    # ------------------------------------------------------------------ decode

    def decode(self, data: bytes | bytearray | memoryview) -> Packet:
        """Check and decode one received packet.

        Whatever the bytes, this returns a packet or raises a
        :class:`~clark_engine.link.errors.ClarkLinkError` subclass, in the order
        given in the module docstring; the error carries the sender and mission
        the header claims, once the header could be read. Only a packet that
        passes every check updates the sender's replay window.

        Raises:
            OversizePacket, TruncatedPacket, BadVersion, MalformedPacket,
            ForeignMission, BadTag, ReplayedPacket: See :mod:`clark_engine.link.errors`.
            TypeError: ``data`` is not bytes, bytearray or memoryview (a caller's bug).
        """
        if type(data) is not bytes:  # (what radios deliver: skip these checks)
            if isinstance(data, memoryview):
                # Count and slice bytes, whatever the view's item format or layout.
                data = data.cast("B") if data.c_contiguous else memoryview(data.tobytes())
            elif not isinstance(data, bytes | bytearray):
                raise TypeError(f"decode takes bytes, not {type(data).__name__}")
        size = len(data)
        if size > self.max_packet_bytes:
            claimed = _claimed(bytes(data[:HEADER_BYTES])) if size >= HEADER_BYTES else {}
            raise OversizePacket(
                f"packet of {size} bytes is over the {self.max_packet_bytes}-byte limit", **claimed
            )
        raw = bytes(data)
        if size < HEADER_BYTES:
            raise TruncatedPacket(f"packet of {size} bytes is shorter than a header")
        version, flags, mission_id, sender_id, *_ = _HEADER.unpack_from(raw)  # _packet: the rest
        ids: dict[str, int] = {"sender_id": sender_id, "mission_id": mission_id}
        if version != PROTOCOL_VERSION:
            raise BadVersion(
                f"protocol version {version}; this engine speaks {PROTOCOL_VERSION}", **ids
            )
        if flags & ~FLAG_AUTHENTICATED:
            raise MalformedPacket(f"unknown header flags 0x{flags:02x}", **ids)
        tagged = bool(flags & FLAG_AUTHENTICATED)
        end = size - TAG_BYTES if tagged else size
        if end < HEADER_BYTES:
            raise TruncatedPacket(f"packet of {size} bytes is shorter than a header and tag", **ids)
        if sender_id == 0:
            raise MalformedPacket("sender id 0 is not an agent", **ids)
        if mission_id != self.mission_id:
            raise ForeignMission(f"from mission {mission_id}, not {self.mission_id}", **ids)
        if self._tagger is not None:
            if not tagged:
                raise BadTag("packet is not authenticated, and this mission has a key", **ids)
            if not self._tagger.verify(raw[:end], raw[end:]):
                raise BadTag("tag does not match: forged, corrupted or another key", **ids)
        elif tagged:
            raise BadTag("packet is authenticated, but this mission has no key", **ids)
        try:
            packet = _packet(raw)
        except MalformedPacket as exc:
            raise MalformedPacket(str(exc), **ids) from None
        counter = packet.counter
        window = self._windows.get(sender_id)
        restart = False
        if window is not None and not window.is_fresh(counter):
            # Without a tag the window only drops duplicates: an older counter restarts it
            # (see ReplayWindow.restart), so one garbled counter cannot lock a sender out.
            if tagged or window.is_duplicate(counter):
                raise ReplayedPacket(
                    f"counter {counter} already seen or older than the window "
                    f"(highest {window.highest})",
                    **ids,
                )
            restart = True
        if self._tiers:
            now_s = self._clock()
            wrote = False
            for tier in self._tiers:  # on disk before the packet is accepted
                mark = tier.marks.get(sender_id, -1)  # -1: even a counter 0 is written first
                # The live tier (last) follows every durable write: it names the durable file.
                if (
                    counter > mark
                    or wrote
                    or self._slack_too_long(sender_id, mark - counter, now_s, tier)
                ):
                    marks = self._marks(sender_id, counter, now_s, tier)
                    tier.write(marks)
                    tier.marks = marks
                    wrote = True
            pace = self._paces.get(sender_id)
            if pace is None:
                self._paces[sender_id] = _Pace(now_s, counter)
            else:
                pace.arrived(now_s, counter, _PACE_SPAN_S, _MEAN_SPAN_S)
        # Every check passed: only now does anything change.
        if window is None:
            window = self._windows[sender_id] = ReplayWindow()
        if restart:
            window.restart(counter)
        else:
            window.commit(counter)
        return packet

    def _slack_too_long(self, sender_id: int, slack: int, now_s: float, tier: _Tier) -> bool:
        """True when the sender's ``slack`` reserved counters now last too long.

        That is, more than twice the tier's ``reserve_s`` at its latest interval (with
        ``by_mean``, at its counters' mean rate, when it has one): it slowed down since
        they were reserved, and a crash now would refuse its packets for that long.
        Writing the marks again trims them to its new rate.
        """
        if slack <= 0:
            return False
        pace = self._paces.get(sender_id)
        if pace is None:
            return False  # resumed from the store: nothing heard yet, nothing reserved since
        interval_s = now_s - pace.last_s
        if tier.by_mean and pace.rate_per_s > 0.0:
            interval_s = min(interval_s, 1.0 / pace.rate_per_s)
        return slack * interval_s > 2.0 * tier.reserve_s

    def _reservation(self, sender_id: int, now_s: float, tier: _Tier) -> int:
        """How many counters above its highest to reserve for a sender at ``now_s``.

        What it sends in the tier's ``reserve_s`` at its slowest recent interval (the
        time since its latest packet counts as one: a sender gone quiet reserves none),
        rounded down; none before its second packet, or when its packets come all at
        once (no rate can be told). With ``by_mean``, at least what its counters advance
        in that time at their mean rate. Capped at the store's block size.
        """
        store = self._replay_store
        assert store is not None  # only called with a store
        pace = self._paces.get(sender_id)
        if pace is None:
            return 0
        longest_s = pace.longest_s(now_s)
        reserved = math.floor(tier.reserve_s / longest_s) if longest_s > 0.0 else 0
        if tier.by_mean:
            reserved = max(reserved, math.floor(tier.reserve_s * pace.rate_per_s))
        return min(store.block_size, reserved)

    def _marks(self, sender_id: int, counter: int, now_s: float, tier: _Tier) -> dict[int, int]:
        """New marks: each sender's highest accepted counter plus its reservation.

        ``counter`` counts as ``sender_id``'s highest (it is being accepted). Every
        mark is at or above everything accepted from its sender; a mark may fall (to
        the sender's highest, when it went quiet), never below it.
        """
        marks = {
            sender: min(window.highest + self._reservation(sender, now_s, tier), MAX_COUNTER)
            for sender, window in self._windows.items()
        }
        window = self._windows.get(sender_id)
        highest = counter if window is None else max(counter, window.highest)
        reserved = highest + self._reservation(sender_id, now_s, tier)
        marks[sender_id] = min(reserved, MAX_COUNTER)
        return marks

    def trim_replay_marks(self, now_s: float | None = None) -> bool:
        """Write the live marks again when a sender's reservation now lasts too long.

        A sender that slowed down or went quiet keeps the reservation made at its
        old pace until its next packet; a crash in between would make the receiver
        refuse that many of its packets at its new pace (fifty counters of a sender
        that went from 100 to 0.2 packets a second: minutes). Called every tick, this
        trims them within about a second. Only the live marks are trimmed (a rename);
        the fsynced ones are not, since their writes are what must stay rare.

        Args:
            now_s: The time on the codec's clock; read from it when None.

        Returns:
            True when the marks were written again.

        Raises:
            ReplayStoreError: The live marks cannot be written (those on disk stand,
                above everything accepted: nothing unsafe).
        """
        store = self._replay_store
        if store is None or not store.live or not self._tiers:
            return False
        tier = self._tiers[-1]
        now = self._clock() if now_s is None else now_s
        for sender, mark in tier.marks.items():
            window = self._windows.get(sender)
            if window is not None and self._slack_too_long(
                sender, mark - window.highest, now, tier
            ):
                marks = self._marks(sender, window.highest, now, tier)
                tier.write(marks)
                tier.marks = marks
                return True
        return False

    def save_replay_marks(self) -> None:
        """Write each sender's highest accepted counter as its exact mark (on a clean stop).

        After this, a restart refuses exactly what was accepted, and nothing of what
        senders send next; without it (a crash), each sender's next packets are
        refused too for about the store's ``reserve_s`` (its reservation).
        Accepting packets afterwards is still safe: it reserves again. A no-op
        without a replay store.

        Raises:
            ReplayStoreError: The store cannot be written.
        """
        if self._replay_store is None or not self._tiers:
            return
        marks = {sender: window.highest for sender, window in self._windows.items()}
        for tier in self._tiers:  # each tier's marks follow its own file, write by write
            tier.write(marks)
            tier.marks = dict(marks)


@functools.lru_cache(maxsize=512)
def _packet(raw: bytes) -> Packet:
    """The packet in ``raw``, whose header :meth:`Codec.decode` has checked up to the tag.

    Parses the bundle and checks that every message is the header's sender's (and
    every heartbeat of its mission). Memoised by the bytes, as :func:`parse_bundle`
    is: the result is a pure function of them and immutable (a frozen Packet of frozen
    messages), and in a simulated fleet every receiver of a broadcast decodes the same
    bytes. What depends on the receiver (size limit, mission, key, replay window) is
    checked by each codec, before and after.

    Raises:
        MalformedPacket: Without ``sender_id`` and ``mission_id``; the codec adds them.
    """
    _version, flags, mission_id, sender_id, destination_id, high, low = _HEADER.unpack_from(raw)
    tagged = bool(flags & FLAG_AUTHENTICATED)
    end = len(raw) - TAG_BYTES if tagged else len(raw)
    messages = parse_bundle(raw[HEADER_BYTES:end])
    for message in messages:
        if message.agent_id != sender_id:
            raise MalformedPacket(
                f"{MESSAGE_NAMES[type(message)]} claims agent {message.agent_id} in a packet "
                f"from agent {sender_id}"
            )
        if isinstance(message, Heartbeat) and message.mission_id != mission_id:
            raise MalformedPacket(
                f"heartbeat claims mission {message.mission_id} in a packet of mission {mission_id}"
            )
    return Packet(
        mission_id=mission_id,
        sender_id=sender_id,
        destination_id=destination_id,
        counter=(high << 32) | low,
        authenticated=tagged,
        messages=messages,
        size_bytes=len(raw),
    )


def _claimed(header: bytes) -> dict[str, int]:
    """The sender and mission a header claims, for an error about its packet."""
    _version, _flags, mission_id, sender_id, *_rest = _HEADER.unpack_from(header)
    return {"sender_id": sender_id, "mission_id": mission_id}
