"""A second Ctrl-C during ``clark run``'s clean stop, on real processes (issue 18 item 3).

Before: 11 runs in 25 ended in a ``ShellAborted`` traceback, exit 1, with the rest of
the stop skipped (replay marks not saved, RC overrides not released, links not closed).
Here a keyed cooperative_follow station runs beside slash_b, whose autopilot is the
simulated one served from this process (as in tests/test_cli_run.py). To land the
second signal inside the stop every time, the autopilot falls silent just before the
first one: the stop then waits for its answer to the terminal mode (the only part a
second signal may cut), and the test sends the second signal once slash_b's interface
log says it waits. Three vehicle runs, restarted beside the same station with the same
state folder: SIGINT twice, SIGINT three times, SIGTERM twice.
"""

from __future__ import annotations

import signal
import subprocess
import threading
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_cli_run import MISSION, TIMEOUT_S, clark_run, free_ports, kill, started, text, wait_for

from clark_engine.link.auth import generate_key_file
from clark_engine.standins.autopilot_sim import ServedSimulated
from clark_engine.validation import validate_file


class PausableAutopilot:
    """The served simulated autopilot; :meth:`pause` stops answering but keeps its port,
    so what the vehicle sends afterwards stays readable (:meth:`received`)."""

    def __init__(self, mission_path: Path, agent: str) -> None:
        mission = validate_file(mission_path).mission
        assert mission is not None
        self.server = ServedSimulated(mission, agent, ready_s=1.0)
        self.port = self.server.transport.address[1]
        self._paused = threading.Event()
        self._thread = threading.Thread(
            target=self.server.serve, args=(self._paused.is_set, lambda _line: None)
        )
        self._thread.start()

    def pause(self) -> None:
        self._paused.set()
        self._thread.join(timeout=TIMEOUT_S)
        assert not self._thread.is_alive()
        self.server.transport.receive()  # what came before the pause: not looked at

    def received(self) -> list[Any]:
        parser = mavlink2.MAVLink(None)
        parser.robust_parsing = True
        return list(parser.parse_buffer(self.server.transport.receive()) or [])

    def close(self) -> None:
        self._paused.set()
        self._thread.join(timeout=TIMEOUT_S)
        self.server.close()


def says(path: Path, words: str) -> Callable[[], bool]:
    """True once the file at ``path`` holds ``words``."""
    return lambda: words in text(path)


def keyed_mission(folder: Path) -> Path:
    """cooperative_follow with a mission key (so replay and counter stores are kept)."""
    generate_key_file(folder / "coop.key")
    mission = folder / "cooperative_follow.yaml"
    source = MISSION.read_text(encoding="utf-8")
    assert "  loop_hz: 10\n" in source
    mission.write_text(source.replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n"))
    return mission


@pytest.mark.slow
def test_a_second_signal_during_the_stop_shortens_it_and_keeps_the_vehicle_safe(
    tmp_path: Path,
) -> None:
    mission = keyed_mission(tmp_path)
    state = tmp_path / "state"
    station_port, vehicle_port = free_ports(2)
    processes: list[subprocess.Popen[str]] = []
    rounds = [
        [signal.SIGINT, signal.SIGINT],
        [signal.SIGINT, signal.SIGINT, signal.SIGINT],
        [signal.SIGTERM, signal.SIGTERM],
    ]
    try:
        station_logs = tmp_path / "station"
        station = clark_run(
            "mcs", station_logs, station_port, "slash_b", vehicle_port, mission=mission
        )
        processes.append(station)
        started(station)
        for k, signals in enumerate(rounds):
            logs = tmp_path / f"run{k}"
            autopilot = PausableAutopilot(mission, "slash_b")
            try:
                vehicle = clark_run(
                    "slash_b",
                    logs,
                    vehicle_port,
                    "mcs",
                    station_port,
                    "--autopilot-connection",
                    f"udpout:127.0.0.1:{autopilot.port}",
                    "--state",
                    str(state),
                    mission=mission,
                )
                processes.append(vehicle)
                started(vehicle)
                wait_for(  # the safety set-up took: its failsafe is switched off at the stop
                    "slash_b's behaviour starts",
                    lambda logs=logs: (
                        "; the behaviour starts" in text(logs / "slash_b.mission.log")
                    ),
                    [station, vehicle],
                )
                wait_for(
                    "slash_b hears the station",
                    says(logs / "slash_b.fleet.csv", "mcs"),
                    [station, vehicle],
                )
                autopilot.pause()
                vehicle.send_signal(signals[0])
                wait_for(
                    "slash_b's stop waits for its autopilot",
                    says(logs / "slash_b.interface.log", "stop: waiting up to"),
                    [vehicle],
                )
                for sig in signals[1:]:
                    if vehicle.poll() is None:
                        vehicle.send_signal(sig)
                out, err = vehicle.communicate(timeout=TIMEOUT_S)
                sent = autopilot.received()
            finally:
                autopilot.close()
            assert vehicle.returncode == 130, (k, out, err)
            assert "Traceback" not in err, err
            shortened = [line for line in out.splitlines() if "stop shortened" in line]
            assert len(shortened) == 1, out
            assert shortened[0].endswith(
                "still done: terminate sequence run (terminal mode, last heartbeat), RC overrides "
                "released, failsafe off (FS_GCS_ENABLE), replay marks saved, links closed"
            ), shortened
            assert shortened[0].startswith(
                f"clark run: stop shortened by a second {signals[1].name}: skipped waiting for "
                "the autopilot to answer "
            ), shortened
            interface = text(logs / "slash_b.interface.log")
            assert "leaving on purpose: FS_GCS_ENABLE = 0" in interface
            assert "stop: replay marks saved" in interface
            assert "stop: links closed (autopilot, radio)" in interface
            mission_log = text(logs / "slash_b.mission.log")
            assert f"real-time shell stopping ({signals[0].name})" in mission_log
            assert "terminated; vehicle to HOLD" in mission_log
            # What the silent autopilot was sent during the stop: the sticks released
            # (none were held), HOLD, and the failsafe switched off.
            kinds = {(m.get_type(), getattr(m, "command", None)) for m in sent}
            assert ("COMMAND_LONG", mavlink2.MAV_CMD_DO_SET_MODE) in kinds, kinds
            assert any(
                m.get_type() == "PARAM_SET" and m.param_id == "FS_GCS_ENABLE" for m in sent
            ), kinds
            marks = state / "cooperative-follow.slash_b.replay"
            assert marks.exists() and marks.stat().st_size > 0
            assert (state / "cooperative-follow.slash_b.counter").exists()
        station.send_signal(signal.SIGTERM)
        _station_out, station_err = station.communicate(timeout=TIMEOUT_S)
    finally:
        kill(processes)
    assert station.returncode == 0, station_err
    assert "Traceback" not in station_err
