"""A dry run split across processes gives what one process gives, byte for byte.

Splitting (clark_engine.sim.parallel) is only worth having if it changes the speed
and nothing else: the same logs, CSV files, recording and link statistics whatever
the number of processes. These runs cover every way agents meet (broadcasts and
unicasts over ranged XBee radios, so positions matter; the operator's commands and
a pilot's stick; cameras) and every fault (kill, link drop, station silence,
autopilot disconnect, corruption), each of which crosses between processes.
"""

from __future__ import annotations

import io
import multiprocessing
import os
import re
import subprocess
import sys
from collections.abc import Callable, Mapping, Sequence
from pathlib import Path
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clark_engine import cli
from clark_engine.mission.model import Mission
from clark_engine.sim import parallel
from clark_engine.sim.dryrun import run_dry_run
from clark_engine.sim.engine import DryRun, DryRunResult
from clark_engine.sim.parallel import (
    WorkerFailed,
    WorkerVanished,
    choose_workers,
    partition,
    run_split,
)
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = ROOT / "missions"

pytestmark = pytest.mark.skipif(not parallel.can_split(), reason="no fork on this platform")


def load(path: Path) -> Mission:
    validation = validate_file(path, str(path))
    assert validation.mission is not None, [f.format_text() for f in validation.findings]
    return validation.mission


def simulate(
    path: Path,
    workers: int,
    until_s: float,
    log_dir: Path,
    faults: Sequence[Mapping[str, Any]] = (),
) -> DryRunResult:
    mission = load(path)
    log_dir.mkdir(parents=True)
    seed = int(mission.sim.get("seed", 0))
    if workers == 1:
        run = DryRun(
            mission, path, seed=seed, until_s=until_s, log_dir=log_dir, extra_faults=faults
        )
        return run.run()
    return run_split(
        mission,
        path,
        workers=workers,
        seed=seed,
        until_s=until_s,
        log_dir=log_dir,
        extra_faults=faults,
        progress=None,
    )


def files(folder: Path) -> dict[str, bytes]:
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


def short_range(tmp_path: Path) -> Path:
    """fault_lost_peer with 110 m radios: some packets are lost to distance, so every
    process needs every vehicle's position at the time of each send."""
    text = (MISSIONS / "fault_lost_peer.yaml").read_text()
    shorter = re.sub(r'(radio: \{address: "[0-9A-F]+")\}', r"\1, range_m: 110}", text)
    assert shorter.count("range_m: 110") == 4
    path = tmp_path / "fault_lost_peer.yaml"
    path.write_text(shorter)
    return path


CASES = [
    # The rovers drive from about 43 s, once ready and armed by their pilots.
    # short-range radios, a kill, an autopilot disconnect, 20 % corruption; plus a link drop
    (
        "fault_lost_peer",
        85.0,
        [{"link_drop": {"between": ["slash_b", "mcs"], "from_s": 50.0, "to_s": 60.0}}],
    ),
    ("fault_station_loss", 95.0, []),  # the station goes silent; failsafes
    ("cooperative_follow", 75.0, []),  # the operator activates a follower
    ("supercub_sysid_rc", 40.0, []),  # a pilot's switch on the RC (an operator rc action)
    ("three_vehicles_payload", 60.0, []),  # cameras; a copter takes off
]


@pytest.mark.parametrize(("name", "until_s", "faults"), CASES, ids=[c[0] for c in CASES])
def test_a_split_run_is_byte_identical_to_one_process(
    tmp_path: Path, name: str, until_s: float, faults: list[dict[str, Any]]
) -> None:
    path = short_range(tmp_path) if name == "fault_lost_peer" else MISSIONS / f"{name}.yaml"
    one = simulate(path, 1, until_s, tmp_path / "one", faults)
    workers = 3 if name == "fault_lost_peer" else 2
    split = simulate(path, workers, until_s, tmp_path / "split", faults)
    assert split.workers == workers
    expected = files(tmp_path / "one")
    assert expected, "the run wrote logs"
    assert files(tmp_path / "split") == expected
    assert split.recording == one.recording
    assert split.radio.links() == one.radio.links()
    assert split.ticks == one.ticks
    assert sum(one.ticks.values()) > 0
    assert split.configs == one.configs  # the checks and the plots read every agent's
    assert list(split.configs) == list(one.configs)


def fleet(agents: int, tmp_path: Path, radio: str = "xbee", extra: str = "") -> Path:
    """A generated fleet (benchmarks/fleet.py) written to ``tmp_path``, plus ``extra`` YAML."""
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        from fleet import fleet_mission
    finally:
        sys.path.pop(0)
    path = tmp_path / f"fleet_{agents}_{radio}{'_extra' if extra else ''}.yaml"
    path.write_text(fleet_mission(agents, radio=radio) + extra)
    return path


FAULTS = st.one_of(
    st.builds(
        lambda victim, at_s: {"kill": {"agent": f"v{victim:03d}", "at_s": at_s}},
        st.integers(2, 7),
        st.floats(0.0, 12.0),
    ),
    st.builds(
        lambda a, b, t1, span: {
            "link_drop": {"between": [f"v{a:03d}", f"v{b:03d}"], "from_s": t1, "to_s": t1 + span}
        },
        st.integers(2, 4),
        st.integers(5, 7),
        st.floats(0.0, 10.0),
        st.floats(0.5, 5.0),
    ),
    st.builds(
        lambda share, t1: {"corrupt": {"share": share, "from_s": t1, "to_s": t1 + 5.0}},
        st.floats(0.0, 1.0),
        st.floats(0.0, 10.0),
    ),
    st.builds(lambda t1: {"station_silent": {"from_s": t1, "to_s": t1 + 4.0}}, st.floats(0, 10)),
)


@settings(
    max_examples=6, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    agents=st.integers(7, 8),
    seed=st.integers(0, 2**16),
    workers=st.integers(2, 4),
    faults=st.lists(FAULTS, max_size=3),
)
def test_any_split_of_any_fleet_is_identical(
    tmp_path_factory: pytest.TempPathFactory,
    agents: int,
    seed: int,
    workers: int,
    faults: list[dict[str, Any]],
) -> None:
    """Random fleets, seeds, faults and numbers of processes: always the same bytes."""
    tmp_path = tmp_path_factory.mktemp("fleet")
    path = fleet(agents, tmp_path)
    mission = load(path)
    runs = []
    for count, folder in ((1, "one"), (workers, "split")):
        log_dir = tmp_path / folder
        log_dir.mkdir()
        if count == 1:
            run = DryRun(
                mission, path, seed=seed, until_s=15.0, log_dir=log_dir, extra_faults=faults
            )
            runs.append(run.run())
        else:
            runs.append(
                run_split(
                    mission,
                    path,
                    workers=count,
                    seed=seed,
                    until_s=15.0,
                    log_dir=log_dir,
                    extra_faults=faults,
                    progress=None,
                )
            )
    one, split = runs
    assert files(tmp_path / "split") == files(tmp_path / "one")
    assert split.recording == one.recording
    assert split.radio.links() == one.radio.links()


EXAMPLES = sorted(MISSIONS.glob("*.yaml"))


@pytest.mark.parametrize("path", EXAMPLES, ids=[p.stem for p in EXAMPLES])
def test_a_split_run_gives_the_same_checks_table(path: Path, tmp_path: Path) -> None:
    """Checks read every agent's config (signals, separation, failsafes): none may be missing.

    So does the safety judgement (every vehicle's envelope, every pair): its tables too.
    """
    tables = []
    for workers in (1, 2):
        out, err = io.StringIO(), io.StringIO()
        outcome = run_dry_run(
            path,
            seed=None,
            until_s=None,
            report=None,
            speed=None,
            workers=workers,
            out=out,
            err=err,
        )
        assert outcome.result is not None and outcome.result.workers == workers, err.getvalue()
        assert outcome.exit_code == 0, out.getvalue() + err.getvalue()
        tables.append(out.getvalue())
    assert tables[0] == tables[1]
    assert tables[0].split("\nSafety (judged in every run):")[0].count("| pass |") >= 3
    assert "Safety (judged in every run):" in tables[0]


def test_the_split_exercises_what_it_claims(tmp_path: Path) -> None:
    """The byte-identity above is not vacuous: packets crossed and were lost to faults."""
    path = short_range(tmp_path)
    mission = load(path)
    result = simulate(path, 3, 90.0, tmp_path / "run")
    shares = partition(mission, 3, int(mission.sim.get("seed", 0)))
    assert all(shares), shares
    crossing = [
        stats
        for (sender, receiver), stats in result.radio.links().items()
        if any(sender in s and receiver not in s for s in shares)
    ]
    assert sum(s.delivered for s in crossing) > 100
    assert sum(s.corrupted for s in crossing) > 0
    assert sum(s.lost_fault for s in crossing) > 0  # the dead leader's radio
    assert sum(s.lost_range for s in crossing) > 0  # positions crossed processes


def test_partition_is_balanced_and_complete() -> None:
    mission = load(MISSIONS / "three_vehicles_payload.yaml")
    for workers in (1, 2, 3, 4):
        shares = partition(mission, workers, 1)
        assert sorted(n for s in shares for n in s) == sorted(mission.agents)
        assert len(shares) == workers
        assert max(map(len, shares)) - min(map(len, shares)) <= 1
    assert partition(mission, 2, 1) == partition(mission, 2, 1)


def test_choose_workers(tmp_path: Path) -> None:
    small = load(MISSIONS / "cooperative_follow.yaml")
    assert choose_workers(None, small) == 1  # too few agents to gain
    assert choose_workers(2, small) == 2
    assert choose_workers(64, small) == len(small.agents)  # at most one per agent
    text = (MISSIONS / "cooperative_follow.yaml").read_text()
    assert "sim: {duration_s: 170," in text
    instant = tmp_path / "instant.yaml"
    instant.write_text(text.replace("sim: {", "sim: {radio_latency_s: 0, "))
    # XBee air time alone (18 framing bytes at 33 kbit/s) still leaves a few milliseconds.
    assert choose_workers(2, load(instant)) == 2
    big = fleet(parallel.AUTO_MIN_AGENTS, tmp_path, radio="udp_lan")
    expected = min(parallel.usable_cores(), parallel.AUTO_MAX_WORKERS)
    assert choose_workers(None, load(big)) == expected
    fast = fleet(parallel.AUTO_MIN_AGENTS, tmp_path, "udp_lan", "sim: {radio_latency_s: 0}\n")
    # a UDP LAN with no latency: a lookahead of microseconds is not worth splitting on
    assert choose_workers(2, load(fast)) == 1


def _raise() -> None:
    raise RuntimeError("boom in a worker")


def _vanish() -> None:
    os._exit(9)  # no error frame: as the OOM killer or kill -9 would end it


def fail_in_workers(monkeypatch: pytest.MonkeyPatch, fail: Callable[[], None]) -> None:
    """Make every forked worker call ``fail`` at its first tick after 5 s (they inherit it)."""
    parent = os.getpid()
    original = DryRun._tick

    def tick(self: DryRun, sim_agent: Any, t_s: float) -> None:
        if os.getpid() != parent and t_s > 5.0:
            fail()
        original(self, sim_agent, t_s)

    monkeypatch.setattr(DryRun, "_tick", tick)


@pytest.mark.parametrize(
    ("fail", "error", "pattern"),
    [
        (_raise, WorkerFailed, "boom in a worker"),  # a bug: its traceback is the message
        (_vanish, WorkerVanished, r"worker process 1 (ended|is gone)"),
    ],
    ids=["raises", "vanishes"],
)
def test_a_failing_worker_is_reported_not_hung(
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    fail: Callable[[], None],
    error: type[Exception],
    pattern: str,
) -> None:
    fail_in_workers(monkeypatch, fail)
    with pytest.raises(error, match=pattern):
        simulate(MISSIONS / "cooperative_follow.yaml", 2, 30.0, tmp_path / "run")
    assert multiprocessing.active_children() == []


def test_cli_reports_a_vanished_worker_in_one_line(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A worker gone mid-run (kill -9, out of memory): exit 2, what to do, no traceback."""
    fail_in_workers(monkeypatch, _vanish)
    mission = MISSIONS / "cooperative_follow.yaml"
    code = cli.main(["dry-run", str(mission), "--workers", "2", "--until", "30"])
    err = capsys.readouterr().err
    assert code == 2, err
    assert "clark dry-run: error: the dry run's worker process 1" in err
    assert "--workers 1" in err and "Traceback" not in err
    assert multiprocessing.active_children() == []


def test_cli_workers_option(tmp_path: Path) -> None:
    mission = MISSIONS / "cooperative_follow.yaml"

    def clark(*args: str) -> subprocess.CompletedProcess[str]:
        return subprocess.run(
            [sys.executable, "-m", "clark_engine", "dry-run", str(mission), *args],
            capture_output=True,
            text=True,
            cwd=ROOT,
            check=False,
        )

    one = clark("--workers", "1")
    two = clark("--workers", "2")
    assert one.returncode == two.returncode == 0, one.stderr + two.stderr
    assert one.stdout == two.stdout  # the checks table
    assert "2 processes" in two.stderr and "processes" not in one.stderr
    bad = clark("--workers", "0")
    assert bad.returncode == 2
    assert "--workers" in bad.stderr and "Traceback" not in bad.stderr
