"""The vehicle lifecycle in the runtime: readiness, arming, take-off, landing, going home.

Each test drives a runtime or a primitive built from a compiled example (or a small
mission written here) on a virtual clock, and asserts the exact commands: when a
behaviour starts, who arms, when a take-off is sent, when a target is sent again.
"""

from __future__ import annotations

import functools
import json
import logging
from dataclasses import replace
from pathlib import Path

import pytest

from clark_engine.behaviors import make_behavior as make_primitive
from clark_engine.behaviors.base import BehaviorRuntime as Primitive
from clark_engine.behaviors.flight import ARM_RETRY_S
from clark_engine.behaviors.takeoff import TAKEOFF_RETRY_S
from clark_engine.link.codec import Codec
from clark_engine.link.fleet import FleetTable
from clark_engine.link.messages import ActivateController, AgentType, Heartbeat
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import Arm, Command, Goto, SetMode, SetUpAutopilotSafety, Takeoff
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.context import Outbox, PrimitiveContext, Status, offset_position
from clark_engine.runtime.events import (
    AutopilotSafetyResult,
    AutopilotStatus,
    CommandRefused,
    LandedState,
    PacketReceived,
    VehicleState,
)
from clark_engine.runtime.launch import LaunchGate, is_airborne
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parent.parent
GPS0 = 1_400_000_000_000
ORIGIN = (30.6372, -96.4787)
READY = AutopilotStatus(3, True, True, (ORIGIN[0], ORIGIN[1], 90.0), LandedState.ON_GROUND)


@functools.cache
def config(mission_file: str, agent: str) -> AgentConfig:
    result = validate_path(ROOT / "missions" / mission_file)
    assert result.mission is not None
    data = json.loads(json.dumps(agent_config(result.mission, result.mission.agents[agent])))
    return config_from_dict(data)


def config_from_text(tmp_path: Path, text: str, agent: str) -> AgentConfig:
    path = tmp_path / "mission.yaml"
    path.write_text(text, encoding="utf-8")
    result = validate_path(path, path.name)
    assert result.mission is not None, [f.format_text() for f in result.findings]
    return config_from_dict(agent_config(result.mission, result.mission.agents[agent]))


def state(
    north_m: float = 0.0,
    east_m: float = 0.0,
    alt_m: float = 0.0,
    *,
    mode: str = "MANUAL",
    armed: bool = False,
    t: float = 0.0,
) -> VehicleState:
    lat, lon = offset_position(*ORIGIN, north_m, east_m)
    return VehicleState(
        GPS0 + round(t * 1000), lat, lon, alt_m, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, mode, 0, armed
    )


def station_packet(cfg: AgentConfig, *messages: object) -> PacketReceived:
    codec = Codec(cfg.mission_id, 1)
    (data,) = codec.encode(
        [Heartbeat(1, GPS0, cfg.mission_id, AgentType.MCS), *messages],  # type: ignore[list-item]
        0,
        256,
    )
    return PacketReceived(data)


def of(commands: list[Command], kind: type) -> list[Command]:
    return [c for c in commands if isinstance(c, kind)]


# ------------------------------------------------------------------------- the gate


def test_a_station_starts_at_once() -> None:
    gate = LaunchGate(config("cooperative_follow.yaml", "mcs"), _log())
    assert gate.open
    assert gate.update(None, None)


def test_a_pilot_armed_rover_waits_for_readiness_then_the_pilot() -> None:
    gate = LaunchGate(config("cooperative_follow.yaml", "slash_b"), _log())
    assert not gate.update(None, None)
    assert "the autopilot's first state" in gate.waiting_for
    booting = AutopilotStatus(gps_fix_type=3, position_ok=False, prearm_ok=False)
    assert not gate.update(booting, state())
    assert gate.waiting_for == (
        "an EKF position",
        "the pre-arm checks",
        "a home position",
        "the autopilot's safety set-up",
        "the pilot to arm it",
    )
    assert not gate.update(READY, state())
    assert gate.waiting_for == ("the autopilot's safety set-up", "the pilot to arm it")
    gate.safety_result("")  # the autopilot's fence and failsafe took
    assert not gate.update(READY, state())
    assert gate.waiting_for == ("the pilot to arm it",)
    assert gate.update(READY, state(armed=True))
    # Open once, open for good: a disarm later does not stop the behaviour.
    assert gate.update(READY, state(armed=False))


def test_an_engine_armed_copter_starts_when_ready_and_disarmed() -> None:
    gate = LaunchGate(config("copter_takeoff_land.yaml", "f450"), _log())
    assert not gate.update(READY, state(mode="STABILIZE"))
    assert gate.waiting_for == ("the autopilot's safety set-up",)
    gate.safety_result("")
    assert gate.update(READY, state(mode="STABILIZE"))


def test_a_failed_safety_set_up_keeps_the_gate_shut_and_says_what_did_not_take() -> None:
    gate = LaunchGate(config("copter_takeoff_land.yaml", "f450"), _log())
    gate.safety_result("FENCE_ALT_MAX did not take: reads 100, asked 118")
    assert not gate.update(READY, state(mode="STABILIZE"))
    assert gate.waiting_for == (
        "the autopilot's safety set-up (FENCE_ALT_MAX did not take: reads 100, asked 118)",
    )
    assert not gate.safety_done


def test_a_bench_profile_without_the_safety_set_up_starts_with_a_warning(
    caplog: pytest.LogCaptureFixture,
) -> None:
    cfg = replace(config("copter_takeoff_land.yaml", "f450"), safety_setup=False)
    gate = LaunchGate(cfg, _log())
    assert gate.safety_done
    with caplog.at_level(logging.WARNING, logger="test-launch"):
        assert gate.update(READY, state(mode="STABILIZE"))
    assert "are NOT set up (its profile says safety_setup: false)" in caplog.text


def test_an_airborne_handover_waits_for_the_pilot_to_take_off() -> None:
    gate = LaunchGate(config("supercub_sysid.yaml", "cub"), _log())
    gate.safety_result("")
    assert not gate.update(READY, state(armed=True))
    assert gate.waiting_for == ("the pilot to take off",)
    flying = replace(READY, landed=LandedState.IN_AIR)
    assert gate.update(flying, state(alt_m=40, armed=True))


def test_a_vehicle_whose_height_disagrees_with_the_origin_does_not_start() -> None:
    """A wrong origin.alt_amsl_m would put every commanded height off by as much."""
    gate = LaunchGate(config("copter_takeoff_land.yaml", "f450"), _log())
    gate.safety_result("")
    assert not gate.update(READY, state(alt_m=23.4, mode="STABILIZE"))
    (why,) = gate.waiting_for
    assert "on the ground it reads +23 m from the origin" in why
    assert "113 m above sea level against mission.origin.alt_amsl_m 90" in why
    assert gate.update(READY, state(alt_m=3.0, mode="STABILIZE"))  # GPS wander is fine


def test_without_wait_ready_only_the_pilot_is_waited_for() -> None:
    cfg = replace(config("cooperative_follow.yaml", "slash_b"), wait_ready=False)
    gate = LaunchGate(cfg, _log())
    gate.safety_result("")
    assert not gate.update(None, state())
    assert gate.waiting_for == ("the pilot to arm it",)
    assert gate.update(None, state(armed=True))


def test_airborne_is_the_landed_state_or_armed_and_up() -> None:
    assert is_airborne(replace(READY, landed=LandedState.TAKING_OFF), None)
    assert not is_airborne(READY, state(alt_m=50, armed=True))  # the autopilot says on ground
    unknown = replace(READY, landed=LandedState.UNKNOWN)
    assert is_airborne(unknown, state(alt_m=3, armed=True))
    assert not is_airborne(unknown, state(alt_m=3, armed=False))
    assert not is_airborne(unknown, state(alt_m=1, armed=True))


# ------------------------------------------------------------------ the runtime


def test_the_behavior_starts_only_once_ready_and_armed() -> None:
    cfg = config("cooperative_follow.yaml", "slash_a")
    runtime = AgentRuntime(cfg)
    assert not of(runtime.tick(0.0), SetMode)
    runtime.deliver(state(t=1.0), 1.0)
    runtime.deliver(READY, 1.0)
    out = runtime.tick(1.0)
    assert not of(out, SetMode)  # ready, not armed by its pilot yet
    assert len(of(out, SetUpAutopilotSafety)) == 1  # the autopilot is asked to hold it too
    runtime.deliver(AutopilotSafetyResult(), 1.5)
    assert not of(runtime.tick(1.5), SetMode)
    assert runtime.machine is not None and not runtime.machine.running
    runtime.deliver(state(armed=True, t=2.0), 2.0)
    out = runtime.tick(2.0)
    assert of(out, SetMode) == [SetMode("GUIDED", 15)]  # the tour starts
    assert of(out, Arm) == []  # the pilot armed it; the engine never does
    assert of(out, Goto)  # its first waypoint (and the second: it stands on the first)
    log = runtime.logbook.streams.mission.getvalue()
    assert "launch: the behaviour waits for the pilot to arm it" in log
    assert "launch: the autopilot is ready; armed by the pilot; the behaviour starts" in log


def test_an_activation_before_the_behavior_starts_never_acts() -> None:
    cfg = config("cooperative_follow.yaml", "slash_b")
    runtime = AgentRuntime(cfg)
    runtime.deliver(state(t=1.0), 1.0)
    activate = ActivateController(1, GPS0, cfg.agent_id, active=True)
    runtime.deliver(station_packet(cfg, activate), 1.0)
    runtime.tick(1.0)
    runtime.deliver(READY, 2.0)
    runtime.deliver(state(armed=True, t=2.0), 2.0)
    runtime.tick(2.0)
    runtime.deliver(AutopilotSafetyResult(), 2.05)
    runtime.tick(2.1)
    runtime.tick(2.2)
    assert runtime.machine is not None
    assert runtime.machine.active_paths() == ("idle",)  # not chase: the activation is gone
    log = runtime.logbook.streams.mission.getvalue()
    assert "ignored" in log and "activate" in log


def test_a_refusal_reaches_the_mission_log_with_its_reason() -> None:
    runtime = AgentRuntime(config("copter_takeoff_land.yaml", "f450"))
    refusal = CommandRefused(
        "MAV_CMD_COMPONENT_ARM_DISARM", "FAILED", "arm", "Arm: Need Position Estimate"
    )
    runtime.deliver(refusal, 1.0)
    log = runtime.logbook.streams.mission.getvalue()
    assert "autopilot refused arm: FAILED (Arm: Need Position Estimate)" in log


# ---------------------------------------------------------------- the primitives


class Run:
    """One primitive on a virtual clock at the config's loop rate."""

    def __init__(self, cfg: AgentConfig, primitive: Primitive) -> None:
        self.cfg = cfg
        self.primitive = primitive
        self.ctx = PrimitiveContext(
            config=cfg, fleet=FleetTable(cfg.agent_id, cfg.mission_id, 3.0, {})
        )
        self.ctx.autopilot = READY
        self.tick = 0

    def _at(self, vehicle: VehicleState | None, status: AutopilotStatus | None) -> None:
        self.ctx.outbox = Outbox()
        self.ctx.now_s = self.tick / self.cfg.loop_hz
        if vehicle is not None:
            self.ctx.vehicle = vehicle
        if status is not None:
            self.ctx.autopilot = status
        self.tick += 1

    def start(self, vehicle: VehicleState | None = None) -> list[Command]:
        self._at(vehicle, None)
        self.primitive.start(self.ctx)
        return list(self.ctx.outbox.commands)

    def step(
        self, vehicle: VehicleState | None = None, status: AutopilotStatus | None = None
    ) -> tuple[Status, list[Command]]:
        self._at(vehicle, status)
        result = self.primitive.update(self.ctx)
        return result, list(self.ctx.outbox.commands)

    def idle(self, seconds: float, vehicle: VehicleState | None = None) -> list[Command]:
        out: list[Command] = []
        for _ in range(round(seconds * self.cfg.loop_hz)):
            out += self.step(vehicle)[1]
        return out


def primitive_of(cfg: AgentConfig, state_name: str) -> Primitive:
    assert cfg.machine is not None
    (spec,) = [s for s in cfg.machine.walk() if s.name == state_name]
    return make_primitive(spec)


def test_engine_arming_arms_once_retries_and_never_fights_a_disarm() -> None:
    cfg = config("copter_takeoff_land.yaml", "f450")
    run = Run(cfg, primitive_of(cfg, "out"))
    first = run.start(state(alt_m=10, mode="GUIDED"))
    assert first[:2] == [SetMode("GUIDED", 4), Arm()]
    # Still disarmed: Arm again every ARM_RETRY_S, not every tick.
    retried = run.idle(ARM_RETRY_S, state(alt_m=10, mode="GUIDED"))
    assert of(retried, Arm) == [Arm()]
    run.step(state(alt_m=10, mode="GUIDED", armed=True))
    # Disarmed after being armed: the engine does not arm it again.
    later = run.idle(3 * ARM_RETRY_S, state(alt_m=10, mode="GUIDED", armed=False))
    assert of(later, Arm) == []


def test_a_pilot_armed_vehicle_is_never_armed_by_the_engine() -> None:
    cfg = config("cooperative_follow.yaml", "slash_b")
    run = Run(cfg, primitive_of(cfg, "chase"))
    out = run.start(state(mode="HOLD")) + run.idle(3 * ARM_RETRY_S, state(mode="GUIDED"))
    assert of(out, Arm) == []


def test_the_target_is_sent_again_when_armed_and_when_flying() -> None:
    cfg = config("copter_takeoff_land.yaml", "f450")
    run = Run(cfg, primitive_of(cfg, "out"))
    (goto,) = of(run.start(state(mode="GUIDED", armed=False)), Goto)
    on_ground = state(mode="GUIDED", armed=False)
    assert of(run.step(on_ground)[1], Goto) == []
    # Armed by its pilot or the engine: ArduCopter may have dropped the target; again.
    assert of(run.step(state(mode="GUIDED", armed=True))[1], Goto) == [goto]
    assert of(run.step(state(mode="GUIDED", armed=True))[1], Goto) == []
    # Lifted off (a takeoff elsewhere): targets sent on the ground were ignored; again.
    flying = replace(READY, landed=LandedState.IN_AIR)
    _, out = run.step(state(alt_m=3, mode="GUIDED", armed=True), flying)
    assert of(out, Goto) == [goto]


def test_copter_takeoff_waits_for_guided_and_armed_then_climbs() -> None:
    cfg = config("copter_takeoff_land.yaml", "f450")
    run = Run(cfg, primitive_of(cfg, "climb"))
    assert run.start(state(mode="STABILIZE")) == [SetMode("GUIDED", 4), Arm()]
    # Not yet reported guided and armed: no takeoff (ArduCopter would refuse it).
    assert of(run.step(state(mode="STABILIZE"))[1], Takeoff) == []
    assert of(run.step(state(mode="GUIDED"))[1], Takeoff) == []
    status, out = run.step(state(mode="GUIDED", armed=True))
    assert (status, of(out, Takeoff)) == (Status.RUNNING, [Takeoff(10.0)])
    # Still on the ground: again after TAKEOFF_RETRY_S, not before.
    again = run.idle(TAKEOFF_RETRY_S, state(mode="GUIDED", armed=True))
    assert of(again, Takeoff) == [Takeoff(10.0)]
    climbing = replace(READY, landed=LandedState.TAKING_OFF)
    assert run.step(state(alt_m=5, mode="GUIDED", armed=True), climbing)[0] is Status.RUNNING
    flying = replace(READY, landed=LandedState.IN_AIR)
    assert run.step(state(alt_m=9.2, mode="GUIDED", armed=True), flying)[0] is Status.DONE


def test_copter_takeoff_fails_when_disarmed_before_it_flies() -> None:
    cfg = config("copter_takeoff_land.yaml", "f450")
    run = Run(cfg, primitive_of(cfg, "climb"))
    run.start(state(mode="GUIDED"))
    run.step(state(mode="GUIDED", armed=True))
    # ArduCopter's auto-disarm (or the pilot): FAILED, and no new Arm.
    status, out = run.step(state(mode="GUIDED", armed=False))
    assert status is Status.FAILED
    assert of(out, Arm) == []


PLANE_TAKEOFF = """
clark: 1
mission: {id: 9, name: plane-takeoff, loop_hz: 10, origin: {lat: 30.64, lon: -96.48, alt_amsl_m: 0}}
agents:
  mcs: {id: 1, profile: mcs_laptop}
  cub:
    id: 2
    profile: super_cub
    launch: {armed_by: engine}
    behavior:
      initial: climb
      states:
        climb: {use: takeoff, with: {alt_m: 40}, transitions: {done: home}}
        home: {use: return_home, with: {tolerance_m: 150}, final: true}
"""


def test_plane_takeoff_is_the_takeoff_mode_then_arming(tmp_path: Path) -> None:
    cfg = config_from_text(tmp_path, PLANE_TAKEOFF, "cub")
    run = Run(cfg, primitive_of(cfg, "climb"))
    assert run.start(state()) == [Takeoff(40.0), Arm()]
    assert of(run.idle(TAKEOFF_RETRY_S, state(mode="TAKEOFF", armed=True)), Takeoff) == [
        Takeoff(40.0)
    ]
    rolling = replace(READY, landed=LandedState.TAKING_OFF)
    assert run.step(state(alt_m=20, mode="TAKEOFF", armed=True), rolling)[0] is Status.RUNNING
    flying = replace(READY, landed=LandedState.IN_AIR)
    assert run.step(state(alt_m=39.5, mode="TAKEOFF", armed=True), flying)[0] is Status.DONE


def test_land_is_the_land_mode_and_done_on_the_ground() -> None:
    cfg = config("copter_takeoff_land.yaml", "f450")
    run = Run(cfg, primitive_of(cfg, "down"))
    assert run.start(state(alt_m=10, mode="GUIDED", armed=True)) == [SetMode("LAND", 9)]
    landing = replace(READY, landed=LandedState.LANDING)
    assert run.step(state(alt_m=4, mode="LAND", armed=True), landing)[0] is Status.RUNNING
    on_ground = replace(READY, landed=LandedState.ON_GROUND)
    assert run.step(state(mode="LAND", armed=True), on_ground)[0] is Status.DONE


def test_return_home_is_rtl_and_done_near_the_autopilots_home(tmp_path: Path) -> None:
    cfg = config_from_text(tmp_path, PLANE_TAKEOFF, "cub")
    run = Run(cfg, primitive_of(cfg, "home"))
    assert run.start(state(300, 0, 60, mode="GUIDED", armed=True)) == [SetMode("RTL", 11)]
    # Home is where the autopilot says, not the mission origin.
    home = offset_position(*ORIGIN, 500, 0)
    status = replace(READY, home=(home[0], home[1], 90.0), landed=LandedState.IN_AIR)
    assert run.step(state(300, 0, 60, mode="RTL", armed=True), status)[0] is Status.RUNNING
    assert run.step(state(400, 0, 60, mode="RTL", armed=True))[0] is Status.DONE
    # Before the autopilot reported a home: never done.
    blind = Run(cfg, primitive_of(cfg, "home"))
    blind.ctx.autopilot = replace(READY, home=None)
    blind.start(state(mode="RTL", armed=True))
    assert blind.step(state(mode="RTL", armed=True))[0] is Status.RUNNING


@pytest.mark.parametrize("armed", [False, True])
def test_an_engine_armed_rover_tour_arms_only_when_disarmed(tmp_path: Path, armed: bool) -> None:
    text = (ROOT / "missions" / "fault_station_loss.yaml").read_text(encoding="utf-8")
    text = text.replace(
        "    failsafe: {mcs_lost: hold}\n",
        "    failsafe: {mcs_lost: hold}\n    launch: {armed_by: engine}\n",
        1,
    )
    cfg = config_from_text(tmp_path, text, "slash_a")
    run = Run(cfg, make_primitive(cfg.machine))  # type: ignore[arg-type]
    out = run.start(state(mode="MANUAL", armed=armed))
    assert of(out, Arm) == ([] if armed else [Arm()])


def _log() -> logging.Logger:
    return logging.getLogger("test-launch")
