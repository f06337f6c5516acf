"""The mission side of flying real ArduPilot: launch, takeoff, land and return_home.

Vehicles start disarmed on the ground; ``launch`` says who arms them and whether the
pilot hands an aircraft over in flight. These tests hold the resolved model, the
checks that compare launch with the start position and the behaviour, the new
primitives' checks, and what the compiler writes for the runtime.
"""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import pytest

from clark_engine.behaviors import UseContext
from clark_engine.behaviors import behaviors as _behaviors
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.findings import Finding
from clark_engine.mission.model import Launch, Mission
from clark_engine.mission.schemas import validator
from clark_engine.mission.validate import Validation, validate_path

ROOT = Path(__file__).resolve().parent.parent
HEAD = (
    "clark: 1\n"
    "mission: {id: 1, name: demo, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, "
    "alt_amsl_m: 0}}\n"
    "agents:\n"
    "  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}\n"
)


def check(tmp_path: Path, agents: str) -> Validation:
    """Validate a mission made of the shared head and ``agents`` (indented agent entries)."""
    path = tmp_path / "mission.yaml"
    path.write_text(HEAD + agents, encoding="utf-8")
    return validate_path(path, "mission.yaml")


#: Warnings every short example here has (agents without telemetry, a station without a key).
INCIDENTAL = frozenset({"W-NO-HEARTBEAT", "W-NO-KEY"})


def codes(result: Validation) -> list[str]:
    """The codes found, in report order, without the incidental warnings."""
    return [f.code for f in result.findings if f.code not in INCIDENTAL]


def valid(result: Validation) -> Mission:
    """The resolved mission of a result that must have no errors."""
    assert result.mission is not None, [f.format_text() for f in result.findings]
    return result.mission


# ----------------------------------------------------------------------- the model


def test_a_vehicle_without_launch_is_armed_by_its_pilot_on_the_ground(tmp_path: Path) -> None:
    mission = valid(check(tmp_path, "  slash: {id: 2, profile: traxxas_slash}\n"))
    launch = mission.agents["slash"].launch
    assert launch is not None
    assert (launch.armed_by, launch.airborne, launch.engine_arms) == ("pilot", False, False)
    assert launch.location == mission.agents["slash"].location
    assert mission.agents["mcs"].launch is None


def test_launch_keeps_where_each_key_was_written(tmp_path: Path) -> None:
    result = check(
        tmp_path,
        "  f450:\n    id: 2\n    profile: dji_f450\n    launch:\n      armed_by: engine\n",
    )
    launch = valid(result).agents["f450"].launch
    assert launch == Launch("engine", False, launch.location, launch.key_locations)
    assert launch.engine_arms
    assert (launch.location.line, launch.locate("armed_by").line) == (9, 9)
    assert launch.locate("armed_by").dotted_path == "agents.f450.launch.armed_by"
    assert launch.locate("airborne") == launch.location  # not written: the launch mapping


# ----------------------------------------------------------------------- launch checks


@pytest.mark.parametrize(
    ("agent", "expected"),
    [
        (
            "  slash: {id: 2, profile: traxxas_slash, launch: {airborne: true}}\n",
            "E-LAUNCH-AIRBORNE",
        ),
        (
            "  cub: {id: 2, profile: super_cub, position: [0, 0, 60],"
            " launch: {airborne: true, armed_by: engine}}\n",
            "E-LAUNCH-AIRBORNE",
        ),
        ("  cub: {id: 2, profile: super_cub, position: [0, 0, 60]}\n", "E-LAUNCH-HEIGHT"),
        ("  cub: {id: 2, profile: super_cub, launch: {airborne: true}}\n", "E-LAUNCH-HEIGHT"),
        (
            "  cub: {id: 2, profile: super_cub, position: [0, 0, -5], launch: {airborne: true}}\n",
            "E-LAUNCH-HEIGHT",
        ),
        ("  slash: {id: 2, profile: traxxas_slash, position: [0, 0, 3]}\n", "E-LAUNCH-HEIGHT"),
        (
            "  f450: {id: 2, profile: dji_f450,"
            " position: {lat: 30.6373, lon: -96.4787, alt_m: 8}}\n",
            "E-LAUNCH-HEIGHT",
        ),
    ],
)
def test_launch_that_contradicts_the_vehicle_is_an_error(
    tmp_path: Path, agent: str, expected: str
) -> None:
    assert codes(check(tmp_path, agent)) == [expected]


def test_a_rover_on_a_hill_is_told_only_to_remove_the_height(tmp_path: Path) -> None:
    result = check(tmp_path, "  slash: {id: 2, profile: traxxas_slash, position: [0, 0, 3]}\n")
    (finding,) = result.errors
    assert "a rover" in finding.message and "airborne" not in finding.message


def test_airborne_without_height_says_where_to_write_it(tmp_path: Path) -> None:
    result = check(tmp_path, "  f450: {id: 2, profile: dji_f450, launch: {airborne: true}}\n")
    (finding,) = result.errors
    # No position written: the finding points at airborne, the value that needs one.
    assert finding.location.dotted_path == "agents.f450.launch.airborne"
    assert "position: [0, 0, <up_m>]" in finding.message


def test_a_station_with_launch_is_an_error(tmp_path: Path) -> None:
    path = tmp_path / "mission.yaml"
    path.write_text(
        HEAD.replace("telemetry: {heartbeat: 1}}", "telemetry: {heartbeat: 1}, launch: {}}"),
        encoding="utf-8",
    )
    result = validate_path(path, "mission.yaml")
    assert [f.code for f in result.errors] == ["E-LAUNCH-STATION"]
    assert result.errors[0].location.dotted_path == "agents.mcs.launch"


@pytest.mark.parametrize(
    "agent",
    [
        # The schema rejects launch; the checks that compare it with the position wait.
        "  cub: {id: 2, profile: super_cub, position: [0, 0, 60], launch: {airborne: 1}}\n",
        # The schema rejects the position; an airborne start is not reported as heightless.
        "  cub: {id: 2, profile: super_cub, position: [0, 0, high], launch: {airborne: true}}\n",
    ],
)
def test_a_broken_launch_or_position_reports_only_the_schema_error(
    tmp_path: Path, agent: str
) -> None:
    assert not any(c.startswith("E-LAUNCH") for c in codes(check(tmp_path, agent)))


def test_valid_launches_compile_for_the_runtime(tmp_path: Path) -> None:
    mission = valid(
        check(
            tmp_path,
            "  cub: {id: 2, profile: super_cub, position: [0, 0, 60], launch: {airborne: true}}\n"
            "  f450: {id: 3, profile: dji_f450, launch: {armed_by: engine}}\n",
        )
    )
    schema = validator("agent-config")
    seen = {}
    for name, agent in mission.agents.items():
        config = agent_config(mission, agent)
        schema.validate(json.loads(json.dumps(config)))
        seen[name] = config["agent"]["launch"]
    assert seen == {
        "mcs": None,
        "cub": {"armed_by": "pilot", "airborne": True},
        "f450": {"armed_by": "engine", "airborne": False},
    }


def test_the_autopilot_part_carries_land_mode_and_wait_ready(tmp_path: Path) -> None:
    mission = valid(
        check(
            tmp_path,
            "  f450: {id: 2, profile: dji_f450}\n"
            "  cub: {id: 3, profile: super_cub, position: [0, 20]}\n",
        )
    )
    copter = agent_config(mission, mission.agents["f450"])["agent"]["hardware"]["autopilot"]
    plane = agent_config(mission, mission.agents["cub"])["agent"]["hardware"]["autopilot"]
    assert (copter["land_mode"], copter["wait_ready"]) == ("LAND", True)
    assert "land_mode" not in plane and plane["wait_ready"] is True


# ----------------------------------------------------------------------- W-TAKEOFF-MISSING


def test_a_takeoff_anywhere_satisfies_the_guided_states(tmp_path: Path) -> None:
    result = check(
        tmp_path,
        "  f450:\n"
        "    id: 2\n"
        "    profile: dji_f450\n"
        "    behavior:\n"
        "      initial: go\n"
        "      states:\n"
        "        go: {use: waypoint, with: {to: [30, 0, 10]}, transitions: {done: up}}\n"
        "        up: {use: takeoff, with: {alt_m: 10}, transitions: {done: go}}\n",
    )
    # No W-TAKEOFF-MISSING; but its pilot arms it and its first state is not the takeoff,
    # so ArduCopter would disarm it before the takeoff comes.
    assert codes(result) == ["W-LAUNCH-NO-FLIGHT"]


@pytest.mark.parametrize(
    "agent",
    [
        "  slash: {id: 2, profile: traxxas_slash,"
        " behavior: {use: waypoint, with: {to: [30, 0]}}}\n",
        "  f450: {id: 2, profile: dji_f450, position: [0, 0, 10], launch: {airborne: true},"
        " behavior: {use: waypoint, with: {to: [30, 0, 10]}}}\n",
        "  f450: {id: 2, profile: dji_f450, behavior: {use: hold}}\n",
    ],
    ids=["rover", "airborne", "no-guided-state"],
)
def test_no_takeoff_warning_where_none_is_needed(tmp_path: Path, agent: str) -> None:
    assert codes(check(tmp_path, agent)) == []


def test_the_takeoff_warning_points_at_the_mission_use_of_a_block(tmp_path: Path) -> None:
    result = check(
        tmp_path,
        "  anaconda:\n"
        "    id: 2\n"
        "    profile: anaconda\n"
        "    behavior:\n"
        "      use: survey_with_photos\n"
        "      with: {waypoints: [[0, 0, 60], [200, 0, 60]], tolerance_m: 45}\n",
    )
    (finding,) = [f for f in result.findings if f.code == "W-TAKEOFF-MISSING"]
    assert finding.location.file == "mission.yaml"
    assert finding.location.dotted_path == "agents.anaconda.behavior.use"
    assert "ArduPlane" in finding.message and "state tour (waypoint_tour)" in finding.message


# ----------------------------------------------------------------------- the primitives


def test_the_new_primitives_are_declared_and_finish() -> None:
    for name in ("takeoff", "land", "return_home"):
        spec = _behaviors()[name]
        assert spec.needs_autopilot
        assert spec.events(spec.with_defaults({"alt_m": 10})) == frozenset({"done"})
    assert _behaviors()["takeoff"].with_defaults({"alt_m": 10}) == {"alt_m": 10, "tolerance_m": 1}
    assert _behaviors()["return_home"].with_defaults({}) == {"tolerance_m": 5}
    assert _behaviors()["land"].with_defaults({}) == {}


def test_return_home_on_a_fixed_wing_warns_of_its_rtl_circle(tmp_path: Path) -> None:
    result = check(
        tmp_path,
        "  cub: {id: 2, profile: super_cub, position: [0, 0, 60], launch: {airborne: true},"
        " behavior: {use: return_home}}\n",
    )
    (finding,) = [f for f in result.findings if f.code not in INCIDENTAL]
    assert finding.code == "W-ORBIT-TOLERANCE"
    assert "circles home in RTL" in finding.message and "home is never reached" in finding.message
    wide = check(
        tmp_path,
        "  cub: {id: 2, profile: super_cub, position: [0, 0, 60], launch: {airborne: true},"
        " behavior: {use: return_home, with: {tolerance_m: 75}}}\n",
    )
    assert codes(wide) == []


def _use_without(mission: Mission, agent: str, role: str, primitive: str) -> list[Finding]:
    """Run a primitive's check on ``agent`` as if its autopilot profile named no ``role``."""
    vehicle = mission.agents[agent]
    hardware = dataclasses.replace(vehicle.hardware, parts=dict(vehicle.hardware.parts))
    hardware.parts["autopilot"] = {
        k: v for k, v in hardware.parts["autopilot"].items() if k != role
    }
    stripped = dataclasses.replace(vehicle, hardware=hardware)
    where = vehicle.location
    ctx = UseContext(mission, stripped, {}, lambda _param: where, where)
    return list(_behaviors()[primitive].check(ctx))


def test_land_and_return_home_need_their_mode_roles(tmp_path: Path) -> None:
    mission = valid(check(tmp_path, "  f450: {id: 2, profile: dji_f450}\n"))
    (land,) = _use_without(mission, "f450", "land_mode", "land")
    assert land.code == "E-MODE-MISSING"
    assert "land_mode" in land.message and "add land_mode: LAND" in land.message
    (home,) = _use_without(mission, "f450", "rtl_mode", "return_home")
    assert home.code == "E-MODE-MISSING" and "add rtl_mode: RTL" in home.message
    assert _use_without(mission, "f450", "hold_mode", "land") == []
