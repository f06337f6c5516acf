"""A dry run split across processes, for fleets too big for one core.

A 50-agent fleet keeps one Python process busy with MAVLink, physics and
ClarkLink for every vehicle; the agents meet only through the radio, and a
packet takes at least the mesh's lookahead (latency plus the shortest air time:
5 ms and more) to arrive. So each process simulates a share of the agents for
one lookahead at a time, then the processes swap what their agents handed to the
radio and every process replays all of it into its own copy of the mesh, in the
order one process would have sent it (:mod:`clark_engine.sim.engine` explains
the keys that carry that order). The result, the logs and the CSV files are the
same, byte for byte, as a run in one process: splitting changes the speed only.

Processes are forked (the mission is already validated in memory, and a fork
starts in milliseconds); where ``fork`` is not available the run stays in one
process. Each pair of processes shares a socket pair; a swap writes this
process's batch to every other and reads theirs, with non-blocking sockets so
that two processes sending large batches at once cannot block each other.
"""

from __future__ import annotations

import multiprocessing
import os
import pickle
import select
import socket
import sys
import time
import traceback
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

from clark_engine.errors import UsageError
from clark_engine.mission.model import Mission
from clark_engine.sim.engine import (
    Action,
    DryRun,
    DryRunResult,
    GridPositions,
    Share,
    build_mesh,
    split_window_s,
    tick_phase,
)

#: Fewest agents for which ``--workers auto`` splits a run: below it, swapping every few
#: milliseconds of simulated time costs more than a second core gives (benchmarks/bench_sim.py).
AUTO_MIN_AGENTS = 12
#: Most processes ``--workers auto`` uses.
AUTO_MAX_WORKERS = 4
#: Shortest window worth splitting for: a shorter lookahead means swaps so frequent
#: that one process is faster.
MIN_WINDOW_S = 0.001

#: How long a swap polls for the other processes' batches before it sleeps until they
#: come. Sleeping costs a wake-up (tens of microseconds here) on every swap, and a swap
#: comes every few milliseconds of simulated time.
SPIN_S = 0.0002

#: How long a failed process waits for the others to read its error before it ends.
ERROR_LINGER_S = 5.0

_BATCH, _SHARE, _ERROR = b"B", b"S", b"E"
_HEADER = 5  # one kind byte and a 4-byte big-endian length


class WorkerFailed(RuntimeError):
    """Another process of a split run raised: a bug, whose traceback is the message."""


class WorkerVanished(UsageError):
    """Another process of a split run ended without a word: killed, or out of memory.

    Not a bug in the engine but something done to it, so the command line reports it
    in one line (exit 2) instead of a traceback.
    """

    def __init__(self, index: int, why: str) -> None:
        super().__init__(
            f"the dry run's worker process {index} {why} (was it killed, or out of memory?); "
            "the run is incomplete: run it again, or in one process with --workers 1"
        )


def usable_cores() -> int:
    """CPU cores this process may run on."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def can_split() -> bool:
    """True where processes can be forked."""
    return "fork" in multiprocessing.get_all_start_methods()


def choose_workers(requested: int | None, mission: Mission) -> int:
    """How many processes a run of ``mission`` uses.

    Args:
        requested: The user's number (``--workers N``); None for automatic.
        mission: The mission (its agents, and its radios' lookahead).

    Returns:
        1 when the run cannot be split (no fork, a lookahead under :data:`MIN_WINDOW_S`,
        a single agent); else the requested number (at most one per agent), or
        automatically one per usable core (at most :data:`AUTO_MAX_WORKERS`) for
        missions of :data:`AUTO_MIN_AGENTS` agents or more, on Linux. (Elsewhere only
        when asked: macOS can fork, but Python calls forking there unsafe, since some
        system libraries do not survive it.)
    """
    agents = len(mission.agents)
    if not can_split() or agents < 2 or split_window_s(build_mesh(mission, 0)) < MIN_WINDOW_S:
        return 1
    if requested is not None:
        return max(1, min(requested, agents))
    if agents < AUTO_MIN_AGENTS or not sys.platform.startswith("linux"):
        return 1
    return max(1, min(usable_cores(), AUTO_MAX_WORKERS, agents))


def partition(mission: Mission, workers: int, seed: int) -> list[list[str]]:
    """Agents per process, dealt in the order of their ticks' phases.

    Every process waits for the slowest at each swap, so what matters is that each
    window's work is shared out, not only the whole run's. An agent's tick (its
    behaviour, its fleet table, its logs) is its costliest moment; every agent ticks at
    the mission's loop rate with a seeded phase, so dealing the agents round-robin in
    phase order puts consecutive ticks in different processes. Deterministic, though the
    results do not depend on it: a split run gives the same results however the agents
    are shared out.
    """
    names = sorted(mission.agents, key=lambda name: (tick_phase(seed, name), name))
    order = {name: i for i, name in enumerate(mission.agents)}
    return [sorted(names[k::workers], key=order.__getitem__) for k in range(workers)]


class SocketExchange:
    """One process's end of the socket pairs to every other process of a split run.

    Args:
        peers: Worker index -> the socket to that worker, for every other worker.
    """

    def __init__(self, peers: Mapping[int, socket.socket]) -> None:
        self.peers = dict(sorted(peers.items()))
        self._inbox = {index: bytearray() for index in self.peers}
        for sock in self.peers.values():
            sock.setblocking(False)

    def swap(
        self, actions: list[Action], grid: list[GridPositions]
    ) -> list[tuple[list[Action], list[GridPositions]]]:
        """Send this process's batch to every other process; return theirs, in worker order."""
        frames = self._exchange(pickle.dumps((actions, grid), pickle.HIGHEST_PROTOCOL))
        return [pickle.loads(frames[index]) for index in self.peers]

    def send_error(self, text: str) -> None:
        """Tell every other process this one failed (best effort: they may be gone)."""
        frame = _frame(_ERROR, text.encode("utf-8", "replace"))
        for sock in self.peers.values():
            try:
                sock.setblocking(True)
                sock.sendall(frame)
                sock.shutdown(socket.SHUT_WR)
            except OSError:
                pass
        # Closing a socket with unread bytes resets it, and the peer would read the reset
        # instead of the error: read until the peers close (they do once they have read it).
        for sock in self.peers.values():
            try:
                sock.settimeout(ERROR_LINGER_S)
                while sock.recv(1 << 16):
                    pass
            except OSError:
                pass

    def send_share(self, to: int, share: Share) -> None:
        """Send this process's share of the results to worker ``to``."""
        sock = self.peers[to]
        sock.setblocking(True)
        sock.sendall(_frame(_SHARE, pickle.dumps(share, pickle.HIGHEST_PROTOCOL)))

    def receive_share(self, index: int) -> Share:
        """Wait for worker ``index``'s share of the results."""
        while (frame := self._next_frame(index, _SHARE)) is None:
            select.select([self.peers[index]], [], [])
        share: Share = pickle.loads(frame)
        return share

    def _exchange(self, payload: bytes) -> dict[int, bytes]:
        """Write one batch to every peer and read one from each, whichever can go first."""
        frame = memoryview(_frame(_BATCH, payload))
        unsent = {index: frame for index in self.peers}
        frames: dict[int, bytes] = {}
        spin_until = time.perf_counter() + SPIN_S
        while True:
            for index, rest in list(unsent.items()):
                try:
                    sent = self.peers[index].send(rest)
                except BlockingIOError:
                    sent = 0
                except OSError as exc:
                    raise WorkerVanished(index, f"is gone ({exc.strerror or exc})") from None
                if sent == len(rest):
                    del unsent[index]
                else:
                    unsent[index] = rest[sent:]
            for index in self.peers:
                if index not in frames:
                    got = self._next_frame(index, _BATCH)
                    if got is not None:
                        frames[index] = got
            if not unsent and len(frames) == len(self.peers):
                return frames
            if not unsent and time.perf_counter() < spin_until:
                continue  # the others are usually a few microseconds away: do not sleep yet
            readers = [self.peers[i] for i in self.peers if i not in frames]
            writers = [self.peers[i] for i in unsent]
            select.select(readers, writers, [])

    def _next_frame(self, index: int, kind: bytes) -> bytes | None:
        """Worker ``index``'s next frame of ``kind`` if it has all arrived, else None.

        Raises:
            WorkerFailed: The worker sent an error or another kind of frame.
            WorkerVanished: The worker closed its end before the frame was whole.
        """
        inbox = self._inbox[index]
        sock = self.peers[index]
        closed = False
        while True:  # read what has arrived
            try:
                chunk = sock.recv(1 << 20)
            except BlockingIOError:
                break
            except OSError as exc:
                raise WorkerVanished(index, f"is gone ({exc.strerror or exc})") from None
            if not chunk:
                closed = True
                break
            inbox += chunk
        size = int.from_bytes(inbox[1:_HEADER], "big") if len(inbox) >= _HEADER else -1
        if size < 0 or len(inbox) < _HEADER + size:
            if closed:
                raise WorkerVanished(index, "ended in the middle of the run")
            return None
        got = bytes(inbox[:1])
        payload = bytes(inbox[_HEADER : _HEADER + size])
        del inbox[: _HEADER + size]
        if got == _ERROR:
            raise WorkerFailed(f"worker {index} failed:\n{payload.decode('utf-8', 'replace')}")
        if got != kind:
            raise WorkerFailed(f"worker {index} sent a {got!r} frame where {kind!r} was due")
        return payload


def _frame(kind: bytes, payload: bytes) -> bytes:
    return kind + len(payload).to_bytes(4, "big") + payload


def run_split(
    mission: Mission,
    mission_path: Path,
    *,
    workers: int,
    seed: int,
    until_s: float,
    log_dir: Path | None,
    extra_faults: Sequence[Mapping[str, Any]],
    progress: Callable[[float, float], None] | None,
) -> DryRunResult:
    """Run the dry run in ``workers`` processes; the same result as :meth:`DryRun.run`.

    This process simulates the first share and gathers the others'. Each process writes
    its own agents' logs into ``log_dir``.

    Raises:
        WorkerFailed: Another process raised (its traceback is in the message).
        WorkerVanished: Another process ended without a word.
    """
    shares = partition(mission, workers, seed)
    # Worker i talks to worker j (i < j) through pairs[i, j]: i holds end 0, j end 1.
    pairs = {(i, j): socket.socketpair() for i in range(workers) for j in range(i + 1, workers)}

    def ends(me: int) -> tuple[dict[int, socket.socket], list[socket.socket]]:
        """Worker ``me``'s ends of the pairs, and every other end (for it to close)."""
        mine: dict[int, socket.socket] = {}
        others: list[socket.socket] = []
        for (i, j), (a, b) in pairs.items():
            if me == i:
                mine[j] = a
                others.append(b)
            elif me == j:
                mine[i] = b
                others.append(a)
            else:
                others += [a, b]
        return mine, others

    settings: dict[str, Any] = {
        "seed": seed,
        "until_s": until_s,
        "log_dir": log_dir,
        "extra_faults": list(extra_faults),
    }
    context = multiprocessing.get_context("fork")
    children = []
    try:
        for me in range(1, workers):
            mine, others = ends(me)
            process = context.Process(
                target=_child,
                args=(me, mine, others, mission, mission_path, shares[me]),
                kwargs=settings,
                daemon=True,
                name=f"clark-dry-run-{me}",
            )
            process.start()
            children.append(process)
        mine, others = ends(0)
        for sock in others:  # so that a child's end closes when the child ends
            sock.close()
        exchange = SocketExchange(mine)
        run = DryRun(
            mission, mission_path, owned=shares[0], exchange=exchange, progress=progress, **settings
        )
        result = run.run()
        for index in range(1, workers):
            _gather(result, exchange.receive_share(index))
        _order_recording(result, mission)
        result.configs = {name: result.configs[name] for name in mission.agents}
        result.ticks = {name: result.ticks[name] for name in mission.agents}
        result.workers = workers
        return result
    finally:
        for pair in pairs.values():
            for sock in pair:
                sock.close()
        for process in children:
            process.join(timeout=5.0)
            if process.is_alive():
                process.kill()
                process.join()


def _child(
    me: int,
    mine: dict[int, socket.socket],
    others: list[socket.socket],
    mission: Mission,
    mission_path: Path,
    owned: Sequence[str],
    **settings: Any,
) -> None:
    """A forked process's life: simulate its share, hand it to worker 0, end."""
    for sock in others:
        sock.close()
    exchange = SocketExchange(mine)
    try:
        run = DryRun(mission, mission_path, owned=owned, exchange=exchange, **settings)
        run.run()
        exchange.send_share(0, run.share())
    except (WorkerFailed, WorkerVanished):
        pass  # another process failed first and says why
    except BaseException:
        exchange.send_error(f"(worker {me}) {traceback.format_exc()}")
    finally:
        for sock in mine.values():
            sock.close()
        os._exit(0)  # no atexit handlers, no flushing of buffers copied from the parent


def _gather(result: DryRunResult, share: Share) -> None:
    """Add another process's share to the result of worker 0."""
    recording = result.recording
    recording.tracks.update(share.recording.tracks)
    recording.states.update(share.recording.states)
    recording.signals.update(share.recording.signals)
    recording.photos.update(share.recording.photos)
    recording.safety.update(share.recording.safety)
    recording.flight.update(share.recording.flight)
    recording.waiting.update(share.recording.waiting)
    recording.killed.update(share.recording.killed)
    result.configs.update(share.configs)
    result.ticks.update(share.ticks)
    result.radio.adopt_links(share.links)


def _order_recording(result: DryRunResult, mission: Mission) -> None:
    """Put every part of the recording in the mission's agent order, as one process has it."""
    order = {name: i for i, name in enumerate(mission.agents)}
    recording = result.recording
    recording.tracks = dict(sorted(recording.tracks.items(), key=lambda kv: order[kv[0]]))
    recording.states = dict(sorted(recording.states.items(), key=lambda kv: order[kv[0]]))
    recording.photos = dict(sorted(recording.photos.items(), key=lambda kv: order[kv[0]]))
    recording.safety = dict(sorted(recording.safety.items(), key=lambda kv: order[kv[0]]))
    recording.flight = dict(sorted(recording.flight.items(), key=lambda kv: order[kv[0]]))
    recording.waiting = dict(sorted(recording.waiting.items(), key=lambda kv: order[kv[0]]))
    recording.killed = dict(sorted(recording.killed.items(), key=lambda kv: order[kv[0]]))
    recording.signals = dict(sorted(recording.signals.items(), key=lambda kv: order[kv[0][0]]))
