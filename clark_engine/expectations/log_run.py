"""A run rebuilt from its logs: a :class:`~clark_engine.expectations.recording.Recording`.

Why separate: the dry run fills in a ``Recording`` as it simulates; a real run (``clark run``,
one process per agent) leaves only its logs. :func:`rebuild` reads them
(:mod:`clark_engine.expectations.log_readers`), puts every agent on mission time
(:mod:`clark_engine.expectations.log_clocks`) and fills in the same ``Recording``, so
``clark analyze --checks`` (:mod:`clark_engine.expectations.from_logs`) and ``clark replay``
judge a flight with the dry run's own evaluators.

- **Tracks** come from the fleet CSVs: each row holds another agent's latest Agent
  Status (``lat_deg``, ``lon_deg``, ``alt_m`` above the origin), which arrived
  ``status_age_s`` before the row's ``now_s``; one sample is kept per arrival. The
  station's view is preferred (what the operator saw); another agent's view fills in
  where the station's has none for over :data:`GAP_STATUS_PERIODS` of the vehicle's
  Agent Status periods: a vehicle the station never saw, or while the station was
  out of range, deaf, or had stopped logging (each use is a warning). Positions are
  converted to metres north, east and up of the mission's origin; attitude is the
  row's roll, pitch and yaw (0 when the agent sends no Agent Attitude). The
  evaluators compare tracks sample by sample, so every track is put on one time grid
  (every arrival of any vehicle), each holding its latest position; before a
  vehicle's first position its samples are NaN, which no distance can pass on.
- **States** come from each agent's mission log lines
  ``behavior.change: EVENT: SOURCE -> TARGET (active: A, B)``. The line does not
  say which states the change entered; they are rebuilt as
  :class:`~clark_engine.runtime.machine.BehaviorMachine` enters them
  (:func:`entered_states`): the target and every state active under it afterwards
  (entered again when it was active: a transition to itself, to an ancestor or to an
  active descendant), and every state active afterwards that was not before.
  ``failed`` enters nothing.
- **Why a state was not reached**: the last ``launch: the behaviour waits for ...``
  line (``launch.wait``, mission log) before the behaviour started, for an agent
  whose behaviour never did; the ``state`` and ``sequence`` checks quote it.
- **Safety events**, as the dry run records them: the first ``failsafe ACTION`` line
  (``failsafe.act``, mission log; ``continue`` is no failsafe) and the first
  ``autopilot silent ...: lost`` line (``autopilot.lost``, interface log).
- **Photos** are the Picture Data an agent sent (its message log's ``sent`` rows of
  ``picture_data``, one per picture however many destinations it went to) plus the
  pictures its mission log says were taken before any position (none sent), at the
  time they were sent. Their position is the agent's track's at that time. A picture
  taken in the last tick before the logs end, whose Picture Data was never sent, is
  not counted (the dry run counts the camera's captures).
- ``end_s`` is the latest mission time in any of the logs.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Final

from clark_engine.analysis.latency import Problem
from clark_engine.analysis.log_folder import find_log_files
from clark_engine.errors import ClarkError
from clark_engine.expectations.log_clocks import align_clocks
from clark_engine.expectations.log_readers import (
    ARRIVAL_DIGITS,
    AgentLogs,
    FleetSample,
    file_names,
    read_fleet_csv,
    read_interface_log,
    read_message_log,
    read_mission_log,
)
from clark_engine.expectations.recording import Photo, Recording, StateEntry, Track
from clark_engine.mission.geo import Origin, to_local
from clark_engine.mission.model import Mission
from clark_engine.runtime.config import AgentConfig

#: A vehicle's positions are taken from the station's fleet table; from another agent's
#: only where the station's has none for over this many of its Agent Status periods (out
#: of range, silent, or its log ended).
GAP_STATUS_PERIODS: Final = 2.5


class LogChecksError(ClarkError):
    """A folder holding none of the mission's logs (exit code 1)."""


@dataclass(slots=True)
class LogRun:
    """A run rebuilt from its logs.

    Attributes:
        folder: The folder read.
        mission: The mission the logs are of.
        configs: Agent -> its compiled config (the evaluators' view of the mission).
        recording: What the logs say, in mission time and the mission's local frame.
        agents: Agent -> its logs, for every agent of the mission with a log in the folder.
        time_origin: What t = 0 is, in words.
        problems: Rows, lines and files skipped, in file then line order.
        notes: Other warnings (clocks, files of other missions or agents).
    """

    folder: Path
    mission: Mission
    configs: dict[str, AgentConfig]
    recording: Recording
    agents: dict[str, AgentLogs]
    time_origin: str
    problems: list[Problem] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    def warnings(self) -> list[str]:
        """Every problem and note, as the command prints them (after ``warning:``)."""
        return [p.format_text() for p in self.problems] + self.notes


def _prefixes(path: str) -> list[str]:
    """``path`` and its ancestors, the root ``""`` included."""
    if not path:
        return [""]
    parts = path.split(".")
    return ["", *(".".join(parts[: i + 1]) for i in range(len(parts)))]


def _under(path: str, top: str) -> bool:
    """``path`` is ``top`` or inside it."""
    return not top or path == top or path.startswith(top + ".")


def entered_states(
    event: str, target: str, before: Sequence[str], after: Sequence[str]
) -> set[str]:
    """The states one change entered, from its log line and the active leaves before it.

    As :class:`~clark_engine.runtime.machine.BehaviorMachine` (the ``transitions``
    library under it) enters them: the target and every state active under it afterwards
    (a transition to the target's own state, an ancestor or a descendant that is already
    active leaves and enters it again), and every state active afterwards that was not
    before (the branch down to the target, a parallel state's other regions). A state
    between the source and the target that stays active is not entered again.

    Args:
        event: The change's event (``failed`` enters nothing).
        target: The state the transition names (``""``: the root, as ``start`` does).
        before: Active leaf paths before the change.
        after: Active leaf paths after it.
    """
    if event == "failed":
        return set()
    active_before = {p for leaf in before for p in _prefixes(leaf)}
    active_after = {p for leaf in after for p in _prefixes(leaf)}
    return {p for p in active_after if _under(p, target)} | (active_after - active_before)


def _states(logs: AgentLogs, config: AgentConfig) -> list[StateEntry]:
    order = {spec.path: i for i, spec in enumerate(config.machine.walk())} if config.machine else {}
    entries = []
    before: tuple[str, ...] = ()
    for t_s, event, _source, target, active in logs.changes:
        entered = entered_states(event, target, before, active)
        ranked = sorted(entered, key=lambda p: (order.get(p, len(order)), p.count("."), p))
        entries.append(StateEntry(t_s + logs.shift_s, event, active, tuple(ranked)))
        before = active
    return entries


def _tracks(
    samples: Mapping[str, list[tuple[float, FleetSample]]], origin: Origin
) -> dict[str, Track]:
    """One track per vehicle on a shared time grid (every arrival), positions held.

    The evaluators pair tracks sample by sample; before a vehicle's first position its
    samples are NaN (no distance passes on them).
    """
    grid = sorted({round(t, ARRIVAL_DIGITS) for seen in samples.values() for t, _ in seen})
    tracks: dict[str, Track] = {}
    nan = math.nan
    for name, seen in sorted(samples.items()):
        track = Track()
        index = -1
        point = (nan, nan, nan, 0.0, 0.0, 0.0)
        for t_s in grid:
            while index + 1 < len(seen) and round(seen[index + 1][0], ARRIVAL_DIGITS) <= t_s:
                index += 1
                s = seen[index][1]
                local = to_local(s.lat_deg, s.lon_deg, s.alt_m, origin)
                point = (
                    local.north_m,
                    local.east_m,
                    local.up_m,
                    s.roll_deg,
                    s.pitch_deg,
                    s.yaw_deg,
                )
            track.add(t_s, *point)
        tracks[name] = track
    return tracks


def position(track: Track | None, t_s: float) -> tuple[float, float, float]:
    """Where ``track`` holds its vehicle at ``t_s``; NaN before its first position."""
    found = track.at(t_s) if track is not None else None
    return found if found is not None else (math.nan, math.nan, math.nan)


def _status_rate_hz(config: AgentConfig) -> float:
    """How often the agent sends its Agent Status (1 Hz when its config does not say)."""
    rates = [t.rate_hz for t in config.telemetry if t.message == "agent_status" and t.rate_hz > 0]
    return max(rates, default=1.0)


def _fill(
    merged: list[tuple[float, FleetSample]], view: list[tuple[float, FleetSample]], gap_s: float
) -> tuple[list[tuple[float, FleetSample]], int]:
    """``merged`` with the samples of ``view`` that fall where it has none for over ``gap_s``.

    Between two of its samples over ``gap_s`` apart, or over ``gap_s`` before its first or
    after its last (all of ``view`` when it is empty).

    Returns:
        The samples, in time order, and how many came from ``view``.
    """
    if not merged:
        return list(view), len(view)
    times = [t for t, _ in merged]
    taken = []
    for item in view:
        t_s = item[0]
        i = bisect.bisect_right(times, t_s)
        before = times[i - 1] if i > 0 else t_s
        after = times[i] if i < len(times) else t_s
        if after - before > gap_s:
            taken.append(item)
    return sorted([*merged, *taken], key=lambda item: item[0]), len(taken)


def _find_logs(
    folder: Path, mission: Mission, configs: Mapping[str, AgentConfig], notes: list[str]
) -> dict[str, AgentLogs]:
    """The mission's agents with at least one log in ``folder``, and their files.

    Found by the readers' one rule (:func:`clark_engine.analysis.log_folder.find_log_files`): in
    ``folder``, its ``logs/`` folder and their sub-folders; the agents in the mission's
    order.

    Raises:
        UsageError: The folder does not exist, is not a folder, or cannot be listed.
        LogChecksError: It holds no log of any agent of the mission.
    """
    names = {name: file_names(config) for name, config in configs.items()}
    found = find_log_files(folder, notes, names)
    agents = {name: AgentLogs(name, files=dict(found[name])) for name in configs if found.get(name)}
    strangers = sorted(
        path.name for name, files in found.items() if name not in configs for path in files.values()
    )
    if not agents:
        shown = f" (it holds {', '.join(strangers[:5])})" if strangers else ""
        raise LogChecksError(
            f"{folder}: no log of any agent of mission {mission.name} "
            f"({', '.join(sorted(configs))}){shown}; looked in it, its logs/ folder and "
            "their sub-folders"
        )
    if strangers:
        notes.append(
            f"{folder}: not of an agent of mission {mission.name}, ignored: {', '.join(strangers)}"
        )
    missing = sorted(set(configs) - set(agents))
    if missing:
        notes.append(
            f"{folder}: no log of {', '.join(missing)}; the checks that need them are not evaluated"
        )
    return agents


def _read_logs(
    agents: Mapping[str, AgentLogs], mission: Mission, problems: list[Problem], notes: list[str]
) -> dict[str, dict[str, list[FleetSample]]]:
    """Read every agent's files; returns observer -> observed agent -> its arrivals.

    Raises:
        UsageError: A file cannot be read.
        LogChecksError: Every header names another mission.
    """
    fleet: dict[str, dict[str, list[FleetSample]]] = {}
    for name, logs in agents.items():
        files = logs.files
        if "mission_log" in files:
            read_mission_log(files["mission_log"], logs, problems)
        if "interface_log" in files:
            read_interface_log(files["interface_log"], logs, problems)
        if "message_log" in files:
            read_message_log(files["message_log"], logs, problems)
        if "fleet_csv" in files:
            fleet[name] = read_fleet_csv(files["fleet_csv"], logs, problems)
        logged_mission = logs.header.get("mission")
        if logged_mission is not None and logged_mission != mission.name:
            notes.append(
                f"{name}: its logs are of mission {logged_mission!r}, not {mission.name!r}"
            )
    others = [
        n for n, logs in agents.items() if logs.header.get("mission") not in (None, mission.name)
    ]
    if len(others) == len(agents):
        raise LogChecksError(
            f"its logs are of mission {agents[others[0]].header['mission']!r}, not "
            f"{mission.name!r} ({mission.file}); give that mission, or its logs"
        )
    return fleet


def _positions(
    fleet: Mapping[str, Mapping[str, list[FleetSample]]],
    agents: Mapping[str, AgentLogs],
    configs: Mapping[str, AgentConfig],
    notes: list[str],
) -> dict[str, list[tuple[float, FleetSample]]]:
    """Vehicle -> its positions in mission time: the station's view, gaps filled by others'."""
    observers = sorted(fleet, key=lambda n: (configs[n].role != "mcs", n))
    stations_logged = any(configs[n].role == "mcs" for n in observers)
    samples: dict[str, list[tuple[float, FleetSample]]] = {}
    for vehicle in (n for n, c in configs.items() if c.is_vehicle):
        gap_s = GAP_STATUS_PERIODS / _status_rate_hz(configs[vehicle])
        merged: list[tuple[float, FleetSample]] = []
        used: list[str] = []
        for observer in observers:
            seen = fleet[observer].get(vehicle)
            if not seen:
                continue
            shift = agents[observer].shift_s
            merged, added = _fill(merged, [(s.arrival_s + shift, s) for s in seen], gap_s)
            if added and used:
                notes.append(
                    f"{vehicle}: {added} position(s) from {observer}'s fleet table, where "
                    f"{' and '.join(used)}'s had none for over {gap_s:g} s"
                )
            elif added and configs[observer].role != "mcs" and stations_logged:
                notes.append(
                    f"{vehicle}: positions from {observer}'s fleet table (no station saw it)"
                )
            used.append(observer)
        if merged:
            samples[vehicle] = merged
    return samples


def rebuild(
    folder: Path,
    mission: Mission,
    configs: Mapping[str, AgentConfig],
    *,
    files: Mapping[str, Mapping[str, Path]] | None = None,
) -> LogRun:
    """Read a folder of a run's logs and rebuild what the run did (see this module's doc).

    Args:
        folder: Where the agents wrote their logs.
        mission: The mission that was run.
        configs: Agent -> its compiled config.
        files: Agent -> config key (``mission_log``...) -> its file, when the caller
            found them already (``clark replay`` also looks in the agents' own
            sub-folders); agents that are not the mission's are left out. None: the
            files named by the configs in ``folder``.

    Raises:
        UsageError: The folder does not exist, is not a folder, or a file cannot be read.
        LogChecksError: The folder holds no log of any of the mission's agents, or only
            logs of another mission.
    """
    problems: list[Problem] = []
    notes: list[str] = []
    if files is None:
        agents = _find_logs(folder, mission, configs, notes)
    else:
        agents = {
            name: AgentLogs(name, files=dict(found))
            for name, found in files.items()
            if name in configs and found
        }
        if not agents:
            raise LogChecksError(f"{folder}: no log of any agent of mission {mission.name}")
    try:
        fleet = _read_logs(agents, mission, problems, notes)
    except LogChecksError as exc:
        raise LogChecksError(f"{folder}: {exc}") from None
    time_origin = align_clocks(agents, {n: c.role for n, c in configs.items()}, notes)
    recording = Recording()
    recording.tracks = _tracks(_positions(fleet, agents, configs, notes), mission.origin)
    for name, logs in agents.items():
        recording.states[name] = _states(logs, configs[name])
        shift = logs.shift_s
        events: list[tuple[float, str]] = []
        if logs.failsafe is not None:
            events.append((logs.failsafe[0] + shift, f"failsafe {logs.failsafe[1]}"))
        if logs.autopilot_lost_s is not None:
            events.append((logs.autopilot_lost_s + shift, "autopilot_lost"))
        if events:
            recording.safety[name] = sorted(events, key=lambda e: e[0])
        if logs.waiting is not None and not recording.states[name]:
            recording.waiting[name] = (logs.waiting,)
        if logs.pictures_s:
            track = recording.tracks.get(name)
            recording.photos[name] = [
                Photo(t + shift, *position(track, t + shift)) for t in sorted(logs.pictures_s)
            ]
    ends = [logs.latest_s + logs.shift_s for logs in agents.values() if logs.latest_s is not None]
    recording.end_s = max(ends, default=0.0)
    problems.sort(key=lambda p: (p.file, p.line or 0))
    return LogRun(folder, mission, dict(configs), recording, agents, time_origin, problems, notes)
