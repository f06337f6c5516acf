"""clark run on loopback: the station and a vehicle as two processes, a simulated autopilot.

The two-process rehearsal of docs/run.md: cooperative_follow's station (``mcs``) and
``slash_b`` each run as ``python -m clark_engine run ...`` with a UDP radio on
127.0.0.1; slash_b's autopilot is the dry run's own simulated ArduRover, served on a
UDP port from a thread of this process at wall-clock pace by ``clark autopilot-sim``'s
:class:`~clark_engine.standins.autopilot_sim.ServedSimulated` (it listens and answers whoever sent
it a datagram; ``clark run`` connects with ``udpout:``). Nothing here sleeps to wait
for a moment: each step waits for a line in a log file or on stdout, with a timeout.
"""

from __future__ import annotations

import select
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from pathlib import Path

import pytest

from clark_engine.cli import main
from clark_engine.standins.autopilot_sim import ServedSimulated
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
TIMEOUT_S = 30.0
"""Longest wait for any one thing to happen (a loaded machine; never reached when it works)."""


class ServedAutopilot:
    """``clark autopilot-sim``'s simulated autopilot (its boot shortened to ``ready_s``),
    served from a thread of this process at wall-clock pace; its pilot arms it when ready."""

    def __init__(self, agent: str, ready_s: float = 1.0) -> None:
        mission = validate_file(MISSION).mission
        assert mission is not None
        self.server = ServedSimulated(mission, agent, ready_s=ready_s)
        self.port = self.server.transport.address[1]
        self._stop = threading.Event()
        self._thread = threading.Thread(
            target=self.server.serve, args=(self._stop.is_set, lambda _line: None)
        )
        self._thread.start()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(timeout=10)
        self.server.close()


@pytest.fixture
def served() -> Iterator[ServedAutopilot]:
    autopilot = ServedAutopilot("slash_b")
    try:
        yield autopilot
    finally:
        autopilot.close()


def free_ports(n: int) -> list[int]:
    """``n`` distinct UDP ports free on loopback now (closed again before use)."""
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for sock in socks:
            sock.bind(("127.0.0.1", 0))
        return [sock.getsockname()[1] for sock in socks]
    finally:
        for sock in socks:
            sock.close()


def wait_for(what: str, found: Callable[[], bool], processes: list[subprocess.Popen[str]]) -> None:
    """Wait until ``found()``; fail with ``what`` after TIMEOUT_S or if a process died."""
    deadline = time.monotonic() + TIMEOUT_S
    while not found():
        for process in processes:
            if process.poll() is not None:
                _out, err = process.communicate()
                raise AssertionError(f"{what}: {process.args} ended {process.returncode}: {err}")
        if time.monotonic() > deadline:
            raise AssertionError(f"{what}: not within {TIMEOUT_S:g} s")
        time.sleep(0.05)


def text(path: Path) -> str:
    return path.read_text(encoding="utf-8") if path.exists() else ""


def clark_run(
    agent: str, logs: Path, own: int, peer: str, port: int, *extra: str, mission: Path = MISSION
) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [
            sys.executable,
            "-m",
            "clark_engine",
            "run",
            str(mission),
            "--agent",
            agent,
            "--radio",
            "udp",
            "--radio-address",
            f"127.0.0.1:{own}",
            "--peer",
            f"{peer}=127.0.0.1:{port}",
            "--no-payload",
            "--plain",
            "--logs",
            str(logs),
            *extra,
        ],
        stdin=subprocess.PIPE,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def stop(process: subprocess.Popen[str]) -> tuple[int, str, str]:
    """SIGTERM once the shell handles it (its first status line), then the exit code."""
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=TIMEOUT_S)
    return process.returncode, out, err


def kill(processes: list[subprocess.Popen[str]]) -> None:
    for process in processes:
        if process.poll() is None:
            process.kill()
        process.communicate()


def started(process: subprocess.Popen[str]) -> None:
    """Read stdout up to the first status line: the loop runs and handles SIGTERM."""
    assert process.stdout is not None
    first = process.stdout.readline()
    assert first.startswith("clark run: "), first
    status = process.stdout.readline()
    assert " mission cooperative-follow " in status, status


@pytest.mark.slow
def test_station_and_vehicle_rehearse_on_loopback(served: ServedAutopilot, tmp_path: Path) -> None:
    logs = tmp_path / "logs"
    station_port, vehicle_port = free_ports(2)
    processes: list[subprocess.Popen[str]] = []
    try:
        station = clark_run("mcs", logs, station_port, "slash_b", vehicle_port)
        processes.append(station)
        vehicle = clark_run(
            "slash_b",
            logs,
            vehicle_port,
            "mcs",
            station_port,
            "--autopilot-connection",
            f"udpout:127.0.0.1:{served.port}",
        )
        processes.append(vehicle)
        started(station)
        started(vehicle)
        # Heartbeats cross: each side's fleet table holds the other.
        wait_for(
            "the station hears slash_b",
            lambda: "slash_b" in text(logs / "mcs.fleet.csv"),
            processes,
        )
        wait_for(
            "slash_b hears the station",
            lambda: "mcs" in text(logs / "slash_b.fleet.csv"),
            processes,
        )
        # The simulated pilot arms the ready vehicle; the behaviour starts in idle.
        wait_for(
            "slash_b's behaviour starts",
            lambda: "; the behaviour starts" in text(logs / "slash_b.mission.log"),
            processes,
        )
        # The operator types on the station's terminal.
        assert station.stdin is not None
        station.stdin.write("activate slash_b\n")
        station.stdin.flush()
        wait_for(
            "the activation reaches slash_b",
            lambda: "activate: idle -> chase" in text(logs / "slash_b.mission.log"),
            processes,
        )
        vehicle_code, _vehicle_out, vehicle_err = stop(vehicle)
        station_code, station_out, station_err = stop(station)
    finally:
        kill(processes)
    assert vehicle_code == 0, vehicle_err
    assert station_code == 0, station_err
    assert "operator: activate slash_b: sent" in station_out
    assert "stopped (SIGTERM)" in station_out
    vehicle_log = text(logs / "slash_b.mission.log")
    assert "terminating: real-time shell stopping (SIGTERM)" in vehicle_log
    assert "terminated; vehicle to HOLD" in vehicle_log
    assert "terminated" in text(logs / "mcs.mission.log").splitlines()[-1]
    assert "Traceback" not in vehicle_err + station_err


def test_check_autopilot_against_the_served_simulated_autopilot(
    served: ServedAutopilot, capsys: pytest.CaptureFixture[str]
) -> None:
    code = main(
        [
            "check",
            "autopilot",
            str(MISSION),
            "--agent",
            "slash_b",
            "--autopilot-connection",
            f"udpout:127.0.0.1:{served.port}",
            "--seconds",
            "3",
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert f"connecting to udp to 127.0.0.1:{served.port}" in out
    assert "heartbeat: " in out and "state: mode " in out
    assert "autopilot: heartbeat yes; verified yes" in out
    assert out.rstrip().endswith("autopilot: OK")


def test_the_station_plays_the_missions_operator_script(tmp_path: Path) -> None:
    """--script: the station sends the mission's operator entries at their times."""
    mission = tmp_path / "follow.yaml"
    text_in = MISSION.read_text(encoding="utf-8")
    assert "{at_s: 65, activate: slash_b}" in text_in
    mission.write_text(
        text_in.replace("{at_s: 65, activate: slash_b}", "{at_s: 1, activate: slash_b}")
    )
    logs = tmp_path / "logs"
    station_port, vehicle_port = free_ports(2)
    processes: list[subprocess.Popen[str]] = []
    try:
        station = clark_run(
            "mcs", logs, station_port, "slash_b", vehicle_port, "--script", mission=mission
        )
        processes.append(station)
        started(station)
        assert station.stdout is not None
        said = ""
        deadline = time.monotonic() + TIMEOUT_S
        while "script at 1 s: activate slash_b" not in said and time.monotonic() < deadline:
            ready, _, _ = select.select([station.stdout], [], [], 0.5)
            if ready:
                said += station.stdout.readline()
        assert "script at 1 s: activate slash_b" in said, said
        code, _out, err = stop(station)
    finally:
        kill(processes)
    assert code == 0, err
    assert "Traceback" not in err
    assert "operator: activate slash_b" in text(logs / "mcs.mission.log")  # the runtime sent it
