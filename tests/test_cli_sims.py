"""clark autopilot-sim and clark radio-sim: the bench's stand-ins for a vehicle and its radios.

Each is met through the real library a mission computer uses against it: pymavlink for
the served autopilot (simulated, and ArduPilot SITL where installed), digi-xbee (through
the engine's XBeeRadio) for the emulated radios.
"""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
from pymavlink import mavutil
from sitl_here import real_install

from clark_engine.cli import main
from clark_engine.io.xbee import XBeeRadio
from clark_engine.sitl.launcher import ENV_SITL

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
INVALID = ROOT / "tests" / "invalid"
TIMEOUT_S = 60.0


def clark(*args: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-m", "clark_engine", *args],
        stdin=subprocess.DEVNULL,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
        env=env,
    )


def line_with(process: subprocess.Popen[str], needle: str) -> str:
    assert process.stdout is not None
    seen = []
    while True:
        line = process.stdout.readline()
        if not line:
            _, err = process.communicate(timeout=TIMEOUT_S)
            raise AssertionError(f"ended {process.returncode} before {needle!r}: {seen} {err}")
        seen.append(line)
        if needle in line:
            return line.strip()


def stop(process: subprocess.Popen[str]) -> tuple[int, str]:
    process.send_signal(signal.SIGTERM)
    out, err = process.communicate(timeout=TIMEOUT_S)
    return process.returncode, out + err


# -- clark autopilot-sim ----------------------------------------------------------------------


def served_heartbeat(connection: str) -> object:
    """The first HEARTBEAT a ground station at ``connection`` hears from the autopilot."""
    link = mavutil.mavlink_connection(connection, source_system=254)
    try:
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            link.mav.heartbeat_send(6, 8, 0, 0, 0)  # a udpout station speaks first
            msg = link.recv_match(type="HEARTBEAT", blocking=True, timeout=0.5)
            if msg is not None and msg.get_srcComponent() == 1:
                return msg
        raise AssertionError(f"no heartbeat at {connection}")
    finally:
        link.close()


def test_the_simulated_autopilot_answers_pymavlink_and_its_pilot_arms_it() -> None:
    process = clark(
        "autopilot-sim", str(MISSION), "--agent", "slash_b", "--ready-s", "1",
        "--listen", "127.0.0.1:0",
    )  # fmt: skip
    try:
        assert "the simulated autopilot" in line_with(process, "clark autopilot-sim:")
        connection = line_with(process, "--autopilot-connection ").rsplit(" ", 1)[1]
        assert connection.startswith("udpout:127.0.0.1:")
        heartbeat = served_heartbeat(connection)
        assert heartbeat.autopilot == mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA  # type: ignore[attr-defined]
        assert "slash_b: autopilot ready at" in line_with(process, "ready")
        assert "slash_b: armed by the pilot at" in line_with(process, "armed")
    finally:
        code, out = stop(process)
    assert code == 0, out
    assert "slash_b: stopped" in out


@pytest.mark.parametrize(
    ("argv", "code", "says"),
    [
        (["--agent", "mcs"], 2, "mcs is the mission's station, which has no autopilot"),
        (["--agent", "nobody"], 2, "there is no agent 'nobody'; vehicles: slash_a, slash_b"),
        (["--agent", "slash_b", "--listen", "nowhere"], 2, "use HOST:PORT"),
        (["--agent", "slash_b", "--sitl", "/nowhere"], 2, "--sitl only applies with"),
        (
            ["--agent", "slash_b", "--autopilot", "sitl", "--ready-s", "3"],
            2,
            "--ready-s only applies to the simulated autopilot",
        ),
    ],
)
def test_autopilot_sim_usage_errors(
    argv: list[str], code: int, says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["autopilot-sim", str(MISSION), *argv]) == code
    assert says in capsys.readouterr().err


def test_autopilot_sim_refuses_an_invalid_mission(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mission = tmp_path / "broken.yaml"
    mission.write_text(MISSION.read_text().replace("loop_hz: 10", "loop_hz: -3"))
    assert main(["autopilot-sim", str(mission), "--agent", "slash_b"]) == 1
    err = capsys.readouterr().err
    assert "broken.yaml" in err and "is not a valid mission" in err
    assert main(["autopilot-sim", str(tmp_path / "absent.yaml"), "--agent", "slash_b"]) == 2


SITL = real_install()


@pytest.mark.sitl
@pytest.mark.skipif(SITL is None, reason=f"no ArduPilot SITL: set {ENV_SITL} to its folder")
def test_sitl_serves_serial1_for_clark_run_and_stops_on_sigterm() -> None:
    assert SITL is not None
    env = {**os.environ, ENV_SITL: str(SITL.folder)}
    process = clark(
        "autopilot-sim", str(MISSION), "--agent", "slash_a", "--autopilot", "sitl", env=env
    )
    try:
        assert "ArduPilot SITL (instance" in line_with(process, "clark autopilot-sim:")
        connection = line_with(process, "--autopilot-connection tcp:127.0.0.1:")
        port = int(connection.rsplit(":", 1)[1])
        heartbeat = served_heartbeat(f"tcp:127.0.0.1:{port}")
        assert heartbeat.autopilot == mavutil.mavlink.MAV_AUTOPILOT_ARDUPILOTMEGA  # type: ignore[attr-defined]
    finally:
        code, out = stop(process)
    assert code == 0, out
    assert "slash_a: stopped" in out


# -- clark radio-sim xbee ---------------------------------------------------------------------


def test_radio_sim_puts_each_agents_xbee_at_its_address(tmp_path: Path) -> None:
    folder = tmp_path / "radios"
    process = clark("radio-sim", "xbee", str(MISSION), "--dir", str(folder))
    try:
        assert "3 emulated XBee 900HP radios" in line_with(process, "clark radio-sim:")
        assert line_with(process, "slash_b:") == (
            f"slash_b: clark run ... --radio xbee --radio-device {folder / 'slash_b'}"
        )
        station = XBeeRadio(str(folder / "mcs"))
        vehicle = XBeeRadio(str(folder / "slash_b"))
        station.open()
        vehicle.open()
        try:
            station.verify()
            assert station.address == "0013A20040A1B201"
            assert vehicle.address == "0013A20040A1B203"
            station.send(b"hello", "0013A20040A1B203")
            deadline = time.monotonic() + 10
            frames = []
            while not frames and time.monotonic() < deadline:
                time.sleep(0.05)
                frames = vehicle.receive()
            assert [f.data for f in frames] == [b"hello"]
        finally:
            station.close()
            vehicle.close()
    finally:
        code, out = stop(process)
    assert code == 0, out
    assert "clark radio-sim: stopped" in out
    assert not any(folder.iterdir()), "the radios' links are left behind"


def test_radio_sim_usage_errors(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    folder = tmp_path / "radios"
    assert main(["radio-sim", "xbee", str(MISSION), "--dir", str(folder), "--loss", "2"]) == 2
    assert "--loss 2: give a share from 0 to 1" in capsys.readouterr().err
    folder.mkdir()
    (folder / "mcs").write_text("mine")
    assert main(["radio-sim", "xbee", str(MISSION), "--dir", str(folder)]) == 2
    assert "is not a radio's link; choose another --dir" in capsys.readouterr().err
    assert (folder / "mcs").read_text() == "mine"


# -- clark run's radio device -----------------------------------------------------------------


def test_run_radio_device_needs_an_xbee(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["run", str(MISSION), "--agent", "mcs", "--radio", "udp", "--radio-device", "/dev/x"]
    assert main(argv) == 2
    assert "use it with --radio xbee" in capsys.readouterr().err


def test_run_refuses_an_invalid_mission_with_exit_1(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mission = tmp_path / "broken.yaml"
    mission.write_text(MISSION.read_text().replace("loop_hz: 10", "loop_hz: -3"))
    assert main(["run", str(mission), "--agent", "mcs"]) == 1
    assert "is not a valid mission" in capsys.readouterr().err
