"""clark run on loopback: a keyed vehicle killed with SIGKILL rejoins its station (issue 18).

cooperative_follow with a key: the station (``mcs``, a heartbeat a second) and
``slash_b`` as two ``python -m clark_engine run`` processes on UDP loopback, slash_b's
autopilot served from this process (tests/test_cli_run.py's rehearsal). slash_b is
killed with SIGKILL once its behaviour runs, and started again on the same state folder
(its replay marks) with a new logs folder. Times asserted are the runtime's own, read
from its logs, never the test's duration. The in-process twin of this test, on virtual
clocks, is tests/test_link_replay_restart.py.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import pytest
from test_cli_run import (
    MISSION,
    ServedAutopilot,
    clark_run,
    free_ports,
    kill,
    started,
    text,
    wait_for,
)

from clark_engine.link.auth import generate_key_file

_LINE_TIME = re.compile(r"^t=(\d+\.\d+) ")


def _times(log: str, needle: str) -> list[float]:
    """The runtime times (s) of the mission log's lines holding ``needle``."""
    found = []
    for line in log.splitlines():
        match = _LINE_TIME.match(line)
        if match and needle in line:
            found.append(float(match.group(1)))
    return found


def _fleet_now_s(path: Path) -> float:
    """The runtime time of the fleet table's latest row (0 before one)."""
    lines = text(path).splitlines()
    last = lines[-1].split(",", 1)[0] if len(lines) > 1 else ""
    try:
        return float(last)
    except ValueError:
        return 0.0  # a row being written


@pytest.fixture
def served() -> ServedAutopilot:
    autopilot = ServedAutopilot("slash_b")
    try:
        yield autopilot  # type: ignore[misc]
    finally:
        autopilot.close()


@pytest.mark.slow
def test_a_keyed_vehicle_killed_and_restarted_hears_its_station_at_once(
    served: ServedAutopilot, tmp_path: Path
) -> None:
    mission = tmp_path / "follow.yaml"
    mission.write_text(
        MISSION.read_text(encoding="utf-8").replace(
            "  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n", 1
        ),
        encoding="utf-8",
    )
    generate_key_file(tmp_path / "coop.key")
    state = tmp_path / "state"
    station_logs, first_logs, second_logs = (tmp_path / n for n in ("mcs", "run1", "run2"))
    station_port, vehicle_port = free_ports(2)
    autopilot = ("--autopilot-connection", f"udpout:127.0.0.1:{served.port}")

    def vehicle(logs: Path) -> subprocess.Popen[str]:
        return clark_run(
            "slash_b",
            logs,
            vehicle_port,
            "mcs",
            station_port,
            *autopilot,
            "--state",
            str(state),
            mission=mission,
        )

    processes: list[subprocess.Popen[str]] = []
    try:
        station = clark_run(
            "mcs", station_logs, station_port, "slash_b", vehicle_port, mission=mission
        )
        processes.append(station)
        first = vehicle(first_logs)
        processes.append(first)
        started(station)
        started(first)
        wait_for(
            "slash_b's behaviour starts, hearing the station",
            lambda: (
                "; the behaviour starts" in text(first_logs / "slash_b.mission.log")
                and "found mcs" in text(first_logs / "slash_b.mission.log")
            ),
            processes,
        )
        wait_for(
            "the station's packets keep coming",
            lambda: len(text(first_logs / "slash_b.fleet.csv").splitlines()) > 5,
            processes,
        )
        first.kill()  # SIGKILL: no clean stop, no replay marks saved
        first.communicate()
        processes.remove(first)
        second = vehicle(second_logs)
        processes.append(second)
        started(second)
        log = second_logs / "slash_b.mission.log"
        wait_for("slash_b hears the station again", lambda: "found mcs" in text(log), processes)
        wait_for(
            "slash_b has run 8 s: past heartbeat_timeout_s (3 s) after its behaviour started",
            lambda: _fleet_now_s(second_logs / "slash_b.fleet.csv") > 8.0,
            processes,
        )
        for process in processes:
            process.terminate()
        for process in processes:
            process.communicate(timeout=30)
    finally:
        kill(processes)
    lines = text(log)
    (found_s,) = _times(lines, "found mcs")
    start_s = _times(lines, "")[0]
    assert found_s - start_s <= 2.0, lines
    assert "mcs_lost" not in lines and "lost mcs" not in lines
    assert "the behaviour starts" in lines
    interface = text(second_logs / "slash_b.interface.log")
    assert interface.count("ReplayedPacket") <= 2, interface
