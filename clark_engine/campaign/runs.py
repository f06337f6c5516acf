"""One run of a campaign, as a worker flies it: its seed, its result, its isolation.

A worker (a process of the local pool, this process, or a Dask worker) gets a
:class:`RunSpec` and gives back a :class:`RunResult`: small and picklable, so that it
travels back over a pipe or the network (each check's verdict, the figures the checks
look at, the values drawn for the run, its seed, exit code and wall time, or the
infrastructure error that kept it from giving a verdict).

Simulated runs are flown in the worker's own process (the engine is imported once per
worker). A run on ArduPilot SITL, and any run given a timeout, is flown in a child
process of its own, in its own process group (:func:`run_in_group`): when the timeout
passes the group is stopped (SIGTERM, then SIGKILL), and the SITL processes the run
started die with it (they stop on the run's SIGTERM, and the kernel kills them when the
process that started them dies: :func:`clark_engine.sitl.launcher._death_pact`).
"""

from __future__ import annotations

import contextlib
import hashlib
import inspect
import io
import os
import pickle
import shutil
import signal
import socket
import subprocess
import sys
import tarfile
import tempfile
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Final

if TYPE_CHECKING:
    from clark_engine.dryrun.command import Outcome

STOP_GRACE_S: Final = 10.0
"""Seconds between SIGTERM and SIGKILL when a run's process group is stopped: time for
its SITL processes to be stopped in order and their instances given back."""

OBSERVED_MAX: Final = 300
"""Longest observed text kept for a failing check (the table's cell, not a log)."""

FIGURE_KINDS: Final = ("closest approach", "highest altitude", "first entry")
"""The figures a run reports, in the table's order: each pair's closest approach (m),
each aircraft's highest altitude above the origin (m), each state's first entry per
agent (s)."""

Figure = tuple[str, str]
"""A figure's key: its kind (:data:`FIGURE_KINDS`) and what it is about
(``slash_a - slash_b``, ``cub``, ``slash_b: parked``)."""


def run_seed(campaign_seed: int, index: int) -> int:
    """Run ``index``'s seed: stable across machines, Python versions and worker counts.

    The first four bytes of SHA-256 of ``clark-campaign:SEED:INDEX`` (Python's ``hash()``
    is salted per process, so it would give each worker other seeds): a whole number
    below 2^32, as a mission's ``sim.seed`` may be.
    """
    digest = hashlib.sha256(f"clark-campaign:{campaign_seed}:{index}".encode()).digest()
    return int.from_bytes(digest[:4], "big")


@dataclass(frozen=True, slots=True)
class SitlSpec:
    """Where a SITL run's worker finds ArduPilot SITL (the same path on every worker).

    Attributes:
        launcher: The ``sitl`` launcher.
        instances: First and last instance number its vehicles may take.
        speedup: SITL's speed-up.
    """

    launcher: str
    instances: tuple[int, int]
    speedup: float


@dataclass(frozen=True, slots=True)
class RunSpec:
    """What a worker needs to fly one run.

    Attributes:
        index: The run's number in the campaign, from 0.
        seed: Its seed (:func:`run_seed`).
        mission_path: The mission file, absolute (on a cluster, at the same path on
            every worker).
        mission_sha256: Its bytes' hash: a worker whose file differs refuses the run.
        until_s: Simulated seconds (the mission's ``sim.duration_s`` when None).
        faults: Command-line faults (``--fault``), as typed.
        vary: Values fixed for every run (``--vary PATH=VALUE``), as typed.
        sitl: Fly on ArduPilot SITL; the simulated autopilot when None.
        timeout_s: Stop the run after this many wall-clock seconds (it is then flown in
            a process group of its own); None: no limit (SITL runs are always isolated).
        report: Write the run's dry-run report and bring it back if the run fails.
        attempt: 0 for the first try, then 1, 2, ... for retries after an
            infrastructure failure.
    """

    index: int
    seed: int
    mission_path: str
    mission_sha256: str
    until_s: float | None = None
    faults: tuple[str, ...] = ()
    vary: tuple[str, ...] = ()
    sitl: SitlSpec | None = None
    timeout_s: float | None = None
    report: bool = False
    attempt: int = 0

    @property
    def isolated(self) -> bool:
        """Flown in a child process of its own (SITL, or a timeout to enforce)."""
        return self.sitl is not None or self.timeout_s is not None


@dataclass(frozen=True, slots=True)
class CheckVerdict:
    """One check's verdict in one run.

    Attributes:
        name: The check's name (``safety: cub`` for the safety judgement's rows).
        passed: It held.
        evaluated: It was judged (False: the run ended before its ``by_s``).
        observed: What the run observed, kept for a failed check only (empty otherwise).
    """

    name: str
    passed: bool
    evaluated: bool = True
    observed: str = ""


@dataclass(frozen=True, slots=True)
class RunResult:
    """What one run gives back: small, picklable, the same whichever worker flew it.

    Attributes:
        index: The run's number.
        seed: Its seed.
        exit_code: The dry run's exit code (0 pass, 1 a check or the safety judgement
            failed); None when an infrastructure failure kept it from a verdict.
        checks: Every check's verdict: the mission's, then the safety judgement's rows.
        figures: The figures the checks look at (:data:`FIGURE_KINDS`).
        drawn: Every value drawn (or fixed) for the run, path -> value.
        wall_s: Wall-clock seconds the run took.
        error: The infrastructure failure (SITL did not start, a timeout, a lost
            worker, exit 2), None for a run with a verdict.
        attempt: Which try this was (0: the first).
        worker: Which process flew it (``host:pid``), for infrastructure failures.
        report_tar: With failure reports: the failing run's report folder as a
            gzipped tar (None for a passing run, or without failure reports).
        cpu_s: CPU seconds the run took in its process (its share of a busy machine
            aside: what a campaign's throughput per core comes from).
    """

    index: int
    seed: int
    exit_code: int | None
    checks: tuple[CheckVerdict, ...] = ()
    figures: Mapping[Figure, float] = field(default_factory=dict)
    drawn: Mapping[str, float | bool] = field(default_factory=dict)
    wall_s: float = 0.0
    error: str | None = None
    attempt: int = 0
    worker: str = ""
    report_tar: bytes | None = None
    cpu_s: float = 0.0

    @property
    def passed(self) -> bool:
        """The run held every check and its safety judgement (exit code 0)."""
        return self.exit_code == 0

    @property
    def infrastructure_failure(self) -> bool:
        """No verdict: the run could not be flown (retried, counted apart)."""
        return self.exit_code is None


def worker_name() -> str:
    """``host:pid`` of this process."""
    return f"{socket.gethostname()}:{os.getpid()}"


def figures_of(outcome: Outcome, agent_order: Sequence[str]) -> dict[Figure, float]:
    """The figures a run's checks look at, from its recording and safety judgement.

    Each pair's closest approach in 3-D while either was armed, each aircraft's highest
    altitude above the origin (a rover's height is its GPS noise: not given), and the
    first time each agent entered each state (a state never entered has no figure).
    """
    figures: dict[Figure, float] = {}
    safety = outcome.safety
    if safety is not None:
        for pair in safety.pairs:
            if pair.distance_m is not None:
                figures[("closest approach", f"{pair.a} - {pair.b}")] = pair.distance_m
        for vehicle in safety.vehicles:
            if vehicle.aircraft and vehicle.highest is not None:
                figures[("highest altitude", vehicle.name)] = vehicle.highest.value
    result = outcome.result
    if result is not None:
        states = result.recording.states
        for agent in [*agent_order, *sorted(set(states) - set(agent_order))]:
            for entry in states.get(agent, []):
                for path in entry.entered:
                    key = ("first entry", f"{agent}: {path}")
                    if path and key not in figures:
                        figures[key] = entry.time_s
    return figures


def verdicts_of(outcome: Outcome) -> tuple[CheckVerdict, ...]:
    """Every check's verdict: the mission's (and the SITL comparison's), then safety's."""
    rows = list(outcome.results)
    if outcome.safety is not None:
        rows += outcome.safety.results()
    return tuple(
        CheckVerdict(
            r.name,
            r.passed,
            r.evaluated,
            "" if r.passed or not r.evaluated else r.observed[:OBSERVED_MAX],
        )
        for r in rows
    )


def _file_sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def mission_sha256(path: Path) -> str:
    """The mission file's hash, for workers to check they fly the same file."""
    return _file_sha256(path)


def _accepts_vary() -> bool:
    """True when this engine's dry run takes ``vary`` (the world's variations)."""
    from clark_engine.dryrun.command import run_dry_run

    return "vary" in inspect.signature(run_dry_run).parameters


def _pack(folder: Path) -> bytes:
    """A folder as a gzipped tar (members relative to it), to travel back to the client."""
    buffer = io.BytesIO()
    with tarfile.open(fileobj=buffer, mode="w:gz") as tar:
        for path in sorted(folder.rglob("*")):
            if path.is_file() and not path.is_symlink():
                tar.add(path, arcname=path.relative_to(folder).as_posix(), recursive=False)
    return buffer.getvalue()


def unpack(data: bytes, folder: Path) -> None:
    """Unpack :func:`_pack`'s bytes into ``folder`` (regular files only, nothing outside)."""
    folder.mkdir(parents=True, exist_ok=True)
    with tarfile.open(fileobj=io.BytesIO(data), mode="r:gz") as tar:
        tar.extractall(folder, filter="data")


def fly(spec: RunSpec) -> RunResult:
    """Fly one run where the spec says: in this process, or isolated in a child.

    Never raises for a run that could not be flown: that is an infrastructure failure
    in the result (KeyboardInterrupt and SystemExit still stop it).
    """
    if spec.isolated:
        return fly_isolated(spec)
    return fly_here(spec)


def fly_here(spec: RunSpec) -> RunResult:
    """Fly one run in this process (the engine imported once per worker)."""
    from clark_engine.dryrun.command import run_dry_run
    from clark_engine.errors import ClarkError
    from clark_engine.sitl.launcher import SitlInstall

    start = time.perf_counter()
    cpu_start = time.process_time()
    path = Path(spec.mission_path)

    def failed(message: str) -> RunResult:
        return RunResult(
            spec.index,
            spec.seed,
            None,
            wall_s=time.perf_counter() - start,
            error=message,
            attempt=spec.attempt,
            worker=worker_name(),
        )

    try:
        if _file_sha256(path) != spec.mission_sha256:
            return failed(
                f"{path} on {worker_name()} is not the campaign's mission file (it differs); "
                "a cluster's workers need the same files at the same paths"
            )
    except OSError as exc:
        return failed(
            f"{path} cannot be read on {worker_name()} ({exc.strerror or exc}); a cluster's "
            "workers need the mission at the same path (a shared file system)"
        )
    options: dict[str, Any] = {}
    if spec.vary or _accepts_vary():
        options["vary"] = list(spec.vary)
    install = None
    if spec.sitl is not None:
        first, last = spec.sitl.instances
        install = SitlInstall(Path(spec.sitl.launcher), range(first, last + 1))
    out, err = io.StringIO(), io.StringIO()
    staging = Path(tempfile.mkdtemp(prefix="clark-campaign-run-")) if spec.report else None
    report = staging / "report" if staging is not None else None
    try:
        try:
            outcome = run_dry_run(
                path,
                seed=spec.seed,
                until_s=spec.until_s,
                report=report,
                speed=None,
                faults=spec.faults,
                sitl=install,
                sitl_speedup=spec.sitl.speedup if spec.sitl is not None else 10.0,
                out=out,
                err=err,
                quiet=True,
                **options,
            )
        except ClarkError as exc:  # a SITL that did not start or stopped answering: exit 2
            tail = err.getvalue().strip().splitlines()[-3:]
            return failed(" / ".join([str(exc), *tail]))
        if outcome.result is None:  # the mission is invalid here (it was valid at the client)
            return failed(f"{path} is invalid on {worker_name()}: {err.getvalue().strip()[:500]}")
        agents = list(outcome.result.configs)
        packed = (
            _pack(report)
            if report is not None and outcome.exit_code != 0 and report.is_dir()
            else None
        )
        return RunResult(
            spec.index,
            spec.seed,
            outcome.exit_code,
            verdicts_of(outcome),
            figures_of(outcome, agents),
            dict(getattr(outcome, "drawn", None) or {}),
            time.perf_counter() - start,
            None,
            spec.attempt,
            worker_name(),
            packed,
            time.process_time() - cpu_start,
        )
    finally:
        if staging is not None:
            shutil.rmtree(staging, ignore_errors=True)


def run_in_group(
    argv: Sequence[str],
    timeout_s: float | None,
    *,
    log: Path | None = None,
    env: Mapping[str, str] | None = None,
    grace_s: float = STOP_GRACE_S,
) -> int | None:
    """Run ``argv`` in a process group of its own; stop the whole group after ``timeout_s``.

    The child dies with this process too (Linux: the kernel kills it when the thread
    that started it ends), and Ctrl-C here stops its group before it is raised on.

    Args:
        argv: The command.
        timeout_s: Wall-clock seconds it may take; None: no limit.
        log: Its standard output and error go here (discarded when None).
        env: Its environment (this process's when None).
        grace_s: Seconds between SIGTERM and SIGKILL when the group is stopped.

    Returns:
        Its exit code, or None when the timeout passed and the group was stopped.
    """
    from clark_engine.sitl.launcher import _death_pact

    in_child = _death_pact(os.getpid())
    with contextlib.ExitStack() as stack:
        output: Any = stack.enter_context(log.open("wb")) if log is not None else subprocess.DEVNULL
        process = subprocess.Popen(
            list(argv),
            stdin=subprocess.DEVNULL,
            stdout=output,
            stderr=subprocess.STDOUT,
            env=dict(env) if env is not None else None,
            start_new_session=True,  # its own process group, to stop it whole
            preexec_fn=in_child,
        )
        try:
            code = process.wait(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            stop_group(process, grace_s)
            return None
        except BaseException:
            stop_group(process, grace_s)
            raise
        _kill_group(process.pid, signal.SIGKILL)  # anything it left behind in its group
        return code


def _kill_group(pgid: int, sig: signal.Signals) -> None:
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(pgid, sig)


def stop_group(process: subprocess.Popen[bytes], grace_s: float = STOP_GRACE_S) -> None:
    """Stop a process and its group: SIGTERM, then SIGKILL after ``grace_s``; reap it."""
    _kill_group(process.pid, signal.SIGTERM)
    with contextlib.suppress(subprocess.TimeoutExpired):
        process.wait(timeout=grace_s)
    _kill_group(process.pid, signal.SIGKILL)
    process.wait()


def _child_env() -> dict[str, str]:
    """This environment, with this engine's source first on the path (the same code)."""
    env = dict(os.environ)
    root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (root, env.get("PYTHONPATH", "")) if p)
    return env


def fly_isolated(spec: RunSpec) -> RunResult:
    """Fly one run in a child process, in its own group, stopped after ``timeout_s``."""
    start = time.perf_counter()
    folder = Path(tempfile.mkdtemp(prefix="clark-campaign-child-"))
    try:
        (folder / "spec.pickle").write_bytes(pickle.dumps(spec))
        code = run_in_group(
            [sys.executable, "-m", "clark_engine.campaign.child", str(folder)],
            spec.timeout_s,
            log=folder / "child.log",
            env=_child_env(),
        )
        result_path = folder / "result.pickle"
        if code == 0 and result_path.is_file():
            result: RunResult = pickle.loads(result_path.read_bytes())
            return result
        if code is None:
            why = (
                f"timed out after {spec.timeout_s:g} s of wall time (--run-timeout-s); its "
                "process group was stopped"
            )
        else:
            tail = _tail(folder / "child.log")
            why = f"its process exited with status {code}" + (f": {tail}" if tail else "")
        return RunResult(
            spec.index,
            spec.seed,
            None,
            wall_s=time.perf_counter() - start,
            error=why,
            attempt=spec.attempt,
            worker=worker_name(),
        )
    finally:
        shutil.rmtree(folder, ignore_errors=True)


def _tail(path: Path, lines: int = 3) -> str:
    try:
        text = path.read_text(encoding="utf-8", errors="replace")
    except OSError:
        return ""
    return " / ".join(line.strip() for line in text.strip().splitlines()[-lines:])
