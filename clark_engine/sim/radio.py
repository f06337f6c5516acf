"""A deterministic model of one shared radio medium, for the discrete-event simulator.

The thesis's agents talk over XBee Pro 900HP radios in one DigiMesh network
(4.1.2) whose measured best-case throughput is 33 kbit/s for the whole network
(5.1.3), not per link. :class:`RadioMesh` models exactly that: ONE channel that
every agent of the mesh shares, so transmissions are serialised one after
another at the sender's measured throughput and a busy mesh queues the rest.

The model is pure: it owns no clock and no thread. The simulator tells it when
a packet is handed to a radio (:meth:`RadioMesh.send`), asks when the next
thing happens (:meth:`RadioMesh.next_event_s`) and collects what has arrived
by a given time (:meth:`RadioMesh.deliveries_until`).

Models, in the order a packet meets them:

1. Packet limit. A packet longer than the sender's ``max_packet_bytes`` is
   refused (counted as ``refused_oversize`` on every link it was addressed to
   and never delivered). The codec never produces one; this is a check.
2. Silence. A silenced sender's radio transmits nothing: its packets never take
   the air and count as ``lost_fault``.
3. Serialisation. A packet occupies the shared channel for
   ``(len(packet) + frame_overhead_bytes) * 8 / throughput_bps`` seconds (the
   sender's radio profile), starting when the channel is free: first come,
   first served, in the order of the :meth:`~RadioMesh.send` calls. The wait is
   the packet's queueing delay. With ``max_queue_s`` set, a packet that would
   wait longer is dropped (``dropped_queue``); by default the queue is unbounded.
4. Latency. A packet arrives ``latency_s`` after its last bit left the air:
   arrival = transmission start + air time + ``latency_s``. Every receiver of a
   broadcast hears the same transmission, so all arrive at the same time.
5. Faults at the arrival time: a dropped link (either direction) or a silenced
   receiver loses the packet (``lost_fault``). Faults may be injected while the
   packet is in flight; they are looked up when the packet arrives, and they
   take precedence: every packet a fault touches counts as ``lost_fault``.
6. Loss, per receiver and independently for each receiver of a broadcast, from
   one uniform ``u`` of the packet's own (see Determinism): ``u < loss_rate`` is a random loss
   (``lost_random``); otherwise ``u < p(d)`` is a range loss (``lost_range``),
   where ``p(d)`` is the distance law below at the send-time positions;
   otherwise, with bursts declared, ``u < 1 - (1 - p(d)) (1 - b)`` is a burst loss
   (``lost_burst``), where ``b`` is the loss of the link's Gilbert-Elliott state at the
   send time (below); otherwise the packet survives. The same uniform serves all three,
   so a burst loses a packet the distance law spared with probability ``b`` exactly,
   as an independent draw would, and the mesh's draws are the same with or without
   bursts.
7. Corruption: a delivered packet inside a corruption window is corrupted with
   the window's probability (a second uniform of the packet's own); 1 to
   :data:`MAX_FLIPPED_BYTES` distinct bytes are XORed with a random non-zero value
   (from a third value of the packet's own), so a corrupted packet always differs.
   Corrupted packets are delivered (and counted both as ``delivered`` and as
   ``corrupted``); an empty packet cannot be corrupted.

Distance law. ``d`` is the straight-line (3-D) distance between sender and
receiver at the send time; ``R`` is the smaller ``range_m`` of the two radios
(``None`` on both: unlimited, no range loss); ``k`` is ``range_fade_factor``
(default 2). Loss is the base rate ``p0 = loss_rate`` up to ``R``, rises along
a smoothstep to 1 at ``k * R`` and stays there::

    p(d) = p0                                        d <= R
    p(d) = p0 + (1 - p0) * (3 x**2 - 2 x**3),        x = (d - R) / ((k - 1) R), R < d < kR
    p(d) = 1                                         d >= kR

The smoothstep has zero slope at both ends, so loss neither jumps at the range
nor kinks at the fade's end. Taking the smaller range makes every link
symmetric: the weaker radio limits both directions.

Bursts (``sim.radio_bursts``). Real links lose packets in runs, not one by one: each
link (pair of agents, both directions) has its own Gilbert-Elliott chain in simulated
time (:mod:`clark_engine.sim.radio_bursts`), whose state at the send time gives ``b``
in step 6.

Not modelled: DigiMesh relaying (every agent is assumed to hear every other
directly, and a relayed packet would cost the channel air time twice), MAC
acknowledgements and retries of unicasts in API mode, collisions (the channel
is a perfect first-come-first-served queue), and the serial link between the
mission computer and its radio (it is inside the measured throughput).

Default latency. The thesis's two-agent runs at 1 to 5 Hz deviate from the
ideal by 0.045 to 0.059 s for a round trip (tables 5.1 and 5.2), about 25 to
30 ms one way, Python processing included. One 100-byte ClarkLink packet plus
the 18-byte XBee frame takes 29 ms on air at 33 kbit/s, so a few milliseconds
of fixed latency (:data:`DEFAULT_LATENCY_S`) on top of serialisation fits.

Determinism: a packet's fate is its own. The loss uniform, the corruption uniform
and the seed of the byte flips of one packet at one receiver are a keyed hash
(BLAKE2b, keyed with 64 bits the mesh draws once from its ``random.Random``) of
that packet's identity: sender, destination (``""`` for a broadcast), receiver,
send time in whole microseconds, and its place among the sender's sends to that
destination at that time (0, then 1 when a bundle is split in two). They do not
depend on which packets were sent before or in between, so:

- the same mission flown on the simulated autopilot and on ArduPilot SITL loses and
  corrupts the same packets: agents tick at the same times on both (a seeded phase
  and ``loop_hz``), and a heartbeat sent at a tick meets the same fate on both,
  though the packets around it differ (a state change a tick later, a report that
  waits for the autopilot); with one uniform stream drawn in the order of the
  sends, one extra packet early in a run moved every later draw onto another packet;
- injecting a fault changes the fate of the packets it touches and of no other.

The hash is computed only when it matters: the loss uniform when the packet can be
lost (a loss rate, range or burst loss above 0 for it), the corruption values when it
arrives inside a corruption window. A mission with neither draws nothing. The same
agents, sends, faults and seed give the same deliveries.
"""

from __future__ import annotations

import hashlib
import heapq
import math
import random
import struct
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, fields, replace
from typing import Any, NamedTuple

from clark_engine.sim.radio_bursts import BurstChain, BurstSettings

#: Fixed latency after the air time when the mesh is built without one, in seconds.
DEFAULT_LATENCY_S = 0.005
#: Multiple of the range at which loss reaches 1 when the mesh is built without one.
DEFAULT_RANGE_FADE_FACTOR = 2.0
#: Most bytes one corruption flips.
MAX_FLIPPED_BYTES = 4
#: A packet's three values (loss uniform, corruption uniform, flip seed) from its 24-byte hash.
_FATE = struct.Struct(">QQQ")
#: 2**-53: the top 53 bits of a 64-bit integer times this are a uniform in [0, 1), never 1.
_TO_UNIT = 2.0**-53

#: A position in the mission's local frame: (north_m, east_m, up_m).
Position = tuple[float, float, float]


@dataclass(frozen=True, slots=True)
class RadioSettings:
    """One agent's radio, read from its (composed) radio profile.

    Attributes:
        throughput_bps: Measured application throughput in bits per second; a packet's air
            time is computed with its sender's.
        max_packet_bytes: Largest packet the radio carries.
        frame_overhead_bytes: Bytes the radio adds to every packet (XBee API frame: 18).
        range_m: Range in metres; None for unlimited.
    """

    throughput_bps: float
    max_packet_bytes: int
    frame_overhead_bytes: int
    range_m: float | None

    @classmethod
    def from_profile(cls, profile: Mapping[str, Any]) -> RadioSettings:
        """Read the fields the mesh needs; a clear ValueError when one is missing or wrong."""

        def number(key: str) -> float:
            value = profile.get(key)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"radio profile: {key} must be a number, got {value!r}")
            return float(value)

        def integer(key: str) -> int:
            value = profile.get(key)
            if isinstance(value, bool) or not isinstance(value, int):
                raise ValueError(f"radio profile: {key} must be an integer, got {value!r}")
            return value

        throughput_bps = number("throughput_bps")
        if throughput_bps <= 0 or not math.isfinite(throughput_bps):
            raise ValueError(f"radio profile: throughput_bps must be > 0, got {throughput_bps}")
        max_packet_bytes = integer("max_packet_bytes")
        if max_packet_bytes < 1:
            raise ValueError(
                f"radio profile: max_packet_bytes must be >= 1, got {max_packet_bytes}"
            )
        frame_overhead_bytes = integer("frame_overhead_bytes")
        if frame_overhead_bytes < 0:
            raise ValueError(
                f"radio profile: frame_overhead_bytes must be >= 0, got {frame_overhead_bytes}"
            )
        range_m: float | None = None
        if profile.get("range_m") is not None:
            range_m = number("range_m")
            if range_m <= 0:
                raise ValueError(f"radio profile: range_m must be > 0 or null, got {range_m}")
        return cls(throughput_bps, max_packet_bytes, frame_overhead_bytes, range_m)

    def air_time_s(self, size_bytes: int) -> float:
        """Seconds a packet of ``size_bytes`` occupies the channel, framing included."""
        return (size_bytes + self.frame_overhead_bytes) * 8 / self.throughput_bps


class Delivery(NamedTuple):
    """One packet arriving at one receiver.

    The first four fields are the order deliveries come out in: time, then
    sender, receiver and send sequence, so equal times have a stable order.

    An immutable named tuple rather than a frozen dataclass: the mesh makes one per
    packet and receiver (a 50-agent fleet: 2,500 a simulated second), and a tuple is
    built in one step where a frozen dataclass sets each field through
    ``object.__setattr__``.

    Attributes:
        at_s: Arrival time (simulation seconds).
        sender: Sending agent's name.
        receiver: Receiving agent's name.
        sequence: Number of the send call that produced it (0, 1, 2, ... per mesh).
        packet: The bytes as received (corrupted ones differ from those sent).
        sent_s: When the sender handed the packet to its radio.
        corrupted: True when bytes were flipped on the way (the receiver cannot know;
            this is for tests and statistics).
    """

    at_s: float
    sender: str
    receiver: str
    sequence: int
    packet: bytes
    sent_s: float
    corrupted: bool = False


@dataclass(slots=True)
class LinkOutcomes:
    """What became of the packets addressed over one directed link (sender -> receiver).

    The medium's truth, which only a simulation knows; not what a receiver infers of a
    peer's link (:class:`clark_engine.link.link_stats.LinkStats`, in its fleet table).

    A broadcast counts once on every link it was addressed to. Outcomes are
    exclusive except ``corrupted``, which is a subset of ``delivered``; once
    nothing is in flight, ``sent`` is the sum of ``delivered``, the ``lost_*``,
    ``refused_oversize`` and ``dropped_queue``.

    Attributes:
        sent: Packets addressed over the link.
        delivered: Packets that arrived (corrupted or not).
        lost_random: Lost to the mesh's base loss rate.
        lost_range: Lost to distance beyond range.
        lost_burst: Lost to the link's bad (or good) Gilbert-Elliott state (``sim.radio_bursts``).
        lost_fault: Lost to an injected fault (dropped link, silenced sender or receiver).
        corrupted: Delivered with bytes flipped.
        refused_oversize: Longer than the sender's packet limit; never sent.
        dropped_queue: Would have waited longer than the mesh's ``max_queue_s``.
    """

    sent: int = 0
    delivered: int = 0
    lost_random: int = 0
    lost_range: int = 0
    lost_fault: int = 0
    lost_burst: int = 0
    corrupted: int = 0
    refused_oversize: int = 0
    dropped_queue: int = 0


@dataclass(slots=True)
class QueueStats:
    """Queueing on the shared channel, over transmissions that took the air.

    Attributes:
        transmissions: Packets that took the air (a broadcast is one).
        total_queue_s: Sum of their waits for the channel.
        max_queue_s: Longest wait.
        air_s: Total air time, framing included (divide by the elapsed time for utilisation).
    """

    transmissions: int = 0
    total_queue_s: float = 0.0
    max_queue_s: float = 0.0
    air_s: float = 0.0

    @property
    def mean_queue_s(self) -> float:
        """Mean wait for the channel; 0 before any transmission."""
        return self.total_queue_s / self.transmissions if self.transmissions else 0.0

    def add(self, queue_s: float, air_s: float) -> None:
        """Account one transmission."""
        self.transmissions += 1
        self.total_queue_s += queue_s
        self.max_queue_s = max(self.max_queue_s, queue_s)
        self.air_s += air_s


@dataclass(frozen=True, slots=True)
class _Window:
    """A half-open fault window [from_s, to_s)."""

    from_s: float
    to_s: float

    def covers(self, t_s: float) -> bool:
        return self.from_s <= t_s < self.to_s


#: A packet in flight to one receiver: (at_s, sender, receiver, sequence, packet, sent_s,
#: loss_probability, destination, place, link, loss_with_bursts), where ``place`` is the
#: packet's place among its sender's sends to that destination at that time. The mesh
#: keeps these in a heap, so they come out as deliveries do: the first four fields are
#: unique per item (one receiver per send sequence), so comparisons never reach the rest.
#: Plain tuples, built and compared in C: a broadcast to 49 receivers makes 49 of them and costs
#: hundreds of comparisons. ``link`` is the link's statistics, counted on arrival.
_Pending = tuple[float, str, str, int, bytes, float, float, str, int, LinkOutcomes, float]
#: A packet's own values at one receiver: (loss uniform, corruption uniform, flip seed).
_Fate = tuple[float, float, int]


@dataclass(slots=True)
class _Agent:
    name: str
    agent_id: int
    radio: RadioSettings


def loss_probability(
    distance_m: float, range_m: float | None, loss_rate: float, fade_factor: float
) -> float:
    """Probability that a packet over ``distance_m`` is lost (the distance law of the module)."""
    if range_m is None or distance_m <= range_m:
        return loss_rate
    far_m = fade_factor * range_m
    if distance_m >= far_m:
        return 1.0
    x = (distance_m - range_m) / (far_m - range_m)
    return loss_rate + (1.0 - loss_rate) * x * x * (3.0 - 2.0 * x)


def _check_window(from_s: float, to_s: float) -> None:
    if math.isnan(from_s) or math.isnan(to_s) or to_s < from_s:
        raise ValueError(f"fault window must have from_s <= to_s, got [{from_s}, {to_s})")


class RadioMesh:
    """One shared radio channel between the agents of a simulated mission.

    Agents whose radios cannot hear each other (different link kinds, say UDP
    on the bench and XBee in the field) belong in separate meshes.

    Args:
        rng: The mesh's seeded random source: the mesh draws the 64-bit key of its
            packets' fates from it, once (module docstring, Determinism).
        latency_s: Fixed delay from the end of a packet's air time to its arrival.
        loss_rate: Base probability (0..1) that a receiver misses a packet within range.
        range_fade_factor: Loss reaches 1 at this multiple of the link's range (> 1).
        max_queue_s: Longest a packet may wait for the channel before it is dropped;
            None for an unbounded queue.
        bursts: A Gilbert-Elliott chain on every link (``sim.radio_bursts``); None: none.
        burst_seed: The run's seed, with ``bursts``: each link's chain is seeded from it
            and the link's names, never from ``rng``.
    """

    def __init__(
        self,
        rng: random.Random,
        *,
        latency_s: float = DEFAULT_LATENCY_S,
        loss_rate: float = 0.0,
        range_fade_factor: float = DEFAULT_RANGE_FADE_FACTOR,
        max_queue_s: float | None = None,
        bursts: BurstSettings | None = None,
        burst_seed: int | str = 0,
    ) -> None:
        if not latency_s >= 0 or not math.isfinite(latency_s):
            raise ValueError(f"latency_s must be >= 0, got {latency_s}")
        if not 0.0 <= loss_rate <= 1.0:
            raise ValueError(f"loss_rate must be within 0..1, got {loss_rate}")
        if not range_fade_factor > 1.0 or not math.isfinite(range_fade_factor):
            raise ValueError(f"range_fade_factor must be > 1, got {range_fade_factor}")
        if max_queue_s is not None and not max_queue_s >= 0:
            raise ValueError(f"max_queue_s must be >= 0 or None, got {max_queue_s}")
        self._fate_key = rng.getrandbits(64).to_bytes(8, "big")
        # Per link, a hash already fed the link's names: each packet copies it.
        self._fate_hashes: dict[tuple[str, str, str], Any] = {}
        # The time of the latest send and, per (sender, destination), the sends made then.
        self._place_s = -math.inf
        self._places: dict[tuple[str, str], int] = {}
        self.latency_s = latency_s
        self.loss_rate = loss_rate
        self.range_fade_factor = range_fade_factor
        self.max_queue_s = max_queue_s
        self.bursts = bursts
        self._burst_seed = burst_seed
        self._chains: dict[tuple[str, str], BurstChain] = {}
        self._agents: dict[str, _Agent] = {}
        self._names: tuple[str, ...] = ()  # sorted: the receivers of a broadcast, in order
        self._ranged = False  # some radio has a range
        self._ids: set[int] = set()
        self._pending: list[_Pending] = []
        self._channel_free_s = 0.0
        self._send_clock_s = -math.inf  # the last send's time
        self._clock_s = -math.inf  # deliveries were taken up to this time
        self._sequence = 0
        self._dropped_links: dict[frozenset[str], list[_Window]] = {}
        self._silenced: dict[str, list[_Window]] = {}
        self._corruption: list[tuple[_Window, float]] = []
        self._links: dict[tuple[str, str], LinkOutcomes] = {}
        self._queue = QueueStats()
        self._queue_by_sender: dict[str, QueueStats] = {}

    # -- configuration -------------------------------------------------------

    def add_agent(self, name: str, agent_id: int, profile: Mapping[str, Any]) -> None:
        """Put an agent's radio on the mesh.

        Args:
            name: Agent name (unique on the mesh).
            agent_id: Agent id (unique on the mesh).
            profile: The agent's composed radio profile: ``throughput_bps``,
                ``max_packet_bytes``, ``frame_overhead_bytes`` and optional ``range_m``.

        Raises:
            ValueError: A duplicate name or id, or a profile field missing or invalid.
        """
        if not name:
            raise ValueError("agent name must not be empty")
        if name in self._agents:
            raise ValueError(f"agent {name!r} is already on the mesh")
        if agent_id in self._ids:
            raise ValueError(f"agent id {agent_id} is already on the mesh")
        radio = RadioSettings.from_profile(profile)
        self._agents[name] = _Agent(name, agent_id, radio)
        self._names = tuple(sorted(self._agents))
        self._ranged = self._ranged or radio.range_m is not None
        self._ids.add(agent_id)
        self._queue_by_sender[name] = QueueStats()

    @property
    def agents(self) -> tuple[str, ...]:
        """Names of the agents on the mesh, sorted."""
        return self._names

    @property
    def uses_positions(self) -> bool:
        """True when some radio on the mesh has a range: only then do positions matter."""
        return self._ranged

    def radio(self, name: str) -> RadioSettings:
        """The radio settings of agent ``name``."""
        return self._agent(name).radio

    # -- faults --------------------------------------------------------------

    def drop_link(self, a: str, b: str, from_s: float, to_s: float = math.inf) -> None:
        """Lose the packets between ``a`` and ``b`` (both ways) arriving in [from_s, to_s)."""
        self._agent(a)
        self._agent(b)
        if a == b:
            raise ValueError(f"a link joins two agents, got {a!r} twice")
        _check_window(from_s, to_s)
        self._dropped_links.setdefault(frozenset((a, b)), []).append(_Window(from_s, to_s))

    def silence(self, agent: str, from_s: float, to_s: float = math.inf) -> None:
        """Silence ``agent``'s radio in [from_s, to_s): it neither sends nor receives.

        A dead agent, or a station that stops talking. Its sends in the window never take
        the air; packets arriving for it in the window are lost.
        """
        self._agent(agent)
        _check_window(from_s, to_s)
        self._silenced.setdefault(agent, []).append(_Window(from_s, to_s))

    def corrupt(self, share: float, from_s: float = 0.0, to_s: float = math.inf) -> None:
        """Flip bytes in ``share`` (0..1) of the packets delivered in [from_s, to_s).

        Where windows overlap, the largest share applies.
        """
        if not 0.0 <= share <= 1.0:
            raise ValueError(f"corruption share must be within 0..1, got {share}")
        _check_window(from_s, to_s)
        self._corruption.append((_Window(from_s, to_s), share))

    # -- traffic -------------------------------------------------------------

    def air_time_s(self, sender: str, size_bytes: int) -> float:
        """Seconds a packet of ``size_bytes`` from ``sender`` occupies the channel."""
        return self._agent(sender).radio.air_time_s(size_bytes)

    def send(
        self,
        sender: str,
        packet: bytes,
        destination: str,
        now_s: float,
        positions: Mapping[str, Position] | None = None,
    ) -> None:
        """Hand one packet to ``sender``'s radio at ``now_s``.

        Args:
            sender: Sending agent's name.
            packet: The encoded ClarkLink packet.
            destination: Receiving agent's name; ``""`` broadcasts to every other agent.
            now_s: Simulation time; never earlier than any time given to this mesh before.
            positions: Agent name -> (north_m, east_m, up_m) at ``now_s``, for range loss.
                An agent missing from it (or no mapping at all) is taken as within range.

        Raises:
            ValueError: Unknown sender or destination, a packet to oneself, a send earlier
                than the one before, or a packet that would arrive before a time whose
                deliveries were already taken.
        """
        source = self._agent(sender)
        if destination == sender:
            raise ValueError(f"agent {sender!r} cannot send a packet to itself")
        if destination:
            self._agent(destination)
            receivers: Iterable[str] = (destination,)
        else:
            receivers = [name for name in self._names if name != sender]
        if math.isnan(now_s) or now_s < self._send_clock_s:
            raise ValueError(
                f"time went back: a send at {now_s} s after one at {self._send_clock_s} s"
            )
        radio = source.radio
        earliest_s = now_s + radio.air_time_s(len(packet)) + self.latency_s
        if earliest_s < self._clock_s:
            raise ValueError(
                f"time went back: a packet sent at {now_s} s would arrive at {earliest_s} s "
                f"or later, but deliveries up to {self._clock_s} s were already taken"
            )
        self._send_clock_s = now_s
        sequence = self._sequence
        self._sequence += 1
        # The packet's place among its sender's sends to this destination at this time.
        if now_s != self._place_s:
            self._place_s = now_s
            self._places.clear()
        place = self._places.get((sender, destination), 0)
        self._places[(sender, destination)] = place + 1
        links = [self._link(sender, receiver) for receiver in receivers]
        for link in links:
            link.sent += 1

        def count(outcome: str) -> None:
            for link in links:
                setattr(link, outcome, getattr(link, outcome) + 1)

        if len(packet) > radio.max_packet_bytes:
            count("refused_oversize")
            return
        if self._is_silenced(sender, now_s):
            count("lost_fault")
            return
        start_s = max(now_s, self._channel_free_s)
        queue_s = start_s - now_s
        if self.max_queue_s is not None and queue_s > self.max_queue_s:
            count("dropped_queue")
            return
        air_s = radio.air_time_s(len(packet))
        self._channel_free_s = start_s + air_s
        self._queue.add(queue_s, air_s)
        self._queue_by_sender[sender].add(queue_s, air_s)
        at_s = start_s + air_s + self.latency_s
        bursts = self.bursts is not None
        for receiver, link in zip(receivers, links, strict=True):
            range_m = self._link_range_m(sender, receiver) if self._ranged else None
            # Without a range the distance law is the base rate: skip measuring the distance.
            p_loss = (
                self.loss_rate
                if range_m is None
                else loss_probability(
                    _distance_m(positions, sender, receiver),
                    range_m,
                    self.loss_rate,
                    self.range_fade_factor,
                )
            )
            # With bursts, the link's state adds its loss on top (the same uniform decides).
            p_total = (
                1.0 - (1.0 - p_loss) * (1.0 - self._chain(sender, receiver).loss_at(now_s))
                if bursts
                else p_loss
            )
            pending: _Pending = (
                at_s,
                sender,
                receiver,
                sequence,
                packet,
                now_s,
                p_loss,
                destination,
                place,
                link,
                p_total,
            )
            heapq.heappush(self._pending, pending)

    def next_event_s(self) -> float | None:
        """Arrival time of the next packet in flight, None when nothing is in flight.

        The packet may still turn out lost when it arrives; a wake-up for it then
        yields no delivery.
        """
        return self._pending[0][0] if self._pending else None

    def deliveries_until(self, t_s: float) -> list[Delivery]:
        """Every packet arriving at or before ``t_s``, in arrival order, losses removed.

        Equal arrival times come out by sender, receiver, then send sequence.
        """
        self._advance_clock(t_s)
        delivered: list[Delivery] = []
        pending = self._pending
        while pending and pending[0][0] <= t_s:
            delivery = self._resolve(heapq.heappop(pending))
            if delivery is not None:
                delivered.append(delivery)
        return delivered

    @property
    def in_flight(self) -> int:
        """Packets (per receiver) sent but not yet arrived or lost."""
        return len(self._pending)

    # -- statistics ----------------------------------------------------------

    def link_stats(self, sender: str, receiver: str) -> LinkOutcomes:
        """A copy of the counts of the link ``sender`` -> ``receiver`` (zeros if unused)."""
        stats = self._links.get((sender, receiver))
        return LinkOutcomes() if stats is None else _copy_link(stats)

    def links(self) -> dict[tuple[str, str], LinkOutcomes]:
        """Copies of the counts of every link used so far, keyed (sender, receiver), sorted."""
        return {key: _copy_link(self._links[key]) for key in sorted(self._links)}

    def totals(self) -> LinkOutcomes:
        """The counts of every link added up."""
        total = LinkOutcomes()
        for stats in self._links.values():
            for item in fields(LinkOutcomes):
                setattr(total, item.name, getattr(total, item.name) + getattr(stats, item.name))
        return total

    def queue_stats(self, sender: str | None = None) -> QueueStats:
        """A copy of the queueing statistics of the whole mesh, or of one sender."""
        source = self._queue if sender is None else self._queue_by_sender[self._agent(sender).name]
        return replace(source)

    # -- internals -----------------------------------------------------------

    def _agent(self, name: str) -> _Agent:
        agent = self._agents.get(name)
        if agent is None:
            raise ValueError(f"agent {name!r} is not on the mesh (known: {', '.join(self.agents)})")
        return agent

    def _advance_clock(self, now_s: float) -> None:
        if math.isnan(now_s) or now_s < self._clock_s:
            raise ValueError(f"time went back: deliveries up to {now_s} s after {self._clock_s} s")
        self._clock_s = now_s

    def _link(self, sender: str, receiver: str) -> LinkOutcomes:
        stats = self._links.get((sender, receiver))
        if stats is None:
            stats = self._links[(sender, receiver)] = LinkOutcomes()
        return stats

    def _chain(self, a: str, b: str) -> BurstChain:
        """The Gilbert-Elliott chain of the link between ``a`` and ``b`` (either way)."""
        key = (a, b) if a < b else (b, a)
        chain = self._chains.get(key)
        if chain is None:
            assert self.bursts is not None
            rng = random.Random(f"{self._burst_seed}:radio-burst:{key[0]}:{key[1]}")
            chain = self._chains[key] = BurstChain(self.bursts, rng)
        return chain

    def _link_range_m(self, sender: str, receiver: str) -> float | None:
        """The smaller range of the two radios; None when neither has one."""
        a, b = self._agents[sender].radio.range_m, self._agents[receiver].radio.range_m
        if a is None:
            return b
        return a if b is None else min(a, b)

    def _is_silenced(self, agent: str, t_s: float) -> bool:
        return any(w.covers(t_s) for w in self._silenced.get(agent, ()))

    def _is_dropped(self, a: str, b: str, t_s: float) -> bool:
        return any(w.covers(t_s) for w in self._dropped_links.get(frozenset((a, b)), ()))

    def _corruption_share(self, t_s: float) -> float:
        return max((share for w, share in self._corruption if w.covers(t_s)), default=0.0)

    def _fate(
        self, sender: str, destination: str, receiver: str, sent_s: float, place: int
    ) -> _Fate:
        """The packet's own loss uniform, corruption uniform and flip seed at ``receiver``.

        A keyed hash of the packet's identity (module docstring, Determinism): the same
        packet gets the same values whatever else the mesh carried.
        """
        link = (sender, destination, receiver)
        prefix = self._fate_hashes.get(link)
        if prefix is None:
            prefix = hashlib.blake2b(digest_size=_FATE.size, key=self._fate_key)
            prefix.update(f"{sender}\0{destination}\0{receiver}\0".encode())
            self._fate_hashes[link] = prefix
        digest = prefix.copy()
        digest.update(f"{round(sent_s * 1e6)}\0{place}".encode())
        loss, corrupt, seed = _FATE.unpack(digest.digest())
        return (loss >> 11) * _TO_UNIT, (corrupt >> 11) * _TO_UNIT, seed

    def _resolve(self, item: _Pending) -> Delivery | None:
        (
            at_s,
            sender,
            receiver,
            sequence,
            packet,
            sent_s,
            p_loss,
            destination,
            place,
            link,
            p_all,
        ) = item
        fate: _Fate | None = None
        # (Each fault look-up is skipped while no fault of its kind was ever injected.)
        if (self._dropped_links and self._is_dropped(sender, receiver, at_s)) or (
            self._silenced and self._is_silenced(receiver, at_s)
        ):
            link.lost_fault += 1
            return None
        if p_all > 0.0:  # the packet may be lost: its own uniform decides
            fate = self._fate(sender, destination, receiver, sent_s, place)
            loss = fate[0]
            if loss < self.loss_rate:
                link.lost_random += 1
                return None
            if loss < p_loss:
                link.lost_range += 1
                return None
            if loss < p_all:
                link.lost_burst += 1
                return None
        corrupted = False
        if packet and self._corruption:
            share = self._corruption_share(at_s)
            if share > 0.0:
                if fate is None:
                    fate = self._fate(sender, destination, receiver, sent_s, place)
                if fate[1] < share:
                    packet = _flip_bytes(packet, fate[2])
                    corrupted = True
                    link.corrupted += 1
        link.delivered += 1
        return Delivery(at_s, sender, receiver, sequence, packet, sent_s, corrupted)


def _distance_m(positions: Mapping[str, Position] | None, a: str, b: str) -> float:
    if positions is None or a not in positions or b not in positions:
        return 0.0
    return math.dist(positions[a], positions[b])


def _flip_bytes(packet: bytes, seed: int) -> bytes:
    """XOR 1..MAX_FLIPPED_BYTES distinct bytes with non-zero values, from ``seed``."""
    rng = random.Random(seed)
    data = bytearray(packet)
    count = rng.randint(1, min(len(data), MAX_FLIPPED_BYTES))
    for index in rng.sample(range(len(data)), count):
        data[index] ^= rng.randint(1, 255)
    return bytes(data)


def _copy_link(stats: LinkOutcomes) -> LinkOutcomes:
    return replace(stats)
