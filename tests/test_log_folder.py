"""One rule finds a run's logs for ``clark analyze``, ``--checks`` and ``clark replay``.

Before, ``clark analyze`` and ``--checks`` read only the folder given and ``clark replay``
also its ``logs/`` and sub-folders; each layout any of them accepted is accepted by all.
"""

from __future__ import annotations

import shutil
from collections.abc import Callable
from pathlib import Path

import pytest

from clark_engine.analysis.latency import analyze_folder
from clark_engine.analysis.log_folder import find_log_files
from clark_engine.expectations.from_logs import check_folder
from clark_engine.runtime.logbook import MESSAGE_LOG_COLUMNS
from clark_engine.station.replay import load_replay
from tests.test_analyze_checks import COOPERATIVE, mission_at, write_run

AGENTS = ["mcs", "slash_a", "slash_b"]


def _run(folder: Path) -> Path:
    """cooperative_follow's mission logs and fleet CSVs, and a message log per agent."""
    folder.mkdir(parents=True)
    write_run(folder)
    for agent in AGENTS:
        rows = [",".join(MESSAGE_LOG_COLUMNS), "sent,1.0,1400000001000,*,1,40,agent_status,,,"]
        (folder / f"{agent}.messages.csv").write_text("\n".join(rows) + "\n")
    return folder


def run_folder(tmp: Path) -> Path:
    """A ``clark run`` folder (or a report's logs/ given itself): the files side by side."""
    return _run(tmp / "run")


def report_folder(tmp: Path) -> Path:
    """A dry-run report: the files in its logs/ folder."""
    _run(tmp / "report" / "logs")
    return tmp / "report"


def agents_folders(tmp: Path) -> Path:
    """The agents' own folders, gathered from several machines."""
    flat = _run(tmp / "flat")
    for path in sorted(flat.iterdir()):
        agent = path.name.split(".")[0]
        (tmp / "gathered" / agent).mkdir(parents=True, exist_ok=True)
        shutil.move(path, tmp / "gathered" / agent / path.name)
    return tmp / "gathered"


LAYOUTS: list[Callable[[Path], Path]] = [run_folder, report_folder, agents_folders]


@pytest.mark.parametrize("layout", LAYOUTS, ids=lambda f: f.__name__)
def test_every_reader_accepts_every_layout(tmp_path: Path, layout: Callable[[Path], Path]) -> None:
    folder = layout(tmp_path)
    assert sorted(find_log_files(folder, [])) == AGENTS
    assert list(analyze_folder(folder).agents) == AGENTS
    assert sorted(check_folder(folder, mission_at(COOPERATIVE)).run.agents) == AGENTS
    replay, _ = load_replay(folder, mission_at(COOPERATIVE))
    vehicles = sorted(str(agent.info["name"]) for agent in replay._agents)
    assert vehicles == AGENTS[1:]  # the station is no row of the table


def test_a_file_found_twice_is_taken_from_the_first_place_and_noted(tmp_path: Path) -> None:
    folder = report_folder(tmp_path)
    shutil.copy(folder / "logs" / "mcs.mission.log", folder / "mcs.mission.log")
    notes: list[str] = []
    files = find_log_files(folder, notes)
    assert files["mcs"]["mission_log"] == folder / "mcs.mission.log"
    assert any("found twice" in note for note in notes)


def test_configured_file_names_are_found(tmp_path: Path) -> None:
    folder = tmp_path / "run"
    folder.mkdir()
    (folder / "station-log.txt").write_text("x\n")
    files = find_log_files(folder, [], {"mcs": {"mission_log": "station-log.txt"}})
    assert files == {"mcs": {"mission_log": folder / "station-log.txt"}}
