"""The simulated autopilot's ground-station failsafe where the conformance suite does not go.

tests/conformance/test_gcs_failsafe.py holds the simulation to what SITL does. These
cover the rest of each firmware's rules as ArduPilot's source has them
(docs/sitl-measurements.md, section 4): what keeps the failsafe away besides heartbeats,
ArduCopter's FS_OPTIONS and its arming refusal, ArduRover's HOLD exemption, ArduPlane's
FS_LONG_ACTN by mode and its failsafe deferred during a takeoff climb.
"""

from __future__ import annotations

import io
import math
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from sim_station import Station

from clark_engine.dryrun.command import run_dry_run

ACCEPTED, FAILED = mavlink2.MAV_RESULT_ACCEPTED, mavlink2.MAV_RESULT_FAILED
WARNING, CRITICAL = 4, 2


def failsafe_on(station: Station, params: dict[str, float]) -> None:
    for name, value in params.items():
        station.set(name, value)


COPTER = {"FS_GCS_TIMEOUT": 2, "FS_GCS_ENABLE": 1}
ROVER = {"FS_GCS_TIMEOUT": 2, "FS_GCS_ENABLE": 1}
PLANE = {"FS_LONG_TIMEOUT": 2, "FS_GCS_ENABL": 1}


def test_rc_overrides_and_manual_control_from_the_gcs_count_as_heartbeats() -> None:
    station = Station("copter")
    station.ready()
    failsafe_on(station, COPTER)
    station.heartbeat_from = ()
    since = station.now_s
    for _ in range(5):  # RC overrides only, from 255
        station.send(mavlink2.MAVLink_rc_channels_override_message(1, 1, *[65535] * 8))
        station.run(1.0)
    for _ in range(5):  # MANUAL_CONTROL only, from 255, aimed at us
        station.send(mavlink2.MAVLink_manual_control_message(1, 0, 0, 500, 0, 0))
        station.run(1.0)
    assert (WARNING, "GCS Failsafe") not in station.texts(since)
    station.run(3.0)
    assert (WARNING, "GCS Failsafe") in station.texts(since)


def test_copter_refuses_to_arm_while_its_failsafe_is_on() -> None:
    station = Station("copter")
    station.ready()
    failsafe_on(station, COPTER)
    station.heartbeat_from = ()
    station.run(3.0)
    since = station.now_s
    assert station.mode("GUIDED") == ACCEPTED
    assert station.arm() == FAILED
    assert (CRITICAL, "Arm: GCS failsafe on") in station.texts(since)
    station.heartbeat_from = (255,)
    station.run(1.5)
    assert station.arm() == ACCEPTED


def test_copter_in_a_pilot_mode_carries_on_with_fs_options_bit_4() -> None:
    station = Station("copter")
    station.ready()
    failsafe_on(station, COPTER)
    assert station.mode("GUIDED") == ACCEPTED
    assert station.arm() == ACCEPTED
    assert station.command(mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10) == ACCEPTED
    station.run_until(lambda: station.up_m > 9.5, 30.0)
    assert station.mode("LOITER") == ACCEPTED
    since = station.now_s
    station.heartbeat_from = ()
    station.run(4.0)
    assert (WARNING, "GCS Failsafe - Continuing Pilot Control") in station.texts(since)
    assert station.mode_now == "LOITER"


def test_rover_in_hold_is_left_alone_unless_fs_options_bit_0() -> None:
    station = Station("rover")
    station.ready()
    failsafe_on(station, ROVER)
    assert station.mode("HOLD") == ACCEPTED
    since = station.now_s
    station.heartbeat_from = ()
    station.run(6.0)
    assert not [t for _, t in station.texts(since) if "Failsafe" in t]
    station.set("FS_OPTIONS", 1)
    station.run(1.0)
    assert (WARNING, "Radio Failsafe") in station.texts(since)


def test_rover_fs_action_5_disarms() -> None:
    station = Station("rover")
    station.ready()
    failsafe_on(station, {**ROVER, "FS_ACTION": 5})
    assert station.arm() == ACCEPTED
    station.heartbeat_from = ()
    station.run(5.0)
    assert not station.model.armed
    assert station.mode_now == "MANUAL"


def test_plane_continue_means_rtl_in_loiter_and_stays_in_guided() -> None:
    station = Station("plane")
    station.ready()
    failsafe_on(station, {**PLANE, "FS_LONG_ACTN": 0})
    assert station.mode("GUIDED") == ACCEPTED
    since = station.now_s
    station.heartbeat_from = ()
    station.run(3.0)
    assert (WARNING, "GCS Failsafe On: GUIDED") in station.texts(since)
    assert station.mode_now == "GUIDED"
    station.heartbeat_from = (255,)
    station.run(1.5)
    assert (WARNING, "GCS Failsafe Off") in station.texts(since)
    assert station.mode("LOITER") == ACCEPTED
    since = station.now_s
    station.heartbeat_from = ()
    station.run(3.0)
    assert (WARNING, "GCS Failsafe On: RTL") in station.texts(since)
    assert station.mode_now == "RTL"


def test_plane_failsafe_waits_for_the_end_of_a_takeoff_climb() -> None:
    # In TAKEOFF's initial climb ArduPlane defers the action (unless glide or parachute);
    # once the climb is over it calls the failsafe again, as an RC failsafe
    # (ModeTakeoff::update), which its RC being fine ends at the next check; the silent
    # ground station then turns it on once more, now in RTL.
    station = Station("plane")
    station.ready()
    failsafe_on(station, {**PLANE, "FS_LONG_ACTN": 1})
    assert station.mode("TAKEOFF") == ACCEPTED
    assert station.arm() == ACCEPTED
    since = station.now_s
    station.heartbeat_from = ()
    station.run(3.0)
    assert (WARNING, "GCS Failsafe On: TAKEOFF") in station.texts(since)
    assert station.mode_now == "TAKEOFF"
    station.run_until(lambda: station.mode_now == "RTL", 40.0)
    station.run(2.0)
    assert [t for s, t in station.texts(since) if s == WARNING][:4] == [
        "GCS Failsafe On: TAKEOFF",
        "RC Long Failsafe On: RTL",
        "RC Long Failsafe Cleared",
        "GCS Failsafe On: RTL",
    ]


KILLED_ROVER = """\
clark: 1
mission:
  id: 902
  name: killed-rover
  loop_hz: 10
  origin: {{lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
agents:
  mcs: {{id: 1, profile: mcs_laptop, telemetry: {{heartbeat: 1}}}}
  rover:
    id: 2
    profile: traxxas_slash
    hardware: {{autopilot: {{{autopilot}}}}}
    telemetry: {{heartbeat: 1, agent_status: 2}}
    behavior:
      use: waypoint_tour
      with: {{loop: true, speed_m_s: 2, waypoints: [[0, 0], [80, 0], [80, 80], [0, 80]]}}
faults:
  - {{kill: {{agent: rover, at_s: 70}}}}
sim: {{duration_s: 80, seed: 1}}
"""


@pytest.mark.parametrize(
    ("autopilot", "mode"),
    [
        ("parameters: {FS_GCS_ENABLE: 0}", "HOLD"),
        ("safety_setup: false, parameters: {FS_GCS_ENABLE: 0}", "GUIDED"),
    ],
    ids=["failsafe-set", "failsafe-off"],
)
def test_a_killed_mission_computer_leaves_its_rover_to_the_autopilot(
    tmp_path: Path, autopilot: str, mode: str
) -> None:
    """The engine's adapter heartbeats as the ground station; killed, it falls silent.

    The engine sets ArduRover's GCS failsafe before the behaviour starts (whatever the
    profile's parameters say): the rover holds FS_GCS_TIMEOUT + FS_TIMEOUT (6.5 s) after
    the last heartbeat. A bench profile that opts out of that set-up leaves it off: the
    rover drives on to its last target in GUIDED.
    """
    path = tmp_path / "killed_rover.yaml"
    path.write_text(KILLED_ROVER.format(autopilot=autopilot), encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(path, seed=None, until_s=None, report=None, speed=None, out=out, err=err)
    assert outcome.result is not None, err.getvalue()
    autopilot = outcome.result.agents["rover"].autopilot
    assert autopilot is not None
    assert autopilot.model.mode == mode
    assert autopilot.gcs_failsafe.active is (mode == "HOLD")
    track = outcome.result.recording.tracks["rover"].samples()
    moving = [(t, n, e) for t, n, e, _ in track if 60.0 <= t <= 70.0]
    assert math.dist(moving[0][1:], moving[-1][1:]) > 10.0, "the rover drove before the kill"
    # (The track ends with the mission computer; the vehicle is there still.)
    speed_m_s = autopilot.model.truth().ground_speed_m_s
    assert speed_m_s < 0.1 if mode == "HOLD" else speed_m_s > 1.0
