"""The dry run's report: plots of paths and control inputs, a state timeline, a summary.

Written into ``--report DIR`` beside every agent's CSV and logs:

* ``tracks.png``: every vehicle's path in metres from the origin, with its
  waypoints, the positions of its pictures, and the closest approach of the pair of
  vehicles that came closest (both positions, the distance and the time);
* ``altitude.png`` (when the fleet has an aircraft): every vehicle's altitude above the
  origin over time, against each aircraft's ceiling and floor, breaches marked;
* ``inputs.png``: the pulse widths the autopilots received for doublets and sweeps,
  each channel named by its function in the vehicle's profile;
* ``timeline.png``: which state each agent was in, over time;
* ``summary.md``: the command line, seed and injected faults, the checks table, the
  safety judgement (:mod:`clark_engine.expectations.safety`), the state timeline as text, and
  the latency and loss tables of ``clark analyze``.

Plots use matplotlib's non-interactive Agg backend; files are written with fixed
metadata so the same run gives the same bytes.

The report is written whole into a fresh hidden folder beside ``DIR``
(``.DIR.incomplete-*``) and moved into place only when complete
(:class:`ReportFolder`), with a ``.clark-report.json`` that lists its files. A run
that is interrupted leaves ``DIR`` as it was. A later run replaces a report it
recognises (by that list, or as a report from before the list) and refuses a
``DIR`` holding any other file: it never deletes a file the engine did not write.
"""

from __future__ import annotations

import math
import os
import re
import shlex
import shutil
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final

from clark_engine.behaviors import behaviors
from clark_engine.errors import UsageError
from clark_engine.expectations.evaluate import CheckResult, checks_table
from clark_engine.expectations.recording import Pace, Recording
from clark_engine.expectations.safety import PairSafety, SafetyJudgement, count_breaches
from clark_engine.mission.compiler import foreign_files, swap_in, write_marker
from clark_engine.runtime.config import AgentConfig

#: PNG metadata without the matplotlib version or a date, for reproducible files.
_PNG_METADATA = {"Software": None}

#: A recorded signal's key: an RC input (``rc1``) or a servo output (``servo3``).
_SIGNAL_LABEL: Final = re.compile(r"(rc|servo)([0-9]+)")

REPORT_MARKER: Final = ".clark-report.json"
"""Written last into a complete report: the list of its files, all the engine's."""

_REPORT_FILES: Final = frozenset(
    {"summary.md", "tracks.png", "altitude.png", "inputs.png", "timeline.png"}
)
_LOG_SUFFIXES: Final = (".mission.log", ".interface.log", ".fleet.csv", ".messages.csv")


def _older_report(folder: Path) -> Callable[[Path, str], bool]:
    """Recognises the files of a report from before :data:`REPORT_MARKER` existed.

    Its summary.md, plots and agents' logs, when summary.md is a dry run's.
    """
    try:
        with (folder / "summary.md").open(encoding="utf-8") as summary:
            is_report = summary.read(20).startswith("# Dry run of ")
    except (OSError, UnicodeDecodeError):
        is_report = False

    def recognise(path: Path, name: str) -> bool:
        if not is_report or path.is_symlink():
            return False
        folder_name, _, file_name = name.rpartition("/")
        if not folder_name:
            return name in _REPORT_FILES
        return folder_name == "logs" and file_name.endswith(_LOG_SUFFIXES)

    return recognise


class ReportFolder:
    """Where ``--report DIR`` is written: whole, beside DIR, then moved into place.

    :meth:`check` before the run refuses a DIR with files the engine did not write;
    :meth:`open` makes the fresh folder the run logs into; :meth:`commit` lists its
    files in :data:`REPORT_MARKER` and swaps it in for DIR; :meth:`discard` (always
    called, e.g. in ``finally``) removes it if it was never committed.
    """

    def __init__(self, target: Path) -> None:
        self.target = target
        """DIR as the user gave it (messages name it so)."""
        self.staging: Path | None = None
        """The folder being written, until it is committed or discarded."""

    @property
    def _place(self) -> Path:
        return self.target.resolve()

    def check(self) -> None:
        """Refuse a DIR that holds files the engine did not write (nothing is deleted).

        Raises:
            UsageError: DIR is a file, or holds such files.
        """
        foreign = foreign_files(self._place, REPORT_MARKER, _older_report(self._place))
        if foreign:
            shown = ", ".join(foreign[:5])
            if len(foreign) > 5:
                shown += f" and {len(foreign) - 5} more"
            raise UsageError(
                f"--report {self.target} holds files clark did not write ({shown}); "
                "a report replaces its folder, so give a new or empty folder, or move them"
            )

    def open(self) -> Path:
        """Make the fresh folder (a hidden sibling of DIR) and return its ``logs`` folder.

        Raises:
            UsageError: It cannot be made.
        """
        place = self._place
        try:
            place.parent.mkdir(parents=True, exist_ok=True)
            staging = Path(tempfile.mkdtemp(prefix=f".{place.name}.incomplete-", dir=place.parent))
            self.staging = staging
            staging.chmod(0o755)  # mkdtemp's 700 would become the report's mode
            (staging / "logs").mkdir()
        except OSError as exc:
            raise UsageError(
                f"cannot write the report to {self.target}: {exc.strerror or exc}"
            ) from None
        return staging / "logs"

    @property
    def folder(self) -> Path:
        """The folder to write the report's files into (before :meth:`commit`)."""
        assert self.staging is not None, "open() first"
        return self.staging

    def commit(self) -> None:
        """List the report's files, then put it in DIR's place.

        Raises:
            UsageError: DIR gained files the engine did not write during the run, or
                the folder cannot be moved.
        """
        self.check()
        try:
            write_marker(self.folder, REPORT_MARKER, "dry-run report (clark dry-run --report)")
            swap_in(self.folder, self._place)
        except OSError as exc:
            raise UsageError(
                f"cannot write the report to {self.target}: {exc.strerror or exc}"
            ) from None
        self.staging = None

    def discard(self) -> None:
        """Remove the fresh folder if it was not committed (an interrupted or failed run)."""
        if self.staging is not None and os.path.isdir(self.staging):
            shutil.rmtree(self.staging, ignore_errors=True)
        self.staging = None


@dataclass(frozen=True, slots=True)
class InjectedFault:
    """A fault the run injected, with where it was given.

    Attributes:
        fault: The fault in the mission's form (``{"kill": {"agent": "a", "at_s": 5}}``).
        given_by: ``mission`` for the mission's ``faults:``, or ``--fault TEXT``.
    """

    fault: Mapping[str, Any]
    given_by: str

    @property
    def kind(self) -> str:
        """The fault's kind (``kill``, ``link_drop``, ...)."""
        return next(iter(self.fault))

    @property
    def body(self) -> Mapping[str, Any]:
        """The fault's parameters."""
        body: Mapping[str, Any] = self.fault[self.kind]
        return body

    @property
    def agents(self) -> tuple[str, ...]:
        """The agents it strikes; empty for a fault on the whole fleet or its stations."""
        body = self.body
        return (*(str(n) for n in body.get("between", [])),) + (
            (str(body["agent"]),) if "agent" in body else ()
        )

    def window(self, end_s: float) -> tuple[float, float]:
        """(start, end) in simulated seconds, clipped to ``end_s``; a kill lasts to the end."""
        body = self.body
        start = float(body.get("at_s", body.get("from_s", 0.0)))
        end = float(body.get("to_s", math.inf)) if "at_s" not in body else math.inf
        return start, min(end, end_s)

    def describe(self) -> str:
        """What the fault does, in words (``kill slash_a``, ``stations silent``)."""
        body = self.body
        if self.kind == "kill":
            return f"kill {body['agent']}"
        if self.kind == "link_drop":
            a, b = body["between"]
            return f"link {a} - {b} dropped"
        if self.kind == "station_silent":
            return "stations silent"
        if self.kind == "autopilot_disconnect":
            return f"autopilot of {body['agent']} disconnected"
        if self.kind == "corrupt":
            return f"{100 * float(body['share']):g}% of packets corrupted"
        return self.kind

    def when(self) -> str:
        """When it strikes, in simulated seconds (``at 75``, ``65 to 80``, ``the whole run``)."""
        body = self.body
        if "at_s" in body:
            return f"at {float(body['at_s']):g}"
        start, end = float(body.get("from_s", 0.0)), float(body.get("to_s", math.inf))
        if start == 0 and math.isinf(end):
            return "the whole run"
        return f"{start:g} to end" if math.isinf(end) else f"{start:g} to {end:g}"


@dataclass(frozen=True, slots=True)
class RunOrigin:
    """How a run was made, for the report: its command line and the faults it injected.

    Attributes:
        command: The command line as typed, or the equivalent one for a run made in
            process (:func:`equivalent_command`).
        command_given: True when ``command`` is the one typed.
        faults: Every fault the run injected, the mission's then the command line's.
    """

    command: str
    command_given: bool
    faults: tuple[InjectedFault, ...] = ()
    drawn: tuple[tuple[str, float | bool], ...] = ()
    """The mission's varied values as this run drew them (or ``--vary`` fixed them)."""


def faults_table(faults: Sequence[InjectedFault]) -> str:
    """The injected faults as a Markdown table, in the order they were given."""
    if not faults:
        return "No faults injected.\n"
    lines = ["| fault | when (s) | given by |", "|---|---|---|"]
    lines += [f"| {f.describe()} | {f.when()} | {f.given_by} |" for f in faults]
    return "\n".join(lines) + "\n"


def drawn_table(drawn: Sequence[tuple[str, float | bool]]) -> str:
    """The varied values one run drew, as a Markdown table (nothing when none varies)."""
    if not drawn:
        return ""
    lines = ["| value | drawn |", "|---|---|"]
    lines += [f"| `{path}` | {vary_value_text(value)} |" for path, value in drawn]
    return "\n".join(lines) + "\n"


def vary_value_text(value: float | bool) -> str:
    """A drawn value as ``--vary`` takes it back: ``true``, or the number exactly (shortest)."""
    if isinstance(value, bool):
        return "true" if value else "false"
    number = float(value)
    return f"{number:g}" if number.is_integer() and abs(number) < 1e15 else repr(number)


def drawn_line(seed: int, drawn: Mapping[str, float | bool]) -> str:
    """What one run drew, as ``clark dry-run`` and ``clark autopilot-sim`` say it."""
    shown = ", ".join(f"{path}={vary_value_text(value)}" for path, value in drawn.items())
    return f"drawn for seed {seed}: {shown}"


def equivalent_command(
    mission_path: Path | str,
    seed: int,
    until_s: float | None,
    fault_texts: Sequence[str],
    report: Path | None,
    vary_texts: Sequence[str] = (),
    more: Sequence[str] = (),
) -> str:
    """The ``clark dry-run`` command line that repeats a run made in process.

    The one place such a line is written: a dry run's own (its report's ``Command
    line``) and each failing run of a campaign
    (:func:`clark_engine.campaign.report.reproduce_command`) are both this.

    Args:
        mission_path: The mission file, as the user named it (written as given).
        seed: The run's seed.
        until_s: ``--until``; None leaves it out (the mission's own duration).
        fault_texts: Each ``--fault``, in order.
        report: ``--report``; None leaves it out.
        vary_texts: Each ``--vary PATH=VALUE``, in order.
        more: Words put last as they are (a campaign's ``--autopilot sitl ...``).
    """
    words = ["clark", "dry-run", str(mission_path), "--seed", str(seed)]
    if until_s is not None:
        words += ["--until", f"{until_s:g}"]
    for text in fault_texts:
        words += ["--fault", text]
    for text in vary_texts:
        words += ["--vary", text]
    if report is not None:
        words += ["--report", str(report)]
    words += list(more)
    return shlex.join(words)


def _pyplot() -> Any:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _waypoints(config: AgentConfig) -> list[tuple[float, float]]:
    points: list[tuple[float, float]] = []
    if config.machine is None:
        return points
    declared = behaviors()
    for state in config.machine.walk():
        behavior = declared.get(state.primitive) if state.primitive is not None else None
        if behavior is not None:
            plan = behavior.plan(state.params)
            points.extend((p["east_m"], p["north_m"]) for p, _param in plan.points)
    return points


def tracks_figure(
    recording: Recording,
    configs: Mapping[str, AgentConfig],
    closest: PairSafety | None = None,
) -> Any:
    """The figure of :func:`plot_tracks`, unsaved (one axes: the paths)."""
    plt = _pyplot()
    names = sorted(recording.tracks)
    fig, ax = plt.subplots(figsize=(8, 7), dpi=100)
    colors = {name: f"C{index % 10}" for index, name in enumerate(names)}
    for name in names:
        track, color = recording.tracks[name], colors[name]
        ax.plot(track.east_m, track.north_m, color=color, linewidth=1.2, label=name)
        if track.east_m:
            ax.plot(track.east_m[0], track.north_m[0], "o", color=color, markersize=5)
        points = _waypoints(configs[name]) if name in configs else []
        if points:
            ax.plot(*zip(*points, strict=True), "x", color=color, markersize=7, linestyle="none")
        photos = recording.photos.get(name, [])
        if photos:
            ax.plot(
                [p.east_m for p in photos],
                [p.north_m for p in photos],
                "^",
                color=color,
                markersize=4,
                linestyle="none",
                label=f"{name} photos",
            )
    if closest is not None and closest.distance_m is not None:
        # Both vehicles where they came closest, joined; the distance and time in the
        # legend (a label on the map could hide the paths it marks).
        (na, ea, _), (nb, eb, _) = closest.where_a, closest.where_b
        verdict = "" if closest.passed else f", under {closest.limit_m:g} m"
        ax.plot(
            [ea, eb], [na, nb], "-", color="black", linewidth=1.0, marker="o",
            markersize=9, markerfacecolor="none", markeredgewidth=1.5,
            label=f"closest: {closest.a} - {closest.b}, {closest.distance_m:.1f} m at "
            f"{closest.time_s:.1f} s{verdict}",
        )  # fmt: skip
    ax.set_xlabel("east of origin (m)")
    ax.set_ylabel("north of origin (m)")
    ax.set_title("Paths (o start, x waypoints, ^ pictures, circled: closest approach)")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(True, linewidth=0.3)
    ax.legend(loc="best", fontsize=8)
    fig.tight_layout()
    return fig


def plot_tracks(
    path: Path,
    recording: Recording,
    configs: Mapping[str, AgentConfig],
    closest: PairSafety | None = None,
) -> None:
    """Every vehicle's path (east right, north up), waypoints and picture positions.

    ``closest``: the pair of vehicles that came closest, marked where each was then.
    """
    _save(tracks_figure(recording, configs, closest), path)


def _limit_lines(
    configs: Mapping[str, AgentConfig], names: Sequence[str], key: str
) -> dict[float, list[str]]:
    """Each distinct ceiling (or floor above the ground) of the aircraft, with who has it."""
    lines: dict[float, list[str]] = {}
    for name in names:
        config = configs.get(name)
        envelope = config.envelope if config is not None else None
        if config is None or envelope is None or not config.is_aircraft:
            continue
        value = envelope.ceiling_m if key == "ceiling" else envelope.floor_m
        if key == "floor" and value <= 0:
            continue  # a floor at the ground: the field is flat at the origin's height
        lines.setdefault(value, []).append(name)
    return lines


def altitude_figure(
    recording: Recording,
    configs: Mapping[str, AgentConfig],
    safety: SafetyJudgement | None = None,
) -> Any | None:
    """The figure of :func:`plot_altitude`, unsaved; None when no vehicle flies."""
    names = sorted(recording.tracks)
    if not any(n in configs and configs[n].is_aircraft for n in names):
        return None
    plt = _pyplot()
    fig, ax = plt.subplots(figsize=(10, 5), dpi=100)
    colors = {name: f"C{index % 10}" for index, name in enumerate(names)}
    for name in names:
        track = recording.tracks[name]
        ax.plot(track.times_s, track.up_m, color=colors[name], linewidth=1.2, label=name)
    for key, style in (("ceiling", "--"), ("floor", ":")):
        for value, owners in sorted(_limit_lines(configs, names, key).items()):
            color = colors[owners[0]] if len(owners) == 1 else "0.3"
            ax.axhline(
                value, color=color, linestyle=style, linewidth=1.0,
                label=f"{key} {value:g} m ({', '.join(owners)})",
            )  # fmt: skip
    for vehicle in safety.vehicles if safety is not None else ():
        if vehicle.passed or vehicle.envelope is None:
            continue
        marks = []
        if vehicle.highest is not None and vehicle.highest.value > vehicle.envelope.ceiling_m:
            marks.append(("above its ceiling", vehicle.highest))
        low = vehicle.lowest_guided
        if low is not None and low.value < vehicle.envelope.floor_m:
            marks.append(("below its floor", low))
        for what, extreme in marks:
            ax.plot(
                [extreme.time_s], [extreme.value], "X", color="red", markersize=10,
                linestyle="none",
                label=f"{vehicle.name} {what}: {extreme.value:.1f} m at {extreme.time_s:.1f} s",
            )  # fmt: skip
    ax.set_xlabel("simulated time (s)")
    ax.set_ylabel("altitude above origin (m)")
    ax.set_title("Altitude above the origin, against each aircraft's ceiling and floor")
    ax.set_xlim(0, max(recording.end_s, 1e-3))
    ax.grid(True, linewidth=0.3)
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8, borderaxespad=0.0)
    fig.tight_layout()
    return fig


def plot_altitude(
    path: Path,
    recording: Recording,
    configs: Mapping[str, AgentConfig],
    safety: SafetyJudgement | None = None,
) -> bool:
    """Every vehicle's altitude over time against the aircraft's ceilings and floors.

    Floors at the ground (0 m) are not drawn. A vehicle the safety judgement found
    above its ceiling, or below its floor in guided flight, is marked there.

    Returns:
        False (no file) when the fleet has no aircraft: a rover's altitude is the ground's.
    """
    fig = altitude_figure(recording, configs, safety)
    if fig is None:
        return False
    _save(fig, path)
    return True


def _save(fig: Any, path: Path) -> None:
    """Write a figure with fixed metadata (the same run gives the same bytes), then close it."""
    fig.savefig(path, metadata=_PNG_METADATA)
    _pyplot().close(fig)


def channel_function(config: AgentConfig | None, label: str) -> str | None:
    """What a recorded signal's channel does (``aileron`` for ``rc1`` on a plane).

    Read from the agent's compiled channel map (its autopilot profile's ``channels:``,
    overlaid by the platform's and the mission's); None when no channel has that number.

    Args:
        config: The agent's compiled config; None gives None.
        label: The recorded signal's key: ``rcN`` (an RC input) or ``servoN`` (an output).
    """
    found = _SIGNAL_LABEL.fullmatch(label)
    if config is None or found is None:
        return None
    via, number = found.group(1), int(found.group(2))
    for name, spec in config.channels.items():
        if (spec.servo if via == "servo" else spec.rc) == number:
            return name
    return None


def inputs_figure(recording: Recording, configs: Mapping[str, AgentConfig]) -> Any | None:
    """The figure of :func:`plot_inputs`, unsaved; None when no signal was recorded."""
    series = {key: values for key, values in sorted(recording.signals.items()) if values}
    if not series:
        return None
    plt = _pyplot()
    fig, axes = plt.subplots(len(series), 1, figsize=(9, 2.4 * len(series)), dpi=100, squeeze=False)
    for ax, ((agent, channel), values) in zip(axes[:, 0], series.items(), strict=True):
        ax.step([t for t, _ in values], [v for _, v in values], where="post", linewidth=1)
        function = channel_function(configs.get(agent), channel)
        name = f"{agent} {function}\n({channel}, us)" if function else f"{agent} {channel} (us)"
        ax.set_ylabel(name)
        ax.grid(True, linewidth=0.3)
    axes[-1, 0].set_xlabel("simulated time (s)")
    fig.suptitle("Control inputs received by the autopilots")
    fig.tight_layout()
    return fig


def plot_inputs(path: Path, recording: Recording, configs: Mapping[str, AgentConfig]) -> bool:
    """The control signals the autopilots received; False (no file) when there were none.

    Each is named by its channel's function in the vehicle's profile (``cub aileron
    (rc1, us)``), with the channel number it was read on.
    """
    fig = inputs_figure(recording, configs)
    if fig is None:
        return False
    _save(fig, path)
    return True


def states_label(active: Sequence[str]) -> str:
    """Active leaf states as the report shows them.

    A behaviour that is one primitive or block has one state, the root, whose path is
    empty: it is named rather than shown blank.
    """
    if not active:
        return "(none)"
    return ", ".join(path or "(the whole behaviour)" for path in active)


#: Hatches that tell fault windows apart on the timeline, and markers for safety events.
_HATCHES: Final = ("//", "\\\\", "xx", "..", "--", "++", "oo", "||")
_MARKERS: Final = ("v", "D", "s", "P", "X", "*", "^", "o")
#: Where a state's label may go in its row (offsets from the row's centre, in rows).
_LANES: Final = (0.0, -0.27, 0.27)


def _fault_label(fault: InjectedFault) -> str:
    when = fault.when()
    return (
        f"{fault.describe()} ({when})"
        if when == "the whole run"
        else f"{fault.describe()} ({when} s)"
    )


def timeline_figure(recording: Recording, faults: Sequence[InjectedFault] = ()) -> Any:
    """The figure of :func:`plot_timeline`, unsaved.

    Fault windows are hatched (on the rows of the agents they strike, or across every
    row for the fleet's), safety events (failsafes, autopilot lost) are markers on their
    agent's row; both are named in a legend beside the plot, so their labels never
    overlap. States are named inside their bars where a label fits without touching
    another (:func:`_place_labels`); ``summary.md``'s timeline lists them all.
    """
    plt = _pyplot()
    from matplotlib.patches import Rectangle

    agents = sorted(a for a, entries in recording.states.items() if entries)
    rows = {agent: row for row, agent in enumerate(agents)}
    end_s = max(recording.end_s, 1e-3)
    events = [(t, agent, what) for agent, seen in recording.safety.items() for t, what in seen]
    entries_in_legend = len(faults) + len(events)
    height = max(1.0 + 0.8 * max(1, len(agents)), 0.8 + 0.17 * entries_in_legend)
    fig, ax = plt.subplots(figsize=(12 if entries_in_legend else 10, height), dpi=100)
    palette: dict[str, str] = {}
    labels: list[tuple[float, int, str]] = []
    for agent, row in rows.items():
        entries = recording.states[agent]
        for i, entry in enumerate(entries):
            end = entries[i + 1].time_s if i + 1 < len(entries) else recording.end_s
            label = states_label(entry.active)
            color = palette.setdefault(label, f"C{len(palette) % 10}")
            ax.broken_barh(
                [(entry.time_s, max(end - entry.time_s, 1e-3))], (row - 0.4, 0.8), facecolors=color
            )
            if end - entry.time_s > end_s / 80:
                labels.append((entry.time_s, row, label))
    for index, fault in enumerate(faults):
        start, stop = fault.window(end_s)
        hatch = _HATCHES[index % len(_HATCHES)]
        struck = [rows[a] for a in fault.agents if a in rows]
        if stop <= start:
            stop = start  # after the run's end, or a kill at it: named, not drawn
        if struck:
            for k, row in enumerate(struck):
                ax.add_patch(
                    Rectangle(
                        (start, row - 0.45), stop - start, 0.9, fill=False, hatch=hatch,
                        edgecolor="0.15", linewidth=0.8,
                        label=_fault_label(fault) if k == 0 else "_nolegend_",
                    )
                )  # fmt: skip
        else:
            ax.axvspan(
                start, stop, fill=False, hatch=hatch, edgecolor="0.75", linewidth=0.0, zorder=0,
                label=_fault_label(fault),
            )  # fmt: skip
    for index, (t, agent, what) in enumerate(sorted(events)):
        ax.plot(
            [t], [rows.get(agent, -0.5)], _MARKERS[index % len(_MARKERS)], color="black",
            markerfacecolor="white", markersize=7, linestyle="none",
            label=f"{agent}: {what} at {t:.1f} s",
        )  # fmt: skip
    ax.set_yticks(range(len(agents)), agents)
    ax.set_ylim(-0.6, max(len(agents), 1) - 0.4)
    ax.set_xlabel("simulated time (s)")
    ax.set_title("Behaviour states, fault windows and safety events")
    ax.set_xlim(0, end_s)
    if entries_in_legend:
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=7, borderaxespad=0.0)
    fig.tight_layout()
    _place_labels(fig, ax, labels, end_s)
    return fig


def _place_labels(
    fig: Any, ax: Any, labels: Sequence[tuple[float, int, str]], end_s: float
) -> None:
    """Name states inside the plot where a label touches no other: else it is left out.

    Each label starts at its state's entry, on the first of its row's lanes
    (:data:`_LANES`) where it stays within the axes and clear of every label placed
    before it. Runs once the layout is final, since it measures text on the canvas.
    """
    renderer = fig.canvas.get_renderer()
    frame = ax.get_window_extent(renderer)
    placed: list[Any] = []
    for start, row, label in sorted(labels, key=lambda item: (item[1], item[0])):
        for lane in _LANES:
            text = ax.text(start + end_s * 0.004, row + lane, label, va="center", fontsize=7)
            box = text.get_window_extent(renderer)
            inside = box.x1 <= frame.x1 and box.y0 >= frame.y0 and box.y1 <= frame.y1
            if inside and not any(box.overlaps(other) for other in placed):
                placed.append(box)
                break
            text.remove()


def plot_timeline(path: Path, recording: Recording, faults: Sequence[InjectedFault] = ()) -> None:
    """One row per agent, a bar per state it was in; fault windows and safety events."""
    _save(timeline_figure(recording, faults), path)


def timeline_text(recording: Recording) -> str:
    """Every state change of every agent, as a Markdown table."""
    lines = ["| time (s) | agent | event | active states |", "|---:|---|---|---|"]
    rows = [
        (entry.time_s, agent, entry.event, states_label(entry.active))
        for agent, entries in recording.states.items()
        for entry in entries
    ]
    for t, agent, event, active in sorted(rows):
        lines.append(f"| {t:.2f} | {agent} | {event} | {active} |")
    return "\n".join(lines) + "\n"


PACE_LATE_S: Final = 3.0
"""A SITL run whose engine fell further behind SITL's clock than this says so plainly: it
heard SITL that late, and its commands and heartbeats reached SITL late (three heartbeat
periods, thirty ticks at 10 Hz; with a heartbeat period more of silence, that is a second
short of the 5 s after which ArduPilot's ground-station failsafe acts). A busy machine puts
a run on time a second or two behind now and then; the run slows SITL down at 2 s
(:data:`~clark_engine.dryrun.sitl_pace.BEHIND_S`)."""


def pace_lines(pace: Mapping[str, Pace]) -> list[str]:
    """One line per SITL vehicle: how far behind SITL's clock the engine fell.

    For the run's output and its summary: a run that could not keep SITL's pace is not
    the mission's flight on ArduPilot, and must not pass for one.
    """
    lines = []
    for name, kept in pace.items():
        silence = f"its link to the autopilot silent {kept.silent_s:.1f} s at most"
        if kept.speedups:
            steps = ", ".join(f"{speedup:.3g}x at {t_s:.1f} s" for t_s, speedup in kept.speedups)
            silence += (
                f"; SITL's speed-up went from {kept.start_speedup:g}x to {steps} of the run, "
                "slowed where the engine fell behind it"
            )
        if kept.behind_s > PACE_LATE_S:
            lines.append(
                f"warning: {name}: the engine fell {kept.behind_s:.1f} s behind ArduPilot "
                f"SITL's clock (at {kept.behind_at_s:.1f} s of the run), too busy for this "
                f"speed-up: it heard SITL late and its commands and heartbeats reached it late "
                f"({silence}; ArduPilot's ground-station failsafe acts after its timeout), so "
                "this is not the mission's flight on ArduPilot; lower --sitl-speedup"
            )
        else:
            lines.append(
                f"{name}: the engine kept ArduPilot SITL's pace ({kept.behind_s:.1f} s behind "
                f"its clock at most; {silence})"
            )
    return lines


def safety_section(safety: SafetyJudgement) -> list[str]:
    """``summary.md``'s Safety section: what was judged, each breach, the two tables."""
    breaches = safety.breaches
    lines = [
        "## Safety",
        "",
        "Every vehicle against its envelope and every pair against its separation, from the "
        "true tracks, whether or not the mission checks it (docs/dry-run.md#safety). "
        + (f"**{count_breaches(len(breaches))}: the run fails.**" if breaches else "No breach."),
        "",
    ]
    lines += [f"- {breach}" for breach in breaches]
    if breaches:
        lines.append("")
    lines.append(safety.table())
    return lines


def write_summary(
    path: Path,
    *,
    mission: str,
    seed: int,
    end_s: float,
    wall_s: float,
    results: Sequence[CheckResult],
    recording: Recording,
    latency: str,
    plots: Sequence[str],
    comparison: str | None = None,
    origin: RunOrigin | None = None,
    links_note: str = "",
    safety: SafetyJudgement | None = None,
) -> None:
    """``summary.md``: how the run was made, the checks, safety, the timeline, the links.

    ``origin``: the command line and the injected faults (none shown when None).
    ``links_note``: Markdown under the link tables: what "deviation from ideal" means
    (:func:`clark_engine.analysis.latency.explain_deviation`).
    ``comparison``: with ``--autopilot sitl``, the tables of each agent's states and each
    check's figures on SITL and on the simulated autopilot
    (:meth:`~clark_engine.dryrun.timeline.Comparison.table`).
    ``safety``: the run's safety judgement, in a section of its own after the checks.
    """
    passed = sum(r.passed for r in results)
    failed = sum(r.evaluated and not r.passed for r in results)
    skipped = sum(not r.evaluated for r in results)
    verdict = f"{failed} failed" if failed else "no check failed"
    if skipped:
        verdict += f", {skipped} not evaluated: the run ended before their by_s"
    elif not failed:
        verdict = "all checks pass"
    if safety is not None and not safety.passed:
        verdict += f"; safety: {count_breaches(len(safety.breaches))}, so the run fails"
    how = "Command line" if origin is None or origin.command_given else "Equivalent command"
    text = [
        f"# Dry run of {mission}",
        "",
        *([f"{how}: `{origin.command}`", ""] if origin is not None else []),
        f"Seed {seed}; {end_s:g} simulated seconds in {wall_s:.1f} s of wall time "
        f"({end_s / wall_s if wall_s > 0 else float('inf'):.0f}x real time); "
        f"{passed} of {len(results)} checks pass ({verdict}).",
        "",
        *(
            ["## Drawn values", "", drawn_table(origin.drawn)]
            if origin is not None and origin.drawn
            else []
        ),
        "## Injected faults",
        "",
        faults_table(origin.faults if origin is not None else ()),
        "## Checks",
        "",
        checks_table(results) if results else "The mission declares no checks.\n",
        *(safety_section(safety) if safety is not None else []),
        "## Plots",
        "",
        *[f"![{p}]({p})" for p in plots],
        "",
        "## State timeline",
        "",
        timeline_text(recording),
        *(
            [
                "## ArduPilot SITL against the simulated autopilot",
                "",
                "Each state's first entry in this run (SITL) and in the same mission on the "
                "simulated autopilot: the difference judged is the entry's or the leg's "
                "(the time since the agent's previous state change), whichever is smaller, "
                "against a share of SITL's leg; how far apart the vehicle was then (and at "
                "the end of the run) and its altitude on SITL minus simulated; then each "
                "check's verdict and figures in both runs "
                '(docs/autopilot-fidelity.md, "The same mission both ways").',
                "",
                *[f"- {line}" for line in pace_lines(recording.pace)],
                *([""] if recording.pace else []),
                comparison,
            ]
            if comparison is not None
            else []
        ),
        "## Links (clark analyze)",
        "",
        "```",
        latency.rstrip(),
        "```",
        "",
        *([links_note] if links_note else []),
    ]
    path.write_text("\n".join(text), encoding="utf-8")
