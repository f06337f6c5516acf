"""The radio link budget: what a fleet's telemetry costs on a shared mesh, byte for byte.

The thesis measured 33 kbps of usable throughput on its XBee Pro 900HP mesh
(5.1.3) and packets of at most 256 bytes. This module replays one hyperperiod
of every sender's schedule tick by tick, bundles the messages due to each
destination as the codec does, splits bundles that exceed the packet limit,
and adds the real per-packet costs (ClarkLink header, authentication tag, the
radio's own framing). The sizes come from the real encoder, so the budget is
exactly what would go on air for worst-case message contents.

It is pure arithmetic on plain inputs; turning a mission into those inputs is
the caller's job (:mod:`clark_engine.validation`).
"""

from __future__ import annotations

import math
from collections import defaultdict
from collections.abc import Sequence
from dataclasses import dataclass, field

#: Longest hyperperiod replayed; schedules whose dividers have a larger common
#: multiple are replayed this long, which bounds the error to a fraction of a packet.
MAX_HYPERPERIOD_TICKS = 20_000


@dataclass(frozen=True, slots=True)
class Flow:
    """One periodic message of one sender.

    Attributes:
        sender: Agent name of the sender.
        message: Message name (``agent_status``...).
        every_ticks: Sent on every tick whose index is a multiple of this.
        destinations: Receiving agents; empty means one broadcast packet.
        size_bytes: Worst-case bytes the message adds to a bundle.
        order: Rank of the message type in a bundle; bundles are split in this order,
            as the codec splits them.
    """

    sender: str
    message: str
    every_ticks: int
    destinations: tuple[str, ...]
    size_bytes: int
    order: int = 0


@dataclass(frozen=True, slots=True)
class PacketCosts:
    """Bytes every packet costs beyond its bundle.

    Attributes:
        header_bytes: ClarkLink header.
        tag_bytes: Authentication tag (0 without a key).
        frame_bytes: The radio's own framing (XBee API transmit request: 18).
        max_packet_bytes: Largest ClarkLink packet the radio carries (header, bundle, tag).
    """

    header_bytes: int
    tag_bytes: int
    frame_bytes: int
    max_packet_bytes: int

    @property
    def room_bytes(self) -> int:
        """Bundle bytes that fit in one packet."""
        return self.max_packet_bytes - self.header_bytes - self.tag_bytes


@dataclass(slots=True)
class SenderLoad:
    """What one sender puts on air.

    Attributes:
        sender: Agent name.
        bytes_per_s: On-air bytes per second, framing included.
        packets_per_s: Packets per second.
        by_message: Message name -> bytes per second attributable to it (its own bytes
            plus its share of the packets' overhead).
        largest_bundle_bytes: Largest bundle of one tick to one destination.
        largest_bundle_messages: The messages of that bundle.
        split_ticks: Ticks in the hyperperiod whose bundle needed more than one packet.
        unsendable: (message, bytes) of messages larger than any packet can carry.
    """

    sender: str
    bytes_per_s: float = 0.0
    packets_per_s: float = 0.0
    by_message: dict[str, float] = field(default_factory=dict)
    largest_bundle_bytes: int = 0
    largest_bundle_messages: tuple[str, ...] = ()
    split_ticks: int = 0
    unsendable: tuple[tuple[str, int], ...] = ()

    @property
    def bits_per_s(self) -> float:
        """On-air bits per second."""
        return self.bytes_per_s * 8


def _hyperperiod(dividers: Sequence[int]) -> int:
    period = 1
    for d in dividers:
        period = period * d // math.gcd(period, d)
        if period > MAX_HYPERPERIOD_TICKS:
            return MAX_HYPERPERIOD_TICKS
    return period


def _pack(sizes: Sequence[int], room: int) -> list[int]:
    """Bundle byte counts of the packets a bundle is split into, as the codec splits."""
    packets: list[int] = []
    current = 0
    for size in sizes:
        if current and current + size > room:
            packets.append(current)
            current = 0
        current += size
    if current:
        packets.append(current)
    return packets


def sender_load(
    sender: str, flows: Sequence[Flow], loop_hz: float, costs: PacketCosts
) -> SenderLoad:
    """Replay one hyperperiod of ``sender``'s flows and add up what goes on air."""
    load = SenderLoad(sender)
    mine = [f for f in flows if f.sender == sender]
    load.unsendable = tuple(
        (f.message, f.size_bytes) for f in mine if f.size_bytes > costs.room_bytes
    )
    sendable = [f for f in mine if f.size_bytes <= costs.room_bytes]
    if not sendable:
        return load
    period = _hyperperiod([f.every_ticks for f in sendable])
    total_bytes = 0
    total_packets = 0
    by_message: dict[str, float] = defaultdict(float)
    per_packet = costs.header_bytes + costs.tag_bytes + costs.frame_bytes
    for tick in range(period):
        due = [f for f in sendable if tick % f.every_ticks == 0]
        if not due:
            continue
        groups: dict[str, list[Flow]] = defaultdict(list)
        for flow in due:
            for destination in flow.destinations or ("*",):
                groups[destination].append(flow)
        for unordered in groups.values():
            group = sorted(unordered, key=lambda f: f.order)
            sizes = [f.size_bytes for f in group]
            bundle = sum(sizes)
            if bundle > load.largest_bundle_bytes:
                load.largest_bundle_bytes = bundle
                load.largest_bundle_messages = tuple(f.message for f in group)
            packets = _pack(sizes, costs.room_bytes)
            if len(packets) > 1:
                load.split_ticks += 1
            total_packets += len(packets)
            total_bytes += bundle + per_packet * len(packets)
            overhead_share = per_packet * len(packets) / bundle
            for flow in group:
                by_message[flow.message] += flow.size_bytes * (1 + overhead_share)
    seconds = period / loop_hz
    load.bytes_per_s = total_bytes / seconds
    load.packets_per_s = total_packets / seconds
    load.by_message = {m: b / seconds for m, b in sorted(by_message.items())}
    return load


@dataclass(slots=True)
class MeshBudget:
    """The load of every sender sharing one mesh, against its measured throughput."""

    throughput_bps: float
    loads: list[SenderLoad]

    @property
    def bits_per_s(self) -> float:
        """All senders' on-air bits per second."""
        return sum(load.bits_per_s for load in self.loads)

    @property
    def utilisation(self) -> float:
        """Share of the measured throughput in use (1.0 = all of it)."""
        return self.bits_per_s / self.throughput_bps if self.throughput_bps else math.inf

    def costliest(self, count: int = 3) -> list[tuple[str, str, float]]:
        """The (sender, message, bits per second) that cost most, largest first."""
        items = [
            (load.sender, message, rate * 8)
            for load in self.loads
            for message, rate in load.by_message.items()
        ]
        return sorted(items, key=lambda item: (-item[2], item[0], item[1]))[:count]

    def by_message(self) -> list[tuple[str, float, int]]:
        """(message, bits per second over every sender, senders) largest first."""
        totals: dict[str, float] = defaultdict(float)
        senders: dict[str, int] = defaultdict(int)
        for load in self.loads:
            for message, rate in load.by_message.items():
                totals[message] += rate * 8
                senders[message] += 1
        return sorted(
            ((m, bps, senders[m]) for m, bps in totals.items()), key=lambda i: (-i[1], i[0])
        )

    def by_sender(self) -> list[tuple[str, float]]:
        """(sender, bits per second) largest first."""
        return sorted(((s.sender, s.bits_per_s) for s in self.loads), key=lambda i: (-i[1], i[0]))


def mesh_budget(
    flows: Sequence[Flow],
    senders: Sequence[str],
    loop_hz: float,
    costs: PacketCosts,
    throughput_bps: float,
) -> MeshBudget:
    """The budget of ``senders`` sharing one mesh."""
    return MeshBudget(throughput_bps, [sender_load(s, flows, loop_hz, costs) for s in senders])
