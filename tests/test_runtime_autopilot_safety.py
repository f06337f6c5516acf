"""The autopilot's safety set-up in the language and the runtime: what is planned per
firmware, when the runtime asks for it, and how the launch gate waits for it.

Configs are compiled from small missions written here (or the examples); the autopilot
is a stream of events on a virtual clock. What the adapter does with the command is in
tests/test_io_autopilot_setup.py; the autopilot's own reaction to a killed ``clark run``
in tests/test_computer_lost_sitl.py.
"""

from __future__ import annotations

import json
from dataclasses import replace
from pathlib import Path

import pytest

from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.autopilot_safety import (
    GCS_ID_NAMES,
    SafetyPlanError,
    safety_setup,
)
from clark_engine.runtime.commands import (
    FenceZone,
    SetMode,
    SetParam,
    SetUpAutopilotSafety,
    UploadFence,
)
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.events import (
    AutopilotSafetyResult,
    AutopilotStatus,
    LandedState,
    VehicleState,
)
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.runtime.safety import SAFETY_RETRY_S

ROOT = Path(__file__).resolve().parent.parent
ORIGIN = (30.6372, -96.4787, 90.0)
HOME = (30.6372, -96.4787, 90.5)  # home half a metre above the origin's ground
MISSION = """
clark: 1
mission:
  {{id: 7, name: safety, loop_hz: 10, origin: {{lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}}}
envelope: {{ceiling_m: 60, margin_m: 2{envelope}}}
agents:
  mcs: {{id: 1, profile: mcs_laptop, telemetry: {{heartbeat: 1}}}}
  v:
    id: 2
    profile: {profile}
    telemetry: {{heartbeat: 1}}
    launch: {{armed_by: pilot}}
    behavior: {{use: hold}}
{agent}
"""


def compiled(tmp_path: Path, profile: str, *, envelope: str = "", agent: str = "") -> AgentConfig:
    path = tmp_path / "mission.yaml"
    path.write_text(
        MISSION.format(profile=profile, envelope=envelope, agent=agent), encoding="utf-8"
    )
    result = validate_path(path, path.name)
    assert result.mission is not None, [f.format_text() for f in result.findings]
    data = json.loads(json.dumps(agent_config(result.mission, result.mission.agents["v"])))
    return config_from_dict(data)


def params(command: SetUpAutopilotSafety) -> list[tuple[str, float, bool] | str]:
    out: list[tuple[str, float, bool] | str] = []
    for step in command.steps:
        if isinstance(step, SetParam):
            out.append((step.name, step.value, step.at_most))
        elif isinstance(step, UploadFence):
            out.append("upload")
        else:
            out.append(f"pause {step.seconds:g} s")
    return out


# -- the language ------------------------------------------------------------------------


def test_defaults_are_rtl_for_aircraft_and_hold_for_rovers_after_5_s(tmp_path: Path) -> None:
    copter = compiled(tmp_path, "dji_f450")
    rover = compiled(tmp_path, "traxxas_slash")
    assert copter.failsafe == {"mcs_lost": "hold", "computer_lost": "rtl"}
    assert rover.failsafe == {"mcs_lost": "hold", "computer_lost": "hold"}
    assert copter.computer_lost_s == rover.computer_lost_s == 5.0
    assert copter.raw["agent"]["failsafe"]["computer_lost_s"] == 5.0
    assert copter.safety_setup and copter.firmware == "arducopter"


def test_computer_lost_cannot_be_turned_off_and_its_time_is_ardupilots_range(
    tmp_path: Path,
) -> None:
    path = tmp_path / "mission.yaml"
    for failsafe, where in (
        ("{computer_lost: continue}", "computer_lost"),
        ("{computer_lost_s: 1}", "computer_lost_s"),
        ("{computer_lost_s: 121}", "computer_lost_s"),
    ):
        path.write_text(
            MISSION.format(profile="dji_f450", envelope="", agent=f"    failsafe: {failsafe}"),
            encoding="utf-8",
        )
        result = validate_path(path, path.name)
        assert [f.location.path[-1] for f in result.errors] == [where], failsafe


def test_a_profile_opting_out_is_warned_at_validation(tmp_path: Path) -> None:
    path = tmp_path / "mission.yaml"
    agent = "    hardware: {autopilot: {safety_setup: false}}"
    path.write_text(MISSION.format(profile="dji_f450", envelope="", agent=agent), "utf-8")
    result = validate_path(path, path.name)
    (finding,) = [f for f in result.findings if f.code == "W-AUTOPILOT-SAFETY-OFF"]
    assert finding.location.path == ("agents", "v", "hardware", "autopilot", "safety_setup")
    assert result.mission is not None
    config = config_from_dict(agent_config(result.mission, result.mission.agents["v"]))
    assert not config.safety_setup


# -- the plan ----------------------------------------------------------------------------


def test_a_copter_gets_its_return_altitude_failsafe_and_fence(tmp_path: Path) -> None:
    config = compiled(tmp_path, "dji_f450")
    command = safety_setup(config, HOME)
    assert command.gcs_id_names == GCS_ID_NAMES == ("MAV_GCS_SYSID", "SYSID_MYGCS")
    radius = round(config.envelope.default_radius_m, 2)  # type: ignore[union-attr, arg-type]
    assert params(command) == [
        ("RTL_ALT", 5750.0, True),  # (60 - 0.5 - 2) m above home, in cm, only lowered
        ("FS_GCS_TIMEOUT", 5.0, False),
        ("FS_GCS_ENABLE", 1.0, False),  # RTL
        ("FENCE_ENABLE", 0.0, False),
        "pause 0.3 s",  # ArduPilot sees FENCE_ENABLE 0 before the new FENCE_TYPE goes on
        "upload",
        ("FENCE_TYPE", 3.0, False),  # maximum altitude and the circle around home
        ("FENCE_ALT_MAX", 59.5, False),  # the ceiling above home
        ("FENCE_RADIUS", radius, False),
        ("FENCE_ACTION", 1.0, False),  # RTL or Land
        ("FENCE_ENABLE", 1.0, False),
    ]
    assert command.steps[5] == UploadFence(())  # no zones: the autopilot's list cleared
    assert command.on_close == (SetParam(("FS_GCS_ENABLE",), 0.0),)
    assert "ceiling 59.5 m above home" in command.summary


def test_a_plane_returns_under_the_ceiling(tmp_path: Path) -> None:
    """ArduPlane's default RTL_ALTITUDE, 100 m, is above a 60 m ceiling."""
    config = compiled(tmp_path, "super_cub")
    command = safety_setup(config, ORIGIN)
    assert params(command)[:4] == [
        ("RTL_ALTITUDE", 58.0, True),
        ("FS_LONG_TIMEOUT", 5.0, False),
        ("FS_LONG_ACTN", 1.0, False),
        ("FS_GCS_ENABL", 1.0, False),
    ]
    assert ("FENCE_ALT_MAX", 60.0, False) in params(command)
    assert command.on_close == (SetParam(("FS_GCS_ENABL",), 0.0),)


def test_a_rover_holds_and_has_no_ceiling_on_its_autopilot(tmp_path: Path) -> None:
    """ArduRover's height above home reads some 90 m: an altitude fence would fire at once."""
    config = compiled(tmp_path, "traxxas_slash")
    command = safety_setup(config, HOME)
    assert params(command) == [
        ("FS_GCS_TIMEOUT", 5.0, False),
        ("FS_ACTION", 2.0, False),  # Hold
        ("FS_GCS_ENABLE", 1.0, False),
        ("FENCE_ENABLE", 0.0, False),
        "pause 0.3 s",
        "upload",
        ("FENCE_TYPE", 2.0, False),
        ("FENCE_RADIUS", 1609.34, False),  # the radio's range, a mile
        ("FENCE_ACTION", 2.0, False),  # Hold
        ("FENCE_ENABLE", 1.0, False),
    ]


@pytest.mark.parametrize(
    ("profile", "action", "expected"),
    [
        ("dji_f450", "land", [("FS_GCS_ENABLE", 5.0)]),
        ("dji_f450", "hold", [("FS_GCS_ENABLE", 7.0)]),  # Brake or Land
        ("super_cub", "land", [("FS_LONG_ACTN", 5.0), ("FS_GCS_ENABL", 1.0)]),  # AUTOLAND
        ("super_cub", "hold", [("FS_LONG_ACTN", 1.0), ("FS_GCS_ENABL", 1.0)]),  # it circles home
        ("traxxas_slash", "rtl", [("FS_ACTION", 1.0), ("FS_GCS_ENABLE", 1.0)]),
        ("traxxas_slash", "land", [("FS_ACTION", 2.0), ("FS_GCS_ENABLE", 1.0)]),  # it stops
    ],
)
def test_computer_lost_per_firmware(
    tmp_path: Path, profile: str, action: str, expected: list[tuple[str, float]]
) -> None:
    agent = f"    failsafe: {{computer_lost: {action}, computer_lost_s: 12}}"
    command = safety_setup(compiled(tmp_path, profile, agent=agent), ORIGIN)
    steps = [(s.name, s.value) for s in command.steps if isinstance(s, SetParam)]
    start = next(i for i, s in enumerate(steps) if s[0] in ("FS_GCS_TIMEOUT", "FS_LONG_TIMEOUT"))
    assert steps[start][1] == 12.0
    assert steps[start + 1 : start + 1 + len(expected)] == expected


@pytest.mark.parametrize(
    ("profile", "on_breach", "fence_action"),
    [
        ("dji_f450", "land", 2.0),
        ("dji_f450", "hold", 4.0),  # Brake or Land
        ("super_cub", "land", 8.0),  # AUTOLAND if possible, else RTL
        ("super_cub", "hold", 1.0),
        ("traxxas_slash", "rtl", 1.0),
    ],
)
def test_on_breach_per_firmware(
    tmp_path: Path, profile: str, on_breach: str, fence_action: float
) -> None:
    command = safety_setup(
        compiled(tmp_path, profile, envelope=f", on_breach: {on_breach}"), ORIGIN
    )
    assert ("FENCE_ACTION", fence_action, False) in params(command)


def test_declared_zones_are_uploaded_and_replace_the_circle(tmp_path: Path) -> None:
    envelope = (
        ", geofence: {include: [{polygon: [[-50, -50], [200, -50], [200, 200], [-50, 200]]}], "
        "exclude: [{circle: {center: [100, 100], radius_m: 20}}]}"
    )
    config = compiled(tmp_path, "dji_f450", envelope=envelope)
    command = safety_setup(config, ORIGIN)
    (upload,) = [s for s in command.steps if isinstance(s, UploadFence)]
    square, pond = upload.zones
    assert square.inclusion and len(square.corners_deg) == 4 and square.center_deg is None
    raw = config.envelope.raw["geofence"]["include"][0]["points"]  # type: ignore[union-attr]
    assert square.corners_deg == tuple((p["lat"], p["lon"]) for p in raw)
    assert not pond.inclusion and pond.radius_m == 20.0 and pond.corners_deg == ()
    assert ("FENCE_TYPE", 5.0, False) in params(command)  # altitude and the zones
    assert not [s for s in params(command) if s[0] == "FENCE_RADIUS"]


def test_exclusions_alone_keep_the_circle_around_home(tmp_path: Path) -> None:
    envelope = ", geofence: {exclude: [{circle: {center: [100, 100], radius_m: 20}}]}"
    command = safety_setup(compiled(tmp_path, "traxxas_slash", envelope=envelope), ORIGIN)
    assert ("FENCE_TYPE", 6.0, False) in params(command)  # the circle and the zone
    (upload,) = [s for s in command.steps if isinstance(s, UploadFence)]
    assert upload.zones == (FenceZone(False, center_deg=upload.zones[0].center_deg, radius_m=20.0),)


def test_a_plan_that_cannot_be_made_says_why(tmp_path: Path) -> None:
    config = compiled(tmp_path, "dji_f450")
    with pytest.raises(SafetyPlanError, match="names no ArduPilot firmware"):
        safety_setup(replace(config, firmware=None), HOME)
    with pytest.raises(SafetyPlanError, match=r"leaves 0\.5 m above home to return at"):
        safety_setup(config, (HOME[0], HOME[1], ORIGIN[2] + 57.5))


# -- the runtime -------------------------------------------------------------------------


def state(t: float, *, armed: bool = False) -> VehicleState:
    return VehicleState(
        1_400_000_000_000 + round(t * 1000),
        ORIGIN[0],
        ORIGIN[1],
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        0.0,
        "MANUAL",
        0,
        armed,
    )


BOOTING = AutopilotStatus(3, True, False, None, LandedState.ON_GROUND)
HOMED = AutopilotStatus(3, True, False, HOME, LandedState.ON_GROUND)  # pre-arm not passed
READY = AutopilotStatus(3, True, True, HOME, LandedState.ON_GROUND)


def setups(out: list[object]) -> list[SetUpAutopilotSafety]:
    return [c for c in out if isinstance(c, SetUpAutopilotSafety)]


def mission_log(runtime: AgentRuntime) -> str:
    return runtime.logbook.streams.mission.getvalue()  # type: ignore[no-any-return]


def test_asked_once_home_is_known_not_after_the_pre_arm_checks(tmp_path: Path) -> None:
    """A fence an earlier mission left may fail the pre-arm checks until this replaces it."""
    runtime = AgentRuntime(compiled(tmp_path, "dji_f450"))
    runtime.deliver(state(0.0), 0.0)
    runtime.deliver(BOOTING, 0.0)
    assert setups(runtime.tick(0.0)) == []
    runtime.deliver(HOMED, 0.1)
    (command,) = setups(runtime.tick(0.1))
    assert command == safety_setup(runtime.config, HOME)
    assert setups(runtime.tick(0.2) + runtime.tick(0.3)) == []  # once
    assert "waits for the pre-arm checks, the autopilot's safety set-up" in mission_log(runtime)
    assert "own safety (the behaviour waits for it): fence (ceiling 59.5 m" in mission_log(runtime)


def test_the_behavior_starts_once_the_set_up_took(tmp_path: Path) -> None:
    runtime = AgentRuntime(compiled(tmp_path, "dji_f450"))
    runtime.deliver(state(0.0, armed=True), 0.0)
    runtime.deliver(READY, 0.0)
    out = runtime.tick(0.0)
    assert setups(out) and not runtime.behavior_started
    assert not runtime.tick(0.1) or not runtime.behavior_started
    runtime.deliver(AutopilotSafetyResult(), 0.15)
    out = runtime.tick(0.2)
    assert runtime.behavior_started
    assert [c for c in out if isinstance(c, SetMode)] == [SetMode("LOITER", 5)]  # hold
    assert "are set and read back" in mission_log(runtime)


def test_a_failed_set_up_keeps_the_behavior_from_starting_and_names_the_parameter(
    tmp_path: Path,
) -> None:
    runtime = AgentRuntime(compiled(tmp_path, "dji_f450"))
    runtime.deliver(state(0.0, armed=True), 0.0)
    runtime.deliver(READY, 0.0)
    runtime.tick(0.0)
    problem = "FENCE_ALT_MAX did not take: reads 100, asked 59.5"
    runtime.deliver(AutopilotSafetyResult(problem, "FENCE_ALT_MAX"), 0.05)
    later: list[object] = []
    for k in range(1, 200):
        later += runtime.tick(k * 0.1)
    assert not runtime.behavior_started
    assert setups(later) == []  # not asked again: the parameter will not take by itself
    assert runtime.launch.waiting_for == (f"the autopilot's safety set-up ({problem})",)
    log = mission_log(runtime)
    assert f"ERROR safety.setup: the autopilot's safety set-up failed: {problem}" in log
    assert f"waits for the autopilot's safety set-up ({problem})" in log


def test_a_set_up_cut_short_is_asked_again_once_the_autopilot_is_back(tmp_path: Path) -> None:
    runtime = AgentRuntime(compiled(tmp_path, "dji_f450"))
    runtime.deliver(state(0.0), 0.0)
    runtime.deliver(READY, 0.0)
    runtime.tick(0.0)
    cut = AutopilotSafetyResult("the autopilot went silent during the set-up", None, retry=True)
    runtime.deliver(cut, 1.0)
    asked: list[float] = []
    for k in range(11, 100):
        t = k * 0.1
        runtime.deliver(state(t), t)
        if setups(runtime.tick(t)):
            asked.append(t)
    assert asked == [pytest.approx(1.0 + SAFETY_RETRY_S)]


def test_not_asked_while_the_autopilot_is_lost(tmp_path: Path) -> None:
    runtime = AgentRuntime(compiled(tmp_path, "dji_f450"))
    runtime.deliver(state(0.0), 0.0)
    runtime.tick(0.0)
    for k in range(1, 40):  # no VehicleState after the first: lost after 3 s
        runtime.tick(k * 0.1)
    assert runtime.autopilot_lost
    runtime.deliver(READY, 4.0)
    assert all(not setups(runtime.tick(4.0 + k * 0.1)) for k in range(1, 20))
    runtime.deliver(state(6.0), 6.0)  # heard again
    assert setups(runtime.tick(6.0))


def test_an_answer_to_nothing_asked_is_ignored(tmp_path: Path) -> None:
    runtime = AgentRuntime(compiled(tmp_path, "dji_f450"))
    runtime.deliver(AutopilotSafetyResult(), 0.0)
    runtime.deliver(state(0.0, armed=True), 0.0)
    runtime.deliver(READY, 0.0)
    assert setups(runtime.tick(0.0))
    assert not runtime.behavior_started


def test_a_config_the_engine_cannot_plan_for_says_so(tmp_path: Path) -> None:
    runtime = AgentRuntime(replace(compiled(tmp_path, "dji_f450"), firmware=None))
    runtime.deliver(state(0.0, armed=True), 0.0)
    runtime.deliver(READY, 0.0)
    assert setups(runtime.tick(0.0)) == []
    (why,) = runtime.launch.waiting_for
    assert "names no ArduPilot firmware" in why


def test_without_wait_ready_it_is_asked_from_the_first_state(tmp_path: Path) -> None:
    runtime = AgentRuntime(replace(compiled(tmp_path, "dji_f450"), wait_ready=False))
    runtime.deliver(state(0.0), 0.0)
    (command,) = setups(runtime.tick(0.0))
    assert command == safety_setup(runtime.config, None)  # home at the origin's height
    assert ("FENCE_ALT_MAX", 60.0, False) in params(command)


def test_stations_and_opted_out_profiles_are_not_asked(tmp_path: Path) -> None:
    bench = AgentRuntime(replace(compiled(tmp_path, "dji_f450"), safety_setup=False))
    bench.deliver(state(0.0, armed=True), 0.0)
    bench.deliver(READY, 0.0)
    assert setups(bench.tick(0.0)) == []
    assert bench.behavior_started
    assert "are NOT set up (its profile says safety_setup: false)" in mission_log(bench)
    path = tmp_path / "mission.yaml"
    result = validate_path(path, path.name)
    assert result.mission is not None
    station = AgentRuntime(
        config_from_dict(agent_config(result.mission, result.mission.agents["mcs"])),
        gps_epoch_ms=0,
    )
    assert station.launch.safety_done
    assert setups(station.tick(0.0) + station.tick(0.1)) == []
