"""The station's live view over a rehearsal: ``clark dry-run MISSION --realtime --station``.

The same page, protocol and security as ``clark run --view`` (docs/station-view.md),
served over the dry run's simulated fleet (or its ArduPilot SITL vehicles) at wall-clock
speed. The view's station is the dry run's station agent (the mission's first agent
that is not a vehicle, :attr:`~clark_engine.dryrun.engine.DryRun.station`): its runtime,
its fleet table, its mission log. The page's commands go out through that agent's
runtime exactly as the mission's operator actions do
(:meth:`~clark_engine.dryrun.engine.DryRun.command_station`).

How it is wired, on the simulation's one thread:

- :class:`RehearsalHost` is the :class:`~clark_engine.station.live_view.ViewHost` the view
  link needs: it chains itself onto the run's ``on_step`` hook (after whatever was
  there, the MAVLink bridge or the stop switch) and, once per station loop period of
  simulated time, calls the link's tick hook and looks at the command inbox. A
  look costs one non-blocking read of the inbox's pipe at the station's tick rate
  (10 Hz for cooperative_follow), never one per engine event.
- :class:`LiveChecks` fills the checks pane: the mission's checks evaluated on the
  recording so far (:func:`live_checks`), about once a wall-clock second, and less often
  if an evaluation ever took more than a tenth of that (so it never takes more than a
  tenth of the loop). cooperative_follow's three checks at 170 s take about 0.3 ms.
- The server thread only submits commands to the inbox; nothing else crosses threads.

When the run ends (``--until``, Ctrl-C), the checks pane gets the dry run's own verdicts
(the ones in the report) and the page the last state before the server stops.
"""

from __future__ import annotations

import dataclasses
import math
import time
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any, Final

from clark_engine.dryrun.engine import DryRun
from clark_engine.dryrun.world import SimAgent
from clark_engine.errors import ClarkError
from clark_engine.expectations.evaluate import CheckResult, evaluate
from clark_engine.expectations.recording import Recording
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.model import Mission
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.events import StationCommand
from clark_engine.runtime.log_events import LogEvent
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.station.live_view import (
    OpenView,
    StationViewLink,
    ViewSettings,
    open_view,
    settings_from_options,
)
from clark_engine.station.view_protocol import Json

DEFAULT_VIEW: Final = "127.0.0.1:8080"
"""Where ``--station`` serves the view when ``--view`` is not given: loopback, port 8080."""

CHECKS_PERIOD_S: Final = 1.0
"""Wall-clock seconds between two evaluations of the checks, at least."""

CHECKS_MAX_SHARE: Final = 0.1
"""At most this share of wall-clock time goes to evaluating checks: after an evaluation
that took ``d`` seconds the next waits ``max(CHECKS_PERIOD_S, d / CHECKS_MAX_SHARE)``."""

PASSED: Final = "passed"
FAILED: Final = "failed"
PENDING: Final = "pending"
"""Not decided yet: it may still hold, or still break, before the time it is judged at."""
NOT_EVALUATED: Final = "not evaluated"
"""At the end: the run stopped before the check's ``by_s`` (as the report says)."""

#: Kinds judged "by by_s" (checks.py's own set): once they hold they hold for good; until
#: by_s a failure so far is not a failure.
_BY_S_KINDS: Final = frozenset({"distance_m", "reached", "state", "sequence", "failsafe"})
#: Kinds judged over the whole run: once broken they are broken for good; until the end a
#: pass so far is not a pass.
_WHOLE_RUN_KINDS: Final = frozenset({"separation_m", "no_failsafe"})


def rehearsal_settings(
    view: str | None, token: str | None, token_file: str | None, update_hz: float | None
) -> ViewSettings:
    """``--station``'s view options checked: ``clark run --view``'s rules.

    ``--view`` defaults to :data:`DEFAULT_VIEW`; a token is needed off loopback.

    Raises:
        UsageError: Both token options; a bad address or token; a non-loopback address
            without a token.
    """
    return settings_from_options(view or DEFAULT_VIEW, token, token_file, update_hz)


def station_name(mission: Mission) -> str | None:
    """The agent whose view a rehearsal serves: the dry run's station (first non-vehicle)."""
    return next((a.name for a in mission.agents.values() if not a.is_vehicle), None)


# -- the checks pane -------------------------------------------------------------------------


def _kind(check: Mapping[str, Any]) -> str:
    return next(k for k in check if k not in ("name", "by_s"))


def live_checks(
    checks: Sequence[Mapping[str, Any]],
    recording: Recording,
    configs: Mapping[str, AgentConfig],
    mission: Mission,
    now_s: float,
    end_s: float,
) -> list[Json]:
    """Each check's standing ``now_s`` into a run planned to end at ``end_s``.

    Evaluated with :func:`~clark_engine.expectations.evaluate.evaluate` on the recording so far
    (each check's ``by_s`` defaulting to ``end_s``, as it would at the end), then
    classified so that ``passed`` and ``failed`` are final and only ``pending`` may
    still change:

    - a "by ``by_s``" check (distance within, reached, state, sequence, failsafe) is
      ``passed`` as soon as it held, ``pending`` until its ``by_s`` otherwise, then
      ``failed``; a distance *at* ``by_s`` (``min``) waits for ``by_s``;
    - a check over the whole run (separation, no failsafe) is ``failed`` as soon as it
      broke, ``pending`` while it holds so far;
    - photos: ``passed`` once a minimum alone is met, ``failed`` once a maximum is
      exceeded, else ``pending``;
    - a doublet's or sweep's signal is judged once its state's first visit has ended.

    Returns:
        ``{"name", "status", "detail"}`` per check, in the mission's order (the form the
        page's checks pane shows).
    """
    filled = [{**c, "by_s": float(c.get("by_s", end_s))} for c in checks]
    # No end: nothing is cut short by evaluate() itself, and an open state interval
    # stays open; the classification below decides what "so far" means.
    raw = evaluate(filled, dataclasses.replace(recording, end_s=math.inf), configs, mission.origin)
    out: list[Json] = []
    for check, result in zip(filled, raw, strict=True):
        kind = _kind(check)
        body = check[kind]
        horizon_s = float(check["by_s"]) if kind in _BY_S_KINDS else end_s
        status = _status(kind, body, result, recording, now_s, horizon_s)
        detail = result.observed
        if status == PENDING:
            detail = f"judged at {horizon_s:g} s; so far: {result.observed}"
        out.append({"name": result.name, "status": status, "detail": detail})
    return out


def _status(
    kind: str,
    body: Any,
    result: CheckResult,
    recording: Recording,
    now_s: float,
    horizon_s: float,
) -> str:
    verdict = PASSED if result.passed else FAILED
    if now_s >= horizon_s - 1e-9:
        return verdict
    if kind in _BY_S_KINDS:
        at_by_s = kind == "distance_m" and isinstance(body, Mapping) and "min" in body
        return PASSED if result.passed and not at_by_s else PENDING
    if kind in _WHOLE_RUN_KINDS:
        return FAILED if not result.passed else PENDING
    if kind == "photos" and isinstance(body, Mapping):
        count = len(recording.photos.get(str(body["agent"]), []))
        if body.get("max") is not None and count > int(body["max"]):
            return FAILED
        return PASSED if result.passed and body.get("max") is None else PENDING
    if kind == "signal" and isinstance(body, Mapping):
        visits = dataclasses.replace(recording, end_s=math.inf).intervals(
            str(body["agent"]), str(body["state"])
        )
        return verdict if visits and math.isfinite(visits[0][1]) else PENDING
    return PENDING


def final_checks(results: Sequence[CheckResult]) -> list[Json]:
    """The dry run's own verdicts (the report's), in the checks pane's form."""
    out: list[Json] = []
    for result in results:
        status = NOT_EVALUATED if not result.evaluated else PASSED if result.passed else FAILED
        out.append({"name": result.name, "status": status, "detail": result.observed})
    return out


class LiveChecks:
    """The mission's checks re-evaluated now and then during a rehearsal, for the page.

    Args:
        run: The dry run (its recording and its agents' configs).
        mission: The mission (its checks and origin).
        end_s: When the run is planned to end (``--until``, or ``sim.duration_s``).
        clock: Wall-clock seconds (monotonic).
    """

    def __init__(
        self,
        run: DryRun,
        mission: Mission,
        end_s: float,
        *,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.run = run
        self.mission = mission
        self.end_s = end_s
        self.clock = clock
        self.configs = {name: agent.config for name, agent in run.agents.items()}
        self.evaluations = 0
        """How many times the checks were evaluated."""
        self.longest_s = 0.0
        """The longest evaluation, in wall-clock seconds."""
        self._next_wall_s = -math.inf

    def due(self) -> bool:
        """True when it is time to evaluate again."""
        return self.clock() >= self._next_wall_s

    def evaluate(self, now_s: float) -> list[Json]:
        """The checks' standing at simulated time ``now_s`` (and when to look again)."""
        started = self.clock()
        checks = live_checks(
            self.mission.checks, self.run.recording, self.configs, self.mission, now_s, self.end_s
        )
        took_s = self.clock() - started
        self.evaluations += 1
        self.longest_s = max(self.longest_s, took_s)
        self._next_wall_s = started + max(CHECKS_PERIOD_S, took_s / CHECKS_MAX_SHARE)
        return checks


# -- the host: the dry run's station agent ---------------------------------------------------


class RehearsalHost:
    """The dry run's station agent as the view's host.

    It fits :class:`~clark_engine.station.live_view.ViewHost`.

    Chained onto the run's ``on_step`` (after any hook already there); once per station
    loop period of simulated time it calls the tick hooks (the view's update) and the
    readers (the command inbox, read without blocking).

    Args:
        run: The dry run, not started.
        station: The run's station agent.
    """

    def __init__(self, run: DryRun, station: SimAgent) -> None:
        self.run = run
        self.station = station
        self._period_s = 1.0 / station.config.loop_hz
        self._on_tick: list[Callable[[Any, float], None]] = []
        self._readers: dict[int, Callable[[float], None]] = {}
        self._next_s = -math.inf
        self.now_s = 0.0
        """The simulated time of the last step seen."""
        self._previous = run.on_step
        run.on_step = self._step

    @property
    def runtime(self) -> AgentRuntime:
        """The station agent's runtime."""
        return self.station.runtime

    @property
    def period_s(self) -> float:
        """The station's loop period."""
        return self._period_s

    @property
    def on_tick(self) -> list[Callable[[Any, float], None]]:
        """Hooks called once per station period with (this host, the simulated time)."""
        return self._on_tick

    def add_reader(self, fd: int, callback: Callable[[float], None]) -> None:
        """Call ``callback(now_s)`` once per station period (it must not block)."""
        self._readers[fd] = callback

    def remove_reader(self, fd: int) -> None:
        """Stop calling the reader of ``fd``."""
        self._readers.pop(fd, None)

    def deliver(self, event: StationCommand, now_s: float) -> None:
        """The page's command through the station's runtime, as an operator action."""
        if not self.run.command_station(event, now_s):
            logbook = self.runtime.logbook
            if not logbook.closed:
                logbook.mission.warning(
                    "view command not sent: the station agent is not running (killed by a "
                    "fault, or terminated)",
                    extra=LogEvent.VIEW_COMMAND.extra,
                )

    def detach(self) -> None:
        """Take the hook off the run (the one before it is put back). Idempotent."""
        if self.run.on_step == self._step:
            self.run.on_step = self._previous

    def _step(self, t_s: float) -> None:
        if self._previous is not None:
            self._previous(t_s)
        self.now_s = t_s
        if t_s < self._next_s:
            return
        self._next_s += self._period_s
        if self._next_s <= t_s:  # the first step, or the loop fell behind: restart the grid
            self._next_s = t_s + self._period_s
        for hook in list(self._on_tick):
            hook(self, t_s)
        for callback in list(self._readers.values()):
            callback(t_s)


# -- the rehearsal ---------------------------------------------------------------------------


class Rehearsal:
    """The station view served over one dry run, from before it starts until after it ends.

    :func:`open_rehearsal` starts the server (before anything is simulated or written);
    :meth:`attach` hooks it into the run; :meth:`finish` shows the run's verdicts and
    sends the last state; :meth:`stop` stops the server (always call it).

    Args:
        served: The started server and its inbox.
        mission: The mission.
        station: The station agent's name.
    """

    def __init__(self, served: OpenView, mission: Mission, station: str) -> None:
        self.served = served
        self.mission = mission
        self.station = station
        self.host: RehearsalHost | None = None
        self.link: StationViewLink | None = None
        self.checks: LiveChecks | None = None

    @property
    def url(self) -> str:
        """The page's address, with the token when there is one (to print for the operator)."""
        return self.served.server.url

    def attach(self, run: DryRun) -> None:
        """Feed the view from ``run``'s station agent; the run has not started.

        Raises:
            ValueError: The run has no station agent of that name.
        """
        station = run.station
        if station is None or station.name != self.station:
            raise ValueError(f"the run has no station agent {self.station!r}")
        self.host = RehearsalHost(run, station)
        self.link = self.served.attach(self.host)
        if self.mission.checks:
            self.checks = LiveChecks(run, self.mission, run.until_s)
            self.link.view.checks = []
            # Before the link's own hook: the snapshot it may send carries fresh checks.
            self.host.on_tick.insert(0, self._update_checks)

    def _update_checks(self, host: object, now_s: float) -> None:
        checks, link = self.checks, self.link
        if checks is None or link is None or not checks.due():
            return
        try:
            link.view.checks = checks.evaluate(now_s)
        except Exception as exc:  # the view's fault must never stop the rehearsal
            link.errors += 1
            logbook = link.host.runtime.logbook
            if not logbook.closed and link.errors == 1:
                logbook.interface.error(
                    "station view: checks failed: %r", exc, extra=LogEvent.VIEW_FAILED.extra
                )

    def finish(self, results: Sequence[CheckResult], end_s: float) -> None:
        """The run is over: its verdicts to the checks pane, the last state to the page."""
        link = self.link
        if link is None:
            return
        if self.mission.checks or results:
            link.view.checks = final_checks(results)
        link.close(end_s)

    def stop(self) -> None:
        """Send the last state (if :meth:`finish` did not), stop the server. Idempotent."""
        if self.link is not None and self.host is not None:
            self.link.close(self.host.now_s)
        if self.host is not None:
            self.host.detach()
        self.served.stop()


def open_rehearsal(settings: ViewSettings, mission: Mission, mission_path: Path) -> Rehearsal:
    """Start serving the station's view of ``mission``'s rehearsal (hello at once).

    Raises:
        ClarkError: The mission has no station agent (exit 1: it is the mission that
            lacks one).
        UsageError: The address cannot be served (a port in use...).
    """
    name = station_name(mission)
    if name is None:
        raise ClarkError(
            f"{mission_path}: --station serves the station agent's view, and the mission "
            "has none: add an agent with role mcs (see missions/cooperative_follow.yaml), "
            "or run without --station"
        )
    fleet = {
        agent_name: config_from_dict(agent_config(mission, agent))
        for agent_name, agent in mission.agents.items()
    }
    served = open_view(settings, fleet[name], fleet, f"the mission {mission_path.name}")
    return Rehearsal(served, mission, name)


__all__ = [
    "CHECKS_PERIOD_S",
    "DEFAULT_VIEW",
    "LiveChecks",
    "Rehearsal",
    "RehearsalHost",
    "final_checks",
    "live_checks",
    "open_rehearsal",
    "rehearsal_settings",
    "station_name",
]
