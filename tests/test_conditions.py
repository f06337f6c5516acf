"""Conditions on other agents and block parameters inside ``when:`` (issue 20 item 8).

Checked by ``clark validate`` (each check on bad input, with its code and line), compiled
as written with the parameters put in, and decided at flight time on fresh peer data only.
The leapfrog example's dry run is tests/test_dry_run.py's (every example passes its own
checks: its sequences show the two rovers taking turns); on SITL, tests/test_dry_run_sitl.py.
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from textwrap import dedent

import pytest

from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentStatus, AgentType, BehaviorState, Heartbeat
from clark_engine.link.packet import Packet
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import Validation, validate_path
from clark_engine.runtime.config import AgentConfig, ConfigError, config_from_dict
from clark_engine.runtime.context import PrimitiveContext, offset_position
from clark_engine.runtime.events import VehicleState
from clark_engine.runtime.peer_conditions import resolve_peer_condition, stale_after_s
from clark_engine.runtime.runtime import AgentRuntime

HEAD = """\
clark: 1
mission: {id: 700, name: cond, loop_hz: 10, heartbeat_timeout_s: 3,
          origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
"""


def _validate(tmp_path: Path, text: str, blocks: dict[str, str] | None = None) -> Validation:
    """Validate a mission written to ``tmp_path`` (with block files beside it)."""
    if blocks:
        folder = tmp_path / "blocks"
        folder.mkdir()
        for name, body in blocks.items():
            (folder / f"{name}.yaml").write_text(dedent(body), encoding="utf-8")
    path = tmp_path / "m.yaml"
    path.write_text(HEAD + dedent(text), encoding="utf-8")
    return validate_path(path, "m.yaml")


def _codes(result: Validation) -> list[tuple[str, int | None]]:
    return [(f.code, f.location.line) for f in result.findings]


def _config(result: Validation, agent: str) -> dict[str, object]:
    assert result.mission is not None, [f.format_text() for f in result.findings]
    return json.loads(compile_mission(result.mission, [agent])[agent])  # type: ignore[no-any-return]


# -- block parameters inside when: ----------------------------------------------------------

WAIT_BLOCK = """\
    block: wait_then_go
    description: Hold until a while has passed, then drive to a point.
    parameters:
      type: object
      required: [point]
      properties:
        wait_s: {type: number, description: How long to hold., default: 5}
        point: {type: array, description: Where to go.}
        gap: {description: Anything at all (its type is checked where it is used).}
    machine:
      initial: wait
      states:
        wait:
          use: hold
          transitions:
            activate: {to: go, when: {in_state_s: {gt: $wait_s}}}
        go: {use: waypoint, with: {to: $point}}
"""

ONE_ROVER = """\
include: {behaviors: [blocks]}
agents:
  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}
  rover:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1}
    behavior: {use: wait_then_go, with: WITH}
"""


def test_a_block_parameter_inside_when_is_put_in_at_compile_time(tmp_path: Path) -> None:
    """Before: the block file's schema refused ``gt: $wait_s`` (E-TYPE in the block)."""
    result = _validate(
        tmp_path,
        ONE_ROVER.replace("WITH", "{point: [20, 0], wait_s: 7}"),
        {"wait_then_go": WAIT_BLOCK},
    )
    assert not result.findings, [f.format_text() for f in result.findings]
    config = _config(result, "rover")
    wait = config["machine"]["states"][0]  # type: ignore[index]
    assert wait["transitions"][0]["when"] == {"in_state_s": {"gt": 7}}


def test_a_block_parameter_inside_when_takes_its_default(tmp_path: Path) -> None:
    result = _validate(
        tmp_path, ONE_ROVER.replace("WITH", "{point: [20, 0]}"), {"wait_then_go": WAIT_BLOCK}
    )
    wait = _config(result, "rover")["machine"]["states"][0]  # type: ignore[index]
    assert wait["transitions"][0]["when"] == {"in_state_s": {"gt": 5}}


def test_a_substituted_value_of_the_wrong_type_is_refused_where_it_was_given(
    tmp_path: Path,
) -> None:
    block = WAIT_BLOCK.replace("{gt: $wait_s}", "{gt: $gap}")
    result = _validate(
        tmp_path,
        ONE_ROVER.replace("WITH", "{point: [20, 0], gap: soon}"),
        {"wait_then_go": block},
    )
    assert result.mission is None
    finding = next(f for f in result.findings if f.code == "E-BLOCK-WHEN")
    assert finding.location.file == "m.yaml"
    assert finding.location.line == 11  # the mission's with:, where "soon" was written
    assert "after the block's parameters are put in" in finding.message
    assert "'soon'" in finding.message
    assert [r.line for r in finding.related] == [11]  # the use: of the block


# -- checks of conditions on other agents ------------------------------------------------------

PAIR = """\
agents:
  rover_a:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1, agent_status: 2, behavior_state: TELEMETRY_A}
    behavior: {initial: drive, states: {drive: {use: waypoint, with: {to: [40, 0]}}}}
  rover_b:
    id: 3
    profile: traxxas_slash
    position: [0, 8]
    telemetry: {heartbeat: 1, agent_status: 2, behavior_state: 2}
    behavior:
      initial: wait
      states:
        wait:
          use: hold
          transitions:
            always: TRANSITION
        go: {use: waypoint, with: {to: [40, 8]}}
"""


def _pair(tmp_path: Path, transition: str, telemetry_a: str = "2") -> Validation:
    text = PAIR.replace("TRANSITION", transition).replace("TELEMETRY_A", telemetry_a)
    return _validate(tmp_path, text)


def test_a_condition_on_another_agents_state_and_position_validates(tmp_path: Path) -> None:
    result = _pair(
        tmp_path,
        "{to: go, when: {all: [{agent_state: {agent: rover_a, in: drive}}, "
        "{ahead_m: {agent: rover_a, gt: 6, bearing_deg: 0}}, {within_m: {agent: rover_a, "
        "lt: 50}}, {above_m: {agent: rover_a, lt: 3}}, {behind_m: {agent: rover_a, lt: 0}}]}}",
    )
    assert not result.findings, [f.format_text() for f in result.findings]
    wait = _config(result, "rover_b")["machine"]["states"][0]  # type: ignore[index]
    assert wait["transitions"][0]["event"] == "always"
    assert wait["transitions"][0]["when"]["all"][1] == {
        "ahead_m": {"agent": "rover_a", "gt": 6, "bearing_deg": 0}
    }


def test_an_unknown_agent_is_named_with_a_hint(tmp_path: Path) -> None:
    result = _pair(tmp_path, "{to: go, when: {agent_state: {agent: rover_c, in: drive}}}")
    assert ("E-AGENT-UNKNOWN", 21) in _codes(result)
    assert "which is not an agent of this mission; did you mean" in result.findings[0].message


def test_a_condition_on_the_agent_itself_is_refused(tmp_path: Path) -> None:
    result = _pair(tmp_path, "{to: go, when: {within_m: {agent: rover_b, lt: 5}}}")
    assert _codes(result) == [("E-CONDITION-SELF", 21)]


def test_a_state_path_the_other_agent_does_not_have_is_refused(tmp_path: Path) -> None:
    result = _pair(tmp_path, "{to: go, when: {agent_state: {agent: rover_a, in: driv}}}")
    assert _codes(result) == [("E-STATE-UNKNOWN", 21)]
    assert "did you mean 'drive'?" in result.findings[0].message


def test_a_behavior_state_the_other_agent_does_not_send_here_is_refused(tmp_path: Path) -> None:
    result = _pair(
        tmp_path,
        "{to: go, when: {agent_state: {agent: rover_a, in: drive}}}",
        telemetry_a="{rate_hz: 2, to: [rover_a_friend]}".replace("rover_a_friend", "rover_a"),
    )
    data = [f for f in result.findings if f.code == "E-CONDITION-DATA"]
    assert [f.location.line for f in data] == [21]
    assert "add behavior_state: {rate_hz: 2, to: [rover_b]} to agents.rover_a.telemetry" in (
        data[0].message
    )


def test_a_position_the_other_agent_does_not_send_is_refused(tmp_path: Path) -> None:
    text = PAIR.replace("TRANSITION", "{to: go, when: {ahead_m: {agent: rover_a, gt: 6}}}")
    text = text.replace("TELEMETRY_A", "2").replace("agent_status: 2, behavior_state: 2}", "}", 1)
    text = text.replace("{heartbeat: 1, agent_status: 2, behavior_state: 2}", "{heartbeat: 1}", 1)
    result = _validate(tmp_path, text)
    assert ("E-CONDITION-DATA", 21) in _codes(result)
    assert "sends no agent_status to rover_b" in result.findings[0].message


def test_a_relative_position_without_bounds_or_with_impossible_ones_is_refused(
    tmp_path: Path,
) -> None:
    result = _pair(tmp_path, "{to: go, when: {behind_m: {agent: rover_a, gt: 5, lt: 2}}}")
    assert _codes(result) == [("E-CONDITION", 21)]


def test_a_relative_position_to_a_station_is_refused_once(tmp_path: Path) -> None:
    text = PAIR.replace("TRANSITION", "{to: go, when: {within_m: {agent: mcs, lt: 3}}}")
    text = text.replace("TELEMETRY_A", "2").replace(
        "agents:\n", "agents:\n  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}\n"
    )
    result = _validate(tmp_path, text)
    assert _codes(result) == [("E-CONDITION", 22)]  # not also "add agent_status to mcs"
    assert "mcs is a station with no position" in result.findings[0].message


def test_an_always_transition_needs_a_condition(tmp_path: Path) -> None:
    assert _codes(_pair(tmp_path, "go")) == [("E-ALWAYS-WHEN", 21)]


def test_a_state_path_is_bounded_by_the_schema(tmp_path: Path) -> None:
    long = ".".join(["s"] * 150)
    result = _pair(tmp_path, "{to: go, when: {agent_state: {agent: rover_a, in: " + long + "}}}")
    assert result.mission is None
    assert any(f.location.line == 21 for f in result.findings)


# -- the runtime: closures on the fleet table ---------------------------------------------------

ROOT = Path(__file__).resolve().parents[1]
LEAPFROG = ROOT / "missions" / "leapfrog.yaml"
ORIGIN = (30.6372, -96.4787)


@functools.cache
def _rover_a_text() -> str:
    """Rover A's compiled config in leapfrog.yaml (compiled once for the module)."""
    result = validate_path(LEAPFROG, "missions/leapfrog.yaml")
    return json.dumps(_config(result, "rover_a"))


def _runtime_parts(heading_deg: float = 0.0) -> tuple[AgentConfig, PrimitiveContext]:
    """Rover A's config and context, its vehicle at the origin heading ``heading_deg``."""
    config = config_from_dict(json.loads(_rover_a_text()))
    fleet = FleetTable(2, config.mission_id, 3.0, {1: "mcs", 3: "rover_b"})
    ctx = PrimitiveContext(config, fleet)
    ctx.vehicle = VehicleState(
        None, *ORIGIN, 0.0, 0.0, 0.0, heading_deg, 0.0, 0.0, heading_deg, "GUIDED", 15, True
    )
    return config, ctx


def _hear_b(
    ctx: PrimitiveContext,
    now_s: float,
    counter: int,
    north_m: float = 0.0,
    east_m: float = 0.0,
    up_m: float = 0.0,
    active: tuple[str, ...] = ("hold",),
) -> None:
    """Rover B's heartbeat, status and behaviour state, received at ``now_s``."""
    lat, lon = offset_position(*ORIGIN, north_m, east_m)
    messages = (
        Heartbeat(3, 0, ctx.config.mission_id, AgentType.VEHICLE),
        AgentStatus(3, 0, lat, lon, up_m, 0.0, 0.0, 0.0, 15),
        BehaviorState(3, 0, active, "always"),
    )
    ctx.fleet.receive(
        Packet(ctx.config.mission_id, 3, 0, counter, False, messages, 60), now_s, None
    )


def test_another_agents_state_holds_for_the_state_and_its_ancestors_only() -> None:
    config, ctx = _runtime_parts()
    in_leg = resolve_peer_condition("agent_state", {"agent": "rover_b", "in": "leg"}, config)
    in_drive = resolve_peer_condition(
        "agent_state", {"agent": "rover_b", "in": "leg.drive"}, config
    )
    assert not in_leg(ctx, 0.0)  # nothing heard yet
    _hear_b(ctx, 0.0, 1, active=("leg.drive", "photos"))
    assert in_leg(ctx, 0.0) and in_drive(ctx, 0.0)
    _hear_b(ctx, 0.1, 2, active=("legs.drive", "leg_b"))  # prefixes of names, not states
    assert not in_leg(ctx, 0.1) and not in_drive(ctx, 0.1)


def test_a_stale_or_lost_peer_never_satisfies_a_condition() -> None:
    config, ctx = _runtime_parts()
    holding = resolve_peer_condition("agent_state", {"agent": "rover_b", "in": "hold"}, config)
    near = resolve_peer_condition("within_m", {"agent": "rover_b", "lt": 100}, config)
    # Rover B sends both at 2 Hz (leapfrog.yaml): stale after three periods, 1.5 s.
    assert stale_after_s(config.peer("rover_b").sends["behavior_state"]) == 1.5  # type: ignore[union-attr]
    _hear_b(ctx, 10.0, 1, north_m=5)
    ctx.now_s = 11.5
    assert holding(ctx, 0.0) and near(ctx, 0.0)
    ctx.now_s = 11.6
    assert not holding(ctx, 0.0) and not near(ctx, 0.0)
    _hear_b(ctx, 11.6, 2, north_m=5)
    assert holding(ctx, 0.0)
    ctx.fleet.check_timeouts(14.7)  # no heartbeat for over heartbeat_timeout_s: lost
    ctx.now_s = 11.7
    assert not holding(ctx, 0.0) and not near(ctx, 0.0)


def test_ahead_and_behind_are_along_this_agents_heading_or_a_fixed_bearing() -> None:
    def figure(key: str, heading_deg: float, north_m: float, east_m: float, **extra: float) -> bool:
        config, ctx = _runtime_parts(heading_deg)
        _hear_b(ctx, 0.0, 1, north_m=north_m, east_m=east_m)
        # the figure is above 9.9 and below 10.1: 10 m to within the flat-earth error
        holds = resolve_peer_condition(
            key, {"agent": "rover_b", "gt": 9.9, "lt": 10.1, **extra}, config
        )
        return holds(ctx, 0.0)

    assert figure("ahead_m", 0, 10, 0)  # heading north, B 10 m north: 10 m ahead
    assert figure("ahead_m", 90, 3, 10)  # heading east, B 10 m east (3 m aside): ahead
    assert figure("behind_m", 90, 0, -10)  # heading east, B 10 m west: 10 m behind
    assert figure("ahead_m", 90, 10, 0, bearing_deg=0)  # a fixed bearing, not the heading
    assert not figure("ahead_m", 90, 10, 0)  # by the heading (east) B is not ahead
    assert figure("ahead_m", 45, 10 / 2**0.5, 10 / 2**0.5)  # north-east
    config, ctx = _runtime_parts(0)
    _hear_b(ctx, 0.0, 1, north_m=-20)
    behind = resolve_peer_condition("ahead_m", {"agent": "rover_b", "lt": -19}, config)
    assert behind(ctx, 0.0)  # 20 m behind is -20 m ahead


def test_above_and_within_use_both_altitudes_above_the_origin() -> None:
    config, ctx = _runtime_parts()
    _hear_b(ctx, 0.0, 1, north_m=3, east_m=0, up_m=4)
    above = resolve_peer_condition("above_m", {"agent": "rover_b", "gt": 3.9, "lt": 4.1}, config)
    within = resolve_peer_condition("within_m", {"agent": "rover_b", "gt": 4.9, "lt": 5.1}, config)
    assert above(ctx, 0.0) and within(ctx, 0.0)  # 3 m away, 4 m up: 5 m apart


def test_a_condition_on_a_peer_that_sends_nothing_here_never_holds() -> None:
    config, ctx = _runtime_parts()
    _hear_b(ctx, 0.0, 1)
    never = resolve_peer_condition("agent_state", {"agent": "mcs", "in": "hold"}, config)
    assert not never(ctx, 0.0)  # the station sends no behavior_state to rover_a
    unknown = resolve_peer_condition("within_m", {"agent": "nobody", "lt": 1e6}, config)
    assert not unknown(ctx, 0.0)


def test_loading_refuses_a_condition_on_an_agent_that_is_not_a_peer() -> None:
    data = json.loads(_rover_a_text())
    hold = data["machine"]["states"][1]  # type: ignore[index]
    when = hold["transitions"][0]["when"]
    when["any"][1]["agent_state"]["agent"] = "rover_z"
    with pytest.raises(ConfigError) as caught:
        config_from_dict(data, source="rover_a.json")
    assert "waits for 'rover_z' (agent_state), which is not a peer" in str(caught.value)
    assert caught.value.path == "machine.states.1.transitions.0.when.any.1.agent_state.agent"


# -- a block that waits for another agent ------------------------------------------------------

PARTNER_BLOCK = """\
    block: wait_for_partner
    description: Hold until the partner is far enough ahead, then drive to a point.
    parameters:
      type: object
      required: [partner, point]
      properties:
        partner: {type: string, description: The agent to wait for.}
        gap_m: {type: number, description: How far ahead it must be., default: 6}
        point: {type: array, description: Where to go then.}
    machine:
      initial: wait
      states:
        wait:
          use: hold
          transitions:
            always: {to: go, when: {ahead_m: {agent: $partner, gt: $gap_m, bearing_deg: 0}}}
        go: {use: waypoint, with: {to: $point}}
"""

PARTNERS = """\
include: {behaviors: [blocks]}
agents:
  rover_a:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: waypoint, with: {to: [40, 0]}}
  rover_b:
    id: 3
    profile: traxxas_slash
    position: [0, 8]
    telemetry: {heartbeat: 1}
    behavior: {use: wait_for_partner, with: {partner: PARTNER, point: [40, 8]}}
"""


def test_a_block_waits_for_the_agent_its_user_names(tmp_path: Path) -> None:
    result = _validate(
        tmp_path, PARTNERS.replace("PARTNER", "rover_a"), {"wait_for_partner": PARTNER_BLOCK}
    )
    assert not result.findings, [f.format_text() for f in result.findings]
    wait = _config(result, "rover_b")["machine"]["states"][0]  # type: ignore[index]
    assert wait["transitions"][0]["when"] == {
        "ahead_m": {"agent": "rover_a", "gt": 6, "bearing_deg": 0}
    }


def test_a_block_given_an_unknown_agent_is_refused_at_the_users_with(tmp_path: Path) -> None:
    result = _validate(
        tmp_path, PARTNERS.replace("PARTNER", "rover_z"), {"wait_for_partner": PARTNER_BLOCK}
    )
    assert [(f.code, f.location.file, f.location.line) for f in result.findings] == [
        ("E-AGENT-UNKNOWN", "m.yaml", 16)
    ]


def test_the_runtime_asks_the_machine_only_when_an_active_states_always_guard_holds() -> None:
    """The library's trigger costs about 0.2 ms even when no guard holds: the runtime's
    watch decides first, on the guards of the active states only, each with its own
    time in state, and follows the machine's changes."""
    config, _ = _runtime_parts()
    runtime = AgentRuntime(config)
    ctx = runtime.context
    ctx.vehicle = VehicleState(None, *ORIGIN, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, "GUIDED", 15, True)
    watch = runtime._always
    assert watch is not None and runtime.machine is not None
    runtime.machine.start(ctx)  # Rover A in advance: holds once Rover B is 15 m behind
    _hear_b(ctx, 0.0, 1, north_m=-10)
    assert not watch.due(ctx)
    _hear_b(ctx, 0.0, 2, north_m=-16)
    assert watch.due(ctx)
    assert runtime.machine.dispatch("always", ctx)
    assert runtime.machine.active_paths() == ("hold",)
    # In hold: sets off when Rover B holds 10 m ahead (it is 16 m behind), or is parked.
    assert not watch.due(ctx)
    _hear_b(ctx, 0.0, 3, north_m=-16, active=("parked",))
    assert watch.due(ctx)
