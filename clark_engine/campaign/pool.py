"""Where a campaign's runs go: this process, a local process pool, or a Dask cluster.

All three are driven through the standard library's futures API
(:class:`concurrent.futures.Future`): the local pool is a
:class:`~concurrent.futures.ProcessPoolExecutor`, and a Dask cluster is reached
through ``distributed.Client(ADDRESS).get_executor(...)``, whose futures are the
standard library's. ``distributed`` is imported only when a scheduler is given.

:func:`fly_all` submits every run, retries a run whose infrastructure failed (SITL that
did not start, a killed worker, a timeout) up to ``retries`` times with the same seed,
and hands back every run's last result in run order, with every infrastructure
failure met on the way. Ctrl-C cancels what has not started and stops the workers.
"""

from __future__ import annotations

import concurrent.futures as cf
import importlib
import multiprocessing
import os
import signal
import sys
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from types import FrameType
from typing import Any, Final, Protocol

from clark_engine.campaign.runs import RunResult, RunSpec, fly, worker_name
from clark_engine.errors import UsageError

SITL_RESOURCE: Final = "sitl"
"""The Dask resource a SITL run takes one of (workers declare ``--resources sitl=K``)."""

CLUSTER_TIMEOUT_S: Final = 30.0
"""Seconds to wait for the scheduler to answer."""


def usable_cores() -> int:
    """The cores this process may run on (its affinity mask; all of them elsewhere)."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


class Backend(Protocol):
    """Somewhere to fly runs: submit one, get a standard future of its result."""

    description: str
    """How the report names it (``local, 2 processes``)."""

    def submit(self, spec: RunSpec) -> cf.Future[RunResult]:
        """Start (or queue) one run."""
        ...

    def recover(self) -> None:
        """Be ready for more runs after a worker died (a broken pool is replaced)."""
        ...

    def close(self, cancel: bool) -> None:
        """Stop the workers; with ``cancel``, at once (Ctrl-C), without waiting for runs."""
        ...


class InProcess:
    """Runs flown one after the other in this process (``--workers 1``)."""

    description = "this process"

    def submit(self, spec: RunSpec) -> cf.Future[RunResult]:
        """Fly it now; the future is already done (Ctrl-C reaches the run itself)."""
        future: cf.Future[RunResult] = cf.Future()
        future.set_result(fly(spec))
        return future

    def recover(self) -> None:
        """Nothing breaks here."""

    def close(self, cancel: bool) -> None:
        """Nothing to stop."""


def _exit_on_term(signum: int, _frame: FrameType | None) -> None:
    raise SystemExit(128 + signum)


def _pool_worker_init() -> None:
    """In each pool process: Ctrl-C is the client's to handle, SIGTERM an orderly exit.

    A terminal's Ctrl-C reaches every process of the foreground group; the client stops
    the pool itself, so a worker ignores it. SIGTERM (the client stopping the pool)
    unwinds the run, so that an isolated run's process group is stopped on the way.
    """
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, _exit_on_term)


class LocalPool:
    """A pool of ``processes`` worker processes on this machine."""

    def __init__(self, processes: int) -> None:
        self.processes = processes
        self.description = f"local pool of {processes} processes"
        self._pool = self._new_pool()

    def _new_pool(self) -> cf.ProcessPoolExecutor:
        # fork (Linux): each worker starts with the engine already imported here.
        method = "fork" if sys.platform.startswith("linux") else "spawn"
        return cf.ProcessPoolExecutor(
            max_workers=self.processes,
            mp_context=multiprocessing.get_context(method),
            initializer=_pool_worker_init,
        )

    def submit(self, spec: RunSpec) -> cf.Future[RunResult]:
        """Queue the run on the pool."""
        return self._pool.submit(fly, spec)

    def recover(self) -> None:
        """Replace a pool broken by a worker's death (its queued runs are resubmitted)."""
        if getattr(self._pool, "_broken", False):
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = self._new_pool()

    def close(self, cancel: bool) -> None:
        """Shut the pool down; with ``cancel``, stop its processes (SIGTERM) at once."""
        if cancel:
            processes = list((getattr(self._pool, "_processes", None) or {}).values())
            self._pool.shutdown(wait=False, cancel_futures=True)
            for process in processes:
                if process.is_alive():
                    process.terminate()  # SIGTERM: the run unwinds, its group is stopped
            for process in processes:
                process.join(timeout=15)
                if process.is_alive():
                    process.kill()
        else:
            self._pool.shutdown(wait=True)


class DaskCluster:
    """A Dask distributed cluster, reached at its scheduler's address.

    SITL runs each take one ``sitl`` resource, so a worker started with
    ``--resources sitl=K`` flies at most K at once.
    """

    def __init__(self, address: str, sitl: bool) -> None:
        try:
            distributed: Any = importlib.import_module("distributed")
        except ImportError:
            raise UsageError(
                "--scheduler needs the Dask distributed package: pip install "
                "'clark-engine[cluster]' (or pip install distributed)"
            ) from None
        try:
            self.client: Any = distributed.Client(
                address, timeout=CLUSTER_TIMEOUT_S, set_as_default=False
            )
        except (OSError, TimeoutError) as exc:
            raise UsageError(f"--scheduler {address}: no Dask scheduler answers ({exc})") from None
        workers = self.client.scheduler_info().get("workers", {})
        if sitl:
            offering = [w for w in workers.values() if w.get("resources", {}).get(SITL_RESOURCE)]
            if not offering:
                self.client.close()
                raise UsageError(
                    f"--scheduler {address}: no worker offers the resource {SITL_RESOURCE!r} "
                    "that SITL runs take: start the workers with `dask worker "
                    f"{address} --nthreads 1 --resources {SITL_RESOURCE}=2` (at most 2 SITL "
                    "runs at once on each)"
                )
        self.description = f"Dask cluster at {address} ({len(workers)} workers)"
        options: dict[str, Any] = {"pure": False}
        if sitl:
            options["resources"] = {SITL_RESOURCE: 1}
        self._executor = self.client.get_executor(**options)
        self._token = uuid.uuid4().hex[:8]

    def submit(self, spec: RunSpec) -> cf.Future[RunResult]:
        """Send the run to the cluster (a key per run and attempt, for its dashboard)."""
        key = f"clark-run-{self._token}-{spec.index}-{spec.attempt}"
        future: cf.Future[RunResult] = self._executor.submit(fly, spec, key=key)
        return future

    def recover(self) -> None:
        """The scheduler reschedules what a lost worker held; nothing to do here."""

    def close(self, cancel: bool) -> None:
        """Cancel what is left (with ``cancel``) and disconnect; the cluster stays up."""
        self._executor.shutdown(wait=not cancel)
        self.client.close()


@dataclass(frozen=True, slots=True)
class Flown:
    """Every run's last result (in run order) and every infrastructure failure met."""

    results: tuple[RunResult, ...]
    infrastructure: tuple[RunResult, ...]
    """Each attempt that failed for want of infrastructure, retried or not, by run and try."""


Progress = Callable[[int, int, int, int], None]
"""(runs done, runs in all, runs failed, infrastructure failures so far)."""


def _lost(spec: RunSpec, exc: BaseException) -> RunResult:
    """An attempt whose worker never gave a result (a killed worker, a lost connection)."""
    name = type(exc).__name__
    if isinstance(exc, cf.process.BrokenProcessPool):
        why = "its worker process died (killed, or out of memory)"
    elif name == "KilledWorker":
        why = f"the Dask workers running it died ({exc})"
    elif isinstance(exc, cf.CancelledError):
        why = "it was cancelled on the cluster"
    else:
        why = f"{name}: {exc}"
    return RunResult(spec.index, spec.seed, None, error=why, attempt=spec.attempt, worker="")


def fly_all(
    specs: Sequence[RunSpec],
    backend: Backend,
    retries: int,
    progress: Progress | None = None,
) -> Flown:
    """Fly every run, retrying infrastructure failures up to ``retries`` times each.

    Raises:
        KeyboardInterrupt: Ctrl-C; the backend is closed at once (runs not started are
            cancelled, running ones stopped) before it is raised on.
    """
    final: dict[int, RunResult] = {}
    infra: list[RunResult] = []
    failed = 0
    pending: dict[cf.Future[RunResult], RunSpec] = {}
    cancel = True
    try:
        for spec in specs:
            pending[backend.submit(spec)] = spec
            if isinstance(backend, InProcess):  # flown already: report as it goes
                failed, final = _collect(pending, backend, retries, final, infra, failed)
                _say(progress, final, len(specs), failed, infra)
        while pending:
            done, _ = cf.wait(list(pending), return_when=cf.FIRST_COMPLETED)
            failed, final = _collect(pending, backend, retries, final, infra, failed, done)
            _say(progress, final, len(specs), failed, infra)
        cancel = False
    finally:
        backend.close(cancel)
    ordered = tuple(final[i] for i in sorted(final))
    return Flown(ordered, tuple(sorted(infra, key=lambda r: (r.index, r.attempt))))


def _say(
    progress: Progress | None,
    final: dict[int, RunResult],
    total: int,
    failed: int,
    infra: list[RunResult],
) -> None:
    if progress is not None:
        progress(len(final), total, failed, len(infra))


def _collect(
    pending: dict[cf.Future[RunResult], RunSpec],
    backend: Backend,
    retries: int,
    final: dict[int, RunResult],
    infra: list[RunResult],
    failed: int,
    done: set[cf.Future[RunResult]] | None = None,
) -> tuple[int, dict[int, RunResult]]:
    """Take the finished futures' results; resubmit infrastructure failures."""
    finished = [f for f in pending if f.done()] if done is None else list(done)
    broken = False
    for future in finished:
        spec = pending.pop(future)
        try:
            result = future.result()
        except (KeyboardInterrupt, SystemExit):
            raise
        except BaseException as exc:  # a lost worker may raise anything
            broken = broken or isinstance(exc, cf.process.BrokenProcessPool)
            result = _lost(spec, exc)
        if result.infrastructure_failure:
            infra.append(result if result.worker else replace(result, worker=""))
            if spec.attempt < retries:
                if broken:
                    backend.recover()
                    broken = False
                retry = replace(spec, attempt=spec.attempt + 1)
                pending[backend.submit(retry)] = retry
                continue
        elif not result.passed:
            failed += 1
        final[spec.index] = result
    if broken:
        backend.recover()
    return failed, final


def backend_for(
    scheduler: str | None, workers: int | None, sitl: bool, sitl_per_worker: int, runs: int
) -> Backend:
    """The backend the options name: a Dask cluster, this process, or a local pool.

    Locally, SITL runs are capped by the pool's size: at most ``sitl_per_worker``
    processes (each flies one SITL stack at a time); never more processes than runs.
    """
    if scheduler is not None:
        return DaskCluster(scheduler, sitl)
    processes = min(workers if workers is not None else usable_cores(), runs)
    if sitl:
        processes = min(processes, sitl_per_worker)
    if processes <= 1:
        return InProcess()
    return LocalPool(processes)


__all__ = ["Backend", "DaskCluster", "Flown", "InProcess", "LocalPool", "fly_all", "worker_name"]
