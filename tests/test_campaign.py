"""clark campaign end to end: the same table whatever the workers, reproducible failures,
exit codes, and runs stopped whole (their process group) on a timeout or Ctrl-C.

The mission (tests/campaign/short_drive.yaml) is one rover's 25 s drive whose tight
"stops near the point" check holds in some runs and not in others.
"""

from __future__ import annotations

import io
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from sitl_here import NO_SITL, real_install

from clark_engine.campaign.command import CampaignOptions, run_campaign
from clark_engine.campaign.pool import DaskCluster, InProcess, LocalPool, backend_for
from clark_engine.campaign.runs import run_in_group
from clark_engine.cli import main
from clark_engine.errors import UsageError

ROOT = Path(__file__).resolve().parent.parent
DRIVE = ROOT / "tests" / "campaign" / "short_drive.yaml"
WALL_LINE = re.compile(r"^Wall time: .*$", re.MULTILINE)


def campaign(path: Path, **options: object) -> tuple[int, str, str]:
    """Run a campaign in process; the exit code, standard output and standard error."""
    out, err = io.StringIO(), io.StringIO()
    code = run_campaign(
        path,
        CampaignOptions(quiet=True, **options),  # type: ignore[arg-type]
        out=out,
        err=err,
        command_line=["clark", "campaign", "MISSION"],
    )
    return code, out.getvalue(), err.getvalue()


def summary_of(folder: Path) -> str:
    """summary.md without its wall-time line (the one line that may differ)."""
    return WALL_LINE.sub("Wall time: -", (folder / "summary.md").read_text(encoding="utf-8"))


@pytest.mark.slow  # starts a Dask scheduler and two worker interpreters
def test_the_table_is_the_same_with_one_or_two_workers_and_through_dask(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    code_1, out_1, _ = campaign(DRIVE, runs=4, workers=1, report=tmp_path / "one")
    code_2, out_2, _ = campaign(DRIVE, runs=4, workers=2, report=tmp_path / "two")
    assert "2 of 4 runs pass" in out_1, out_1
    assert "| stops near the point | 4 | 2 | 50.0 % | 15.0 % - 85.0 % |" in out_1
    with distributed.LocalCluster(
        n_workers=2,
        threads_per_worker=1,
        processes=True,
        host="127.0.0.1",
        scheduler_port=0,
        dashboard_address=None,
        # The scheduler's HTTP server (metrics, health) on a free port: by default it
        # binds Dask's well-known 8787 even without a dashboard, and warns when a
        # user's own cluster holds it.
        scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
    ) as cluster:
        code_d, out_d, err_d = campaign(
            DRIVE, runs=4, scheduler=cluster.scheduler_address, report=tmp_path / "dask"
        )
        # SITL runs each take a `sitl` resource: workers that offer none are refused.
        with pytest.raises(UsageError, match="no worker offers the resource 'sitl'"):
            DaskCluster(cluster.scheduler_address, sitl=True)
    assert "Dask cluster at tcp://127.0.0.1:" in err_d
    assert code_1 == code_2 == code_d == 0
    assert out_1 == out_2 == out_d
    one = summary_of(tmp_path / "one")
    assert one == summary_of(tmp_path / "two") == summary_of(tmp_path / "dask")
    csv = (tmp_path / "one" / "runs.csv").read_text()
    assert csv == (tmp_path / "two" / "runs.csv").read_text()
    assert csv == (tmp_path / "dask" / "runs.csv").read_text()
    assert "## Failing runs" in one and "Reproduce: `clark dry-run" in one


def test_a_failing_run_is_reproduced_by_its_printed_command(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    code, out, _ = campaign(DRIVE, runs=4, workers=1, report=tmp_path / "r", failure_reports=True)
    assert code == 0
    commands = re.findall(r"^  run (\d+): (clark dry-run .*)$", out, re.MULTILINE)
    assert len(commands) == 2, out
    index, command = commands[0]
    # Every value drawn for the run is in the command, to be fixed with --vary.
    assert "--vary sim.gps_noise_m=" in command
    assert "--vary faults.0.corrupt.injected=" in command
    monkeypatch.chdir(ROOT)
    capsys.readouterr()
    assert main(shlex.split(command)[1:]) == 1
    table = capsys.readouterr().out
    assert "| stops near the point |" in table
    rows = [line for line in table.splitlines() if "**FAIL**" in line]
    assert len(rows) == 1 and rows[0].startswith("| stops near the point |")
    # The failing run's own dry-run report, and the campaign's lists it.
    run_summary = tmp_path / "r" / "runs" / index / "summary.md"
    assert run_summary.read_text().startswith("# Dry run of short-drive")
    assert f"runs/{index}/summary.md" in (tmp_path / "r" / "summary.md").read_text()
    # A second campaign replaces the report whole (its run reports included).
    code, _, _ = campaign(DRIVE, runs=2, workers=1, report=tmp_path / "r")
    assert code == 0
    assert not (tmp_path / "r" / "runs").exists()


def test_exit_status_follows_the_declared_minimum_pass_rates(tmp_path: Path) -> None:
    # The mission declares 20 % of runs and `drives` in every run: both met.
    assert campaign(DRIVE, runs=4, workers=1)[0] == 0
    code, out, err = campaign(DRIVE, runs=4, workers=1, min_pass_rate=0.9)
    assert code == 1
    assert "**NOT MET**" in out
    assert "minimum pass rate not met: every check (the run's verdict)" in err
    text = DRIVE.read_text().replace("{drives: 1.0}", "{parks: 1.0, drivez: 0.5}")
    wrong = tmp_path / "wrong.yaml"
    wrong.write_text(text)
    with pytest.raises(Exception, match=r"wrong.yaml:\d+:\d+: campaign.min_pass_rates: no check"):
        campaign(wrong, runs=1, workers=1)


def cli(*args: str, timeout_s: float = 120) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "clark_engine", "campaign", *args],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=timeout_s,
        check=False,
    )


def test_usage_errors_exit_2_and_an_invalid_mission_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["campaign", str(DRIVE), "--failure-reports"]) == 2
    assert "--failure-reports goes with --report" in capsys.readouterr().err
    assert main(["campaign", str(DRIVE), "--sitl-per-worker", "2"]) == 2
    assert main(["campaign", str(DRIVE), "--fault", "kill:nobody@3"]) == 2
    assert "there is no agent 'nobody'" in capsys.readouterr().err
    assert main(["campaign", str(tmp_path / "absent.yaml")]) == 2
    bad = tmp_path / "bad.yaml"
    bad.write_text(DRIVE.read_text().replace("loop_hz: 10", "loop_hz: -1"))
    assert main(["campaign", str(bad), "--runs", "2"]) == 1
    assert "invalid; nothing flown" in capsys.readouterr().err
    with pytest.raises(SystemExit) as stop:
        main(["campaign", str(DRIVE), "--runs", "0"])
    assert stop.value.code == 2


def test_a_run_past_its_timeout_is_stopped_retried_and_counted_apart(tmp_path: Path) -> None:
    # 0.2 s is less than an interpreter takes to import the engine: every try times out.
    result = cli(
        str(DRIVE), "--runs", "2", "--workers", "1", "--run-timeout-s", "0.2", "--retries", "1",
        "--report", str(tmp_path / "r"),
    )  # fmt: skip
    assert result.returncode == 2, result.stderr
    assert "4 infrastructure failure(s)" in result.stderr
    assert "timed out after 0.2 s" in result.stderr
    assert "no run gave a verdict" in result.stderr
    summary = (tmp_path / "r" / "summary.md").read_text()
    assert "## Infrastructure failures" in summary and "timed out" in summary
    assert "Traceback" not in result.stderr


SLOW_RUN = """
import os, subprocess, sys, time
child = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
open(sys.argv[1], "w").write(f"{os.getpid()} {child.pid}")
time.sleep(60)
"""


def _gone(pid: int) -> bool:
    try:
        status = Path(f"/proc/{pid}/stat").read_text().split(")")[-1].split()[0]
    except OSError:
        return True
    return status == "Z"


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="process groups and /proc")
def test_a_timeout_kills_the_runs_whole_process_group(tmp_path: Path) -> None:
    pids = tmp_path / "pids"
    script = tmp_path / "slow.py"
    script.write_text(SLOW_RUN)
    start = time.monotonic()
    code = run_in_group([sys.executable, str(script), str(pids)], timeout_s=2.0, grace_s=1.0)
    assert code is None
    assert time.monotonic() - start < 30
    leader, grandchild = (int(p) for p in pids.read_text().split())
    deadline = time.monotonic() + 10
    while not (_gone(leader) and _gone(grandchild)) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert _gone(leader) and _gone(grandchild)


def _children(pid: int) -> list[int]:
    out = []
    for task in Path(f"/proc/{pid}/task").iterdir():
        text = (task / "children").read_text().split()
        out += [int(p) for p in text]
    return out


@pytest.mark.slow  # starts clark and its pool
@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc")
def test_ctrl_c_stops_the_workers_and_writes_nothing(tmp_path: Path) -> None:
    report = tmp_path / "r"
    process = subprocess.Popen(
        [sys.executable, "-m", "clark_engine", "campaign", str(DRIVE), "--runs", "40",
         "--workers", "2", "--report", str(report)],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        assert process.stderr is not None
        for line in process.stderr:
            if line.startswith("campaign of short-drive"):
                break
        deadline = time.monotonic() + 30
        workers: list[int] = []
        while len(workers) < 2 and time.monotonic() < deadline:
            workers = _children(process.pid)
            time.sleep(0.05)
        assert len(workers) >= 2
        time.sleep(0.5)
        process.send_signal(signal.SIGINT)
        _, err = process.communicate(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 130, err
    assert "no report written" in err
    assert not report.exists()
    assert not [p for p in os.listdir(tmp_path) if p.startswith(".r.")]
    deadline = time.monotonic() + 10
    while not all(_gone(p) for p in workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    assert all(_gone(p) for p in workers)


SITL = real_install()


def test_a_local_sitl_campaign_flies_at_most_sitl_per_worker_at_once() -> None:
    """Locally, the pool's size caps the SITL stacks flown at once (one per process)."""
    pools = [backend_for(None, 4, True, 2, 10), backend_for(None, 4, False, 1, 10)]
    try:
        assert [getattr(p, "processes", None) for p in pools] == [2, 4]  # SITL's cap only
        assert all(isinstance(p, LocalPool) for p in pools)
    finally:
        for pool in pools:
            pool.close(cancel=False)  # no run was queued: no process was started
    assert isinstance(backend_for(None, 4, True, 1, 10), InProcess)


@pytest.mark.sitl
@pytest.mark.slow  # a Dask scheduler, a worker interpreter, two SITL stacks
@pytest.mark.skipif(SITL is None, reason=NO_SITL)
def test_a_sitl_campaign_on_a_dask_cluster_isolates_each_run(tmp_path: Path) -> None:
    """Two SITL runs through a loopback Dask cluster whose one worker offers two ``sitl``.

    Each run takes one ``sitl`` resource, its own SITL instances and ports: the two fly
    at once on the one worker and both finish with the comparison's row.
    """
    distributed = pytest.importorskip("distributed")
    assert SITL is not None
    with distributed.LocalCluster(
        n_workers=1,
        threads_per_worker=2,
        processes=True,
        resources={"sitl": 2},
        host="127.0.0.1",
        scheduler_port=0,
        dashboard_address=None,
        scheduler_kwargs={"dashboard": False, "dashboard_address": "127.0.0.1:0"},
    ) as cluster:
        result = cli(
            str(DRIVE), "--runs", "2", "--autopilot", "sitl", "--sitl", str(SITL.folder),
            "--scheduler", cluster.scheduler_address, "--until", "20",
            "--report", str(tmp_path / "r"), timeout_s=400,
        )  # fmt: skip
    assert result.returncode in (0, 1), result.stderr
    assert "on ArduPilot SITL at 10x" in result.stderr
    assert "Dask cluster at tcp://127.0.0.1:" in result.stderr
    summary = (tmp_path / "r" / "summary.md").read_text()
    assert "| the same mission on ArduPilot SITL | 2 |" in summary
    assert "Traceback" not in result.stderr
