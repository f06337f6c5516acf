"""The fleet table: what one agent knows about every other agent (the thesis's Clark Agent).

One :class:`FleetTable` per agent, owned by its runtime and never shared. Decoded
packets are applied the moment they arrive (:meth:`FleetTable.receive`), so a
message is available to the behaviour as soon as it lands; packets the codec
rejected are counted against their claimed sender (:meth:`FleetTable.note_error`);
each tick the runtime checks heartbeat timeouts (:meth:`FleetTable.check_timeouts`,
thesis requirement 7.3.7) and appends :meth:`FleetTable.csv_rows` to its CSV
export (7.3.6).

What the table holds, following the thesis (section 3.7, requirements 7.2.1-7.2.10):

- An agent gets a record on its first heartbeat of our mission (7.2.10), never
  before: the heartbeat is where its mission id and agent type are checked.
  Other messages from a sender without a record are counted in its link
  statistics but not stored, so nothing unverified reaches the behaviour. A
  packet that bundles a first heartbeat with other messages stores them all,
  whatever their order in the bundle.
- For each message type, the latest value with its receive time, the packet
  counter it came in and a new-data flag (7.2.2). The behaviour clears the flag
  by reading (:meth:`FleetTable.read`); :meth:`FleetTable.peek` reads without
  clearing. "Latest" means latest sent: a reordered packet does not overwrite a
  value that came in a newer one.
- Per-peer link statistics (:class:`~clark_engine.link.link_stats.LinkStats`) in O(1)
  memory per peer.

The table stores every message type, commands included (7.2.4), but acts on
none: whether a Mode Change Request or a Terminate is obeyed (authenticated,
aimed at us, from the station) is the runtime's decision, made on the packet.

The core is pure: nothing here reads a clock. ``now_s`` is the caller's
monotonic clock in seconds and ``gps_now_ms`` the receiver's GPS time; the two
are never compared with each other. Single-threaded by design, like the loop
that owns it.
"""

from __future__ import annotations

import math
import operator
from collections import OrderedDict
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from typing import Any, Generic, TypeVar

from clark_engine.link.errors import (
    BadTag,
    ClarkLinkError,
    ForeignMission,
    ReplayedPacket,
)
from clark_engine.link.link_stats import DUPLICATE, LATE, NEW, LinkStats
from clark_engine.link.messages import (
    MESSAGE_NAMES,
    AgentAttitude,
    AgentStatus,
    AgentType,
    Condition,
    Heartbeat,
    Message,
    PictureData,
    VehicleHealth,
)
from clark_engine.link.packet import Packet
from clark_engine.untrusted import printable

M = TypeVar("M", bound=Message)

#: Distinct (sender, mission) pairs reported as foreign; further ones are only
#: counted, so a stream of corrupted headers cannot grow the table without bound.
MAX_FOREIGN_REPORTS = 256

#: Senders not in the mission remembered by id (the most recently heard, with their
#: packet counts) for diagnostics; older ones are only counted in
#: :attr:`FleetTable.unknown_packets`, so forged ids cannot grow the table.
MAX_RECENT_UNKNOWN = 16


# --------------------------------------------------------------------- events


@dataclass(frozen=True, slots=True)
class AgentFound:
    """An agent's heartbeat arrived: its first, or its first since it was lost.

    The runtime turns this into the behaviour event ``found:<name>``.
    """

    agent_id: int
    name: str
    """Name from the mission's peer table; empty for an agent not in it."""
    agent_type: AgentType
    rejoined: bool
    """False on the first heartbeat ever, True when the agent had been lost."""


@dataclass(frozen=True, slots=True)
class AgentLost:
    """An agent sent no heartbeat for longer than the heartbeat timeout.

    The runtime turns this into ``lost:<name>``, and into ``mcs_lost`` when
    ``agent_type`` is :attr:`AgentType.MCS`. Reported once per loss.
    """

    agent_id: int
    name: str
    agent_type: AgentType
    silent_s: float
    """Seconds since its last heartbeat when the loss was found."""


@dataclass(frozen=True, slots=True)
class ForeignAgent:
    """An agent that runs another mission: reported once, never added to the table."""

    agent_id: int
    name: str
    mission_id: int | None
    """The mission it claims, when the packet header could be read that far."""


FleetEvent = AgentFound | AgentLost | ForeignAgent


# ------------------------------------------------------------------- records


@dataclass(slots=True)
class Sample(Generic[M]):
    """The latest value of one message type from one agent.

    Attributes:
        value: The message.
        received_s: When it was applied, on the receiver's monotonic clock.
        counter: Counter of the packet it came in (orders values by send time).
        authenticated: True when that packet's tag was checked.
        is_new: Set when the value arrives, cleared when the behaviour reads it.
    """

    value: M
    received_s: float
    counter: int
    authenticated: bool
    is_new: bool = True

    @property
    def gps_time_ms(self) -> int:
        """The sender's GPS stamp on the message."""
        return self.value.gps_time_ms


@dataclass(slots=True)
class AgentRecord:
    """Everything known about one other agent. Owned by its table: read, do not write.

    Attributes:
        agent_id: The agent's id.
        name: Its name in the mission's peer table; empty when it is not in it.
        agent_type: Vehicle or station, from its latest heartbeat.
        condition: Its own view of its health, from its latest heartbeat.
        found_s: When its first heartbeat arrived.
        last_heartbeat_s: When its latest heartbeat arrived.
        lost: True from a timeout until its next heartbeat.
        stats: The link statistics of packets from it.
    """

    agent_id: int
    name: str
    agent_type: AgentType
    condition: Condition
    found_s: float
    last_heartbeat_s: float
    stats: LinkStats
    lost: bool = False
    _samples: dict[type, Sample[Any]] = field(default_factory=dict, repr=False)

    def sample(self, message_type: type[M]) -> Sample[M] | None:
        """The latest value of ``message_type`` with its receive time and flag, or None."""
        return self._samples.get(message_type)

    def since_heartbeat_s(self, now_s: float) -> float:
        """Seconds since its latest heartbeat."""
        return now_s - self.last_heartbeat_s


# --------------------------------------------------------------------- table

_STATUS_FIELDS = (
    "lat_deg",
    "lon_deg",
    "alt_m",
    "ground_speed_m_s",
    "climb_rate_m_s",
    "heading_deg",
    "mode",
)
_ATTITUDE_FIELDS = ("roll_deg", "pitch_deg", "yaw_deg")
#: Vehicle Health's columns (docs/logs.md); ``health_age_s`` follows them.
_HEALTH_COLUMNS = (
    *("armed", "battery_v", "battery_pct", "gps_fix_type", "satellites", "prearm"),
    *("autopilot_severity", "autopilot_text", "autopilot_text_age_s", "failsafe"),
    "autopilot_lost",
)
_CSV_HEADER = (
    *("agent_id", "name", "agent_type", "condition", "lost", "since_heartbeat_s"),
    *_STATUS_FIELDS,
    "status_age_s",
    *_ATTITUDE_FIELDS,
    *_HEALTH_COLUMNS,
    "health_age_s",
    *("since_packet_s", "since_rejected_s", "packets", "bytes"),
    *(f"rx_{name}" for name in MESSAGE_NAMES.values()),
    *("lost_packets", "loss_ratio", "duplicates", "out_of_window", "resyncs"),
    *("bad_tags", "malformed", "foreign", "misattributed"),
    *("latency_count", "latency_mean_ms", "latency_std_ms", "latency_min_ms", "latency_max_ms"),
)

CsvValue = str | float | int

_STATUS_CELLS = operator.attrgetter(*_STATUS_FIELDS)
_ATTITUDE_CELLS = operator.attrgetter(*_ATTITUDE_FIELDS)
_NO_STATUS: tuple[CsvValue, ...] = ("",) * len(_STATUS_FIELDS)
_NO_ATTITUDE: tuple[CsvValue, ...] = ("",) * len(_ATTITUDE_FIELDS)
_NO_HEALTH: tuple[CsvValue, ...] = ("",) * len(_HEALTH_COLUMNS)
_MESSAGE_COLUMNS = tuple(MESSAGE_NAMES.values())
_ZEROS = (0,) * len(_MESSAGE_COLUMNS)  # the count of a message never received
# (Two tables: both are IntEnums, whose members with equal values are equal keys.)
_TYPE_NAMES = {member: member.name.lower() for member in AgentType}
_CONDITION_NAMES = {member: member.name.lower() for member in Condition}
_COUNT_CELLS = operator.attrgetter(
    *("duplicates", "out_of_window", "resyncs", "bad_tags", "malformed", "foreign"),
    *("misattributed", "latency_count"),
)


def _health_cells(health: VehicleHealth) -> tuple[CsvValue, ...]:
    """Vehicle Health as the CSV has it: flags 0/1, unknowns empty, texts escaped.

    The texts came over the air: :func:`~clark_engine.untrusted.printable` escapes every
    control character, so a text is one inert cell on one line whatever it holds.
    """
    return (
        int(health.armed),
        _blank(health.battery_v),
        _blank(health.battery_pct),
        health.gps_fix_type,
        _blank(health.satellites),
        health.prearm.name.lower(),
        health.text_severity if health.text else "",
        printable(health.text),
        health.text_age_s if health.text else "",
        printable(health.failsafe),
        int(health.autopilot_lost),
    )


def _blank(value: float | None) -> CsvValue:
    """An absent figure as an empty CSV cell."""
    return "" if value is None else value


def _stats_cells(stats: LinkStats) -> list[CsvValue]:
    """A link's counts and latency, as the CSV row has them (packets to latency_max_ms)."""
    return [
        stats.packets,
        stats.bytes,
        *map(stats.messages.get, _MESSAGE_COLUMNS, _ZEROS),
        stats.lost,
        _blank(stats.loss_ratio),
        *_COUNT_CELLS(stats),
        _blank(stats.latency_mean_ms),
        _blank(stats.latency_std_ms),
        _blank(stats.latency_min_ms),
        _blank(stats.latency_max_ms),
    ]


def _texts(values: Iterable[CsvValue]) -> tuple[str, ...]:
    """Cells as the csv module writes them: ``str`` of each (``repr`` for floats), None empty."""
    return tuple("" if v is None else str(v) for v in values)


#: The counters a link's statistics change with. Each only grows, and every other figure of
#: the group (loss ratio, latency) changes only when one of them does: equal counters mean
#: equal figures, so the formatted cells can be kept.
_STATS_KEY = operator.attrgetter(
    *("packets", "bytes", "lost", "_sequenced", "duplicates", "out_of_window", "resyncs"),
    *("bad_tags", "malformed", "foreign", "misattributed", "latency_count"),
)


class _SampleText:
    """One message's CSV cells as text, made again only for a new sample.

    A new message is stored as a new :class:`Sample` object, so identity tells a change.
    """

    __slots__ = ("_cells", "_empty", "_sample", "_text")

    def __init__(
        self, cells: Callable[[Any], tuple[CsvValue, ...]], empty: tuple[CsvValue, ...]
    ) -> None:
        self._cells = cells
        self._empty = empty
        self._sample: Sample[Any] | None = None
        self._text = empty

    def __call__(self, sample: Sample[Any] | None) -> tuple[CsvValue, ...]:
        if sample is not self._sample:
            self._sample = sample
            self._text = self._empty if sample is None else _texts(self._cells(sample.value))
        return self._text


class _CsvTexts:
    """One agent's CSV cells that change only when a packet arrives, kept as text."""

    __slots__ = ("_key", "_link", "_stats_text", "attitude", "health", "status")

    def __init__(self) -> None:
        self.status = _SampleText(_STATUS_CELLS, _NO_STATUS)
        self.attitude = _SampleText(_ATTITUDE_CELLS, _NO_ATTITUDE)
        self.health = _SampleText(_health_cells, _NO_HEALTH)
        self._link: LinkStats | None = None  # held, so that its identity stays its own
        self._key: tuple[int, ...] | None = None
        self._stats_text: tuple[str, ...] = ()

    def stats(self, stats: LinkStats) -> tuple[str, ...]:
        """The counts and latency cells, formatted again only when a counter moved."""
        key = _STATS_KEY(stats)
        if key != self._key or stats is not self._link:
            self._link = stats
            self._key = key
            self._stats_text = _texts(_stats_cells(stats))
        return self._stats_text


class FleetTable:
    """One agent's table of every other agent, with link statistics per peer.

    Args:
        own_id: This agent's id; packets from it (a mesh echo) are ignored.
        mission_id: Our mission; a heartbeat claiming another is reported and its
            sender never added.
        heartbeat_timeout_s: Silence after which an agent is reported lost.
        expected: Peer id -> name from the compiled config's peer table (every
            other agent of the mission). Only these agents ever get a record and
            link statistics of their own; a sender not in it, whatever it sends
            (heartbeats included: its id may be forged or garbled), is only counted,
            in :attr:`unknown_packets`, :attr:`recent_unknown` and
            :attr:`unattributed`, so the table's size and the cost of a tick are
            fixed by the mission, not by the radio. None (no peer table: a tool
            replaying a message log, a test) admits every sender of the mission on
            its heartbeat instead; the runtime always gives the peer table.

    Attributes:
        unattributed: Link statistics of every packet from a sender without a
            record of its own, and of rejected packets whose header was unreadable.
        unknown_packets: Packets (accepted or rejected) from senders not in the
            peer table.
        recent_unknown: The last :data:`MAX_RECENT_UNKNOWN` such sender ids with
            their packet counts, least recently heard first (for diagnostics).

    Raises:
        ValueError: ``heartbeat_timeout_s`` is not positive.
    """

    def __init__(
        self,
        own_id: int,
        mission_id: int,
        heartbeat_timeout_s: float,
        expected: Mapping[int, str] | None = None,
    ) -> None:
        if not heartbeat_timeout_s > 0:
            raise ValueError(f"heartbeat_timeout_s must be positive, not {heartbeat_timeout_s}")
        self.own_id = own_id
        self.mission_id = mission_id
        self.heartbeat_timeout_s = heartbeat_timeout_s
        self._names: dict[int, str] = dict(expected or {})
        self._names.pop(own_id, None)
        self._closed = expected is not None  # only the peer table's agents get records
        self._stats: dict[int, LinkStats] = {peer: LinkStats() for peer in self._names}
        self._records: dict[int, AgentRecord] = {}  # kept sorted by id
        self._csv_text: dict[int, _CsvTexts] = {}  # agent id -> its CSV cells kept as text
        # Senders that put a heartbeat of another mission in a packet of ours. Defence in
        # depth: the codec already refuses such a packet as MalformedPacket, so through
        # Codec.decode this never fills; it guards callers that hand packets to receive()
        # directly (tests, tools replaying a message log).
        self._banned: set[int] = set()
        self._foreign_reported: set[tuple[int, int | None]] = set()
        # No agent that is not lost heard its last heartbeat before this (a lower bound):
        # check_timeouts skips its scan while even this one is within the timeout.
        self._oldest_heartbeat_s = math.inf
        self.unattributed = LinkStats()
        #: Counts every Agent Status stored as an agent's latest: a reader that caches what
        #: it derives from the positions (the envelope's peer positions) rebuilds when it
        #: moves.
        self.statuses_stored = 0
        self.unknown_packets = 0
        self.recent_unknown: OrderedDict[int, int] = OrderedDict()

    # ------------------------------------------------------------- input

    def receive(self, packet: Packet, now_s: float, gps_now_ms: int | None) -> list[FleetEvent]:
        """Apply one decoded packet at once, in O(messages).

        A duplicate counter is counted and nothing else happens: it proves nothing
        new. A heartbeat adds its sender (or brings it back from lost); the other
        messages are stored only for a sender with a record. A message whose agent
        id is not the packet's sender is dropped and counted as misattributed.

        Args:
            packet: A packet the codec accepted.
            now_s: Receive time on the caller's monotonic clock.
            gps_now_ms: The receiver's GPS time, or None while it has none (no
                latency is recorded then, nor for messages stamped 0, which is
                proto3's "unset").

        Returns:
            AgentFound and ForeignAgent events, in message order.
        """
        sender = packet.sender_id
        if sender == self.own_id:
            return []
        counter = packet.counter
        stats = self._stats.get(sender)
        order = NEW
        events: list[FleetEvent] = []
        messages = packet.messages
        if stats is not None:
            order = stats._order(counter, packet.authenticated)
            if order is DUPLICATE:
                return []
        elif self._closed:  # not in the mission: counted, never recorded
            self._note_unknown(sender)
            messages = ()
        for message in messages:  # heartbeats first: a first one admits the whole bundle
            if (
                type(message) is Heartbeat
                and message.agent_id == sender
                and self._heartbeat(message, now_s, events)
                and stats is None
            ):
                stats = self._stats[sender]  # created with the record
                order = stats._order(counter, packet.authenticated)
        if stats is None:
            stats = self.unattributed
        stats.packets += 1
        stats.bytes += packet.size_bytes
        stats.last_packet_s = now_s
        counts = stats.messages
        record = None if sender in self._banned else self._records.get(sender)
        messages = packet.messages
        samples = None if record is None else record._samples
        late = order is LATE  # a late packet replaces only values from older ones
        for message in messages:
            if message.agent_id != sender:
                stats.misattributed += 1
                continue
            cls = type(message)
            name = MESSAGE_NAMES.get(cls, cls.__name__)
            counts[name] = counts.get(name, 0) + 1
            stamp = message.gps_time_ms
            if gps_now_ms is not None and stamp > 0 and cls is not PictureData:
                stats._add_latency(float(gps_now_ms - stamp))
            if samples is not None:
                old = samples.get(cls)
                if old is None or not late or counter >= old.counter:
                    samples[cls] = Sample(message, now_s, counter, packet.authenticated)
                    if cls is AgentStatus:
                        self.statuses_stored += 1
        return events

    def _heartbeat(self, heartbeat: Heartbeat, now_s: float, events: list[FleetEvent]) -> bool:
        """Admit, refresh or reject the sender of ``heartbeat``; True when a record was created."""
        sender = heartbeat.agent_id
        if sender in self._banned or heartbeat.mission_id != self.mission_id:
            self._stats.get(sender, self.unattributed).foreign += 1
            if sender not in self._banned:
                self._banned.add(sender)
                self._report_foreign(sender, heartbeat.mission_id, events)
            return False
        if now_s < self._oldest_heartbeat_s:
            self._oldest_heartbeat_s = now_s
        record = self._records.get(sender)
        if record is None:
            stats = self._stats.setdefault(sender, LinkStats())
            record = AgentRecord(
                agent_id=sender,
                name=self._names.get(sender, ""),
                agent_type=heartbeat.agent_type,
                condition=heartbeat.condition,
                found_s=now_s,
                last_heartbeat_s=now_s,
                stats=stats,
            )
            self._records[sender] = record
            self._records = dict(sorted(self._records.items()))  # rare: once per agent
            events.append(AgentFound(sender, record.name, record.agent_type, rejoined=False))
            return True
        record.last_heartbeat_s = now_s
        record.agent_type = heartbeat.agent_type
        record.condition = heartbeat.condition
        if record.lost:
            record.lost = False
            events.append(AgentFound(sender, record.name, record.agent_type, rejoined=True))
        return False

    def _note_unknown(self, sender: int) -> None:
        """Count a packet from a sender not in the mission, in O(1) time and bounded memory."""
        self.unknown_packets += 1
        recent = self.recent_unknown
        recent[sender] = recent.pop(sender, 0) + 1  # to the most recent end
        if len(recent) > MAX_RECENT_UNKNOWN:
            recent.popitem(last=False)

    def _report_foreign(
        self, sender: int, mission_id: int | None, events: list[FleetEvent]
    ) -> None:
        """Report (sender, mission) once; beyond MAX_FOREIGN_REPORTS pairs, only count."""
        key = (sender, mission_id)
        reported = self._foreign_reported
        if key in reported or len(reported) >= MAX_FOREIGN_REPORTS:
            return
        reported.add(key)
        events.append(ForeignAgent(sender, self._names.get(sender, ""), mission_id))

    def note_error(self, error: ClarkLinkError, now_s: float) -> list[FleetEvent]:
        """Count a packet the codec rejected against the sender its header claims.

        Replays count as duplicates, failed tags as bad tags, foreign missions as
        foreign (with a ForeignAgent event once per sender and mission; the sender
        is not added), anything else as malformed. A rejected packet never changes
        an agent's data or liveness: its content cannot be trusted.

        Args:
            error: What the codec raised.
            now_s: When it arrived, on the caller's monotonic clock.

        Returns:
            A ForeignAgent event the first time a (sender, mission) pair is seen.
        """
        sender = error.sender_id
        stats = self.unattributed if sender is None else self._stats.get(sender, self.unattributed)
        if sender is not None and stats is self.unattributed and self._closed:
            self._note_unknown(sender)
        stats.last_rejected_s = now_s
        events: list[FleetEvent] = []
        if isinstance(error, ReplayedPacket):
            stats.duplicates += 1
        elif isinstance(error, BadTag):
            stats.bad_tags += 1
        elif isinstance(error, ForeignMission):
            stats.foreign += 1
            if sender is not None:
                self._report_foreign(sender, error.mission_id, events)
        else:
            stats.malformed += 1
        return events

    def check_timeouts(self, now_s: float) -> list[FleetEvent]:
        """Report each agent silent for longer than the heartbeat timeout, once, in O(agents).

        A lost agent keeps its record and last data; its next heartbeat brings an
        AgentFound with ``rejoined=True``.

        Called every tick by every agent, so the scan is skipped while the oldest
        heartbeat of an agent not lost is within the timeout: then all are.
        """
        events: list[FleetEvent] = []
        timeout_s = self.heartbeat_timeout_s
        if now_s - self._oldest_heartbeat_s <= timeout_s:
            return events
        oldest_s = math.inf
        for record in self._records.values():
            if not record.lost:
                silent_s = now_s - record.last_heartbeat_s
                if silent_s > timeout_s:
                    record.lost = True
                    events.append(
                        AgentLost(record.agent_id, record.name, record.agent_type, silent_s)
                    )
                elif record.last_heartbeat_s < oldest_s:
                    oldest_s = record.last_heartbeat_s
        self._oldest_heartbeat_s = oldest_s
        return events

    # ------------------------------------------------------------ access

    def read(self, agent_id: int, message_type: type[M]) -> M | None:
        """The latest ``message_type`` from an agent, clearing its new-data flag.

        Returns None when the agent has no record or never sent one. A lost
        agent's last data stays readable; check :attr:`AgentRecord.lost`.
        """
        sample = self._sample(agent_id, message_type)
        if sample is None:
            return None
        sample.is_new = False
        return sample.value

    def peek(self, agent_id: int, message_type: type[M]) -> M | None:
        """Like :meth:`read`, without clearing the new-data flag (for logs and views)."""
        sample = self._sample(agent_id, message_type)
        return None if sample is None else sample.value

    def is_new(self, agent_id: int, message_type: type[M]) -> bool:
        """True when a value arrived since the behaviour last read this type from this agent."""
        sample = self._sample(agent_id, message_type)
        return sample is not None and sample.is_new

    def _sample(self, agent_id: int, message_type: type[M]) -> Sample[M] | None:
        record = self._records.get(agent_id)
        return None if record is None else record.sample(message_type)

    def record(self, agent_id: int) -> AgentRecord | None:
        """The record of one agent, or None before its first heartbeat."""
        return self._records.get(agent_id)

    def agents(self) -> list[AgentRecord]:
        """Every agent with a record, lost ones included, by id."""
        return list(self._records.values())

    def stats(self, agent_id: int) -> LinkStats | None:
        """Link statistics of one peer: expected ones from the start, others once recorded."""
        return self._stats.get(agent_id)

    # ------------------------------------------------------------ export

    @staticmethod
    def csv_header() -> list[str]:
        """Column names of :meth:`csv_rows`, in a fixed order."""
        return list(_CSV_HEADER)

    def csv_rows(self, now_s: float, *, text: bool = False) -> list[list[CsvValue]]:
        """One flat row per recorded agent, by id, for the runtime's CSV export.

        Absent values (no status yet, fewer than two latency samples) are empty
        strings; flags are 0 or 1; types and conditions are lower-case names.

        Every tick exports every agent (a 50-agent fleet: 500 rows a second per agent),
        so fields are read in groups by :func:`operator.attrgetter`, in C. With
        ``text``, the cells that change only when a packet arrives (status, attitude,
        the link's counts and latency) come as the very strings the csv module writes
        for them, made once per change instead of once per tick: formatting floats is
        most of the cost of writing the CSV, and the file is the same byte for byte.
        """
        rows: list[list[CsvValue]] = []
        cache = self._csv_text if text else None
        for record in self._records.values():
            stats = record.stats
            samples = record._samples
            status = samples.get(AgentStatus)
            attitude = samples.get(AgentAttitude)
            health = samples.get(VehicleHealth)
            last_s = stats.last_packet_s
            rejected_s = stats.last_rejected_s
            row: list[CsvValue] = [
                record.agent_id,
                record.name,
                _TYPE_NAMES[record.agent_type],
                _CONDITION_NAMES[record.condition],
                int(record.lost),
                now_s - record.last_heartbeat_s,
            ]
            if cache is None:
                row += _NO_STATUS if status is None else _STATUS_CELLS(status.value)
                row.append("" if status is None else now_s - status.received_s)
                row += _NO_ATTITUDE if attitude is None else _ATTITUDE_CELLS(attitude.value)
                row += _NO_HEALTH if health is None else _health_cells(health.value)
                row.append("" if health is None else now_s - health.received_s)
                row.append("" if last_s is None else now_s - last_s)
                row.append("" if rejected_s is None else now_s - rejected_s)
                row += _stats_cells(stats)
            else:
                texts = cache.get(record.agent_id)
                if texts is None:
                    texts = cache[record.agent_id] = _CsvTexts()
                row += texts.status(status)
                row.append("" if status is None else now_s - status.received_s)
                row += texts.attitude(attitude)
                row += texts.health(health)
                row.append("" if health is None else now_s - health.received_s)
                row.append("" if last_s is None else now_s - last_s)
                row.append("" if rejected_s is None else now_s - rejected_s)
                row += texts.stats(stats)
            rows.append(row)
        return rows
