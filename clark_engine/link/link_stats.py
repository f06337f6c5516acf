"""What an agent knows of the link from each peer: :class:`LinkStats`, in O(1) memory.

Why separate: the fleet table (:mod:`clark_engine.link.fleet`) keeps one per peer, but how
a packet's counter is placed in its sender's sequence (new, late, duplicate, out of the
window), and so how losses, reordering, replays and latency are counted, is a concept of
its own, tested on its own. Not the simulated medium's counts of what became of the
packets on a link (:class:`clark_engine.sim.radio.LinkOutcomes`): those are the truth a
dry run knows; these are what a receiver can infer.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from enum import Enum

#: Counters below the highest one seen that the loss tracker still tells apart
#: (seen or not). A packet later than this is counted as ``out_of_window``.
COUNTER_WINDOW = 64

#: A forward counter jump larger than this is taken as the sender restarting or
#: moving its counter on (a time-based counter jumps by the time it was down),
#: not as that many lost packets: it is counted in ``resyncs`` and loss counting
#: starts again from the new counter. At 10 packets/s this is over 16 minutes of
#: packets, far beyond any outage a heartbeat timeout would not already report.
MAX_COUNTED_GAP = 10_000

_WINDOW_MASK = (1 << COUNTER_WINDOW) - 1


class _Order(Enum):
    """Where a packet's counter falls relative to those already seen from its sender."""

    NEW = 1  # above every counter seen
    LATE = 2  # below the highest, inside the window, not seen before: fills a gap
    DUPLICATE = 3  # seen before
    OUT_OF_WINDOW = 4  # too far below the highest to tell


# Looking a member up on an Enum class costs a descriptor call in Python 3.11, and every
# packet every agent receives is placed: the hot path uses these names.
NEW, LATE, DUPLICATE, _OUT_OF_WINDOW = (
    _Order.NEW,
    _Order.LATE,
    _Order.DUPLICATE,
    _Order.OUT_OF_WINDOW,
)


@dataclass(slots=True)
class LinkStats:
    """How the link from one peer is doing, in O(1) memory.

    Losses are inferred from the sender's packet counter: a jump of k > 1 over
    the highest counter seen counts k - 1 losses, and a late packet that fills
    one of those gaps takes one back, so reordering is never counted as loss.
    A bitmap of the last :data:`COUNTER_WINDOW` counters tells a late packet
    from a duplicate. Counters are 48-bit and never reused by a sender, so they
    never wrap.

    An unauthenticated counter proves nothing: one garbled on the way can land
    anywhere in the 48 bits. So on an unauthenticated packet a counter more than
    :data:`COUNTER_WINDOW` away from the sequence (ahead of it, or behind its
    window) is held as a *candidate* and becomes the new baseline only when the
    next packet continues from it (a sender that restarted or moved its counter
    on). Otherwise the candidate was an outlier (``outliers``, or
    ``out_of_window`` when behind) and the old sequence carries on, so one bad
    counter costs one count, never the rest of the run. This is the replay
    window's recovery (the codec restarts its window on the next genuine
    packet) applied to the accounting. A tagged counter is trusted at once.

    Latency is the receiver's GPS time minus a message's GPS stamp, in
    milliseconds, over every message received except Picture Data (whose stamp
    is the capture time, not the send time) and unstamped ones. It is kept
    signed: a negative figure shows the two GPS clocks disagree. Count, mean, standard
    deviation, minimum and maximum are kept with Welford's algorithm; the
    median needs every sample, so the log analyzer computes it offline from
    the logs.

    Attributes:
        packets: Packets accepted from this peer (duplicates excluded).
        bytes: Their total size on the wire.
        messages: Messages received, by message name (``"agent_status"``).
        misattributed: Messages whose agent id is not the packet's sender; dropped.
        lost: Packets inferred lost from counter gaps, net of late arrivals.
        duplicates: Counters seen again, whether the codec rejected them as
            replays or they reached the table.
        out_of_window: Packets too late to tell from duplicates; their data is
            still applied, in arrival order.
        resyncs: Counter jumps above :data:`MAX_COUNTED_GAP`, and unauthenticated
            counters far from the sequence that the next packet confirmed (a
            sender that restarted): loss counting starts again there.
        outliers: Unauthenticated counters far ahead of the sequence that the next
            packet did not confirm (garbled on the way, or forged): counted here
            only, never as loss nor as the new baseline.
        bad_tags: Packets that failed authentication.
        malformed: Packets the codec could not read (truncated, malformed,
            oversize, unknown protocol version).
        foreign: Packets or heartbeats claiming another mission.
        last_packet_s: Receive time of the last accepted packet, or None.
        last_rejected_s: Receive time of the last packet the codec rejected, or None.
        latency_count: Latency samples.
        latency_mean_ms: Their mean, or None before the first.
        latency_min_ms: Smallest sample, or None.
        latency_max_ms: Largest sample, or None.
    """

    packets: int = 0
    bytes: int = 0
    messages: dict[str, int] = field(default_factory=dict)
    misattributed: int = 0
    lost: int = 0
    duplicates: int = 0
    out_of_window: int = 0
    resyncs: int = 0
    outliers: int = 0
    bad_tags: int = 0
    malformed: int = 0
    foreign: int = 0
    last_packet_s: float | None = None
    last_rejected_s: float | None = None
    latency_count: int = 0
    latency_mean_ms: float | None = None
    latency_min_ms: float | None = None
    latency_max_ms: float | None = None
    _latency_m2: float = field(default=0.0, repr=False)
    # packets placed in the counter sequence (new, or filling a counted gap)
    _sequenced: int = field(default=0, repr=False)
    _highest: int = field(default=-1, repr=False)  # highest counter seen; -1 before any
    # counter from which gaps are counted: the first seen, or the last resync
    _floor: int = field(default=0, repr=False)
    _seen: int = field(default=0, repr=False)  # bit i set: counter _highest - i was seen
    # unauthenticated counter far from the sequence, awaiting confirmation; -1 when none
    _candidate: int = field(default=-1, repr=False)

    @property
    def loss_ratio(self) -> float | None:
        """Lost packets over packets the sender sent (lost + received), or None before any."""
        sent = self.lost + self._sequenced
        return self.lost / sent if sent else None

    @property
    def latency_std_ms(self) -> float | None:
        """Sample standard deviation of latency (n - 1, as ``statistics.stdev``), or None.

        None below two samples, where it is undefined.
        """
        if self.latency_count < 2:
            return None
        return math.sqrt(self._latency_m2 / (self.latency_count - 1))

    def _order(self, counter: int, authenticated: bool = True) -> _Order:
        """Place ``counter`` in the sequence and update losses; O(1).

        Args:
            counter: The packet's counter.
            authenticated: True when a tag vouches for it; otherwise a counter far
                from the sequence waits for the next packet to confirm it.
        """
        if self._candidate >= 0:
            self._settle(counter)
        highest = self._highest
        if counter > highest:
            if highest < 0:
                self._floor = counter
                self._seen = 1
            else:
                jump = counter - highest
                if jump > COUNTER_WINDOW and not authenticated:
                    self._candidate = counter  # placed (or not) by the next packet
                    return NEW
                if jump > MAX_COUNTED_GAP:
                    self.resyncs += 1
                    self._floor = counter
                    self._seen = 1
                else:
                    self.lost += jump - 1
                    self._seen = ((self._seen << jump) | 1) & _WINDOW_MASK
            self._highest = counter
            self._sequenced += 1
            return NEW
        behind = highest - counter
        if behind >= COUNTER_WINDOW:
            self.out_of_window += 1  # taken back if the next packet confirms a new sequence
            if not authenticated:
                self._candidate = counter
            return _OUT_OF_WINDOW
        bit = 1 << behind
        if self._seen & bit:
            self.duplicates += 1
            return DUPLICATE
        self._seen |= bit
        if counter > self._floor:  # inside a gap that was counted as loss
            self.lost -= 1
            self._sequenced += 1
        return LATE

    def _settle(self, counter: int) -> None:
        """Adopt or drop the candidate baseline, now that ``counter`` follows it.

        ``counter`` confirms the candidate when it continues from it (above it, by
        no more than the window): the sender's sequence really moved there. Else
        the candidate was a lone bad counter and the old sequence stands.
        """
        candidate = self._candidate
        self._candidate = -1
        highest = self._highest
        if not candidate < counter <= candidate + COUNTER_WINDOW:
            if candidate > highest:
                self.outliers += 1
            return  # one behind stays counted as out_of_window, like a straggler
        if candidate < highest:
            self.out_of_window -= 1  # not a straggler: the start of a new sequence
            self.resyncs += 1
            self._floor = candidate
        elif candidate - highest > MAX_COUNTED_GAP:
            self.resyncs += 1
            self._floor = candidate
        else:
            self.lost += candidate - highest - 1  # more than the window: no bit survives
        self._seen = 1
        self._highest = candidate
        self._sequenced += 1

    def _add_latency(self, latency_ms: float) -> None:
        """Welford's update: exact running mean and variance in O(1) memory."""
        n = self.latency_count + 1
        self.latency_count = n
        if n == 1:
            self.latency_mean_ms = self.latency_min_ms = self.latency_max_ms = latency_ms
            return
        # Set by the first sample. (Type comments, not typing.cast: this runs for every
        # message every agent receives, and cast is a function call.)
        mean: float = self.latency_mean_ms  # type: ignore[assignment]
        delta = latency_ms - mean
        mean += delta / n
        self.latency_mean_ms = mean
        self._latency_m2 += delta * (latency_ms - mean)
        if latency_ms < self.latency_min_ms:  # type: ignore[operator]
            self.latency_min_ms = latency_ms
        if latency_ms > self.latency_max_ms:  # type: ignore[operator]
            self.latency_max_ms = latency_ms
