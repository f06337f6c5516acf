"""``clark analyze LOGDIR --checks MISSION``: a mission's checks, judged from a run's logs.

Why: a mission's ``checks:`` say what a good run looks like, but only ``clark dry-run``
judged them, against the :class:`~clark_engine.expectations.recording.Recording` the simulator
fills in. A real run (``clark run``, one process per agent) leaves only its logs.
:func:`~clark_engine.expectations.log_run.rebuild` rebuilds a ``Recording`` from a folder of
them (:mod:`~clark_engine.expectations.log_run`: tracks, states, photos, safety events; each
log kind read by :mod:`~clark_engine.expectations.log_readers`, the agents' clocks aligned by
:mod:`~clark_engine.expectations.log_clocks`), and this module, the command's front end,
evaluates the checks on it with the dry run's own evaluators
(:func:`clark_engine.expectations.evaluate.evaluate`), so a flight and its rehearsal are
judged by the same code and printed in the same table.

**Control signals** (the ``signal`` check) are not in the logs: that check is
reported ``not evaluated``. So is any check whose data the folder lacks (an
agent's log missing, a log level that hides the lines, a vehicle never seen):
no check passes on missing data. ``altitude_m`` and ``ends_at`` read the tracks
(the altitude is Agent Status's ``alt_m``, above the origin), as ``reached`` does.
"""

from __future__ import annotations

import json
import math
import sys
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, TextIO

from clark_engine.errors import UsageError
from clark_engine.expectations.evaluate import CheckResult, checks_table, evaluate
from clark_engine.expectations.log_readers import file_names
from clark_engine.expectations.log_run import LogRun, position, rebuild
from clark_engine.mission.model import Mission

#: Why the ``signal`` check cannot be judged from logs.
NO_SIGNALS: Final = (
    "the logs do not record the pulse widths the autopilot received (a dry run reads "
    "them from its simulated autopilot; the runtime logs no RC or servo values)"
)


@dataclass(frozen=True, slots=True)
class LogChecks:
    """The checks of a mission judged on a run's logs."""

    run: LogRun
    results: list[CheckResult]

    @property
    def failed(self) -> list[CheckResult]:
        """Checks evaluated that did not hold."""
        return [r for r in self.results if r.evaluated and not r.passed]

    @property
    def skipped(self) -> list[CheckResult]:
        """Checks not evaluated."""
        return [r for r in self.results if not r.evaluated]

    def to_json(self) -> dict[str, Any]:
        """A JSON-ready summary: the folder, the clocks and every check's verdict."""
        run = self.run
        return {
            "folder": str(run.folder),
            "mission": run.mission.name,
            "agents": sorted(run.agents),
            "time_origin": run.time_origin,
            "clocks": {
                name: {"shift_s": logs.shift_s, "how": logs.clock}
                for name, logs in sorted(run.agents.items())
            },
            "end_s": run.recording.end_s,
            "checks": [
                {
                    "name": r.name,
                    "expected": r.expected,
                    "observed": r.observed,
                    "result": r.verdict,
                    "passed": r.passed,
                    "evaluated": r.evaluated,
                }
                for r in self.results
            ],
            "warnings": run.warnings(),
        }


def _needs_file(run: LogRun, agent: str, key: str, what: str) -> str | None:
    logs = run.agents.get(agent)
    if logs is None or key not in logs.files:
        file_name = file_names(run.configs[agent])[key] if agent in run.configs else agent
        return f"no {file_name} in the folder ({what})"
    return None


def _needs_level(run: LogRun, agent: str, level: str, what: str) -> str | None:
    logs = run.agents[agent]
    if logs.hides(level):
        return (
            f"{agent}'s logs are at level {logs.level}, which leaves out the {level} lines "
            f"of {what}"
        )
    return None


def _needs_position(run: LogRun, agent: str) -> str | None:
    if agent not in run.recording.tracks:
        return f"no position of {agent} in the logs (no fleet CSV row with its Agent Status)"
    return None


def _needs_safety(run: LogRun, agent: str) -> str | None:
    """Why the safety events of ``agent`` are not known (stations have none)."""
    config = run.configs.get(agent)
    if config is None or not config.is_vehicle:
        return None
    return (
        _needs_file(run, agent, "mission_log", "failsafes are logged there")
        or _needs_file(run, agent, "interface_log", "an autopilot loss is logged there")
        or _needs_level(run, agent, "ERROR", "failsafes and autopilot losses")
    )


def unsupported(check: Mapping[str, Any], run: LogRun) -> str | None:
    """Why ``check`` cannot be judged from these logs, or None when it can."""
    kind = next(k for k in check if k not in ("name", "by_s"))
    body = check[kind]
    if kind == "signal":
        return NO_SIGNALS
    if kind in ("distance_m", "reached", "altitude_m", "ends_at"):
        names = [str(n) for n in body["between"]] if kind == "distance_m" else [str(body["agent"])]
        why = next((w for n in names if (w := _needs_position(run, n)) is not None), None)
        by_s = float(check.get("by_s", run.recording.end_s))
        if why is None and by_s <= run.recording.end_s:
            late = [n for n in names if math.isnan(position(run.recording.tracks[n], by_s)[0])]
            if late:
                return f"no position of {', '.join(late)} known by {by_s:g} s"
        return why
    if kind == "separation_m":
        names = [str(n) for n in body.get("agents", [])] or [
            n for n, c in run.configs.items() if c.is_vehicle
        ]
        missing = [n for n in names if n not in run.recording.tracks]
        if missing:
            return (
                f"no position of {', '.join(missing)} in the logs (no fleet CSV row with "
                "its Agent Status)"
            )
        return None
    if kind in ("state", "sequence"):
        agent = str(body["agent"])
        return _needs_file(run, agent, "mission_log", "state changes are logged there") or (
            _needs_level(run, agent, "INFO", "state changes")
        )
    if kind == "photos":
        agent = str(body["agent"])
        return _needs_file(run, agent, "message_log", "the Picture Data sent is logged there") or (
            _needs_file(
                run, agent, "mission_log", "pictures taken without a position are logged there"
            )
        )
    if kind == "failsafe":
        return _needs_safety(run, str(body["agent"]))
    if kind == "no_failsafe":
        names = [str(n) for n in body.get("agents", [])] or list(run.configs)
        return next((w for n in names if (w := _needs_safety(run, n)) is not None), None)
    return None


def judge(run: LogRun) -> list[CheckResult]:
    """The mission's checks on the rebuilt run, with the dry run's evaluators.

    A check whose data the logs lack is ``not evaluated``, with the reason.
    """
    checks = run.mission.checks
    results = evaluate(checks, run.recording, run.configs, run.mission.origin)
    out = []
    for check, result in zip(checks, results, strict=True):
        why = unsupported(check, run)
        if why is not None:
            result = CheckResult(
                result.name, result.expected, f"not evaluated: {why}", False, False
            )
        out.append(result)
    return out


def check_folder(folder: Path, mission: Mission) -> LogChecks:
    """Rebuild the run in ``folder`` and judge ``mission``'s checks on it.

    Raises:
        UsageError: The folder or a file in it cannot be read.
        LogChecksError: The folder holds none of the mission's logs.
    """
    from clark_engine.mission.compiler import agent_config
    from clark_engine.runtime.config import config_from_dict

    configs = {
        name: config_from_dict(agent_config(mission, agent))
        for name, agent in mission.agents.items()
    }
    run = rebuild(folder, mission, configs)
    return LogChecks(run, judge(run))


def format_text(checks: LogChecks) -> str:
    """The report: which logs, how the clocks were aligned, then the dry run's checks table."""
    run = checks.run
    lines = [
        f"{run.folder}: mission {run.mission.name}, logs of {len(run.agents)} of "
        f"{len(run.configs)} agents ({', '.join(sorted(run.agents))}); "
        f"{run.recording.end_s:.1f} s of mission time",
        f"time: {run.time_origin}",
    ]
    for name, logs in sorted(run.agents.items()):
        lines.append(f"  {name}: {logs.clock}")
    lines.append("")
    table = checks_table(checks.results) if checks.results else "the mission declares no checks\n"
    return "\n".join(lines) + "\n" + table


def run_log_checks(
    folder: Path,
    mission_path: Path,
    *,
    json_format: bool = False,
    quiet: bool = False,
    out: TextIO | None = None,
    err: TextIO | None = None,
) -> int:
    """``clark analyze LOGDIR --checks MISSION``: print the checks; returns the exit code.

    0 when every evaluated check holds, 1 when one fails or the mission is invalid.
    ``quiet`` hides warnings: the mission's, and the logs' (rows skipped, clocks).

    Raises:
        UsageError: The mission or a log cannot be read, or the folder does not exist (2).
        LogChecksError: The folder holds none of the mission's logs (1).
    """
    from clark_engine.mission.validate import validate_path

    out = sys.stdout if out is None else out
    err = sys.stderr if err is None else err
    validation = validate_path(mission_path, str(mission_path))
    if validation.kind != "mission" and validation.ok:
        raise UsageError(f"--checks {mission_path} is a {validation.kind}, not a mission")
    for finding in validation.findings:
        if finding.is_error or not quiet:
            print(finding.format_text(), file=err)
    mission = validation.mission
    if mission is None:
        print(f"{mission_path}: invalid; no check evaluated", file=err)
        return 1
    checks = check_folder(folder, mission)
    for warning in [] if quiet else checks.run.warnings():
        print(f"clark analyze: warning: {warning}", file=err)
    if json_format:
        out.write(json.dumps(checks.to_json(), indent=2) + "\n")
    else:
        out.write(format_text(checks))
    total = len(checks.results)
    if checks.skipped:
        print(
            f"{len(checks.skipped)} of {total} checks not evaluated (the table says why)", file=err
        )
    if checks.failed:
        print(f"{len(checks.failed)} of {total} checks failed", file=err)
    return 1 if checks.failed else 0
