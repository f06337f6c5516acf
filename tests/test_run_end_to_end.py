"""The cooperative-follow mission flown end to end as the bench rehearses it (docs/flight.md).

Three ``clark run`` processes on loopback (the station ``mcs`` playing the mission's
operator script, ``slash_a`` and ``slash_b``), each vehicle's autopilot a real ArduRover
SITL served by ``clark autopilot-sim --autopilot sitl`` at real time (the simulated
autopilot, ``--autopilot sim``, where ../shared/ardupilot-sitl is absent), the safety
pilot arming each rover once ArduPilot says it is ready. The radios are UDP, then
emulated XBee 900HPs (``clark radio-sim xbee``: digi-xbee in every process, one 33 kbit/s
channel). The mission completes (Slash B parks by Slash A), its checks pass when
evaluated from the logs alone (``clark analyze LOGS --checks MISSION``), and the
station's logs hold every agent's status.

Every process is a real ``python -m clark_engine`` child; nothing is mocked. Each wait is
for a line in a log or on stdout, with a timeout: the mission runs in real time (about
100 s: ArduRover needs 42 s to be ready, the operator activates Slash B at 65 s).
"""

from __future__ import annotations

import csv
import os
import signal
import socket
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path

import pytest
from sitl_here import real_install

from clark_engine.sitl.launcher import ENV_SITL

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
AGENTS = ("mcs", "slash_a", "slash_b")
VEHICLES = ("slash_a", "slash_b")
START_TIMEOUT_S = 90.0
"""Longest wait for a process's first lines (SITL unpacks its binary on a first start)."""
MISSION_TIMEOUT_S = 240.0
"""Longest wait for Slash B to park: the checks want it by 120 s of the station's clock."""
STOP_TIMEOUT_S = 60.0


SITL = real_install()
AUTOPILOT = "sitl" if SITL is not None else "sim"
"""ArduPilot SITL where it is installed; the simulated autopilot in real time elsewhere."""


def clark(*args: str) -> subprocess.Popen[str]:
    env = dict(os.environ)
    if SITL is not None:
        env[ENV_SITL] = str(SITL.folder)
    return subprocess.Popen(
        [sys.executable, "-m", "clark_engine", *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        cwd=ROOT,
    )


def free_udp_ports(n: int) -> list[int]:
    socks = [socket.socket(socket.AF_INET, socket.SOCK_DGRAM) for _ in range(n)]
    try:
        for sock in socks:
            sock.bind(("127.0.0.1", 0))
        return [sock.getsockname()[1] for sock in socks]
    finally:
        for sock in socks:
            sock.close()


def read_line_with(process: subprocess.Popen[str], needle: str) -> str:
    """Read the process's stdout up to the first line holding ``needle``."""
    assert process.stdout is not None
    seen = []
    deadline = time.monotonic() + START_TIMEOUT_S
    while time.monotonic() < deadline:
        line = process.stdout.readline()
        if not line:
            _, err = process.communicate(timeout=STOP_TIMEOUT_S)
            raise AssertionError(
                f"{process.args} ended {process.returncode} before {needle!r}: {seen} {err}"
            )
        seen.append(line.rstrip())
        if needle in line:
            return line.rstrip()
    raise AssertionError(f"{process.args}: no {needle!r} in {START_TIMEOUT_S:g} s: {seen}")


def text(path: Path) -> str:
    return path.read_text(encoding="utf-8", errors="replace") if path.exists() else ""


class Rehearsal:
    """The fleet's processes; every one is stopped (SIGTERM, then killed) at the end."""

    def __init__(self, logs: Path) -> None:
        self.logs = logs
        self.servers: list[subprocess.Popen[str]] = []
        self.agents: dict[str, subprocess.Popen[str]] = {}
        self.connections: dict[str, str] = {}

    def serve_autopilots(self) -> None:
        # The simulated autopilot answers on 14550 unless told otherwise: a user's ground
        # station may hold it, and two of them cannot share it. SITL picks free instances.
        listen = iter(free_udp_ports(len(VEHICLES)))
        for name in VEHICLES:
            where = ["--listen", f"127.0.0.1:{next(listen)}"] if AUTOPILOT == "sim" else []
            process = clark(
                "autopilot-sim", str(MISSION), "--agent", name, "--autopilot", AUTOPILOT, *where
            )
            self.servers.append(process)
        for name, process in zip(VEHICLES, self.servers[-2:], strict=True):
            line = read_line_with(process, "--autopilot-connection ")
            self.connections[name] = line.rsplit(" ", 1)[1]

    def run_agents(self, radios: Callable[[str], list[str]]) -> None:
        for name in AGENTS:
            args = ["run", str(MISSION), "--agent", name, "--plain", "--no-payload"]
            args += ["--logs", str(self.logs), *radios(name)]
            if name == "mcs":
                args += ["--script", "--no-console"]
            else:
                args += ["--autopilot-connection", self.connections[name]]
            self.agents[name] = clark(*args)
        for process in self.agents.values():
            read_line_with(process, "clark run: ")

    def wait_for(self, what: str, found: Callable[[], bool]) -> None:
        deadline = time.monotonic() + MISSION_TIMEOUT_S
        while not found():
            for process in [*self.servers, *self.agents.values()]:
                if process.poll() is not None:
                    out, err = process.communicate()
                    raise AssertionError(
                        f"{what}: {process.args} ended {process.returncode}:\n{out[-3000:]}\n"
                        f"{err[-3000:]}\n{self.tails()}"
                    )
            if time.monotonic() > deadline:
                raise AssertionError(f"{what}: not within {MISSION_TIMEOUT_S:g} s\n{self.tails()}")
            time.sleep(0.25)

    def tails(self) -> str:
        return "\n".join(
            f"--- {name}.mission.log\n" + "\n".join(text(self.mission_log(name)).splitlines()[-15:])
            for name in AGENTS
        )

    def received(self, sender: str, message: str) -> int:
        """How many ``message`` the station's message log has from ``sender`` so far."""
        return sum(
            1
            for line in text(self.logs / "mcs.messages.csv").splitlines()
            if line.startswith("received,") and f",{sender}," in line and f",{message}," in line
        )

    def mission_log(self, name: str) -> Path:
        return self.logs / f"{name}.mission.log"

    def stop_agents(self) -> None:
        for process in self.agents.values():
            process.send_signal(signal.SIGTERM)
        for name, process in self.agents.items():
            out, err = process.communicate(timeout=STOP_TIMEOUT_S)
            assert process.returncode == 0, f"{name}: {process.returncode}\n{out[-2000:]}\n{err}"
            assert "clark run: stopped (SIGTERM)" in out, out[-2000:]

    def close(self) -> None:
        for process in [*self.agents.values(), *self.servers]:
            if process.poll() is None:
                process.send_signal(signal.SIGTERM)
        for process in [*self.agents.values(), *self.servers]:
            try:
                process.communicate(timeout=STOP_TIMEOUT_S)
            except subprocess.TimeoutExpired:
                process.kill()
                process.communicate()


def fly_and_check(fleet: Rehearsal) -> None:
    """Serve the autopilots; the caller started the agents; fly to the end and check."""
    slash_b_log = fleet.mission_log("slash_b")
    fleet.wait_for("Slash B parks", lambda: "-> parked" in text(slash_b_log))
    # The station hears it: Slash B's Behavior State on start, activate and parking.
    fleet.wait_for(
        "the station hears Slash B park", lambda: fleet.received("slash_b", "behavior_state") >= 3
    )
    fleet.stop_agents()

    # The mission as it happened, from the vehicles' own logs.
    assert "armed by the pilot; the behaviour starts" in text(slash_b_log)
    assert "activate: idle -> chase" in text(slash_b_log)

    # The station's logs hold every agent's status.
    with (fleet.logs / "mcs.fleet.csv").open(encoding="utf-8") as f:
        rows = list(csv.DictReader(f))
    for name in VEHICLES:
        seen = [r for r in rows if r["name"] == name and r["lat_deg"]]
        assert seen, f"the station's fleet table never had {name}'s position"
        assert {r["mode"] for r in seen} - {""}, f"no autopilot mode for {name}"
    with (fleet.logs / "mcs.messages.csv").open(encoding="utf-8") as f:
        received = {
            (r["peer"], r["message_type"])
            for r in csv.DictReader(f)
            if r["direction"] == "received"
        }
    for name in VEHICLES:
        assert (name, "agent_status") in received
        assert (name, "heartbeat") in received
        assert (name, "behavior_state") in received

    # The checks, from the logs alone.
    check = subprocess.run(
        [
            sys.executable,
            "-m",
            "clark_engine",
            "analyze",
            str(fleet.logs),
            "--checks",
            str(MISSION),
        ],
        capture_output=True,
        text=True,
        cwd=ROOT,
        timeout=120,
    )
    assert check.returncode == 0, check.stdout + check.stderr
    for name in ("Slash B reaches Slash A", "Slash B parks", "no failsafe"):
        assert name in check.stdout


def start_on_udp_radios(fleet: Rehearsal) -> None:
    ports = dict(zip(AGENTS, free_udp_ports(len(AGENTS)), strict=True))

    def radios(name: str) -> list[str]:
        args = ["--radio", "udp", "--radio-address", f"127.0.0.1:{ports[name]}"]
        for peer in AGENTS:
            if peer != name:
                args += ["--peer", f"{peer}=127.0.0.1:{ports[peer]}"]
        return args

    fleet.serve_autopilots()
    fleet.run_agents(radios)


def start_on_emulated_xbees(fleet: Rehearsal, folder: Path) -> None:
    network = clark("radio-sim", "xbee", str(MISSION), "--dir", str(folder))
    fleet.servers.append(network)
    for name in AGENTS:
        read_line_with(network, f"{name}: clark run")

    def radios(name: str) -> list[str]:
        return ["--radio", "xbee", "--radio-device", str(folder / name)]

    fleet.serve_autopilots()
    fleet.run_agents(radios)


@pytest.mark.slow
@pytest.mark.sitl
def test_cooperative_follow_on_udp_radios_and_on_emulated_xbees(tmp_path: Path) -> None:
    """The two fleets fly side by side, each its own processes, autopilots and logs.

    Each takes about 100 s of real time and most of it is waiting for ArduRover and the
    operator's script; one after the other they held a test worker for 200 s.
    """
    on_udp = Rehearsal(tmp_path / "udp" / "logs")
    on_xbees = Rehearsal(tmp_path / "xbee" / "logs")
    try:
        start_on_udp_radios(on_udp)
        start_on_emulated_xbees(on_xbees, tmp_path / "xbee" / "radios")
        fly_and_check(on_udp)
        fly_and_check(on_xbees)
    finally:
        on_udp.close()
        on_xbees.close()
