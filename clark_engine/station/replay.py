"""``clark replay LOGS``: the station's page over a finished run's logs, at any time of it.

Why: the live view (:mod:`clark_engine.station.view_model`) shows a run as it happens; after it,
the operator, the team and the examiner want to see it again, moment by moment, from
what the agents logged (docs/logs.md). This module loads a run's log folder once into
time-indexed arrays and builds, for any mission time ``t``, the same messages the live
view sends (docs/station-view.md, "Replay"): the ``state`` at ``t`` (its agent rows by
:func:`~clark_engine.station.view_rows.agent_row`, as the live view builds them) and, when the
page jumps, a ``reset`` with the tracks, photos and mission-log lines up to ``t``.

What comes from where (each agent's four files, docs/logs.md, "The files"):

- **Mission time** is ``clark analyze --checks``'s
  (:func:`clark_engine.expectations.log_clocks.align_clocks`):
  t = 0 is the start of the station's runtime clock, every agent's clock mapped onto it
  by GPS time.
- **Agent rows** (heartbeat age, lost, condition, position, speed, heading, mode,
  attitude, link statistics) come from the station's fleet CSV, one row per known agent
  per tick: what the operator saw. A vehicle the station's table never holds (the
  station's logs are not in the folder, or it never heard it) is shown as another
  agent's fleet table saw it (the one with the most rows of it). Between two rows the
  ages grow with ``t``, as they did on the station.
- **Behaviour** (active states and the event that led there) comes from the vehicle's
  own mission log (``behavior.change`` lines, docs/logs.md): the fleet CSV does not log Behavior
  State; its age is the time since the change.
- **Tracks**: one point per Agent Status arrival in the rows used (as the live view
  draws one per Agent Status received).
- **Photos**: the Picture Data each agent sent (as ``clark analyze --checks`` counts
  them), placed at the agent's position then.
- **The mission log**: the station's, as the live view shows it (every agent's,
  each line prefixed with its name, when the folder holds no station log).
- **Checks**: with a mission (``--checks MISSION``, or the mission a dry-run report's
  summary names), its checks judged on the whole run's logs by
  :func:`clark_engine.expectations.from_logs.judge`, as ``clark analyze --checks`` judges them.

Everything read is data: every text goes to the page escaped and bounded
(:func:`~clark_engine.runtime.log_lines.line_safe`) and the page writes it as text; names
are bounded; a row or line that cannot be read is a warning with its file and line and
is skipped; a folder with nothing to replay is an error (:class:`ReplayError`, exit 1).

Reading the fleet CSVs into columns is :mod:`clark_engine.station.replay_fleet`; the
loaded replay, which answers the page at any time, is
:mod:`clark_engine.station.replay_frames`'s :class:`~clark_engine.station.replay_frames.Replay`;
this module finds and reads the folder's files and puts them together
(:func:`load_replay`).
"""

from __future__ import annotations

import bisect
import math
import re
import shlex
import statistics
from array import array
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

from clark_engine.analysis import log_folder
from clark_engine.analysis.latency import Problem
from clark_engine.analysis.log_folder import shown_name
from clark_engine.errors import ClarkError
from clark_engine.expectations.from_logs import judge
from clark_engine.expectations.log_clocks import align_clocks
from clark_engine.expectations.log_readers import (
    AgentLogs,
    file_names,
    read_interface_log,
    read_message_log,
    read_mission_log,
    text_lines,
)
from clark_engine.expectations.log_run import LogChecksError, rebuild
from clark_engine.link.messages import PictureData
from clark_engine.mission.geo import Origin, to_local
from clark_engine.mission.model import Mission
from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.log_lines import line_safe
from clark_engine.station.alarms import Alarm, AlarmWatch, failsafe_words
from clark_engine.station.replay_fleet import (
    ALT,
    CONDITIONS,
    FAILSAFE,
    LAT,
    LON,
    MAX_AGENTS,
    STATUS_AGE,
    FleetRows,
    read_fleet_columns,
)
from clark_engine.station.replay_frames import Replay, ReplayAgent
from clark_engine.station.view_hello import build_hello
from clark_engine.station.view_protocol import MAX_LOG_TEXT_CHARS, PROTOCOL_VERSION, Json
from clark_engine.station.view_rows import photo_json
from clark_engine.untrusted import printable

SPEEDS: Final = (1, 2, 5, 10, 20, 60, 120)
"""Replay speeds the page offers (mission seconds per wall-clock second)."""

MAX_SUBFOLDERS: Final = log_folder.MAX_SUBFOLDERS
"""Most sub-folders searched for agents' logs."""

_DRY_RUN_LINE: Final = re.compile(r"^Command line: `(?P<command>clark dry-run [^`]*)`", re.M)


class ReplayError(ClarkError):
    """A folder with nothing to replay, or logs of another mission (exit code 1)."""


MAX_ALARMS: Final = 10_000
"""Alarm episodes a replay keeps (the earliest); a run with more is noted."""


# -- finding the files -----------------------------------------------------------------------
# -- finding the files -----------------------------------------------------------------------


def find_log_files(
    folder: Path, notes: list[str], names: Mapping[str, Mapping[str, str]] | None = None
) -> dict[str, dict[str, Path]]:
    """Agent -> config key (``mission_log``...) -> its file, by the readers' one rule.

    :func:`clark_engine.analysis.log_folder.find_log_files`: in ``folder`` itself (a ``clark
    run``'s folder), in its ``logs`` folder (a dry-run report), and in their sub-folders
    (the agents' folders, gathered from several machines); at most :data:`MAX_AGENTS`.

    Raises:
        UsageError: The folder does not exist, is not a folder, or cannot be listed (2).
        ReplayError: It holds no agent's log (1).
    """
    found = log_folder.find_log_files(folder, notes, names)
    if not found:
        raise ReplayError(f"{folder}: {log_folder.NO_LOGS}")
    if len(found) > MAX_AGENTS:
        notes.append(f"{folder}: logs of {len(found)} agents; only the first {MAX_AGENTS} shown")
        found = dict(sorted(found.items())[:MAX_AGENTS])
    return found


def mission_from_report(folder: Path) -> Path | None:
    """The mission file a dry-run report's ``summary.md`` names, if it still exists.

    A report written by ``clark dry-run --report`` keeps the command line it was made
    with; its mission path is taken as it was typed (relative to the current folder).
    The caller checks that the mission is the one the logs name.
    """
    for summary in (folder / "summary.md", folder.parent / "summary.md"):
        try:
            with summary.open(encoding="utf-8", errors="replace") as stream:
                head = stream.read(4096)
        except OSError:
            continue
        match = _DRY_RUN_LINE.search(head)
        if match is None:
            continue
        try:
            words = shlex.split(match["command"])
        except ValueError:
            continue
        candidates = [w for w in words[2:] if not w.startswith("-")]
        if candidates:
            path = Path(candidates[0])
            return path if path.is_file() else None
    return None


@dataclass(slots=True)
class ReplayLoad:
    """What loading said besides the replay: warnings, and where things came from."""

    problems: list[Problem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    mission_source: str = ""

    def warnings(self) -> list[str]:
        """Every problem and note, as the command prints them (after ``warning:``)."""
        return [p.format_text() for p in self.problems] + self.notes


# -- loading ---------------------------------------------------------------------------------


def _configs(mission: Mission) -> dict[str, AgentConfig]:
    from clark_engine.mission.compiler import agent_config
    from clark_engine.runtime.config import config_from_dict

    return {
        name: config_from_dict(agent_config(mission, agent))
        for name, agent in mission.agents.items()
    }


def _header_int(logs: AgentLogs | None, key: str) -> int | None:
    text = logs.header.get(key) if logs is not None else None
    return int(text) if text is not None and text.isascii() and text.isdigit() else None


def _hello_from_logs(
    agents: Mapping[str, AgentLogs],
    seen: Mapping[str, int],
    station: str | None,
    origin: Origin,
) -> Json:
    """A ``hello`` from the logs alone (no mission): names, ids and roles from the headers.

    Without the mission the page knows no airframe, mode names, heartbeat rates or plan;
    an agent is never shown stale (its heartbeat period is unknown), lost as the fleet
    table said.
    """
    header = next((logs.header for logs in agents.values() if logs.header), {})
    names = sorted(set(agents) | set(seen))
    rows = []
    for name in names:
        if name == station:
            continue
        logs = agents.get(name)
        agent_id = _header_int(logs, "agent_id")
        rows.append(
            {
                "name": name,
                "id": agent_id if agent_id is not None else seen.get(name, 0),
                "role": shown_name(logs.header.get("role", "vehicle")) if logs else "vehicle",
                "airframe": None,
                "modes": [],
                "heartbeat_hz": None,
                "stale_after_s": None,
                "home": None,
                "envelope": None,
            }
        )
    station_logs = agents.get(station) if station else None
    loop_hz = header.get("loop_hz")
    return {
        "type": "hello",
        "protocol": PROTOCOL_VERSION,
        "mission": {
            "name": shown_name(header.get("mission", "(unknown mission)")),
            "id": _header_int(next(iter(agents.values()), None), "mission_id"),
            "description": None,
            "origin": {
                "lat": origin.lat_deg,
                "lon": origin.lon_deg,
                "alt_amsl_m": origin.alt_amsl_m,
            },
            "loop_hz": float(loop_hz) if loop_hz and re.fullmatch(r"[0-9.]+", loop_hz) else None,
            "heartbeat_timeout_s": None,
            "authenticated": None,
        },
        "station": {
            "name": station,
            "id": _header_int(station_logs, "agent_id"),
            "home": None,
        },
        "agents": rows,
        "plan": {},
        "plan_source": "",
        "answer_timeout_s": None,
        "update_hz": None,
        "actions": [],
    }


def _first_position(rows: Mapping[str, Mapping[str, FleetRows]]) -> Origin:
    """Without a mission, the map's origin: the first position in any fleet table."""
    best: tuple[float, float, float, float] | None = None
    for seen in rows.values():
        for agent in seen.values():
            lat, lon = agent.numbers[LAT], agent.numbers[LON]
            for i in range(len(agent)):
                if math.isfinite(lat[i]) and math.isfinite(lon[i]):
                    if best is None or agent.now_s[i] < best[0]:
                        alt = agent.numbers[ALT][i]
                        best = (agent.now_s[i], lat[i], lon[i], alt if math.isfinite(alt) else 0.0)
                    break
    return Origin(best[1], best[2], 0.0) if best is not None else Origin(0.0, 0.0, 0.0)


def _check_json(result: Any) -> Json:
    status = "not evaluated" if not result.evaluated else "passed" if result.passed else "failed"
    return {
        "name": line_safe(result.name, 200),
        "status": status,
        "detail": line_safe(f"{result.expected}; {result.observed}", MAX_LOG_TEXT_CHARS),
    }


def _log_lines(
    agents: Mapping[str, AgentLogs], station: str | None, problems: list[Problem]
) -> list[tuple[float, str, str]]:
    """The mission-log lines the page shows, in mission time: the station's, else everyone's."""
    chosen = [station] if station and "mission_log" in agents[station].files else sorted(agents)
    prefix = len(chosen) > 1 or chosen[0] != station
    lines: list[tuple[float, str, str]] = []
    for name in chosen:
        logs = agents[name]
        path = logs.files.get("mission_log")
        if path is None:
            continue
        ignored: list[Problem] = []  # read_mission_log reported them already
        for line in text_lines(path, ignored):
            text = f"{name}: {line.message}" if prefix else line.message
            lines.append((line.t_s + logs.shift_s, line.level, line_safe(text, MAX_LOG_TEXT_CHARS)))
    lines.sort(key=lambda item: item[0])
    return lines


def _changes(logs: AgentLogs | None) -> tuple[list[float], list[tuple[str, tuple[str, ...]]]]:
    if logs is None:
        return [], []
    items = sorted(
        ((t + logs.shift_s, event, active) for t, event, _s, _t, active in logs.changes),
        key=lambda item: item[0],
    )
    return [t for t, _, _ in items], [
        (line_safe(event, 64), tuple(line_safe(a, 200) for a in active[:64]))
        for _, event, active in items
    ]


def _tracks(
    chosen: Mapping[str, tuple[FleetRows, float]], ids: Mapping[str, int], origin: Origin
) -> tuple[
    tuple[array[float], array[float], array[float], array[float], array[int]],
    dict[str, tuple[list[float], array[int]]],
]:
    """Every agent's track points (one per Agent Status arrival), merged in time order."""
    points: list[tuple[float, int, float, float, float, str]] = []
    for name, (rows, shift) in chosen.items():
        n = rows.numbers
        last = math.nan
        for i in range(len(rows)):
            lat, lon, age = n[LAT][i], n[LON][i], n[STATUS_AGE][i]
            if not (math.isfinite(lat) and math.isfinite(lon)):
                continue
            arrival = rows.now_s[i] - (age if math.isfinite(age) else 0.0)
            if abs(arrival - last) < 1e-6:
                continue
            last = arrival
            alt_m = n[ALT][i] if math.isfinite(n[ALT][i]) else 0.0
            local = to_local(lat, lon, alt_m, origin)
            points.append((arrival + shift, ids[name], local.north_m, local.east_m, alt_m, name))
    points.sort(key=lambda p: p[0])
    t, north, east, alt, agent = array("d"), array("d"), array("d"), array("d"), array("q")
    per_agent: dict[str, tuple[list[float], array[int]]] = {}
    for index, (t_s, agent_id, n_m, e_m, a_m, name) in enumerate(points):
        t.append(t_s)
        north.append(round(n_m, 2))
        east.append(round(e_m, 2))
        alt.append(round(a_m, 2))
        agent.append(agent_id)
        times, indexes = per_agent.setdefault(name, ([], array("q")))
        times.append(t_s)
        indexes.append(index)
    return (t, north, east, alt, agent), per_agent


def _photos(
    agents: Mapping[str, AgentLogs],
    ids: Mapping[str, int],
    chosen: Mapping[str, tuple[FleetRows, float]],
    origin: Origin,
) -> list[Json]:
    """The pictures each agent sent, at its position then (those without one left out)."""
    out: list[tuple[float, int, PictureData]] = []
    for name, logs in agents.items():
        if name not in ids:
            continue
        rows_shift = chosen.get(name)
        for k, t in enumerate(sorted(logs.pictures_s), start=1):
            t_s = t + logs.shift_s
            if rows_shift is None:
                continue
            rows, shift = rows_shift
            i = bisect.bisect_right(rows.now_s, t_s - shift) - 1
            n = rows.numbers
            if i < 0 or not math.isfinite(n[LAT][i]):
                continue  # before its first position: nowhere to draw it
            alt = n[ALT][i] if math.isfinite(n[ALT][i]) else 0.0
            out.append((t_s, ids[name], PictureData(ids[name], 0, n[LAT][i], n[LON][i], alt, k)))
    out.sort(key=lambda item: item[0])
    return [
        photo_json(seq, agent_id, t_s, picture, origin)
        for seq, (t_s, agent_id, picture) in enumerate(out, start=1)
    ]


def _alarm_episodes(
    chosen: Mapping[str, tuple[FleetRows, float]],
    station: AgentConfig,
    origin: Origin,
    notes: list[str],
) -> list[Alarm]:
    """The alarms the station's view raised, judged again from the fleet tables' rows.

    The same :class:`~clark_engine.station.alarms.AlarmWatch` the live view runs, fed in
    mission time with what each row holds: a position at each Agent Status arrival, the
    heartbeat's condition and the Vehicle Health's failsafe as they change. The fleet
    CSV is written every tick from the fleet table the live view reads, so the episodes
    are those the operator saw (where the station's own table is the one shown).
    """
    envelopes = {p.name: p.envelope for p in station.peers if p.envelope is not None}
    if not envelopes:
        return []
    events: list[tuple[float, int, str, tuple[float, float, float, float] | str | None]] = []
    for name, (rows, shift) in chosen.items():
        if name not in envelopes:
            continue
        n = rows.numbers
        last_arrival = math.nan
        last_words: str | None = None
        for i in range(len(rows)):
            t_s = rows.now_s[i] + shift
            code = rows.condition[i]
            words = failsafe_words(
                CONDITIONS[code] if code >= 0 else None,
                rows.strings[rows.texts[FAILSAFE][i]] or None,
            )
            if words != last_words:
                last_words = words
                events.append((t_s, 0, name, words))
            lat, lon, age = n[LAT][i], n[LON][i], n[STATUS_AGE][i]
            if not (math.isfinite(lat) and math.isfinite(lon)):
                continue
            arrival = rows.now_s[i] - (age if math.isfinite(age) else 0.0)
            if abs(arrival - last_arrival) < 1e-6:
                continue
            last_arrival = arrival
            alt_m = n[ALT][i] if math.isfinite(n[ALT][i]) else 0.0
            local = to_local(lat, lon, alt_m, origin)
            events.append((t_s, 1, name, (local.north_m, local.east_m, alt_m, arrival + shift)))
    events.sort(key=lambda e: (e[0], e[1], e[2]))
    watch = AlarmWatch(envelopes, station.heartbeat_timeout_s)
    episodes: list[Alarm] = []
    k = 0
    while k < len(events):
        t_s = events[k][0]
        while k < len(events) and events[k][0] == t_s:
            _, kind, name, data = events[k]
            if kind == 0:
                watch.see_condition(name, data if isinstance(data, str) else None)
            elif isinstance(data, tuple):
                watch.see_position(name, *data)
            k += 1
        for change in watch.evaluate(t_s):
            if change.raised:
                episodes.append(change.alarm)
        if len(episodes) > MAX_ALARMS:
            notes.append(f"more than {MAX_ALARMS} alarms: only the first are shown")
            return episodes[:MAX_ALARMS]
    return episodes


def load_replay(
    folder: Path,
    mission: Mission | None = None,
    *,
    mission_source: str = "",
    update_hz: float = 5.0,
) -> tuple[Replay, ReplayLoad]:
    """Read a finished run's log folder once; returns the replay and what loading said.

    Args:
        folder: The run's logs (a ``clark run`` folder, agents' sub-folders, or a
            dry-run report).
        mission: The mission that was run, for the agents' airframes, modes, heartbeat
            rates, the plan and the checks; None shows what the logs alone tell.
        mission_source: Where the mission came from, in words, for the page.
        update_hz: How often a playing page is sent the state.

    Raises:
        UsageError: The folder does not exist or a file cannot be read (exit 2).
        ReplayError: Nothing to replay in it, or logs of another mission (exit 1).
    """
    load = ReplayLoad(mission_source=mission_source)
    problems, notes = load.problems, load.notes
    configs = _configs(mission) if mission is not None else {}
    names = {name: file_names(config) for name, config in configs.items()}
    files = find_log_files(folder, notes, names)
    if mission is not None:
        strangers = sorted(set(files) - set(configs))
        if strangers:
            notes.append(
                f"not agents of mission {mission.name}, ignored: {', '.join(strangers[:10])}"
            )
        files = {name: found for name, found in files.items() if name in configs}
        if not files:
            raise ReplayError(
                f"{folder}: no log of any agent of mission {mission.name} "
                f"({', '.join(sorted(configs))})"
            )
    agents = {name: AgentLogs(name, files=dict(found)) for name, found in files.items()}
    for logs in agents.values():
        found = logs.files
        if "mission_log" in found:
            read_mission_log(found["mission_log"], logs, problems)
        if "interface_log" in found:
            read_interface_log(found["interface_log"], logs, problems)
        if "message_log" in found:
            read_message_log(found["message_log"], logs, problems)
    named = {logs.header["mission"] for logs in agents.values() if "mission" in logs.header}
    if mission is not None and named and mission.name not in named:
        raise ReplayError(
            f"{folder}: its logs are of mission {printable(sorted(named)[0], 64)!r}, not "
            f"{mission.name!r} ({mission.file}); give that mission, or its logs"
        )
    if mission is None and len(named) > 1:
        notes.append(f"logs of several missions: {', '.join(sorted(named))}")
    roles = {
        name: (configs[name].role if name in configs else logs.header.get("role", ""))
        for name, logs in agents.items()
    }
    time_origin = align_clocks(agents, roles, notes)
    stations = sorted(name for name, role in roles.items() if role == "mcs")
    if mission is not None:
        stations = [n for n, c in configs.items() if c.role == "mcs"]
    station = stations[0] if stations else None

    # The fleet tables: the station's first, others for the agents it never holds.
    ids = {name: c.agent_id for name, c in configs.items()} if configs else None
    observers = sorted(
        (n for n in agents if "fleet_csv" in agents[n].files),
        key=lambda n: (n != station, n),
    )
    fleet: dict[str, dict[str, FleetRows]] = {}
    wanted = (set(configs) if configs else set(agents)) - {station}
    for observer in observers:
        if fleet and not (wanted - _covered(fleet)):
            break  # every agent has rows already: no need to read further tables
        fleet[observer] = read_fleet_columns(agents[observer].files["fleet_csv"], ids, problems)
    chosen: dict[str, tuple[FleetRows, float]] = {}
    observer_of: dict[str, str] = {}
    for observed in sorted(_covered(fleet)):
        if observed == station:
            continue
        candidates = [(o, seen[observed]) for o, seen in fleet.items() if observed in seen]
        best = next((c for c in candidates if c[0] == station), None) or max(
            candidates, key=lambda c: (len(c[1]), c[0] == station)
        )
        chosen[observed] = (best[1], agents[best[0]].shift_s)
        observer_of[observed] = best[0]
        if best[0] != station and station in fleet:
            notes.append(
                f"{observed}: shown as {best[0]}'s fleet table saw it (the station's never held it)"
            )

    # The hello: the mission's when known, else the logs'.
    if mission is not None and station is not None:
        origin = mission.origin
        hello = build_hello(
            configs[station], configs, plan_source=mission_source, update_hz=update_hz
        )
        modes = {peer.name: peer.modes for peer in configs[station].peers}
    else:
        origin = mission.origin if mission is not None else _first_position(fleet)
        seen_ids = {name: rows.agent_id for name, (rows, _) in chosen.items()}
        hello = _hello_from_logs(agents, seen_ids, station, origin)
        hello["update_hz"] = update_hz
        modes = {}
        if mission is None:
            notes.append(
                "no mission given (--checks MISSION): no plan, mode names, airframes or "
                "checks, and agents are never shown stale"
            )
    hello["actions"] = []
    ids_by_name = {str(a["name"]): int(a["id"]) for a in hello["agents"]}
    track, per_agent = _tracks(
        {n: c for n, c in chosen.items() if n in ids_by_name}, ids_by_name, origin
    )
    shown: list[ReplayAgent] = []
    for info in hello["agents"]:
        name = str(info["name"])
        rows_shift = chosen.get(name)
        times, indexes = per_agent.get(name, ([], array("q")))
        changes_t, changes = _changes(agents.get(name))
        shown.append(
            ReplayAgent(
                info=info,
                rows=rows_shift[0] if rows_shift else None,
                shift_s=rows_shift[1] if rows_shift else 0.0,
                observer=observer_of.get(name),
                modes=modes.get(name, {}),
                changes_t=changes_t,
                changes=changes,
                track_t=times,
                track_index=indexes,
            )
        )
    photos = _photos(agents, ids_by_name, chosen, origin)
    log = _log_lines(agents, station, problems)
    alarms: list[Alarm] = []
    if mission is not None and station is not None:
        alarms = _alarm_episodes(
            {n: c for n, c in chosen.items() if n in ids_by_name}, configs[station], origin, notes
        )

    checks: list[Json] | None = None
    checks_note = "no mission given (--checks MISSION): no check is judged"
    if mission is not None:
        if mission.checks:
            try:
                run = rebuild(folder, mission, configs, files=files)
            except LogChecksError as exc:
                raise ReplayError(str(exc)) from None
            checks = [_check_json(result) for result in judge(run)]
            checks_note = "judged on the whole run's logs, as clark analyze --checks judges them"
        else:
            checks = []
            checks_note = "the mission declares no checks"

    ends = [logs.latest_s + logs.shift_s for logs in agents.values() if logs.latest_s is not None]
    for observer, seen in fleet.items():
        ends += [rows.now_s[-1] + agents[observer].shift_s for rows in seen.values() if len(rows)]
    starts = [0.0 if station in agents else math.inf]
    for rows, shift in chosen.values():
        if len(rows):
            starts.append(rows.now_s[0] + shift)
    starts += [logs.shift_s for logs in agents.values() if logs.latest_s is not None]
    start_s = min(starts) if starts and min(starts) < math.inf else 0.0
    end_s = max(ends, default=start_s)
    if not (len(track[0]) or log or any(a.rows is not None for a in shown) or ends):
        why = "; ".join(p.format_text() for p in problems[:3])
        raise ReplayError(
            f"{folder}: its logs hold nothing to replay (no readable row or line)"
            + (f": {why}" if why else "")
        )

    station_logs = agents.get(station) if station else None
    gps_ms: float | None = None
    if station_logs is not None:
        offsets = station_logs.offsets_ms or station_logs.message_offsets_ms
        if offsets:
            gps_ms = statistics.median(offsets) - 1000 * station_logs.shift_s
    station_json: Json = {
        "name": hello["station"]["name"],
        "id": hello["station"]["id"],
        "gps_time_ms": None,
        "terminated": False,
        "unknown_packets": None,
    }
    hello["mode"] = "replay"
    hello["replay"] = {
        "start_s": round(start_s, 3),
        "end_s": round(end_s, 3),
        "speeds": list(SPEEDS),
        "folder": printable(str(folder), 200),
        "time_origin": line_safe(time_origin, 200),
        "observers": observer_of,
        "mission_source": line_safe(mission_source, 200),
        "checks_note": checks_note,
    }
    span = (round(start_s, 3), round(max(end_s, start_s), 3))
    replay = Replay(
        hello, origin, shown, track, photos, log, checks, station_json, gps_ms, span, alarms
    )
    problems.sort(key=lambda p: (p.file, p.line or 0))
    return replay, load


def _covered(fleet: Mapping[str, Mapping[str, FleetRows]]) -> set[str]:
    return {name for seen in fleet.values() for name in seen}


def iter_warnings(load: ReplayLoad, limit: int = 50) -> Iterator[str]:
    """The first ``limit`` warnings, then how many more there were."""
    warnings = load.warnings()
    yield from warnings[:limit]
    if len(warnings) > limit:
        yield f"... and {len(warnings) - limit} more"


__all__ = [
    "SPEEDS",
    "ReplayError",
    "ReplayLoad",
    "find_log_files",
    "iter_warnings",
    "load_replay",
    "mission_from_report",
]
