"""The runtime primitives: exact commands per tick on a virtual clock, from compiled configs."""

from __future__ import annotations

import dataclasses
import functools
import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import pytest

from clark_engine.behaviors import behaviors
from clark_engine.behaviors import make_behavior as make_primitive
from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.behaviors.doublet import DoubletBehavior
from clark_engine.behaviors.follow_agent import FollowAgentBehavior
from clark_engine.behaviors.photo_trigger import PhotoTriggerBehavior
from clark_engine.behaviors.sine_sweep import SineSweepBehavior
from clark_engine.behaviors.terminate import TerminateBehavior
from clark_engine.behaviors.waypoint import WaypointBehavior
from clark_engine.behaviors.waypoint_tour import WaypointTourBehavior
from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import AgentStatus, AgentType, Heartbeat, PictureData
from clark_engine.link.packet import Packet
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.model import Mission
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import (
    Command,
    Goto,
    PayloadCommand,
    RcOverride,
    SetMode,
    SetServo,
)
from clark_engine.runtime.config import AgentConfig, ConfigError, StateSpec, config_from_dict
from clark_engine.runtime.context import (
    Outbox,
    PrimitiveContext,
    Status,
    ground_distance_m,
    offset_position,
)
from clark_engine.runtime.events import PayloadEvent, VehicleState

ROOT = Path(__file__).resolve().parent.parent
GPS_MS = 1_400_000_000_000

# ------------------------------------------------------------------ helpers


@functools.cache
def mission(mission_file: str) -> Mission:
    result = validate_path(ROOT / "missions" / mission_file)
    assert result.mission is not None, [str(f) for f in result.errors]
    return result.mission


@functools.cache
def compiled(mission_file: str, agent: str) -> AgentConfig:
    """An example mission compiled in-process, read back as the runtime reads a file."""
    resolved = mission(mission_file)
    data = json.loads(json.dumps(agent_config(resolved, resolved.agents[agent])))
    return config_from_dict(data)


def states_of(config: AgentConfig, primitive: str) -> list[StateSpec]:
    assert config.machine is not None
    return [s for s in config.machine.walk() if s.primitive == primitive]


def params_of(config: AgentConfig, primitive: str, **changes: Any) -> dict[str, Any]:
    """The compiled parameters of the agent's first use of a primitive, with changes."""
    return {**states_of(config, primitive)[0].params, **changes}


def fleet_for(config: AgentConfig) -> FleetTable:
    return FleetTable(
        config.agent_id,
        config.mission_id,
        config.heartbeat_timeout_s,
        {peer.id: peer.name for peer in config.peers},
    )


def vehicle(
    lat_deg: float, lon_deg: float, alt_m: float = 0.0, mode: str = "GUIDED"
) -> VehicleState:
    return VehicleState(
        gps_time_ms=GPS_MS,
        lat_deg=lat_deg,
        lon_deg=lon_deg,
        alt_m=alt_m,
        ground_speed_m_s=0.0,
        climb_rate_m_s=0.0,
        heading_deg=0.0,
        roll_deg=0.0,
        pitch_deg=0.0,
        yaw_deg=0.0,
        mode=mode,
        custom_mode=0,
        armed=True,
    )


def local(config: AgentConfig, north_m: float, east_m: float) -> tuple[float, float]:
    """Latitude and longitude of a point metres from the mission origin."""
    return offset_position(config.origin_lat_deg, config.origin_lon_deg, north_m, east_m)


def at(config: AgentConfig, north_m: float, east_m: float, **kw: Any) -> VehicleState:
    return vehicle(*local(config, north_m, east_m), **kw)


def goto(point: Mapping[str, Any], speed_m_s: float | None = None) -> Goto:
    return Goto(point["lat"], point["lon"], point["alt_m"], speed_m_s)


def set_mode(config: AgentConfig, mode: str) -> SetMode:
    return SetMode(mode, config.modes[mode])


class Run:
    """One primitive on a virtual clock: ``now_s = tick / loop_hz``, one update per tick.

    As in the behaviour machine, ``start`` runs at the tick that enters the state
    and the first ``step`` (update) at the tick after it; each call moves the
    clock on by one tick. Payload events and ``stop`` come at the current time.
    """

    def __init__(
        self, config: AgentConfig, primitive: Primitive, fleet: FleetTable | None = None
    ) -> None:
        self.config = config
        self.primitive = primitive
        self.ctx = PrimitiveContext(config=config, fleet=fleet or fleet_for(config))
        self.tick = 0

    def _call(self) -> list[Command]:
        self.ctx.outbox = Outbox()
        self.ctx.now_s = self.tick / self.config.loop_hz
        self.ctx.tick = self.tick
        return self.ctx.outbox.commands

    def start(self, state: VehicleState | None = None) -> list[Command]:
        commands = self._call()
        self.ctx.vehicle = state
        self.primitive.start(self.ctx)
        self.tick += 1
        return list(commands)

    def step(self, state: VehicleState | None = None) -> tuple[Status, list[Command]]:
        commands = self._call()
        if state is not None:
            self.ctx.vehicle = state
        status = self.primitive.update(self.ctx)
        self.tick += 1
        return status, list(commands)

    def stop(self) -> list[Command]:
        commands = self._call()
        self.primitive.stop(self.ctx)
        return list(commands)

    def payload(self, event: PayloadEvent) -> tuple[list[Command], list[Any]]:
        commands = self._call()
        self.primitive.on_payload(self.ctx, event)
        return list(commands), list(self.ctx.outbox.messages)


# ----------------------------------------------------------------- registry


def test_each_behavior_declares_its_runtime_class_and_its_typed_parameters() -> None:
    # One registry: the declaration names the runtime class, which reads its typed params.
    for name, behavior in behaviors().items():
        assert issubclass(behavior.runtime, Primitive)
        assert behavior.runtime.name == name
        assert behavior.runtime.params_type is behavior.parameters


@pytest.mark.parametrize(
    "mission_file",
    sorted(p.name for p in (ROOT / "missions").glob("*.yaml")),
)
def test_every_compiled_example_state_builds_its_primitive(mission_file: str) -> None:
    for agent in mission(mission_file).agents:
        config = compiled(mission_file, agent)
        if config.machine is None:
            continue
        for state in config.machine.walk():
            if state.primitive is not None:
                built = make_primitive(state)
                behavior = behaviors()[state.primitive]
                assert type(built) is behavior.runtime
                assert built.params == behavior.parameters.from_config(state.params)


def test_make_primitive_refuses_states_without_a_known_primitive() -> None:
    config = compiled("supercub_sysid.yaml", "cub")
    assert config.machine is not None
    with pytest.raises(ConfigError, match="runs no primitive"):
        make_primitive(config.machine)
    wait_state = states_of(config, "wait")[0]
    with pytest.raises(ConfigError, match=r"'teleport'.*does not have"):
        make_primitive(dataclasses.replace(wait_state, primitive="teleport"))


def test_a_channel_without_an_output_for_via_fails_when_built() -> None:
    config = compiled("supercub_sysid.yaml", "cub")
    params = params_of(config, "doublet")
    params["channel"] = {**params["channel"], "servo": None}
    with pytest.raises(ConfigError, match="no servo output"):
        DoubletBehavior({**params, "via": "servo"})


# ----------------------------------------------------------------- waypoint

SLASH = ("single_vehicle_mode_change.yaml", "slash")


def test_waypoint_rover_goes_guided_and_is_done_within_ground_tolerance() -> None:
    config = compiled(*SLASH)
    params = params_of(config, "waypoint")
    point = params["to"]
    run = Run(config, make_primitive(states_of(config, "waypoint")[0]))
    far = at(config, 0, 0, mode="MANUAL")
    assert run.start(far) == [set_mode(config, "GUIDED"), goto(point)]
    # still MANUAL a tick (2 s) later: refused or lost, so asked again
    assert run.step() == (Status.RUNNING, [set_mode(config, "GUIDED")])
    # the vehicle enters guided: the target is sent again (ArduPilot reset it)
    assert run.step(at(config, 0, 0)) == (Status.RUNNING, [goto(point)])
    assert run.step(at(config, 10, 5)) == (Status.RUNNING, [])
    # 2.5 m short on the ground, whatever the altitude: not there (tolerance 2 m)
    assert run.step(at(config, 27.5, 20, alt_m=40)) == (Status.RUNNING, [])
    # within 2 m on the ground, 40 m "above": a rover's altitude does not count
    assert run.step(at(config, 28.5, 20, alt_m=40)) == (Status.DONE, [])


def test_waypoint_without_vehicle_state_runs_and_only_asks_for_guided_again() -> None:
    config = compiled(*SLASH)
    run = Run(config, make_primitive(states_of(config, "waypoint")[0]))
    assert run.start() == [set_mode(config, "GUIDED"), goto(params_of(config, "waypoint")["to"])]
    for _ in range(5):  # no report of guided yet: asked again every tick (2 s), nothing else
        assert run.step() == (Status.RUNNING, [set_mode(config, "GUIDED")])


def test_waypoint_does_not_fight_a_mode_change_and_resumes_on_guided() -> None:
    config = compiled(*SLASH)
    point = params_of(config, "waypoint")["to"]
    run = Run(config, make_primitive(states_of(config, "waypoint")[0]))
    assert run.start(at(config, 0, 0)) == [set_mode(config, "GUIDED"), goto(point)]
    assert run.step(at(config, 1, 1)) == (Status.RUNNING, [])
    # the pilot takes over: no SetMode, no Goto
    for _ in range(3):
        assert run.step(at(config, 2, 2, mode="MANUAL")) == (Status.RUNNING, [])
    # the station puts it back in guided: the leg resumes
    assert run.step(at(config, 2, 2)) == (Status.RUNNING, [goto(point)])
    assert run.step(at(config, 3, 3)) == (Status.RUNNING, [])


def test_waypoint_air_vehicle_counts_the_altitude_difference() -> None:
    config = compiled("anaconda_survey.yaml", "anaconda")
    point = params_of(config, "waypoint_tour")["waypoints"][1]  # 300 m north, 60 m up
    run = Run(config, WaypointBehavior({"to": point, "tolerance_m": 5, "speed_m_s": 18}))
    assert run.start() == [set_mode(config, "GUIDED"), goto(point, 18.0)]
    overhead = (point["lat"], point["lon"])
    assert run.step(vehicle(*overhead, alt_m=40)) == (Status.RUNNING, [goto(point, 18.0)])
    assert run.step(vehicle(*overhead, alt_m=54)) == (Status.RUNNING, [])
    assert run.step(vehicle(*overhead, alt_m=56)) == (Status.DONE, [])


def test_waypoint_fails_without_a_guided_mode() -> None:
    config = dataclasses.replace(compiled(*SLASH), guided_mode=None)
    run = Run(config, make_primitive(states_of(config, "waypoint")[0]))
    assert run.start() == []
    assert run.step() == (Status.FAILED, [])


# ------------------------------------------------------------ waypoint_tour


def test_tour_visits_in_order_and_loops() -> None:
    config = compiled("cooperative_follow.yaml", "slash_a")
    params = params_of(config, "waypoint_tour")
    waypoints, speed = params["waypoints"], params["speed_m_s"]
    assert len(waypoints) == 8 and speed == 1
    # Slash A's tour, looped (the example drives it once round, to keep clear of Slash B)
    run = Run(config, WaypointTourBehavior(params_of(config, "waypoint_tour", loop=True)))
    assert run.start(at(config, -5, -5)) == [
        set_mode(config, "GUIDED"),
        goto(waypoints[0], speed),
    ]
    assert run.step(at(config, -5, -5)) == (Status.RUNNING, [])
    for lap in range(2):
        for index, point in enumerate(waypoints):
            here = vehicle(point["lat"], point["lon"])
            following = waypoints[(index + 1) % len(waypoints)]
            assert run.step(here) == (Status.RUNNING, [goto(following, speed)]), (lap, index)
            assert run.step(here) == (Status.RUNNING, []), (lap, index)


def test_tour_without_loop_is_done_at_the_last_waypoint() -> None:
    config = compiled("anaconda_survey.yaml", "anaconda")
    waypoints = params_of(config, "waypoint_tour")["waypoints"]
    run = Run(config, make_primitive(states_of(config, "waypoint_tour")[0]))
    assert run.start() == [set_mode(config, "GUIDED"), goto(waypoints[0])]
    assert run.step() == (Status.RUNNING, [])
    for index, point in enumerate(waypoints[:-1]):
        here = vehicle(point["lat"], point["lon"], point["alt_m"])
        assert run.step(here) == (Status.RUNNING, [goto(waypoints[index + 1])]), index
    # 80 m below the last one is not within the survey's 75 m tolerance
    last = waypoints[-1]
    assert run.step(vehicle(last["lat"], last["lon"], last["alt_m"] - 80)) == (Status.RUNNING, [])
    assert run.step(vehicle(last["lat"], last["lon"], last["alt_m"] - 1)) == (Status.DONE, [])


def test_looping_single_point_tour_does_not_repeat_its_goto() -> None:
    config = compiled("cooperative_follow.yaml", "slash_a")
    point = params_of(config, "waypoint_tour")["waypoints"][2]
    run = Run(config, WaypointTourBehavior({"waypoints": [point], "loop": True, "tolerance_m": 2}))
    there = vehicle(point["lat"], point["lon"])
    assert run.start(there) == [set_mode(config, "GUIDED"), goto(point)]
    for _ in range(4):
        assert run.step(there) == (Status.RUNNING, [])


# ------------------------------------------------------------- follow_agent

FOLLOW = ("cooperative_follow.yaml", "slash_b")


class Leader:
    """Slash A as Slash B's fleet table sees it: packets of its status as it moves."""

    def __init__(self, config: AgentConfig, fleet: FleetTable) -> None:
        peer = config.peer("slash_a")
        assert peer is not None
        self.config, self.fleet, self.id, self.counter = config, fleet, peer.id, 0

    def report(self, north_m: float, east_m: float, now_s: float, alt_m: float = 0.0) -> None:
        lat, lon = local(self.config, north_m, east_m)
        gps_ms = GPS_MS + round(now_s * 1000)
        self.counter += 1
        status = AgentStatus(self.id, gps_ms, lat, lon, alt_m, 2.0, 0.0, 0.0, 15)
        beat = Heartbeat(self.id, gps_ms, self.config.mission_id, AgentType.VEHICLE)
        packet = Packet(self.config.mission_id, self.id, 0, self.counter, False, (beat, status), 60)
        self.fleet.receive(packet, now_s, gps_ms)


LEAD_M = 2.0 * 2.5  # the leader reports 2 m/s due north; follow_agent leads by 2.5 s


def aimed(config: AgentConfig, north_m: float, east_m: float, alt_m: float = 0.0) -> Goto:
    """The Goto that follows a leader reported at north/east.

    It is moved by the mission's offset (Slash B aims beside Slash A, never at it) and
    led along the leader's velocity.
    """
    offset = params_of(config, "follow_agent").get("offset") or {}
    lat, lon = offset_position(
        *local(config, north_m + LEAD_M, east_m),
        float(offset.get("north_m", 0.0)),
        float(offset.get("east_m", 0.0)),
    )
    return Goto(lat, lon, alt_m, None, 2.0, 0.0)


class Near:
    """Equal to a Goto whose position is within a millimetre of this one's (float noise)."""

    def __init__(self, goto: Goto) -> None:
        self.goto = goto

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, Goto):
            return NotImplemented
        mine = dataclasses.replace(self.goto, lat_deg=other.lat_deg, lon_deg=other.lon_deg)
        return (
            mine == other
            and math.isclose(self.goto.lat_deg, other.lat_deg, abs_tol=1e-8)
            and math.isclose(self.goto.lon_deg, other.lon_deg, abs_tol=1e-8)
        )

    def __repr__(self) -> str:
        return f"Near({self.goto!r})"


def test_follow_tracks_a_moving_agent_at_the_retarget_rate() -> None:
    config = compiled(*FOLLOW)
    params = params_of(config, "follow_agent")
    assert params["retarget_hz"] == 2 and config.loop_hz == 10  # a Goto every 5 ticks
    fleet = fleet_for(config)
    leader = Leader(config, fleet)
    run = Run(config, make_primitive(states_of(config, "follow_agent")[0]), fleet)
    me = at(config, -50, -50)
    # no status yet: guided mode, no target
    assert run.start(me) == [set_mode(config, "GUIDED")]  # tick 0
    assert run.step(me) == (Status.RUNNING, [])  # tick 1
    assert run.step(me) == (Status.RUNNING, [])  # tick 2
    gotos: list[tuple[int, Goto]] = []
    for tick in range(3, 40):
        assert run.tick == tick
        leader.report(north_m=tick * 1.0, east_m=10.0, now_s=tick / config.loop_hz)
        status, commands = run.step(me)
        assert status is Status.RUNNING
        gotos.extend((tick, c) for c in commands if isinstance(c, Goto))
        assert all(isinstance(c, Goto) for c in commands)
    # the first Goto as soon as the leader is known, then every 0.5 s from it
    assert [tick for tick, _ in gotos] == [3, 8, 13, 18, 23, 28, 33, 38]
    for tick, command in gotos:
        assert command == Near(aimed(config, tick * 1.0, 10.0))


def test_follow_applies_the_offset_and_finishes_at_the_offset_goal() -> None:
    config = compiled(*FOLLOW)
    fleet = fleet_for(config)
    leader = Leader(config, fleet)
    leader.report(40, 10, now_s=0.0, alt_m=1.0)
    params = params_of(
        config, "follow_agent", offset={"north_m": -8, "east_m": 3, "up_m": 0}, tolerance_m=6
    )
    run = Run(config, FollowAgentBehavior(params), fleet)
    goal = Goto(*offset_position(*local(config, 40 + LEAD_M, 10), -8, 3), 1.0, None, 2.0, 0.0)
    start = run.start(at(config, 0, 0, mode="HOLD"))
    assert start == [set_mode(config, "GUIDED"), Near(goal)]
    # on the leader, 8.5 m from the goal: not there; entering guided re-sends the target
    assert run.step(at(config, 40, 10)) == (Status.RUNNING, [Near(goal)])
    assert run.step(at(config, 25, 13)) == (Status.RUNNING, [])  # 7 m short
    assert run.step(at(config, 27, 13)) == (Status.DONE, [])  # 5 m short


def test_continuous_follow_never_finishes() -> None:
    config = compiled(*FOLLOW)
    fleet = fleet_for(config)
    Leader(config, fleet).report(40, 10, now_s=0.0)
    run = Run(
        config, FollowAgentBehavior(params_of(config, "follow_agent", continuous=True)), fleet
    )
    run.start()
    for _ in range(12):
        status, _commands = run.step(at(config, 40, 10))
        assert status is Status.RUNNING


def test_follow_without_a_vehicle_state_sends_targets_but_never_finishes() -> None:
    config = compiled(*FOLLOW)
    fleet = fleet_for(config)
    Leader(config, fleet).report(0, 0, now_s=0.0)
    run = Run(config, make_primitive(states_of(config, "follow_agent")[0]), fleet)
    target = Near(aimed(config, 0, 0))
    assert run.start() == [set_mode(config, "GUIDED"), target]
    statuses = [run.step() for _ in range(5)]  # ticks 1..5; the next Goto is due at 0.5 s
    assert [s for s, _ in statuses] == [Status.RUNNING] * 5
    assert [c for _, c in statuses] == [[], [], [], [], [target]]


# ------------------------------------------------------------------ doublet

CUB = ("supercub_sysid.yaml", "cub")


def drive(via: str, number: int, pwm_us: int) -> Command:
    return RcOverride({number: pwm_us}) if via == "rc_override" else SetServo(number, pwm_us)


@pytest.mark.parametrize("loop_hz", [10.0, 20.0])
@pytest.mark.parametrize("via", ["rc_override", "servo"])
@pytest.mark.parametrize("first", ["up", "down"])
def test_doublet_pwm_sequence_tick_by_tick(loop_hz: float, via: str, first: str) -> None:
    config = dataclasses.replace(compiled(*CUB), loop_hz=loop_hz)
    params = params_of(config, "doublet", via=via, first=first)
    assert params["width_s"] == 0.5 and params["amplitude_us"] == 150
    assert params["channel"]["rc"] == params["channel"]["servo"] == 1  # the aileron
    run = Run(config, DoubletBehavior(params))
    assert run.start() == []
    n = {10.0: 5, 20.0: 10}[loop_hz]
    high, low = (1650, 1350) if first == "up" else (1350, 1650)
    expected = [[drive(via, 1, high)]] * n + [[drive(via, 1, low)]] * n
    for tick, commands in enumerate(expected):
        assert run.step() == (Status.RUNNING, commands), tick
    final: list[Command]
    if via == "rc_override":  # trim, then hand the stick back to the pilot
        final = [RcOverride({1: 1500}), RcOverride({1: 0})]
    else:
        final = [SetServo(1, 1500)]
    assert run.step() == (Status.DONE, final)
    assert run.stop() == []  # already handed back


def test_doublet_values_are_clamped_integers() -> None:
    config = compiled(*CUB)
    params = params_of(config, "doublet", amplitude_us=450.4)
    doublet = DoubletBehavior(params)
    assert [doublet.pwm_us(k, 10.0) for k in (0, 5, 10)] == [1900, 1100, 1500]
    assert DoubletBehavior(params_of(config, "doublet", amplitude_us=100.6)).pwm_us(0, 10.0) == 1601


def test_doublet_cut_short_returns_to_trim_and_releases() -> None:
    config = compiled(*CUB)
    run = Run(config, DoubletBehavior(params_of(config, "doublet")))
    run.start()
    run.step()
    run.step()
    assert run.stop() == [RcOverride({1: 1500}), RcOverride({1: 0})]
    assert run.stop() == []


# --------------------------------------------------------------- sine_sweep


@pytest.mark.parametrize("law", ["linear", "exponential"])
@pytest.mark.parametrize("via", ["rc_override", "servo"])
def test_sine_sweep_follows_its_frequency_law_at_every_tick(law: str, via: str) -> None:
    config = compiled(*CUB)
    params = params_of(config, "sine_sweep", law=law, via=via)
    channel = params["channel"]
    number = channel["rc"] if via == "rc_override" else channel["servo"]
    sweep = SineSweepBehavior(params)
    f0, f1, duration_s = params["f_start_hz"], params["f_stop_hz"], params["duration_s"]
    assert (f0, f1, duration_s) == (0.2, 2.0, 30)
    assert sweep.frequency_hz(0.0) == pytest.approx(f0, rel=1e-12)
    assert sweep.frequency_hz(duration_s) == pytest.approx(f1, rel=1e-12)
    assert sweep.phase_rad(0.0) == 0.0

    def law_hz(t_s: float) -> float:
        if law == "linear":
            return float(f0 + (f1 - f0) * t_s / duration_s)
        return float(f0 * (f1 / f0) ** (t_s / duration_s))

    def envelope(t_s: float) -> float:
        fade_in_s, fade_out_s = float(params["fade_in_s"]), float(params["fade_out_s"])
        return min(1.0, t_s / fade_in_s, (float(duration_s) - t_s) / fade_out_s)

    run = Run(config, sweep)
    assert run.start() == []
    dt_s = 1.0 / config.loop_hz
    ticks = round(duration_s * config.loop_hz)
    for k in range(ticks):
        t_s = k / config.loop_hz
        measured_hz = (sweep.phase_rad((k + 1) / config.loop_hz) - sweep.phase_rad(t_s)) / (
            2 * math.pi * dt_s
        )
        assert measured_hz == pytest.approx(law_hz(t_s + dt_s / 2), rel=0.01), k
        pwm = round(
            channel["pwm_trim_us"]
            + params["amplitude_us"] * envelope(t_s) * math.sin(sweep.phase_rad(t_s))
        )
        pwm = min(max(pwm, channel["pwm_min_us"]), channel["pwm_max_us"])
        assert run.step() == (Status.RUNNING, [drive(via, number, pwm)]), k
    trim = channel["pwm_trim_us"]
    final = (
        [RcOverride({number: trim}), RcOverride({number: 0})]
        if via == "rc_override"
        else [SetServo(number, trim)]
    )
    assert run.step() == (Status.DONE, final)


def test_sine_sweep_phase_is_the_integral_of_its_frequency() -> None:
    config = compiled(*CUB)
    for law in ("linear", "exponential"):
        sweep = SineSweepBehavior(params_of(config, "sine_sweep", law=law))
        steps = 30_000
        h = 30.0 / steps
        integral = sum(sweep.frequency_hz((i + 0.5) * h) * h for i in range(steps))
        assert sweep.phase_rad(30.0) == pytest.approx(2 * math.pi * integral, rel=1e-6)


def test_sine_sweep_exponential_with_equal_frequencies_is_a_plain_sine() -> None:
    config = compiled(*CUB)
    sweep = SineSweepBehavior(params_of(config, "sine_sweep", f_start_hz=1.0, f_stop_hz=1.0))
    sweep_exp = SineSweepBehavior(
        params_of(config, "sine_sweep", f_start_hz=1.0, f_stop_hz=1.0, law="exponential")
    )
    for t_s in (0.0, 0.3, 7.25, 30.0):
        assert sweep.frequency_hz(t_s) == sweep_exp.frequency_hz(t_s) == 1.0
        assert sweep_exp.phase_rad(t_s) == pytest.approx(2 * math.pi * t_s, abs=1e-12)


def test_sine_sweep_starts_at_trim_and_fades() -> None:
    config = compiled(*CUB)
    sweep = SineSweepBehavior(params_of(config, "sine_sweep"))
    assert sweep.pwm_us(0.0) == 1500
    assert sweep.envelope(1.0) == 0.5
    assert sweep.envelope(15.0) == 1.0
    assert sweep.envelope(29.0) == pytest.approx(0.5)
    assert sweep.envelope(30.0) == 0.0


def test_sine_sweep_cut_short_returns_to_trim_and_releases() -> None:
    config = compiled(*CUB)
    run = Run(config, SineSweepBehavior(params_of(config, "sine_sweep")))
    run.start()
    for _ in range(30):
        run.step()
    assert run.stop() == [RcOverride({2: 1500}), RcOverride({2: 0})]


# ------------------------------------------------------------ photo_trigger

ANACONDA = ("anaconda_survey.yaml", "anaconda")


def test_photo_trigger_requests_every_interval_and_reports_captures() -> None:
    config = compiled(*ANACONDA)
    params = params_of(config, "photo_trigger")
    assert params["interval_s"] == 5 and config.loop_hz == 10
    run = Run(config, make_primitive(states_of(config, "photo_trigger")[0]))
    assert run.start() == [PayloadCommand("camera", "capture", 1)]
    requests: list[tuple[int, Command]] = []
    for tick in range(1, 160):
        status, commands = run.step()
        assert status is Status.RUNNING
        requests.extend((tick, c) for c in commands)
    assert requests == [
        (50, PayloadCommand("camera", "capture", 2)),
        (100, PayloadCommand("camera", "capture", 3)),
        (150, PayloadCommand("camera", "capture", 4)),
    ]
    run.ctx.vehicle = at(config, 120, 30, alt_m=60)
    run.ctx.gps_time_ms = GPS_MS + 16_000
    commands, messages = run.payload(PayloadEvent("camera", "captured", 2, "img_0002.jpg"))
    lat, lon = local(config, 120, 30)
    assert commands == []
    assert messages == [(PictureData(config.agent_id, GPS_MS + 16_000, lat, lon, 60.0, 1), ())]
    # answers that are not ours, or repeated, change nothing
    for event in (
        PayloadEvent("camera", "captured", 99),
        PayloadEvent("camera", "captured", 2),
        PayloadEvent("other_camera", "captured", 3),
    ):
        assert run.payload(event) == ([], [])
    assert run.payload(PayloadEvent("camera", "refused", 3, "too soon")) == ([], [])
    assert run.payload(PayloadEvent("camera", "error", 4, "disk full")) == ([], [])
    primitive = run.primitive
    assert isinstance(primitive, PhotoTriggerBehavior)
    assert (primitive.captured, primitive.refused, primitive.errors) == (1, 1, 1)


def test_photo_trigger_is_done_after_count_and_sends_to_the_named_agents() -> None:
    config = compiled(*ANACONDA)
    run = Run(config, PhotoTriggerBehavior(params_of(config, "photo_trigger", count=2, to=["mcs"])))
    assert run.start(at(config, 0, 0, alt_m=60)) == [PayloadCommand("camera", "capture", 1)]
    _, messages = run.payload(PayloadEvent("camera", "captured", 1))
    assert [(m.image_index, to) for m, to in messages] == [(1, ("mcs",))]
    for _ in range(49):  # ticks 1..49
        assert run.step() == (Status.RUNNING, [])
    assert run.step() == (Status.RUNNING, [PayloadCommand("camera", "capture", 2)])  # 5 s
    _, messages = run.payload(PayloadEvent("camera", "captured", 2))
    assert [(m.image_index, m.gps_time_ms) for m, _ in messages] == [(2, 0)]
    assert run.step() == (Status.DONE, [])


def test_photo_trigger_without_a_position_still_captures_but_sends_nothing() -> None:
    config = compiled(*ANACONDA)
    run = Run(config, PhotoTriggerBehavior(params_of(config, "photo_trigger", count=1)))
    assert run.start() == [PayloadCommand("camera", "capture", 1)]
    assert run.payload(PayloadEvent("camera", "captured", 1)) == ([], [])
    assert run.step() == (Status.DONE, [])


# ------------------------------------------------- hold, set_mode, wait, terminate


def test_hold_switches_to_the_hold_mode_and_runs_forever() -> None:
    config = compiled(*ANACONDA)
    run = Run(config, make_primitive(states_of(config, "hold")[0]))
    assert run.start(at(config, 0, 0, mode="LOITER")) == [set_mode(config, "LOITER")]
    for _ in range(20):
        assert run.step(at(config, 0, 0, mode="MANUAL")) == (Status.RUNNING, [])


def test_hold_asks_again_while_refused_and_never_after_it_was_granted() -> None:
    # ArduRover armed before its EKF had a position refuses position modes for about a
    # second after it has one (its EKF failsafe; measured on SITL): ask again, once a second
    config = dataclasses.replace(compiled(*ANACONDA), loop_hz=10.0)
    loiter = set_mode(config, "LOITER")
    run = Run(config, make_primitive(states_of(config, "hold")[0]))
    assert run.start(at(config, 0, 0, mode="MANUAL")) == [loiter]
    sent: list[int] = []
    for _ in range(25):
        tick = run.tick
        if run.step(at(config, 0, 0, mode="MANUAL")) == (Status.RUNNING, [loiter]):
            sent.append(tick)
    assert sent == [10, 20]  # ticks, at 10 Hz: 1 s and 2 s after the first request
    assert run.step(at(config, 0, 0, mode="LOITER")) == (Status.RUNNING, [])
    # granted: the pilot's switch back to MANUAL is theirs, not a refusal
    for _ in range(30):
        assert run.step(at(config, 0, 0, mode="MANUAL")) == (Status.RUNNING, [])


def test_a_refused_mode_is_not_asked_again_once_someone_chose_another() -> None:
    config = dataclasses.replace(compiled(*ANACONDA), loop_hz=10.0)
    run = Run(config, make_primitive(states_of(config, "hold")[0]))
    assert run.start(at(config, 0, 0, mode="MANUAL")) == [set_mode(config, "LOITER")]
    assert run.step(at(config, 0, 0, mode="FBWA")) == (Status.RUNNING, [])  # the pilot's switch
    for _ in range(30):
        assert run.step(at(config, 0, 0, mode="MANUAL")) == (Status.RUNNING, [])


def test_hold_fails_without_a_hold_mode() -> None:
    config = dataclasses.replace(compiled(*ANACONDA), hold_mode=None)
    run = Run(config, make_primitive(states_of(config, "hold")[0]))
    assert run.start() == []
    assert run.step() == (Status.FAILED, [])


def test_set_mode_resends_once_a_second_until_the_autopilot_reports_it() -> None:
    config = dataclasses.replace(compiled(*SLASH), loop_hz=10.0)
    run = Run(config, make_primitive(states_of(config, "set_mode")[0]))
    manual = set_mode(config, "MANUAL")
    assert run.start(at(config, 0, 0, mode="GUIDED")) == [manual]
    sent: list[int] = []
    for tick in range(1, 26):
        status, commands = run.step()
        assert status is Status.RUNNING
        sent.extend(tick for c in commands if c == manual)
    assert sent == [10, 20]
    assert run.step(at(config, 0, 0, mode="MANUAL")) == (Status.DONE, [])


def test_set_mode_without_vehicle_state_keeps_asking() -> None:
    config = compiled(*SLASH)  # loop_hz 0.5: every tick is 2 s after the last
    run = Run(config, make_primitive(states_of(config, "set_mode")[0]))
    manual = set_mode(config, "MANUAL")
    assert run.start() == [manual]
    assert run.step() == (Status.RUNNING, [manual])
    assert run.step() == (Status.RUNNING, [manual])


def test_wait_is_done_after_its_duration_on_the_runtime_clock() -> None:
    config = compiled(*CUB)
    state = next(s for s in states_of(config, "wait") if s.params.get("duration_s") == 3)
    run = Run(config, make_primitive(state))
    for _ in range(7):
        run.step()  # the clock moves on before the state is entered
    assert run.start(at(config, 0, 0)) == []  # at 0.7 s
    results = [run.step() for _ in range(30)]  # 0.8 s .. 3.7 s
    assert results[:29] == [(Status.RUNNING, [])] * 29
    assert results[29] == (Status.DONE, [])


def test_wait_without_duration_waits_forever_and_commands_nothing() -> None:
    config = compiled(*CUB)
    state = next(s for s in states_of(config, "wait") if "duration_s" not in s.params)
    run = Run(config, make_primitive(state))
    assert run.start() == []
    for _ in range(100):
        assert run.step() == (Status.RUNNING, [])


@pytest.mark.parametrize("mode", [None, "RTL"])
def test_terminate_asks_the_runtime_to_terminate(mode: str | None) -> None:
    config = compiled(*CUB)
    run = Run(config, TerminateBehavior({} if mode is None else {"mode": mode}))
    assert run.start() == []
    assert run.ctx.terminate_requested
    assert run.ctx.terminal_mode == mode
    assert run.step() == (Status.RUNNING, [])


def test_ground_distance_helper_agrees_with_the_local_frame() -> None:
    config = compiled(*SLASH)
    a, b = local(config, 0, 0), local(config, 30, 40)
    assert ground_distance_m(*a, *b) == pytest.approx(50.0, rel=1e-3)
