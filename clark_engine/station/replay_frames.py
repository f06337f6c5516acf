"""A loaded replay: the page's messages (``reset``, ``state``) at any time of the run.

Separate from the loading (:mod:`clark_engine.station.replay`) because this is what the
server calls for every client as it seeks and plays, from its event loop: immutable,
built once, answering each time with bisections into the arrays the loading made. The
agent rows are built by :func:`~clark_engine.station.view_rows.agent_row`, as the live
view builds them, from the fleet-table columns (:mod:`clark_engine.station.replay_fleet`).
"""

from __future__ import annotations

import bisect
import math
from array import array
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Final

from clark_engine.link.messages import (
    AgentAttitude,
    AgentStatus,
    BehaviorState,
    PrearmState,
    VehicleHealth,
)
from clark_engine.mission.geo import Origin
from clark_engine.station.alarms import CLEARED_SHOWN_S, Alarm
from clark_engine.station.replay_fleet import (
    ALT,
    AP_LOST,
    AP_SEVERITY,
    AP_TEXT,
    AP_TEXT_AGE,
    ARMED,
    BAD_TAGS,
    BATTERY_PCT,
    BATTERY_V,
    CLIMB,
    CONDITIONS,
    DUPLICATES,
    FAILSAFE,
    GPS_FIX,
    HEADING,
    HEALTH_AGE,
    LAT,
    LATENCY,
    LON,
    LOSS_RATIO,
    LOST_PACKETS,
    MALFORMED,
    MODE,
    PACKETS,
    PITCH,
    PREARM,
    ROLL,
    SATELLITES,
    SINCE_HB,
    SPEED,
    STATUS_AGE,
    YAW,
    FleetRows,
)
from clark_engine.station.view_protocol import MAX_LOG_LINES, Json
from clark_engine.station.view_rows import agent_row, link_json, mode_name

RESET_TRACK_POINTS: Final = 2_000
"""Most track points per agent a ``reset`` sends; a longer track is evenly thinned
(its first and latest points kept), so the whole path shows at any time."""

RESET_PHOTOS: Final = 2_000
"""Most photos a ``reset`` sends (the latest)."""

MAX_DELTA_ITEMS: Final = 5_000
"""More new track points than this between two states is sent as a ``reset`` instead."""


def _int(value: float) -> int:
    return int(value) if math.isfinite(value) else 0


def _opt(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _int_opt(value: float) -> int | None:
    return int(value) if math.isfinite(value) else None


_PREARM_STATES: Final = {state.name.lower(): state for state in PrearmState}
MAX_ALARMS: Final = 10_000


@dataclass(frozen=True, slots=True)
class ReplayAgent:
    """What the replay knows of one agent shown in the table."""

    info: Json
    rows: FleetRows | None
    shift_s: float  # the observer's clock to mission time
    observer: str | None
    modes: Mapping[str, int]
    changes_t: list[float]
    changes: list[tuple[str, tuple[str, ...]]]  # (event, active leaves)
    track_t: list[float]  # mission time of each of its track points
    track_index: array[int]  # their indexes in the replay's track arrays


class Replay:
    """A finished run, loaded once, that gives the page's messages at any time.

    Build it with :func:`load_replay`. Immutable once built: the server's clients call
    :meth:`frame` from its event loop, each at its own time.

    Attributes:
        hello: The ``hello`` message, with ``"mode": "replay"``, no actions, and the
            replay's span, speeds and sources under ``"replay"``.
        start_s: The earliest mission time in the logs.
        end_s: The latest.
    """

    def __init__(
        self,
        hello: Json,
        origin: Origin,
        agents: list[ReplayAgent],
        track: tuple[array[float], array[float], array[float], array[float], array[int]],
        photos: list[Json],
        log: list[tuple[float, str, str]],
        checks: list[Json] | None,
        station: Json,
        station_gps_ms: float | None,
        span: tuple[float, float],
        alarms: Sequence[Alarm] = (),
    ) -> None:
        self.hello = hello
        self.origin = origin
        self._agents = agents
        self._track_t, self._north, self._east, self._alt, self._track_agent = track
        self._photos = photos
        self._photo_t = [float(p["t"]) for p in photos]
        self._log = log
        self._log_t = [line[0] for line in log]
        self.checks = checks
        self._station = station
        self._station_gps_ms = station_gps_ms
        self.start_s, self.end_s = span
        self._alarms = sorted(alarms, key=lambda a: (a.raised_s, a.id))
        self._alarm_t = [a.raised_s for a in self._alarms]

    # -- time ----------------------------------------------------------------------------

    def clamp(self, t_s: float) -> float:
        """``t_s`` within the run's span (a NaN is its start)."""
        if not math.isfinite(t_s):
            return self.start_s if not t_s > 0 else self.end_s
        return min(max(t_s, self.start_s), self.end_s)

    # -- messages ------------------------------------------------------------------------

    def frame(self, t_s: float, after_s: float | None) -> list[Json]:
        """The messages that bring a page that has everything up to ``after_s`` to ``t_s``.

        ``[state]`` when the page moves forward by a little (the state carries the
        track points, photos and log lines after ``after_s``); ``[reset, state]`` when
        it has nothing yet (``after_s`` None), goes back, or jumps so far ahead that a
        reset is smaller.
        """
        t = self.clamp(t_s)
        if (
            after_s is None
            or t < after_s
            or self._count(self._track_t, after_s, t) > (MAX_DELTA_ITEMS)
        ):
            return [self.reset(t), self.state(t, t)]
        log_new = self._count(self._log_t, after_s, t)
        photos_new = self._count(self._photo_t, after_s, t)
        if log_new > MAX_LOG_LINES or photos_new > RESET_PHOTOS:
            return [self.reset(t), self.state(t, t)]
        return [self.state(t, after_s)]

    @staticmethod
    def _count(times: Sequence[float], after_s: float, t_s: float) -> int:
        return bisect.bisect_right(times, t_s) - bisect.bisect_right(times, after_s)

    def reset(self, t_s: float) -> Json:
        """Everything up to ``t_s`` the page draws from the start: tracks, photos, log.

        Each agent's track is thinned evenly to :data:`RESET_TRACK_POINTS` (first and
        latest points kept); the latest :data:`RESET_PHOTOS` photos and
        :data:`MAX_LOG_LINES` log lines.
        """
        t = self.clamp(t_s)
        indexes: list[int] = []
        for agent in self._agents:
            n = bisect.bisect_right(agent.track_t, t)
            if n == 0:
                continue
            stride = max(1, math.ceil(n / RESET_TRACK_POINTS))
            chosen = list(agent.track_index[0:n:stride])
            if chosen[-1] != agent.track_index[n - 1]:
                chosen.append(agent.track_index[n - 1])
            indexes += chosen
        indexes.sort()
        photos_end = bisect.bisect_right(self._photo_t, t)
        log_end = bisect.bisect_right(self._log_t, t)
        return {
            "type": "reset",
            "t": round(t, 3),
            "track": [self._point(i) for i in indexes],
            "photos": self._photos[max(0, photos_end - RESET_PHOTOS) : photos_end],
            "log": self._lines(max(0, log_end - MAX_LOG_LINES), log_end),
        }

    def state(self, t_s: float, after_s: float) -> Json:
        """The ``state`` message at ``t_s``, with the items after ``after_s`` (up to ``t_s``)."""
        t = self.clamp(t_s)
        start = bisect.bisect_right(self._track_t, after_s)
        end = bisect.bisect_right(self._track_t, t)
        photos = self._photos[
            bisect.bisect_right(self._photo_t, after_s) : bisect.bisect_right(self._photo_t, t)
        ]
        log = self._lines(
            bisect.bisect_right(self._log_t, after_s), bisect.bisect_right(self._log_t, t)
        )
        station = dict(self._station)
        if self._station_gps_ms is not None:
            station["gps_time_ms"] = int(self._station_gps_ms + 1000 * t)
        alarms = self.alarms_at(t)
        alarmed = {name for a in alarms if a["cleared_s"] is None for name in a["agents"]}
        rows = [self._row(agent, t) for agent in self._agents]
        for row in rows:
            row["alarm"] = row["name"] in alarmed
        return {
            "type": "state",
            "t": round(t, 3),
            "station": station,
            "agents": rows,
            "alarms": alarms,
            "track": [self._point(i) for i in range(start, end)],
            "photos": photos,
            "log": log,
            "commands": [],
            "checks": self.checks,
            "replay": {"t": round(t, 3), "start_s": self.start_s, "end_s": self.end_s},
        }

    def alarms_at(self, t_s: float) -> list[Json]:
        """The banner at ``t_s``: alarms in force then, and those cleared just before.

        An alarm cleared after ``t_s`` is shown in force (``cleared_s`` null), as the
        operator saw it then.
        """
        out: list[Json] = []
        for alarm in self._alarms[: bisect.bisect_right(self._alarm_t, t_s)]:
            cleared = alarm.cleared_s
            if cleared is not None and cleared <= t_s:
                if t_s - cleared >= CLEARED_SHOWN_S:
                    continue
                out.append(alarm.to_json())
            else:
                item = alarm.to_json()
                item["cleared_s"] = None
                out.append(item)
        return out

    def _point(self, i: int) -> Json:
        return {
            "seq": i + 1,
            "agent": self._track_agent[i],
            "t": round(self._track_t[i], 3),
            "north_m": self._north[i],
            "east_m": self._east[i],
            "alt_m": self._alt[i],
        }

    def _lines(self, start: int, end: int) -> list[Json]:
        return [
            {"seq": i + 1, "t": round(t, 3), "level": level, "text": text}
            for i, (t, level, text) in enumerate(self._log[start:end], start=start)
        ]

    def _row(self, agent: ReplayAgent, t_s: float) -> Json:
        """The agent's row at ``t_s``: its latest fleet-table row, its ages grown since."""
        info = agent.info
        behavior: BehaviorState | None = None
        behavior_age: float | None = None
        k = bisect.bisect_right(agent.changes_t, t_s) - 1
        if k >= 0:
            event, active = agent.changes[k]
            behavior = BehaviorState(int(info["id"]), 0, active, event)
            behavior_age = t_s - agent.changes_t[k]
        rows = agent.rows
        i = -1 if rows is None else bisect.bisect_right(rows.now_s, t_s - agent.shift_s) - 1
        if rows is None or i < 0:
            row = agent_row(info, self.origin, heard=False)
            if behavior is not None:  # its own log says so, though the station heard nothing
                row["behaviour"] = agent_row(
                    info,
                    self.origin,
                    heard=True,
                    behavior=behavior,
                    behavior_age_s=behavior_age,
                )["behaviour"]
            return row
        n = rows.numbers
        grown = t_s - agent.shift_s - rows.now_s[i]
        status: AgentStatus | None = None
        status_age: float | None = None
        mode: str | None = None
        if math.isfinite(n[LAT][i]) and math.isfinite(n[LON][i]):
            number = _int(n[MODE][i])
            status = AgentStatus(
                int(info["id"]),
                0,
                n[LAT][i],
                n[LON][i],
                n[ALT][i] if math.isfinite(n[ALT][i]) else 0.0,
                n[SPEED][i],
                n[CLIMB][i],
                n[HEADING][i],
                number,
            )
            status_age = n[STATUS_AGE][i] + grown if math.isfinite(n[STATUS_AGE][i]) else None
            mode = mode_name(agent.modes, number)
        attitude: AgentAttitude | None = None
        if math.isfinite(n[ROLL][i]):
            attitude = AgentAttitude(int(info["id"]), 0, n[ROLL][i], n[PITCH][i], n[YAW][i])
        link = None
        if math.isfinite(n[PACKETS][i]):
            link = link_json(
                packets=_int(n[PACKETS][i]),
                lost_packets=_int(n[LOST_PACKETS][i]),
                loss_ratio=_opt(n[LOSS_RATIO][i]),
                latency_mean_ms=_opt(n[LATENCY][i]),
                bad_tags=_int(n[BAD_TAGS][i]),
                malformed=_int(n[MALFORMED][i]),
                duplicates=_int(n[DUPLICATES][i]),
            )
        since = n[SINCE_HB][i]
        code = rows.condition[i]
        health: VehicleHealth | None = None
        health_age: float | None = None
        if math.isfinite(n[HEALTH_AGE][i]):
            texts = rows.texts
            health = VehicleHealth(
                int(info["id"]),
                0,
                armed=n[ARMED][i] == 1,
                battery_v=_opt(n[BATTERY_V][i]),
                battery_pct=_int_opt(n[BATTERY_PCT][i]),
                gps_fix_type=_int(n[GPS_FIX][i]),
                satellites=_int_opt(n[SATELLITES][i]),
                prearm=_PREARM_STATES.get(rows.strings[texts[PREARM][i]], PrearmState.UNKNOWN),
                text_severity=_int(n[AP_SEVERITY][i]),
                text=rows.strings[texts[AP_TEXT][i]],
                failsafe=rows.strings[texts[FAILSAFE][i]],
                autopilot_lost=n[AP_LOST][i] == 1,
                text_age_s=_int(n[AP_TEXT_AGE][i]),
            )
            health_age = n[HEALTH_AGE][i] + grown
        return agent_row(
            info,
            self.origin,
            heard=True,
            link=link,
            lost=bool(rows.lost[i]),
            since_heartbeat_s=since + grown if math.isfinite(since) else None,
            condition=CONDITIONS[code] if code >= 0 else None,
            status=status,
            status_age_s=status_age,
            mode=mode,
            behavior=behavior,
            behavior_age_s=behavior_age,
            attitude=attitude,
            health=health,
            health_age_s=health_age,
        )


__all__ = ["MAX_DELTA_ITEMS", "RESET_PHOTOS", "RESET_TRACK_POINTS", "Replay", "ReplayAgent"]
