"""``clark dry-run``: validate, simulate, evaluate the checks, write the report.

This is the command's logic, apart from argument parsing: it turns a mission
file into a verdict. Every run is also judged against each vehicle's safety envelope
(:mod:`clark_engine.expectations.safety`), whether or not the mission declares a check. Exit
codes: 0 when every check holds and nothing left its envelope, 1 when a check fails,
a vehicle breached its envelope or the mission is invalid, 2 for usage errors (and a
SITL that cannot be started).

With ``--autopilot sitl`` every vehicle's autopilot is real ArduPilot SITL
(:mod:`clark_engine.dryrun.sitl_backend`); the mission is then also simulated on the
simulated autopilot, and the two runs are compared (:mod:`clark_engine.dryrun.timeline`):
each state's entry time, where each vehicle was then and at the end, and the checks'
verdicts and figures; one more row in the checks table.

With ``--realtime --station`` the station agent's live web view is served over the run
(a :class:`LiveView`, :mod:`clark_engine.station.rehearsal_view`, handed in by the command line so
that the simulator does not import the web server): opened before anything is
simulated or written, fed by the run, given the verdicts at the end, stopped last.
"""

from __future__ import annotations

import dataclasses
import shlex
import sys
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final, Protocol, TextIO

from clark_engine.dryrun.engine import DryRun, DryRunResult
from clark_engine.dryrun.rehearsal import (
    DEFAULT_HOST,
    MavlinkBridge,
    StopSwitch,
    stop_on_interrupt,
    vehicle_names,
)
from clark_engine.dryrun.report import (
    InjectedFault,
    ReportFolder,
    RunOrigin,
    drawn_line,
    equivalent_command,
    pace_lines,
    write_summary,
)
from clark_engine.dryrun.report_plots import plot_altitude, plot_inputs, plot_timeline, plot_tracks
from clark_engine.dryrun.sitl_backend import SitlBackend
from clark_engine.dryrun.timeline import Comparison, Tolerance, compare
from clark_engine.errors import UsageError
from clark_engine.expectations.evaluate import CheckResult, checks_table, evaluate
from clark_engine.expectations.safety import SafetyJudgement, count_breaches
from clark_engine.expectations.safety import judge as judge_safety
from clark_engine.mission.faults import FAULT_HELP as FAULT_FORMS
from clark_engine.mission.faults import MAX_FAULT_TEXT, FaultError, parse_fault_text
from clark_engine.mission.model import Mission
from clark_engine.mission.variation import (
    Drawn,
    VaryError,
    mission_varied_fields,
    parse_vary,
    resolve_mission,
)
from clark_engine.sim.ardupilot.airframes.base import DEFAULT_GPS_NOISE_M
from clark_engine.sitl.errors import SitlError
from clark_engine.sitl.launcher import SitlInstall
from clark_engine.validation import mission_to_fly

DEFAULT_DURATION_S: Final = 300.0
"""A mission's simulated duration when its ``sim.duration_s`` says none."""

DEFAULT_SITL_SPEEDUP: Final = 10.0
"""SITL's speed-up when ``--sitl-speedup`` is not given: a 3-minute mission in about
20 s, while ArduPilot still keeps its loop rates on a busy 2-core machine."""

FAULT_HELP = f"a fault: {FAULT_FORMS}"


def parse_fault(text: str) -> dict[str, Any]:
    """A command-line fault (``kill:slash_a@30``) in the mission's fault form.

    The grammar and its rules are the mission's own (:mod:`clark_engine.mission.faults`).

    Raises:
        UsageError: Not one of the forms in :data:`FAULT_HELP`, or a rule broken (a
            reversed window, a share outside 0..1, a link from an agent to itself).
    """
    try:
        return parse_fault_text(text)
    except FaultError as exc:
        shown = text if len(text) <= MAX_FAULT_TEXT else text[:MAX_FAULT_TEXT] + "..."
        verdict = "" if exc.broken_rule else " is not a fault"
        raise UsageError(f"--fault {shown!r}{verdict}: {exc.message}") from None


class LiveView(Protocol):
    """A view served over a real-time dry run: the station's page of a rehearsal.

    :class:`~clark_engine.station.rehearsal_view.Rehearsal` is one; it is opened (its server
    started) before anything is simulated or written.
    """

    @property
    def url(self) -> str:
        """The page's address, to print."""
        ...

    @property
    def station(self) -> str:
        """The station agent whose view it is."""
        ...

    def attach(self, run: DryRun) -> None:
        """Feed the view from ``run`` (not started yet)."""
        ...

    def finish(self, results: Sequence[CheckResult], end_s: float) -> None:
        """The run is over: show its verdicts and send the last state."""
        ...

    def stop(self) -> None:
        """Stop serving (after :meth:`finish`, or on an error or interrupt)."""
        ...


#: Opens a :class:`LiveView` over a validated mission (mission, mission file); raises
#: UsageError when it cannot be served (a port in use), ClarkError when the mission
#: cannot have one (no station).
LiveViewOpener = Callable[[Mission, Path], LiveView]


@dataclass(slots=True)
class Outcome:
    """A dry run's verdict."""

    exit_code: int
    results: list[CheckResult]
    result: DryRunResult | None
    comparison: Comparison | None = None
    """With SITL: its states against the simulated autopilot's."""
    safety: SafetyJudgement | None = None
    """Every vehicle against its envelope and every pair against its separation."""
    drawn: Drawn = field(default_factory=dict)
    """The mission's varied values as this run drew them (or ``vary`` fixed them), by path
    (:mod:`clark_engine.mission.variation`)."""


class _Progress:
    """Progress on a stream, for a terminal or for a log.

    On a terminal, a one-line bar redrawn in place (a carriage return); elsewhere (a
    CI log, a file), a plain line every :attr:`PLAIN_EVERY` calls, never a carriage return.

    The engine calls it about once a wall-clock second.
    """

    PLAIN_EVERY: Final = 10
    """Calls between two plain lines: about one line per 10 s of wall-clock time."""

    def __init__(self, stream: TextIO, terminal: bool = True) -> None:
        self.stream = stream
        self.terminal = terminal
        self.shown = False
        self.calls = 0

    def __call__(self, t_s: float, end_s: float) -> None:
        self.calls += 1
        share = t_s / end_s if end_s else 1.0
        if self.terminal:
            bar = "#" * int(share * 30)
            self.stream.write(f"\r  simulating [{bar:<30}] {t_s:7.1f} / {end_s:g} s")
            self.shown = True
        elif self.calls % self.PLAIN_EVERY == 0:
            self.stream.write(f"  simulated {t_s:.1f} of {end_s:g} s ({share:.0%})\n")
        self.stream.flush()

    def finish(self) -> None:
        """End the bar's line, if it was ever drawn (a run under a second never draws it).

        Called on every way out, Ctrl-C included, so what follows starts on its own line.
        """
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()
            self.shown = False


def run_dry_run(
    mission_path: Path,
    *,
    seed: int | None,
    until_s: float | None,
    report: Path | None,
    speed: float | None,
    faults: Sequence[str] = (),
    realtime_base_port: int | None = None,
    realtime_host: str = DEFAULT_HOST,
    sitl: SitlInstall | None = None,
    sitl_speedup: float = DEFAULT_SITL_SPEEDUP,
    realtime: bool = False,
    out: TextIO | None = None,
    err: TextIO | None = None,
    quiet: bool = False,
    command_line: Sequence[str] | None = None,
    station_view: LiveViewOpener | None = None,
    operator_script: bool = True,
    vary: Sequence[str] = (),
) -> Outcome:
    """Validate the mission, simulate it, evaluate its checks and write the report.

    Args:
        mission_path: The mission file.
        seed: Seeds every random draw; the mission's ``sim.seed`` when None.
        until_s: Simulated seconds to run; the mission's ``sim.duration_s`` when None.
        report: Folder for logs, CSV, plots and ``summary.md``; none written when None.
            Written whole beside it and moved into place when complete
            (:class:`~clark_engine.dryrun.report.ReportFolder`): an interrupted run leaves
            it as it was; a folder holding files the engine did not write is refused.
        speed: Simulated seconds per wall-clock second; as fast as possible when None.
        faults: Command-line faults (:data:`FAULT_HELP`).
        realtime_base_port: Real time with a ground station: run at wall-clock speed
            (``speed`` is ignored) with vehicle k's simulated autopilot on UDP port
            BASE + k (:mod:`clark_engine.dryrun.rehearsal`); Ctrl-C ends the run early
            and the report is still written. Off when None.
        realtime_host: The address those ports are bound to (loopback by default).
        sitl: Fly every vehicle's autopilot as ArduPilot SITL from this install, and
            compare the states with a simulated run's; the simulated autopilot when None.
        sitl_speedup: SITL's speed-up (``speed`` does not apply: SITL sets the pace).
        realtime: Real time. With ``sitl``: SITL at real time, each vehicle's SERIAL1
            free for a ground station. Without SITL: wall-clock speed, with
            ``realtime_base_port`` or ``station_view`` (or both). Ctrl-C ends the run
            early and the report is still written.
        out: Where the checks table goes; ``sys.stdout`` (as it is at the call) when None.
        err: Where progress and diagnostics go; ``sys.stderr`` when None.
        quiet: Hide the mission's warnings (``--quiet``); errors are always shown.
        command_line: The command as typed (``clark dry-run ...``), for the report's
            summary; when None the summary gives the equivalent command instead.
        station_view: Serve the station agent's live view over the run (``--station``,
            with ``realtime``): opened once the mission is validated, before anything
            is simulated or written. The verdicts and the exit code are the same.
        operator_script: Play the mission's operator actions for the station; False
            leaves them to the person at the station's view (the pilots' ``rc``
            actions still play).
        vary: ``PATH=VALUE`` texts (``--vary``) that fix varied values of the mission
            instead of drawing them (:mod:`clark_engine.mission.variation`).

    Raises:
        UsageError: Unreadable mission, bad fault, a ``--vary`` naming no value of the
            mission or out of its range, a report folder that cannot be made
            or holds files the engine did not write,
            (in real time) no vehicle or a port that cannot be bound, or a SITL that
            cannot be started or stops answering.
        ClarkError: ``station_view`` for a mission without a station agent.
    """
    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    extra = [parse_fault(text) for text in faults]
    mission = mission_to_fly(mission_path, err, quiet=quiet, nothing="nothing simulated")
    if mission is None:
        return Outcome(1, [], None)
    for fault in extra:
        ((kind, body),) = fault.items()
        names = [*body.get("between", []), *([body["agent"]] if "agent" in body else [])]
        for name in names:
            if name not in mission.agents:
                raise UsageError(f"--fault {kind}: there is no agent {name!r} in the mission")
    seed = int(seed if seed is not None else mission.sim.get("seed", 0))
    until = float(
        until_s if until_s is not None else mission.sim.get("duration_s", DEFAULT_DURATION_S)
    )
    try:
        fixed = parse_vary(vary, mission_varied_fields(mission))
    except VaryError as exc:
        raise UsageError(str(exc)) from None
    mission, drawn = resolve_mission(mission, seed, fixed)
    if drawn:
        print(drawn_line(seed, drawn), file=err)
    origin = RunOrigin(
        shlex.join(command_line)
        if command_line is not None
        else equivalent_command(mission_path, seed, until, faults, report, vary),
        command_line is not None,
        tuple(InjectedFault(f, "mission") for f in mission.faults)
        + tuple(InjectedFault(f, f"--fault {t}") for f, t in zip(extra, faults, strict=True)),
        tuple(drawn.items()),
    )
    folder = ReportFolder(report) if report is not None else None
    if folder is not None:
        folder.check()  # before the run: a folder it may not replace is refused at once
    try:
        return _run_and_report(
            mission, mission_path, seed, until, folder, speed, extra, realtime_base_port,
            realtime_host, sitl, sitl_speedup, realtime, out, err, origin,
            station_view, operator_script,
        )  # fmt: skip
    except KeyboardInterrupt:
        if folder is not None:
            print(f"interrupted: no report written ({folder.target} is as it was)", file=err)
        raise
    finally:
        if folder is not None:
            folder.discard()


def _run_and_report(
    mission: Mission,
    mission_path: Path,
    seed: int,
    until: float,
    folder: ReportFolder | None,
    speed: float | None,
    extra: Sequence[Mapping[str, Any]],
    realtime_base_port: int | None,
    realtime_host: str,
    sitl: SitlInstall | None,
    sitl_speedup: float,
    realtime: bool,
    out: TextIO,
    err: TextIO,
    origin: RunOrigin,
    station_view: LiveViewOpener | None = None,
    operator_script: bool = True,
) -> Outcome:
    """:func:`run_dry_run` once the mission is loaded: run, evaluate, write the report."""
    # Real time: bind the ports and start the view first, so a port in use is reported
    # before anything is written.
    bridge = (
        MavlinkBridge(vehicle_names(mission), realtime_base_port, host=realtime_host)
        if realtime_base_port is not None
        else None
    )
    try:
        view = station_view(mission, mission_path) if station_view is not None else None
    except BaseException:
        if bridge is not None:
            bridge.close()
        raise
    try:
        return _run_live(
            mission, mission_path, seed, until, folder, speed, extra, bridge, view, sitl,
            sitl_speedup, realtime, out, err, origin, operator_script,
        )  # fmt: skip
    finally:
        if view is not None:
            view.stop()  # the page gets the last state; after finish() it already has


def _run_live(
    mission: Mission,
    mission_path: Path,
    seed: int,
    until: float,
    folder: ReportFolder | None,
    speed: float | None,
    extra: Sequence[Mapping[str, Any]],
    bridge: MavlinkBridge | None,
    view: LiveView | None,
    sitl: SitlInstall | None,
    sitl_speedup: float,
    realtime: bool,
    out: TextIO,
    err: TextIO,
    origin: RunOrigin,
    operator_script: bool,
) -> Outcome:
    """Run with the real-time pieces open (ports, view), evaluate, write the report."""
    # A real-time run without MAVLink ports (SITL's, or a rehearsal's view alone) still
    # ends at Ctrl-C; the bridge has a switch of its own.
    switch = StopSwitch() if realtime and bridge is None else None
    simulated: DryRunResult | None = None
    try:
        log_dir = folder.open() if folder is not None else None
        if sitl is None:
            result = _simulate(
                mission, mission_path, seed, until, log_dir, speed, extra, bridge, err,
                view=view, switch=switch, operator_script=operator_script,
            )  # fmt: skip
        else:
            # The simulated autopilot first (seconds), so a SITL run has something to meet;
            # in SITL's world (what SITL cannot be given is held equal).
            held = held_equal_for_sitl(mission)
            if held:
                print(
                    "  note: compared with a simulated run without "
                    + "; ".join(held.values())
                    + ", as SITL flies",
                    file=err,
                )
            simulated = DryRun(
                as_sitl_flies(mission),
                mission_path,
                seed=seed,
                until_s=until,
                extra_faults=extra,
                operator_script=operator_script,
            ).run()
            result = _fly_sitl(
                mission,
                mission_path,
                seed,
                until,
                log_dir,
                extra,
                sitl,
                1.0 if realtime else sitl_speedup,
                switch,
                err,
                view=view,
                operator_script=operator_script,
            )
    except SitlError as exc:
        raise UsageError(str(exc)) from None
    finally:
        if bridge is not None:
            bridge.close()
    stopper = bridge if bridge is not None else switch
    if stopper is not None and stopper.stopped_at_s is not None:
        print(
            f"stopped at {stopper.stopped_at_s:.1f} s of {until:g} s ({stopper.stopped_by})",
            file=err,
        )
    until = min(until, result.recording.end_s)  # earlier when Ctrl-C ended a real-time run
    _say_unplayed(mission, until, err)
    planned_end_s = float(mission.sim.get("duration_s", DEFAULT_DURATION_S))
    results = evaluate(
        mission.checks, result.recording, result.configs, mission.origin, planned_end_s
    )
    safety = judge_safety(result.recording, result.configs)
    comparison = None
    if simulated is not None:
        # The mission's checks on the simulated run too, their verdicts and figures compared;
        # not when a SITL run was ended early (the simulated one went on to its end).
        whole = until >= simulated.recording.end_s - 1e-9
        ours = evaluate(
            mission.checks, simulated.recording, simulated.configs, mission.origin, planned_end_s
        )
        comparison = compare(
            simulated.recording,
            result.recording,
            vehicle_names(mission),
            Tolerance.from_sim(mission.sim),
            end_s=until,
            aircraft=[n for n, c in result.configs.items() if c.is_aircraft],
            checks=(ours, results) if whole else None,
        )
        results.append(comparison.check())
    if view is not None:
        # The page shows the report's verdicts, safety's too, then stops updating.
        view.finish([*results, *safety.results()], until)
    rate = until / result.wall_s if result.wall_s > 0 else float("inf")
    print(f"simulated {until:g} s in {result.wall_s:.1f} s ({rate:.0f}x real time)", file=err)
    for line in pace_lines(result.recording.pace):
        print(f"  {line}", file=err)
    if results:
        out.write(checks_table(results))
    else:
        print("the mission declares no checks", file=out)
    out.write("\nSafety (judged in every run):\n\n" + safety.table())
    if folder is not None:
        _write_report(
            folder.folder, mission.name, seed, until, result, results, comparison, origin, safety
        )
        folder.commit()
        print(f"report: {folder.target / 'summary.md'}", file=err)
    failed = [r for r in results if r.evaluated and not r.passed]
    skipped = [r for r in results if not r.evaluated]
    if skipped:
        print(
            f"{len(skipped)} of {len(results)} checks not evaluated: the run ended before "
            "their by_s (run longer, or without --until, to judge them)",
            file=err,
        )
    if failed:
        print(f"{len(failed)} of {len(results)} checks failed", file=err)
    breaches = safety.breaches
    if breaches:
        print(f"safety: {count_breaches(len(breaches))}; the run fails:", file=err)
        for breach in breaches:
            print(f"  {breach}", file=err)
    code = 1 if failed or breaches else 0
    return Outcome(code, results, result, comparison, safety, dict(origin.drawn))


def _simulate(
    mission: Mission,
    mission_path: Path,
    seed: int,
    until_s: float,
    log_dir: Path | None,
    speed: float | None,
    faults: Sequence[Mapping[str, Any]],
    bridge: MavlinkBridge | None,
    err: TextIO,
    *,
    view: LiveView | None = None,
    switch: StopSwitch | None = None,
    operator_script: bool = True,
) -> DryRunResult:
    """Run the simulation, the agents logging to ``log_dir``.

    In real time with a bridge (MAVLink ports), a view (the station's page), or both;
    ``switch`` ends a real-time run without a bridge at Ctrl-C.
    """
    progress = _progress_for(err, until_s)
    try:
        return _simulate_with(
            mission, mission_path, seed, until_s, log_dir, speed, faults, bridge, err, progress,
            view, switch, operator_script,
        )  # fmt: skip
    finally:
        if progress is not None:
            progress.finish()  # also on Ctrl-C: what follows starts on its own line


def _simulate_with(
    mission: Mission,
    mission_path: Path,
    seed: int,
    until_s: float,
    log_dir: Path | None,
    speed: float | None,
    faults: Sequence[Mapping[str, Any]],
    bridge: MavlinkBridge | None,
    err: TextIO,
    progress: _Progress | None,
    view: LiveView | None,
    switch: StopSwitch | None,
    operator_script: bool,
) -> DryRunResult:
    realtime = bridge is not None or view is not None
    print(
        f"dry run of {mission.name}: {len(mission.agents)} agents, {until_s:g} s, seed {seed}",
        file=err,
    )
    run = DryRun(
        mission,
        mission_path,
        seed=seed,
        until_s=until_s,
        log_dir=log_dir,
        extra_faults=faults,
        progress=progress,
        speed=1.0 if realtime else speed,
        wall_clock=bridge is not None,
        operator_script=operator_script,
    )
    if not realtime:
        result = run.run()
    else:
        # Wall-clock speed, each vehicle on its port; the ports (and the view) were opened
        # before the clock starts, so a station may connect first. Ctrl-C ends the run early.
        stop = bridge.stop if bridge is not None else None
        if bridge is not None:
            bridge.attach(run)
        elif switch is not None:
            switch.attach(run)
            stop = switch.stop
        if view is not None:
            view.attach(run)
            _announce_view(view, err)
        for endpoint in bridge.endpoints if bridge is not None else ():
            print(
                f"  {endpoint.agent}: MAVLink on udp {endpoint.address} (system id "
                f"{endpoint.system_id}); e.g. mavproxy.py --master=udpout:{endpoint.address}",
                file=err,
            )
        endpoints = bridge.endpoints if bridge is not None else []
        shared = len({e.system_id for e in endpoints}) < len(endpoints)
        if shared:
            print(
                "  note: vehicles share a system id, so a station connected to several of them "
                "takes them for one; give each its own (hardware: {autopilot: {mavlink: "
                "{system_id: N}}}) to watch them together",
                file=err,
            )
        if stop is None:  # not expected: the caller gives a switch when there is no bridge
            raise ValueError("a real-time run needs a bridge or a stop switch")
        with stop_on_interrupt(stop):
            print("real time: Ctrl-C ends the run early (the report is still written)", file=err)
            result = run.run()
    return result


def _say_unplayed(mission: Mission, end_s: float, err: TextIO) -> None:
    """One line for the operator's actions the run ended before: never played, said so."""
    late = [item for item in mission.operator if float(item["at_s"]) > end_s + 1e-9]
    if not late:
        return
    first = min(float(item["at_s"]) for item in late)
    print(
        f"operator: {len(late)} action(s) not played: the run ended at {end_s:g} s, before "
        f"them (the first at {first:g} s)",
        file=err,
    )


def _announce_view(view: LiveView, err: TextIO) -> None:
    """Where the station's page is (with its token, as ``clark run`` prints it)."""
    print(f"  {view.station}: station view at {view.url}", file=err, flush=True)


def _progress_for(err: TextIO, until_s: float) -> _Progress | None:
    """A progress bar on a terminal; plain lines now and then for a long run into a log.

    None (no progress shown) for a short run that is not on a terminal.
    """
    interactive = err.isatty() if hasattr(err, "isatty") else False
    if interactive:
        return _Progress(err, terminal=True)
    return _Progress(err, terminal=False) if until_s > 60 else None


SITL_LACKS: Final[Mapping[str, str]] = {
    "jitter.ready_s": "the readiness jitter (sim.jitter.ready_s: SITL boots on its own time)",
    "gps_noise_m": "the GPS's white noise (sim.gps_noise_m: SITL's GPS has none)",
    "wind.gusts": "the gusts (sim.wind.gusts: SITL has no gust model)",
}
"""What a simulated run has and SITL cannot be given: the comparison's simulated run
(``--autopilot sitl``) is run without it, so that the two runs differ by their autopilots
and vehicles, not by their worlds."""


def held_equal_for_sitl(mission: Mission) -> dict[str, str]:
    """Of :data:`SITL_LACKS`, what ``mission`` (its distributions drawn) declares: key -> why."""
    sim = mission.sim
    jitter = sim.get("jitter") or {}
    gusts = (sim.get("wind") or {}).get("gusts") or {}
    declared = {
        "jitter.ready_s": float(jitter.get("ready_s", 0.0)) > 0.0,
        "gps_noise_m": float(sim.get("gps_noise_m", DEFAULT_GPS_NOISE_M)) > 0.0,
        "wind.gusts": float(gusts.get("speed_mps", 0.0)) > 0.0,
    }
    return {key: why for key, why in SITL_LACKS.items() if declared[key]}


def as_sitl_flies(mission: Mission) -> Mission:
    """``mission`` (its distributions drawn) without what SITL cannot be given.

    The simulated run that ``--autopilot sitl`` compares SITL's with: no readiness
    jitter (SITL boots on its own time), no white GPS noise (SITL's GPS has none; the
    slow ``sim.gps_error`` is played to SITL and stays), no gusts (SITL has no gust
    model). The operator's and the pilot's jitter, the radio and the faults act in the
    engine and so apply to both runs alike; the seed is the same. A declared
    ``sim.autopilot_ready_s`` stays: it is the user's own choice of a quicker
    simulated boot, and the run says its timelines will differ.
    """
    held = held_equal_for_sitl(mission)
    if not held:
        return mission
    sim = dict(mission.sim)
    if "jitter.ready_s" in held:
        sim["jitter"] = {**sim["jitter"], "ready_s": 0}
    if "gps_noise_m" in held:
        sim["gps_noise_m"] = 0
    if "wind.gusts" in held:
        sim["wind"] = {k: v for k, v in sim["wind"].items() if k != "gusts"}
    return dataclasses.replace(mission, sim=sim)


def _fly_sitl(
    mission: Mission,
    mission_path: Path,
    seed: int,
    until_s: float,
    log_dir: Path | None,
    faults: Sequence[Mapping[str, Any]],
    install: SitlInstall,
    speedup: float,
    switch: StopSwitch | None,
    err: TextIO,
    *,
    view: LiveView | None = None,
    operator_script: bool = True,
) -> DryRunResult:
    """The run with every vehicle's autopilot on ArduPilot SITL (one process each).

    With a ``switch`` (real time), Ctrl-C ends the run early and each vehicle's
    SERIAL1 is announced for a ground station; a ``view`` (real time too) serves the
    station's page over it.

    Raises:
        SitlError: A SITL could not be started or stopped answering.
    """
    progress = _progress_for(err, until_s)
    if mission.sim.get("autopilot_ready_s") is not None:
        print(
            f"  note: sim.autopilot_ready_s ({mission.sim['autopilot_ready_s']:g} s) speeds up "
            "the simulated autopilot only; SITL takes its own time (about 42 s for ArduRover "
            "and ArduCopter, 23 s for ArduPlane), so the runs' timelines will differ",
            file=err,
        )
    print(
        f"dry run of {mission.name}: {len(mission.agents)} agents, {until_s:g} s, seed {seed}, "
        f"on ArduPilot SITL at {speedup:g}x ({install.folder})",
        file=err,
    )
    run = DryRun(
        mission,
        mission_path,
        seed=seed,
        until_s=until_s,
        log_dir=log_dir,
        extra_faults=faults,
        progress=progress,
        sitl=install,
        sitl_speedup=speedup,
        operator_script=operator_script,
    )
    try:
        if switch is None:
            result = run.run()
        else:
            switch.attach(run)
            if view is not None:
                view.attach(run)
                _announce_view(view, err)
            for name, agent in run.agents.items():
                backend = agent.backend
                if isinstance(backend, SitlBackend):
                    port = backend.process.ports.serial1_tcp_port
                    print(
                        f"  {name}: ArduPilot SITL, system id {backend.system_id}; a ground "
                        f"station connects to tcp:127.0.0.1:{port} (its SERIAL1), e.g. "
                        f"mavproxy.py --master=tcp:127.0.0.1:{port}",
                        file=err,
                    )
            with stop_on_interrupt(switch.stop):
                print(
                    "real time: Ctrl-C ends the run early (the report is still written)", file=err
                )
                result = run.run()
    finally:
        run.close()  # SITL stops even when the run never started
        if progress is not None:
            progress.finish()  # also on Ctrl-C: what follows starts on its own line
    for name, wall_s in run.preflight_wall_s.items():
        print(f"  {name}: flown up to its start point before the run, in {wall_s:.1f} s", file=err)
    for name, misses_m in run.handover_again.items():
        print(
            f"  {name}: {', '.join(f'{m:.0f}' for m in misses_m)} m off its position at time 0 "
            "(the machine held the engine back while SITL flew on): flown round again",
            file=err,
        )
    return result


def _write_report(
    report: Path,
    mission: str,
    seed: int,
    until_s: float,
    result: DryRunResult,
    results: list[CheckResult],
    comparison: Comparison | None = None,
    origin: RunOrigin | None = None,
    safety: SafetyJudgement | None = None,
) -> None:
    from clark_engine.analysis.latency import analyze_folder, explain_deviation, format_text

    plots = ["tracks.png"]
    closest = safety.closest_pair if safety is not None else None
    plot_tracks(report / "tracks.png", result.recording, result.configs, closest)
    if plot_altitude(report / "altitude.png", result.recording, result.configs, safety):
        plots.append("altitude.png")
    if plot_inputs(report / "inputs.png", result.recording, result.configs):
        plots.append("inputs.png")
    plot_timeline(
        report / "timeline.png", result.recording, origin.faults if origin is not None else ()
    )
    plots.append("timeline.png")
    # Named as the summary's reader finds it: beside summary.md, not where the report was
    # staged before it was moved into place.
    analysis = dataclasses.replace(analyze_folder(report / "logs"), folder="logs")
    write_summary(
        report / "summary.md",
        mission=mission,
        seed=seed,
        end_s=until_s,
        wall_s=result.wall_s,
        results=results,
        recording=result.recording,
        latency=format_text(analysis),
        plots=plots,
        comparison=comparison.table() if comparison is not None else None,
        origin=origin,
        links_note=explain_deviation(analysis),
        safety=safety,
    )
