"""Real time: outside ground stations (pymavlink's mavutil, MAVSDK) watch and command the fleet.

These tests run the cooperative-follow example at wall-clock speed for a few
seconds each, with the simulated autopilots on UDP loopback ports, and connect
ground stations that nobody here wrote, as a user would. Every wait has a
deadline of a few seconds; the runs are stopped as soon as a test has seen what
it needs.
"""

from __future__ import annotations

import math
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from mission_text import with_sim_keys
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.cli import main
from clark_engine.dryrun.engine import DryRun, DryRunResult
from clark_engine.dryrun.rehearsal import MavlinkBridge, datagrams, vehicle_names
from clark_engine.mission.geo import LocalPoint, Origin, parse_point, to_local
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
WAIT_S = 5.0  # the longest any single wait may take


def free_base_port(count: int) -> int:
    """A base port with ``count`` consecutive free UDP ports on loopback (the OS picks it)."""
    for _ in range(20):
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as probe:
            probe.bind(("127.0.0.1", 0))
            base = int(probe.getsockname()[1])
        if base + count - 1 > 65535:
            continue
        held: list[socket.socket] = []
        try:
            for port in range(base, base + count):
                sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
                held.append(sock)
                sock.bind(("127.0.0.1", port))
        except OSError:
            continue
        finally:
            for sock in held:
                sock.close()
        return base
    pytest.fail("no free run of UDP ports on loopback")


def wait_for(
    condition: Callable[[], bool], what: str, pump: Callable[[], None], timeout_s: float = WAIT_S
) -> None:
    """Call ``pump`` until ``condition`` holds, for at most ``timeout_s``."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        pump()
        if condition():
            return
    pytest.fail(f"timed out after {timeout_s:g} s waiting for {what}")


START_S = 60.0
"""The longest a `clark dry-run` child may take to start: an interpreter, the imports and
the mission's validation, on a machine that may be busy (seen over 5 s at a load of 8)."""


def idle() -> None:
    """Let a library's own threads work a moment (for stations that poll, not pump)."""
    time.sleep(0.05)


READY_S = 2.0
"""How soon the simulated autopilots of the real-time runs here are ready: ArduPilot's own
40-odd seconds (the dry run's default) would make every test wait that long."""


def quick_mission(folder: Path) -> Path:
    """The cooperative-follow example with autopilots ready after :data:`READY_S`."""
    path = folder / MISSION.name
    text = MISSION.read_text(encoding="utf-8")
    # No bad radio spells: what a test sends at a wall-clock moment must not fall in one.
    quick = with_sim_keys(text, f"autopilot_ready_s: {READY_S}, radio_bursts: {{loss_bad: 0}}")
    path.write_text(quick, encoding="utf-8")
    return path


@contextmanager
def realtime_run(base_port: int, folder: Path) -> Iterator[tuple[DryRun, MavlinkBridge]]:
    """The example mission in real time on a thread, its vehicles from ``base_port`` on."""
    path = quick_mission(folder)
    mission = validate_file(path, str(path)).mission
    assert mission is not None
    run = DryRun(mission, path, seed=1, until_s=60.0, speed=1.0, wall_clock=True)
    bridge = MavlinkBridge(vehicle_names(mission), base_port)
    bridge.attach(run)
    results: list[DryRunResult] = []
    thread = threading.Thread(target=lambda: results.append(run.run()), daemon=True)
    thread.start()
    try:
        yield run, bridge
    finally:
        bridge.stop()
        thread.join(timeout=WAIT_S)
        bridge.close()
    assert not thread.is_alive(), "the run did not stop"
    assert results and results[0].recording.end_s < 60.0  # stopped early, and cleanly


@pytest.fixture
def mavutil(monkeypatch: pytest.MonkeyPatch) -> Iterator[Any]:
    """pymavlink's mavutil, with its process-wide dialect and environment restored after."""
    monkeypatch.setenv("MAVLINK20", "1")
    monkeypatch.setenv("MAVLINK_DIALECT", "ardupilotmega")
    from pymavlink import mavutil as module

    monkeypatch.setattr(module, "mavlink", module.mavlink)
    monkeypatch.setattr(module, "current_dialect", module.current_dialect)
    yield module


class Station:
    """A mavutil ground station on ``udpout:127.0.0.1:PORT``, sending its heartbeat at 1 Hz."""

    def __init__(self, mavutil: Any, port: int) -> None:
        self.link = mavutil.mavlink_connection(
            f"udpout:127.0.0.1:{port}", source_system=255, source_component=190
        )
        self.last: dict[str, Any] = {}
        self.acks: list[Any] = []
        self.heartbeats = 0
        self._beat_at = 0.0

    def pump(self) -> None:
        """Send the heartbeat when due; take every message that arrives within 20 ms."""
        now = time.monotonic()
        if now >= self._beat_at:
            self._beat_at = now + 1.0
            self.link.mav.heartbeat_send(
                mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0
            )
        while (msg := self.link.recv_match(blocking=True, timeout=0.02)) is not None:
            kind = msg.get_type()
            self.last[kind] = msg
            self.heartbeats += kind == "HEARTBEAT"
            if kind == "COMMAND_ACK" and msg.target_component == 190:
                self.acks.append(msg)  # ours: the engine's own (to 255/191) come by too

    def close(self) -> None:
        self.link.close()


def distance_m(lat_deg: float, lon_deg: float, to: LocalPoint, origin: Origin) -> float:
    """Horizontal distance from a reported position to a point of the mission."""
    return to_local(lat_deg, lon_deg, 0.0, origin).horizontal_distance_m(to)


# -- the bridge's pieces --------------------------------------------------------------------


def _frame(payload_len: int, signed: bool = False) -> bytes:
    flags = 0x01 if signed else 0x00
    body = bytes([0xFD, payload_len, flags]) + bytes(7 + payload_len + 2)
    return body + (bytes(13) if signed else b"")


def test_datagrams_keep_frames_whole() -> None:
    frames = [_frame(200), _frame(200), _frame(30, signed=True), _frame(250)]
    data = b"".join(frames)
    out = datagrams(data, limit=500)
    assert b"".join(out) == data
    assert [len(d) for d in out] == [212 + 212 + 55, 262]  # the last frame does not fit
    assert all(len(d) <= 500 for d in out)
    assert datagrams(b"") == []
    assert datagrams(b"\x00garbage") == [b"\x00garbage"]  # not a frame: sent as it is


def test_vehicles_get_consecutive_ports_in_agent_order() -> None:
    base = free_base_port(2)
    mission = validate_file(MISSION, str(MISSION)).mission
    assert mission is not None
    assert vehicle_names(mission) == ["slash_a", "slash_b"]  # the station mcs has no autopilot
    run = DryRun(mission, MISSION, seed=1, until_s=1.0)
    with MavlinkBridge(vehicle_names(mission), base) as bridge:
        bridge.attach(run)
        assert [(e.agent, e.address, e.system_id) for e in bridge.endpoints] == [
            ("slash_a", f"127.0.0.1:{base}", 1),
            ("slash_b", f"127.0.0.1:{base + 1}", 1),
        ]
        assert set(run.autopilot_taps) == {"slash_a", "slash_b"}
    assert run.autopilot_taps == {} and run.on_step is None  # closing unhooks it
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", base))  # and frees the ports


# -- the command line -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("extra", "message"),
    [
        (["--realtime"], "--realtime needs --mavlink-port"),
        (["--realtime", "--mavlink-port", "14550", "--speed", "2"], "--speed does not go"),
        (["--mavlink-port", "14550"], "--mavlink-port only applies with --realtime"),
        (["--mavlink-host", "0.0.0.0"], "--mavlink-host only applies with --realtime"),
        (["--realtime", "--mavlink-port", "65535"], "must lie within 1-65535"),
        (["--realtime", "--mavlink-port", "0"], "must lie within 1-65535"),
    ],
)
def test_usage_errors_exit_2(
    extra: list[str], message: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    report = tmp_path / "report"
    assert main(["dry-run", str(MISSION), "--report", str(report), *extra]) == 2
    assert message in capsys.readouterr().err
    assert not report.exists()  # nothing simulated, nothing written


def test_a_port_in_use_exits_2_before_anything_is_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    base = free_base_port(2)
    report = tmp_path / "report"
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as taken:
        taken.bind(("127.0.0.1", base + 1))
        args = ["dry-run", str(MISSION), "--realtime", "--mavlink-port", str(base)]
        assert main([*args, "--report", str(report)]) == 2
    err = capsys.readouterr().err
    assert f"slash_b's udp 127.0.0.1:{base + 1}: cannot listen there" in err
    assert "choose another --mavlink-port" in err
    assert not report.exists()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sock:
        sock.bind(("127.0.0.1", base))  # the first vehicle's socket was closed again


# -- ground stations ------------------------------------------------------------------------


def test_mavutil_watches_and_commands_a_vehicle_the_engine_flies(
    mavutil: Any, tmp_path: Path
) -> None:
    base = free_base_port(2)
    mission = validate_file(MISSION, str(MISSION)).mission
    assert mission is not None
    origin = mission.origin
    with realtime_run(base, tmp_path) as (run, bridge):
        a, b = Station(mavutil, base), Station(mavutil, base + 1)
        try:

            def pump() -> None:
                a.pump()
                b.pump()

            def located(station: Station) -> bool:
                position = station.last.get("GLOBAL_POSITION_INT")
                return "HEARTBEAT" in station.last and position is not None and position.lat != 0

            # Before its GPS fix ArduPilot reports 0, 0; the autopilots are quick here.
            wait_for(lambda: located(a) and located(b), "telemetry with positions", pump)
            assert len(bridge.peers("slash_a")) == 1
            # In real time SYSTEM_TIME is the wall clock's: the station shows today's time
            wait_for(lambda: "SYSTEM_TIME" in a.last, "SYSTEM_TIME", pump)
            assert abs(a.last["SYSTEM_TIME"].time_unix_usec / 1e6 - time.time()) < 60
            # Vehicle 0 is slash_a, at the origin; vehicle 1 is slash_b, 15 m south, 10 m west.
            heartbeat = a.last["HEARTBEAT"]
            assert (heartbeat.get_srcSystem(), heartbeat.type) == (
                1,
                mavlink2.MAV_TYPE_GROUND_ROVER,
            )
            position = a.last["GLOBAL_POSITION_INT"]
            home = parse_point([0, 0], origin)
            assert distance_m(position.lat / 1e7, position.lon / 1e7, home, origin) < 15
            position = b.last["GLOBAL_POSITION_INT"]
            start_b = parse_point([-15, -10], origin)
            assert distance_m(position.lat / 1e7, position.lon / 1e7, start_b, origin) < 5
            # Once ready, its pilot arms slash_a and the engine flies its tour in GUIDED;
            # slash_b holds, waiting.
            wait_for(
                lambda: a.link.flightmode == "GUIDED" and a.link.motors_armed(), "GUIDED", pump
            )
            wait_for(lambda: b.link.flightmode == "HOLD", "HOLD", pump)

            # The station takes slash_a out of the engine's hands: HOLD.
            a.link.set_mode("HOLD")
            wait_for(lambda: bool(a.acks), "the mode change's COMMAND_ACK", pump)
            ack = a.acks[0]
            assert (ack.command, ack.result, ack.target_system) == (
                mavlink2.MAV_CMD_DO_SET_MODE,
                mavlink2.MAV_RESULT_ACCEPTED,
                255,
            )
            seen = a.heartbeats
            wait_for(lambda: a.heartbeats > seen, "the next HEARTBEAT", pump)
            assert a.link.flightmode == "HOLD"
            model = run.agents["slash_a"].model
            assert model is not None and model.mode == "HOLD"
            runtime = run.agents["slash_a"].runtime  # the engine sees it as a pilot's switch

            def engine_sees_hold() -> bool:
                vehicle = runtime.context.vehicle
                return vehicle is not None and vehicle.mode == "HOLD"

            wait_for(engine_sees_hold, "the engine to see HOLD", pump)
            assert b.link.flightmode == "HOLD"  # the other vehicle is untouched
            autopilot = run.agents["slash_a"].autopilot
            assert autopilot is not None and (255, 190) in autopilot.gcs_peers
        finally:
            a.close()
            b.close()


def test_mavsdk_watches_and_commands_a_vehicle(tmp_path: Path) -> None:
    mavsdk = pytest.importorskip(
        "mavsdk", minversion="4.1", reason="MAVSDK 4 (pip install 'mavsdk>=4.1') is not installed"
    )
    from mavsdk.plugins.action import Action
    from mavsdk.plugins.telemetry import FlightMode, Telemetry

    base = free_base_port(2)
    mission = validate_file(MISSION, str(MISSION)).mission
    assert mission is not None
    origin, home = mission.origin, parse_point([0, 0], mission.origin)
    with realtime_run(base, tmp_path) as (run, _bridge):
        config = mavsdk.Configuration.create_with_component_type(
            mavsdk.ComponentType.GROUND_STATION
        )
        station = mavsdk.Mavsdk(config)
        try:
            # MAVSDK's URL for "send to this address first": udpout://HOST:PORT.
            result = station.add_any_connection(f"udpout://127.0.0.1:{base}")
            assert result == mavsdk.ConnectionResult.SUCCESS
            system = station.first_autopilot(WAIT_S)
            assert system is not None, "MAVSDK found no autopilot"
            telemetry = Telemetry(system)

            def near_origin() -> bool:
                p = telemetry.position()
                return not math.isnan(p.latitude_deg) and (
                    distance_m(p.latitude_deg, p.longitude_deg, home, origin) < 15
                )

            wait_for(near_origin, "a position near the origin", idle)
            wait_for(telemetry.armed, "armed", idle)
            # MAVSDK names ArduRover's GUIDED as its PX4 counterpart, OFFBOARD.
            wait_for(lambda: telemetry.flight_mode() == FlightMode.OFFBOARD, "GUIDED", idle)
            Action(system).hold()  # ArduRover's HOLD, by MAV_CMD_DO_SET_MODE
            wait_for(lambda: telemetry.flight_mode() == FlightMode.HOLD, "HOLD", idle)
            model = run.agents["slash_a"].model
            assert model is not None and model.mode == "HOLD"
        finally:
            station.destroy()


@pytest.mark.parametrize(
    ("signum", "said"), [(signal.SIGINT, "(Ctrl-C)"), (signal.SIGTERM, "(SIGTERM)")]
)
def test_ctrl_c_or_sigterm_ends_a_realtime_run_and_the_report_is_written(
    mavutil: Any, tmp_path: Path, signum: signal.Signals, said: str
) -> None:
    """SIGTERM (a service manager, a CI timeout) ends the run as Ctrl-C does: the report
    is written (before, SIGTERM killed the run and lost it)."""
    base = free_base_port(2)
    report = tmp_path / "report"
    args = ["--realtime", "--mavlink-port", str(base), "--until", "60", "--report", str(report)]
    proc = subprocess.Popen(
        [sys.executable, "-m", "clark_engine", "dry-run", str(MISSION), *args],
        cwd=ROOT,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert proc.stdout is not None and proc.stderr is not None
    stdout, stderr = proc.stdout, proc.stderr
    lines: list[str] = []  # stderr, read on a thread: a pipe read must never stall the test
    reader = threading.Thread(target=lambda: lines.extend(iter(stderr.readline, "")))
    reader.start()
    try:

        def started() -> bool:
            return any(line.startswith("real time:") for line in list(lines))

        wait_for(started, "the run to start", idle, START_S)
        assert f"  slash_a: MAVLink on udp 127.0.0.1:{base} (system id 1)" in "".join(lines)
        station = Station(mavutil, base + 1)
        try:
            wait_for(lambda: "HEARTBEAT" in station.last, "slash_b's HEARTBEAT", station.pump)
        finally:
            station.close()
        proc.send_signal(signum)
        proc.wait(timeout=30)  # plotting the report takes a moment
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
        reader.join(timeout=WAIT_S)
        out = stdout.read()
        stdout.close()
        stderr.close()
    err = "".join(lines)
    assert "Traceback" not in err
    assert "stopped at" in err and said in err
    # Its checks are due at 120 s: stopped before, they were not judged (not a failure).
    assert proc.returncode == 0
    row = next(line for line in out.splitlines() if line.startswith("| Slash B parks"))
    assert row.endswith("| not evaluated |") and "checks not evaluated" in err
    assert (report / "summary.md").is_file()
    assert (report / "logs" / "slash_a.mission.log").is_file()
