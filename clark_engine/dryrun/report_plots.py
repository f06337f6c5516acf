"""The dry run's plots: tracks, altitude, control inputs and the state timeline.

``tracks.png``, ``altitude.png``, ``inputs.png`` and ``timeline.png`` of the report
(:mod:`clark_engine.dryrun.report`, which writes the folder and the text). Kept apart from
the text because they are the one part that needs matplotlib (imported when a plot is
drawn, on its non-interactive Agg backend) and whose bytes depend on its version; files
are written with fixed metadata so the same run gives the same bytes.
"""

from __future__ import annotations

import re
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from clark_engine.behaviors import behaviors
from clark_engine.dryrun.report import InjectedFault, states_label
from clark_engine.expectations.recording import Recording
from clark_engine.expectations.safety import PairSafety, SafetyJudgement
from clark_engine.runtime.config import AgentConfig

#: PNG metadata without the matplotlib version or a date, for reproducible files.
_PNG_METADATA = {"Software": None}

#: A recorded signal's key: an RC input (``rc1``) or a servo output (``servo3``).
_SIGNAL_LABEL: Final = re.compile(r"(rc|servo)([0-9]+)")


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
