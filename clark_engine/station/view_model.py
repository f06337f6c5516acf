"""What the station's view shows, as JSON-able dicts built from the station's runtime.

Pure: no clock, no socket, no thread. The shell side (:mod:`clark_engine.station.live_view`)
calls :meth:`StationView.observe` after every tick of the station's loop and
:meth:`StationView.snapshot` at the view's update rate, both on the loop's thread, and
hands the snapshot to the server (:mod:`clark_engine.station.server`), which sends it on.

Three kinds of data (docs/station-view.md, "The protocol"):

- **hello** (:func:`~clark_engine.station.view_hello.build_hello`): what does not change
  during a run (:mod:`clark_engine.station.view_hello`).
- **state** (:meth:`StationView.snapshot`): the live part, from the station's fleet table
  (:class:`~clark_engine.link.fleet.AgentRecord`: its peers' Agent Status, Behavior State,
  Picture Data, heartbeat condition and link statistics) and its clock; plus what is new
  since the last snapshot, each item with a sequence number: track points (one per Agent
  Status received), photos (one per Picture Data) and mission-log lines
  (:class:`~clark_engine.station.view_log.MissionLogBuffer`); each agent's row is
  built by :mod:`clark_engine.station.view_rows`, as the replay builds it.
- **commands** (:class:`~clark_engine.station.view_commands.CommandRequest` in,
  lifecycle out): kept by the view's
  :class:`~clark_engine.station.view_commands.CommandDesk`.

Stale and lost (docs/station-view.md, "Stale and lost"): an agent is *lost* when the
fleet table says so (silent for longer than ``mission.heartbeat_timeout_s``); it is
*stale* when it is not lost and silent for longer than
:func:`~clark_engine.station.view_hello.stale_after_s`: one and a half of its heartbeat
periods (one heartbeat missed, with room for jitter), at most half the heartbeat timeout.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from clark_engine.link.fleet import AgentRecord, Sample
from clark_engine.link.messages import (
    AgentAttitude,
    AgentStatus,
    BehaviorState,
    Condition,
    PictureData,
    VehicleHealth,
)
from clark_engine.mission.geo import to_local
from clark_engine.runtime.events import StationCommand
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.station.alarms import AlarmChange, AlarmWatch, failsafe_words
from clark_engine.station.view_commands import CommandDesk, CommandRequest, answer_timeout_s
from clark_engine.station.view_hello import origin_of
from clark_engine.station.view_log import MissionLogBuffer
from clark_engine.station.view_protocol import Json, rounded
from clark_engine.station.view_rows import (
    agent_row,
    link_json,
    mode_name,
    photo_json,
    track_point_json,
)

_CONDITION_WORDS: Final = {member: member.name.lower() for member in Condition}


# -- the live view ---------------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class Snapshot:
    """One ``state`` message's content, built on the station's loop thread.

    Attributes:
        state: The current part (agents, station, commands, checks), replaced whole by
            the next snapshot.
        track: Track points new since the last snapshot, each with a ``seq``.
        photos: Photos new since the last snapshot, each with a ``seq``.
        log: Mission-log lines new since the last snapshot, each with a ``seq``.
    """

    state: Json
    track: list[Json]
    photos: list[Json]
    log: list[Json]


class StationView:
    """The station's view of its fleet, built from its runtime; one per station.

    Everything here runs on the station loop's thread (the runtime is single-threaded):
    :meth:`observe` after each tick, :meth:`snapshot` at the update rate, and
    :meth:`execute` for each command the page sent.

    Args:
        runtime: The station's runtime.
        hello: The :func:`build_hello` message (the agents' modes and heartbeat rates).
        log: The mission-log copy, attached by the caller to the runtime's mission
            logger; None shows no log (and a refusal logged by the runtime is then
            not seen, so such a command ends ``unanswered``).
        answer_timeout: Seconds before ``unanswered``; :func:`answer_timeout_s` of
            the mission's heartbeat timeout by default.
    """

    def __init__(
        self,
        runtime: AgentRuntime,
        hello: Json,
        *,
        log: MissionLogBuffer | None = None,
        answer_timeout: float | None = None,
    ) -> None:
        self.runtime = runtime
        self.config = runtime.config
        self.hello = hello
        self.log = log
        self.origin = origin_of(self.config)
        self.answer_timeout_s = (
            answer_timeout
            if answer_timeout is not None
            else answer_timeout_s(self.config.heartbeat_timeout_s)
        )
        self.checks: list[Json] | None = None
        """A rehearsal's checks as they are evaluated; None where nothing evaluates them."""
        self._agents: dict[int, Json] = {int(a["id"]): a for a in hello["agents"]}
        self._seen_status: dict[int, Sample[AgentStatus]] = {}
        self._seen_picture: dict[int, Sample[PictureData]] = {}
        envelopes = {p.name: p.envelope for p in self.config.peers if p.envelope is not None}
        self.alarms = AlarmWatch(envelopes, self.config.heartbeat_timeout_s)
        """Breaches, near misses and failsafes, judged after every tick (docs/station-view.md)."""
        self._track_seq = 0
        self._photo_seq = 0
        self._new_track: list[Json] = []
        self._new_photos: list[Json] = []
        self._log_sent = 0
        self._desk = CommandDesk(runtime, hello, log, self.answer_timeout_s)
        self._track_cap = 10_000  # new points held between two snapshots at most

    # -- per tick ------------------------------------------------------------------------

    def observe(self, now_s: float) -> None:
        """Take what arrived since the last call: track points, photos, alarms, answers."""
        fleet = self.runtime.fleet
        alarms = self.alarms
        for record in fleet.agents():
            status = record.sample(AgentStatus)
            if status is not None and status is not self._seen_status.get(record.agent_id):
                self._seen_status[record.agent_id] = status
                self._track_point(record, status)
                value = status.value
                local = to_local(value.lat_deg, value.lon_deg, value.alt_m, self.origin)
                alarms.see_position(
                    record.name, local.north_m, local.east_m, value.alt_m, status.received_s
                )
            picture = record.sample(PictureData)
            if picture is not None and picture is not self._seen_picture.get(record.agent_id):
                self._seen_picture[record.agent_id] = picture
                self._photo(record, picture)
            health = record.sample(VehicleHealth)
            alarms.see_condition(
                record.name,
                failsafe_words(
                    _CONDITION_WORDS[record.condition],
                    health.value.failsafe if health is not None else None,
                ),
            )
        changes = alarms.evaluate(now_s)
        if changes:
            self._log_alarms(changes)
        self._desk.follow_pending(now_s)

    def _log_alarms(self, changes: list[AlarmChange]) -> None:
        """One mission-log line per alarm raised and per alarm cleared: never one per tick."""
        logbook = self.runtime.logbook
        if logbook.closed:
            return
        for change in changes:
            alarm = change.alarm
            if change.raised:
                logbook.mission.warning(
                    "ALARM %d %s: %s",
                    alarm.id,
                    alarm.kind,
                    alarm.text,
                    extra=LogEvent.ALARM_RAISED.extra,
                )
                continue
            lasted_s = (alarm.cleared_s or alarm.raised_s) - alarm.raised_s
            worst = ""
            if alarm.kind == "near miss":
                worst = f"; closest {-alarm.worst:.1f} m"
            elif alarm.kind == "breach":
                side = "over" if alarm.what == "ceiling" else "outside"
                worst = f"; at worst {alarm.worst:.1f} m {side}"
            logbook.mission.info(
                "alarm %d cleared after %.1f s (%s: %s)%s",
                alarm.id,
                lasted_s,
                alarm.kind + (f" {alarm.what}" if alarm.what else ""),
                " and ".join(alarm.agents),
                worst,
                extra=LogEvent.ALARM_CLEARED.extra,
            )

    def _track_point(self, record: AgentRecord, sample: Sample[AgentStatus]) -> None:
        value = sample.value
        self._track_seq += 1
        if len(self._new_track) < self._track_cap:
            self._new_track.append(
                track_point_json(
                    self._track_seq,
                    record.agent_id,
                    sample.received_s,
                    value.lat_deg,
                    value.lon_deg,
                    value.alt_m,
                    self.origin,
                )
            )

    def _photo(self, record: AgentRecord, sample: Sample[PictureData]) -> None:
        self._photo_seq += 1
        if len(self._new_photos) < self._track_cap:
            self._new_photos.append(
                photo_json(
                    self._photo_seq, record.agent_id, sample.received_s, sample.value, self.origin
                )
            )

    # -- the snapshot --------------------------------------------------------------------

    def snapshot(self, now_s: float) -> Snapshot:
        """The ``state`` message now, with what is new since the previous snapshot."""
        self.observe(now_s)
        runtime = self.runtime
        fleet = runtime.fleet
        agents: list[Json] = []
        alarmed = self.alarms.in_alarm()
        for info in self.hello["agents"]:
            agent_id = int(info["id"])
            row = self._agent(info, fleet.record(agent_id), agent_id, now_s)
            row["alarm"] = info["name"] in alarmed
            agents.append(row)
        log: list[Json] = []
        if self.log is not None:
            lines = self.log.since(self._log_sent)
            if lines:
                self._log_sent = lines[-1].seq
            log = [line.to_json() for line in lines]
        track, self._new_track = self._new_track, []
        photos, self._new_photos = self._new_photos, []
        state: Json = {
            "type": "state",
            "t": rounded(now_s, 3),
            "station": {
                "name": self.config.agent,
                "id": self.config.agent_id,
                "gps_time_ms": runtime.context.gps_time_ms,
                "terminated": runtime.terminated,
                "unknown_packets": fleet.unknown_packets,
            },
            "agents": agents,
            "commands": self._desk.commands(),
            "checks": self.checks,
            "alarms": [a.to_json() for a in self.alarms.shown(now_s)],
        }
        return Snapshot(state, track, photos, log)

    def _agent(
        self, info: Mapping[str, Any], record: AgentRecord | None, agent_id: int, now_s: float
    ) -> Json:
        stats = self.runtime.fleet.stats(agent_id)
        link: Json | None = None
        if stats is not None:
            link = link_json(
                packets=stats.packets,
                lost_packets=stats.lost,
                loss_ratio=stats.loss_ratio,
                latency_mean_ms=stats.latency_mean_ms,
                bad_tags=stats.bad_tags,
                malformed=stats.malformed,
                duplicates=stats.duplicates,
            )
        if record is None:
            return agent_row(info, self.origin, heard=False, link=link)
        status = record.sample(AgentStatus)
        behavior = record.sample(BehaviorState)
        attitude = record.sample(AgentAttitude)
        health = record.sample(VehicleHealth)
        return agent_row(
            info,
            self.origin,
            heard=True,
            link=link,
            lost=record.lost,
            since_heartbeat_s=record.since_heartbeat_s(now_s),
            condition=record.condition.name.lower(),
            status=status.value if status is not None else None,
            status_age_s=now_s - status.received_s if status is not None else None,
            mode=self._mode_name(info, status.value.mode) if status is not None else None,
            behavior=behavior.value if behavior is not None else None,
            behavior_age_s=now_s - behavior.received_s if behavior is not None else None,
            attitude=attitude.value if attitude is not None else None,
            health=health.value if health is not None else None,
            health_age_s=now_s - health.received_s if health is not None else None,
        )

    def _mode_name(self, info: Mapping[str, Any], number: int) -> str | None:
        peer = self.config.peer(str(info["name"]))
        if peer is None:
            return None
        return mode_name(peer.modes, number)

    # -- commands ------------------------------------------------------------------------

    def execute(
        self,
        request: CommandRequest,
        deliver: Callable[[StationCommand], None],
        now_s: float,
    ) -> Json:
        """Log, check and send one operator command; returns its lifecycle entry.

        The view's :class:`~clark_engine.station.view_commands.CommandDesk` does it
        (:meth:`~clark_engine.station.view_commands.CommandDesk.execute`).
        """
        return self._desk.execute(request, deliver, now_s)

    def commands(self) -> list[Json]:
        """Every command kept, oldest first, with its lifecycle."""
        return self._desk.commands()


__all__ = ["Snapshot", "StationView"]
