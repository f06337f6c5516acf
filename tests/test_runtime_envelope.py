"""The envelope held in flight by the runtime (issue 17 item 4): typed events in, commands out.

Every config here is compiled from a small mission written below, and where a test needs
a target that ``clark validate`` would refuse (a waypoint over the ceiling, outside the
fence), the compiled config is edited afterwards: the static checks are bypassed, as a
hand-edited config, an older compiler or a reactive behaviour would bypass them, and
the runtime must still never send the target. The peers are real ClarkLink codecs and
their reports are hostile: a rover that reports 90 m above the origin (a wrong origin
height, or the datum bug of issue 17) is what made a copter following it 12 m up climb
to 102 m.
"""

from __future__ import annotations

import io
import json
import logging
import math
import random
from collections.abc import Callable
from dataclasses import replace
from pathlib import Path
from string import Template
from typing import Any

import pytest

from clark_engine.behaviors.shared import orbit_radius_m
from clark_engine.link.codec import Codec
from clark_engine.link.messages import AgentStatus, AgentType, Heartbeat
from clark_engine.mission import validate
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.fence import Fence
from clark_engine.mission.geo import LocalPoint, Origin, to_global, to_local
from clark_engine.mission.model import Mission
from clark_engine.mission.yaml_loader import decode_text, load_yaml
from clark_engine.runtime.commands import Command, Goto, RcOverride, SetMode, Takeoff
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.envelope import BREACH_CLEAR_M
from clark_engine.runtime.envelope_guard import EnvelopeGuard
from clark_engine.runtime.events import (
    AutopilotHeartbeat,
    AutopilotStatus,
    LandedState,
    PacketReceived,
    VehicleState,
)
from clark_engine.runtime.mode_owner import ModeOwner
from clark_engine.runtime.runtime import AgentRuntime

GPS0 = 1_400_000_000_000
ORIGIN = Origin(30.6372, -96.4787, 90.0)
MISSION_ID = 77

MISSION = Template("""\
clark: 1
mission:
  id: 77
  name: envelope-test
  loop_hz: 10
  heartbeat_timeout_s: 3
  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}
envelope: $envelope
agents:
  rover:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: $rover
  copter:
    id: 3
    profile: dji_f450
    position: [-10, -10, 20]
    launch: {airborne: true}
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: $copter
""")

PLANE_MISSION = """\
clark: 1
mission:
  id: 78
  name: envelope-plane
  loop_hz: 10
  heartbeat_timeout_s: 3
  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}
envelope:
  geofence: {include: [{polygon: [[-400, -400], [400, -400], [400, 400], [-400, 400]]}]}
agents:
  cub:
    id: 2
    profile: super_cub
    position: [0, 0, 60]
    launch: {airborne: true}
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: waypoint, with: {to: [100, 0, 60], tolerance_m: 100}}
"""

HOLD = "{use: hold}"
WAYPOINT = "{use: waypoint, with: {to: [20, 0, 30]}}"
SQUARE = "{geofence: {include: [{polygon: [[-50, -50], [50, -50], [50, 50], [-50, 50]]}]}}"

Edit = Callable[[dict[str, Any]], None]


def compiled(
    tmp_path: Path,
    agent: str,
    *,
    envelope: str = "{}",
    rover: str = HOLD,
    copter: str = WAYPOINT,
    text: str | None = None,
    edit: Edit | None = None,
) -> AgentConfig:
    """A mission compiled as ``clark compile`` does, then edited past validation."""
    path = tmp_path / "mission.yaml"
    path.write_text(
        text or MISSION.substitute(envelope=envelope, rover=rover, copter=copter),
        encoding="utf-8",
    )
    mission = past_the_proofs(path)
    data = json.loads(json.dumps(agent_config(mission, mission.agents[agent])))
    if edit is not None:
        edit(data)
    # The autopilot here is a stream of events, which cannot answer the autopilot's safety
    # set-up (tests/test_runtime_autopilot_safety.py): the behaviour starts without it.
    return replace(config_from_dict(data), safety_setup=False)


#: What `clark validate` proves of the envelope (mission/envelope_checks.py and
#: envelope_mission_checks.py): a mission here may break these on purpose, as a hand-edited
#: config or a reactive behaviour would.
PROOFS = frozenset(
    {
        "E-ALTITUDE-CEILING",
        "E-ALTITUDE-FLOOR",
        "E-GEOFENCE-POINT",
        "E-GEOFENCE-LEG",
        "E-ORBIT-FENCE",
        "E-FOLLOW-HEIGHT",
        "E-FOLLOW-SEPARATION",
        "E-SEPARATION-START",
    }
)


def past_the_proofs(path: Path) -> Mission:
    """The mission, resolved as validation resolves it, with only the envelope's proofs
    allowed to fail: the runtime must hold what they would have refused."""
    raw = path.read_bytes()
    doc = load_yaml(decode_text(raw, path.name), path.name)
    result = validate._validate_mission(path, doc, raw)  # the resolved mission, errors or not
    other = [f.format_text() for f in result.findings if f.is_error and f.code not in PROOFS]
    assert result.mission is not None and not other, other
    return result.mission


def waypoint_to(north_m: float, east_m: float, up_m: float) -> Edit:
    """An edit of the compiled config: the waypoint's point moved (no validation)."""

    def edit(data: dict[str, Any]) -> None:
        lat, lon, alt = to_global(LocalPoint(north_m, east_m, up_m), ORIGIN)
        data["machine"]["params"]["to"] = {
            "north_m": north_m,
            "east_m": east_m,
            "up_m": up_m,
            "lat": lat,
            "lon": lon,
            "alt_m": alt,
        }

    return edit


def envelope_set(**changes: Any) -> Edit:
    """An edit of the compiled config: envelope settings changed (no validation)."""

    def edit(data: dict[str, Any]) -> None:
        data["envelope"].update(changes)

    return edit


def both(*edits: Edit) -> Edit:
    def edit(data: dict[str, Any]) -> None:
        for one in edits:
            one(data)

    return edit


def position(north_m: float, east_m: float) -> tuple[float, float]:
    lat, lon, _ = to_global(LocalPoint(north_m, east_m, 0.0), ORIGIN)
    return lat, lon


def local(goto: Goto) -> LocalPoint:
    return to_local(goto.lat_deg, goto.lon_deg, goto.alt_m, ORIGIN)


class Flight:
    """One runtime on a virtual clock at 10 Hz, with its autopilot and its peers.

    Args:
        config: The agent's compiled config.
    """

    def __init__(self, config: AgentConfig) -> None:
        self.config = config
        self.runtime = AgentRuntime(config)
        self.t = 0.0
        self.codecs: dict[str, Codec] = {}
        landed = LandedState.IN_AIR if config.is_aircraft else LandedState.ON_GROUND
        self.ready = AutopilotStatus(3, True, True, (ORIGIN.lat_deg, ORIGIN.lon_deg, 90.0), landed)

    def state(
        self,
        north_m: float,
        east_m: float,
        up_m: float,
        mode: str | None = None,
        *,
        armed: bool = True,
    ) -> VehicleState:
        """The vehicle's own report at the current time."""
        mode = mode or self.config.guided_mode or "GUIDED"
        lat, lon = position(north_m, east_m)
        return VehicleState(
            GPS0 + round(self.t * 1000),
            lat,
            lon,
            up_m,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            0.0,
            mode,
            int(self.config.modes.get(mode, 0)),
            armed,
        )

    def peer(
        self,
        name: str,
        north_m: float,
        east_m: float,
        up_m: float,
        speed_m_s: float = 0.0,
        heading_deg: float = 0.0,
    ) -> PacketReceived:
        """A peer's heartbeat and Agent Status, as its radio would bring them."""
        spec = self.config.peer(name)
        assert spec is not None
        codec = self.codecs.setdefault(name, Codec(self.config.mission_id, spec.id))
        gps = GPS0 + round(self.t * 1000)
        lat, lon = position(north_m, east_m)
        messages = [
            Heartbeat(spec.id, gps, self.config.mission_id, AgentType.VEHICLE),
            AgentStatus(spec.id, gps, lat, lon, up_m, speed_m_s, 0.0, heading_deg, 0),
        ]
        (data,) = codec.encode(messages, 0, 256)  # type: ignore[arg-type]
        return PacketReceived(data)

    def tick(self, *events: object, ready: bool = True) -> list[Command]:
        """Deliver the events (after a ready autopilot status), tick, advance 0.1 s."""
        out: list[Command] = []
        if ready:
            out += self.runtime.deliver(self.ready, self.t)
        for event in events:
            out += self.runtime.deliver(event, self.t)  # type: ignore[arg-type]
        out += self.runtime.tick(self.t)
        self.t = round(self.t + 0.1, 6)
        return out

    def mission_log(self) -> str:
        return self.runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]


def of(commands: list[Command], kind: type) -> list[Any]:
    return [c for c in commands if isinstance(c, kind)]


def lines(log: str, text: str) -> list[str]:
    return [line for line in log.splitlines() if text in line]


# ----------------------------------------------------------------------- the done-when


def test_the_102_m_follow_climb_is_never_sent(tmp_path: Path) -> None:
    """A copter follows a rover 12 m up; the rover reports 90 m (a wrong origin height)."""
    config = compiled(
        tmp_path,
        "copter",
        envelope="{ceiling_m: 60}",
        copter="{use: follow_agent, with: {target: rover, offset: {north_m: -6, up_m: 12}, "
        "continuous: true}}",
    )
    flight = Flight(config)
    gotos: list[Goto] = []
    for _ in range(100):  # 10 s: a Goto a second
        out = flight.tick(flight.state(-6, 0, 20), flight.peer("rover", 0, 0, 90.0))
        gotos += of(out, Goto)
    assert len(gotos) >= 10
    assert max(g.alt_m for g in gotos) == pytest.approx(58.0)  # 60 m less the 2 m margin
    assert all(g.alt_m < 102.0 - 40 for g in gotos)
    counts = flight.runtime.envelope_counts
    assert counts is not None
    assert counts.clamped == len(gotos) and counts.clamped_by == {"ceiling": len(gotos)}
    assert counts.refused == 0
    (first,) = lines(flight.mission_log(), "Goto clamped (ceiling)")
    assert "ceiling: 102.0 m above the origin is over the ceiling 60 m less the 2 m margin" in first
    assert flight.runtime.failsafe is None  # the copter itself never left the envelope


def test_a_132_m_waypoint_past_validation_is_sent_under_the_ceiling(tmp_path: Path) -> None:
    """clark validate refuses it; a config built around validation still never sends it."""
    config = compiled(tmp_path, "copter", edit=waypoint_to(20, 0, 132))
    assert config.envelope is not None and config.envelope.ceiling_m == 120
    flight = Flight(config)
    out = flight.tick(flight.state(0, 0, 30))
    (goto,) = of(out, Goto)
    assert goto.alt_m == pytest.approx(118.0)
    point = local(goto)
    assert (point.north_m, point.east_m) == (pytest.approx(20.0, abs=1e-3), pytest.approx(0.0))
    assert SetMode("GUIDED", 4) in out


# ----------------------------------------------------------------------- the guard


def test_refuse_drops_the_goto_and_the_vehicle_keeps_its_last_target(tmp_path: Path) -> None:
    config = compiled(
        tmp_path,
        "copter",
        envelope="{outside: refuse}",
        edit=waypoint_to(20, 0, 132),
    )
    flight = Flight(config)
    out = flight.tick(flight.state(0, 0, 30))
    assert of(out, Goto) == []
    assert of(out, SetMode) == [SetMode("GUIDED", 4)]  # the state's mode is not the target
    counts = flight.runtime.envelope_counts
    assert counts is not None and (counts.refused, counts.refused_by) == (1, {"ceiling": 1})
    (line,) = lines(flight.mission_log(), "Goto refused (ceiling)")
    assert line.endswith("; not sent")


def test_a_target_under_the_floor_is_lifted_to_it(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope="{floor_m: 30}", edit=waypoint_to(20, 0, 5))
    flight = Flight(config)
    (goto,) = of(flight.tick(flight.state(0, 0, 40)), Goto)
    assert goto.alt_m == pytest.approx(32.0)
    assert "floor: 5.0 m above the origin is under the floor 30 m" in flight.mission_log()


def test_a_target_outside_the_fence_is_cut_on_the_line_from_the_vehicle(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope=SQUARE, edit=waypoint_to(120, 30, 30))
    fence = config.envelope.fence if config.envelope else Fence()
    flight = Flight(config)
    (goto,) = of(flight.tick(flight.state(0, 0, 30)), Goto)
    point = local(goto)
    # 2 m inside the north edge, on the straight line from (0, 0) towards the target,
    # moved first to the nearest point inside (120, 30) -> (48, 30)
    assert fence.margin_m(point.north_m, point.east_m) == pytest.approx(2.0, abs=0.06)
    assert point.north_m == pytest.approx(48.0, abs=0.06)
    assert point.east_m == pytest.approx(30.0, abs=0.06)
    assert goto.alt_m == pytest.approx(30.0)
    (line,) = lines(flight.mission_log(), "Goto clamped (fence)")
    assert "north 120.0 m, east 30.0 m is 70.0 m outside the geofence" in line


def test_refuse_drops_a_target_outside_the_fence(tmp_path: Path) -> None:
    envelope = SQUARE[:-1] + ", outside: refuse}"
    config = compiled(tmp_path, "copter", envelope=envelope, edit=waypoint_to(120, 30, 30))
    flight = Flight(config)
    assert of(flight.tick(flight.state(0, 0, 30)), Goto) == []
    counts = flight.runtime.envelope_counts
    assert counts is not None and counts.refused_by == {"fence": 1} and counts.clamped == 0
    (line,) = lines(flight.mission_log(), "Goto refused (fence)")
    assert "is 70.0 m outside the geofence" in line and line.endswith("; not sent")


def test_a_line_that_leaves_the_fence_is_cut_where_it_leaves(tmp_path: Path) -> None:
    """Both ends inside an L-shaped field; the straight line crosses the corner cut out."""
    config = compiled(tmp_path, "copter", envelope=L_SHAPE, edit=waypoint_to(10, 90, 30))
    flight = Flight(config)
    (goto,) = of(flight.tick(flight.state(90, 10, 30)), Goto)
    point = local(goto)
    # the line from (90, 10) to (10, 90) leaves the L at the inner corner's edges:
    # it is cut 2 m before east 20 - 2 = 18 (where north = 100 - east)
    assert point.east_m == pytest.approx(point.north_m * -1 + 100, abs=0.1)
    assert point.east_m < 20 and point.north_m > 20
    assert "the straight line to it from north 90.0 m, east 10.0 m leaves the geofence" in (
        flight.mission_log()
    )


L_SHAPE = (
    "{geofence: {include: [{polygon: "
    "[[0, 0], [100, 0], [100, 20], [20, 20], [20, 100], [0, 100]]}]}}"
)


@pytest.mark.parametrize(
    "envelope",
    [
        SQUARE,
        L_SHAPE,
        "{geofence: {include: [{polygon: [[-50, -50], [50, -50], [50, 50], [-50, 50]]}], "
        "exclude: [{circle: {center: [10, 10], radius_m: 15}}]}}",
    ],
    ids=["convex", "l-shape", "with-exclusion"],
)
def test_the_guard_moves_targets_where_fence_clamp_does(tmp_path: Path, envelope: str) -> None:
    """The guard skips Fence.clamp's walk along lines plainly inside: same answers."""
    config = compiled(tmp_path, "copter", envelope=envelope)
    assert config.envelope is not None
    fence = config.envelope.fence
    guard = EnvelopeGuard(config, config.envelope, _logger(io.StringIO()))
    draw = random.Random(17)
    moved = checked = 0
    while checked < 200:
        start = (draw.uniform(-60, 110), draw.uniform(-60, 110))
        if not fence.contains(*start):
            continue
        checked += 1
        target = (draw.uniform(-120, 170), draw.uniform(-120, 170))
        lat, lon, _ = to_global(LocalPoint(*target, 30.0), ORIGIN)
        here_lat, here_lon = position(*start)
        state = VehicleState(None, here_lat, here_lon, 30.0, 0, 0, 0, 0, 0, 0, "GUIDED", 4, True)
        sent = guard.check(Goto(lat, lon, 30.0), state, [], 0.0)
        expected = fence.clamp(start, target, 2.0)
        if expected is None:
            assert sent is None
            continue
        assert isinstance(sent, Goto)
        point = local(sent)
        assert math.dist((point.north_m, point.east_m), expected) < 0.01, (start, target)
        moved += math.dist(expected, target) > 0.01
    assert moved > 100  # most targets were outside, or their lines left the fence


def test_a_target_in_an_exclusion_zone_is_moved_out_of_it(tmp_path: Path) -> None:
    envelope = "{geofence: {exclude: [{circle: {center: [20, 0], radius_m: 10}}]}}"
    config = compiled(tmp_path, "copter", envelope=envelope, edit=waypoint_to(22, 0, 30))
    flight = Flight(config)
    (goto,) = of(flight.tick(flight.state(50, 0, 30)), Goto)
    point = local(goto)
    assert math.hypot(point.north_m - 20, point.east_m) >= 12.0 - 0.06
    assert point.north_m > 30  # out on the side the target was, towards the vehicle


def test_a_target_that_cannot_be_clamped_is_refused(tmp_path: Path) -> None:
    """A fence too small for the margin (a 1 m circle): no point is 2 m inside it."""

    def shrink(data: dict[str, Any]) -> None:
        fence = data["envelope"]["geofence"]
        fence["default_radius_m"] = None
        fence["include"] = [
            {"kind": "circle", "center": fence["home"] | {"north_m": 0.0, "east_m": 0.0}}
            | {"radius_m": 1.0}
        ]

    config = compiled(tmp_path, "copter", edit=both(waypoint_to(0.5, 0, 30), shrink))
    flight = Flight(config)
    assert of(flight.tick(flight.state(0, 0, 30)), Goto) == []
    (line,) = lines(flight.mission_log(), "Goto refused (fence)")
    assert "no point 2 m inside the geofence was found" in line


def test_a_goto_without_a_vehicle_state_is_refused(tmp_path: Path) -> None:
    """Where the vehicle is, and so the line to the target, is unknown: not checkable.

    A runtime's behaviour starts only after a VehicleState, so the guard is asked
    directly here, as it would be by a shell that lost the state.
    """
    config = compiled(tmp_path, "copter")
    assert config.envelope is not None
    stream = io.StringIO()
    guard = EnvelopeGuard(config, config.envelope, _logger(stream))
    assert guard.check(Goto(30.6373, -96.4787, 30.0), None, [], 0.0) is None
    assert guard.counts.refused_by == {"no vehicle state": 1}
    assert "no VehicleState has arrived yet" in stream.getvalue()


def test_a_follower_is_kept_out_of_its_leaders_separation(tmp_path: Path) -> None:
    config = compiled(
        tmp_path,
        "copter",
        copter="{use: follow_agent, with: {target: rover, offset: {up_m: 3}, continuous: true}}",
    )
    assert config.envelope is not None and config.envelope.separation_from_m("rover") == 5.0
    flight = Flight(config)
    out = flight.tick(flight.state(-30, 0, 10), flight.peer("rover", 0, 0, 0.0))
    (goto,) = of(out, Goto)
    point = local(goto)
    # 3-D, along the line from the rover (0, 0, 0) to the target (0, 0, 3): straight up
    apart_m = math.dist((point.north_m, point.east_m, point.up_m), (0.0, 0.0, 0.0))
    assert apart_m == pytest.approx(7.0, abs=0.02)  # 5 m separation and the 2 m margin
    assert goto.alt_m == pytest.approx(7.0, abs=1e-3)
    assert (goto.velocity_north_m_s, goto.velocity_east_m_s) == (None, None)  # a fixed point
    assert "the target is 3.0 m from rover's last reported position" in flight.mission_log()


def test_a_rover_is_pushed_along_the_ground(tmp_path: Path) -> None:
    config = compiled(
        tmp_path,
        "rover",
        rover="{use: waypoint, with: {to: [20, 0]}}",
        copter=HOLD,
        edit=envelope_set(separation={"copter": 4.0}),
    )
    flight = Flight(config)
    out = flight.tick(flight.state(0, 0, 0, "MANUAL"), flight.peer("copter", 21, 0, 0.0))
    (goto,) = of(out, Goto)
    point = local(goto)
    # kept 4 m + 2 m from the copter, along the line from the copter to the target
    # (to ClarkLink's 1e-7 degrees, a centimetre, in which the copter reported)
    assert math.hypot(point.north_m - 21, point.east_m) == pytest.approx(6.0, abs=0.02)
    assert point.north_m == pytest.approx(15.0, abs=0.02)
    assert goto.alt_m == 0.0  # a rover's height is not a command


def test_separation_refuse(tmp_path: Path) -> None:
    config = compiled(
        tmp_path,
        "copter",
        envelope="{outside: refuse}",
        copter="{use: follow_agent, with: {target: rover, offset: {up_m: 3}, continuous: true}}",
    )
    flight = Flight(config)
    out = flight.tick(flight.state(-30, 0, 10), flight.peer("rover", 0, 0, 0.0))
    assert of(out, Goto) == []
    counts = flight.runtime.envelope_counts
    assert counts is not None and counts.refused_by == {"separation from rover": 1}


def test_a_plane_is_kept_its_loiter_radius_further_in(tmp_path: Path) -> None:
    config = compiled(tmp_path, "cub", text=PLANE_MISSION, edit=waypoint_to(390, 0, 60))
    hardware = config.raw["agent"]["hardware"]
    radius_m = orbit_radius_m(hardware["airframe"], hardware["autopilot"])
    assert radius_m is not None and radius_m > 50  # the W-ORBIT-TOLERANCE figure
    flight = Flight(config)
    (goto,) = of(flight.tick(flight.state(0, 0, 60, "FBWA")), Goto)
    assert local(goto).north_m == pytest.approx(400 - 2 - radius_m, abs=0.06)
    assert f"{2 + radius_m:.0f} m (the 2 m margin and its {radius_m:.0f} m loiter radius)" in (
        flight.mission_log()
    )


def test_a_copter_is_kept_only_the_margin_in(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope=SQUARE, edit=waypoint_to(49, 0, 30))
    flight = Flight(config)
    (goto,) = of(flight.tick(flight.state(0, 0, 30)), Goto)
    assert local(goto).north_m == pytest.approx(48.0, abs=0.06)


def test_a_takeoff_is_clamped_under_the_ceiling(tmp_path: Path) -> None:
    def takeoff_to(alt_m: float) -> Edit:
        def edit(data: dict[str, Any]) -> None:
            data["machine"]["params"]["alt_m"] = alt_m

        return edit

    text = (
        MISSION.substitute(envelope="{}", rover=HOLD, copter="{use: takeoff, with: {alt_m: 20}}")
        .replace("    position: [-10, -10, 20]\n    launch: {airborne: true}\n", "")
        .replace("  copter:\n    id: 3\n", "  copter:\n    id: 3\n    launch: {armed_by: engine}\n")
    )
    config = compiled(tmp_path, "copter", text=text, edit=takeoff_to(130))
    flight = Flight(config)
    flight.ready = AutopilotStatus(  # on the ground: the engine arms it, it takes off
        3, True, True, (ORIGIN.lat_deg, ORIGIN.lon_deg, 90.0), LandedState.ON_GROUND
    )
    takeoffs: list[Takeoff] = []
    for _ in range(3):
        takeoffs += of(flight.tick(flight.state(0, 0, 0, "GUIDED")), Takeoff)
    assert takeoffs == [Takeoff(118.0)]
    assert "Takeoff clamped (ceiling)" in flight.mission_log()


def test_clamps_are_logged_once_per_episode_and_summed_up(tmp_path: Path) -> None:
    config = compiled(
        tmp_path,
        "copter",
        envelope="{ceiling_m: 60}",
        copter="{use: follow_agent, with: {target: rover, offset: {north_m: -6, up_m: 12}, "
        "continuous: true}}",
    )
    flight = Flight(config)
    for _ in range(100):  # 10 Gotos over the ceiling
        flight.tick(flight.state(-6, 0, 20), flight.peer("rover", 0, 0, 90.0))
    for _ in range(50):  # the rover's report right again: 5 Gotos inside
        flight.tick(flight.state(-6, 0, 20), flight.peer("rover", 0, 0, 0.0))
    for _ in range(30):  # then it wanders out of the fence: another reason
        flight.tick(flight.state(-6, 0, 20), flight.peer("rover", 2000, 0, 0.0))
    log = flight.mission_log()
    clamps = lines(log, "envelope: Goto")
    assert len(clamps) == 2  # the first of each episode, never a line per Goto
    assert "clamped (ceiling)" in clamps[0] and "clamped (fence)" in clamps[1]
    (summary,) = lines(log, "envelope: 10 Gotos clamped (ceiling) from t=0.000 to t=9.000")
    assert summary.endswith("9 of them not logged one by one")
    counts = flight.runtime.envelope_counts
    assert counts is not None
    assert counts.clamped_by == {"ceiling": 10, "fence": 3}
    assert counts.checked == 18 and counts.clamped == 13 and counts.refused == 0
    assert lines(log, "envelope: 3 Gotos clamped (fence)") == []  # not over yet
    flight.runtime.logbook.close()  # as a dry run's end or a shell's stop closes it
    log = flight.mission_log()
    (closing,) = lines(log, "envelope.summary")
    assert closing.endswith(
        "envelope: 18 targets checked, 13 clamped (ceiling 10, fence 3), 0 refused; "
        "no breach acted on"
    )
    assert lines(log, "envelope: 3 Gotos clamped (fence) from t=15.000 to t=17.000")


# ----------------------------------------------------------------------- the watch


def _leave(
    flight: Flight, *where: tuple[float, float, float], peers: tuple[object, ...] = ()
) -> list[Command]:
    out: list[Command] = []
    for north_m, east_m, up_m in where:
        out += flight.tick(flight.state(north_m, east_m, up_m), *peers)
    return out


def test_a_fence_breach_returns_the_copter_home_once(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope=SQUARE)
    assert config.envelope is not None and config.envelope.on_breach == "rtl"
    flight = Flight(config)
    assert of(_leave(flight, (0, 0, 30), (20, 0, 30)), Goto)  # flying its waypoint
    out = _leave(flight, (51.0, 0, 30))
    assert of(out, SetMode) == [SetMode("RTL", 6)]
    assert of(out, Goto) == []
    breach = flight.runtime.breach
    assert breach is not None and breach.kind == "fence" and breach.action == "rtl"
    assert flight.runtime.failsafe == "rtl"
    # the breach goes on; then another kind: the failsafe is never applied again
    out = _leave(flight, (55.0, 0, 30), (60.0, 0, 130), (60.0, 0, 130))
    assert of(out, SetMode) == [] and of(out, Goto) == []
    log = flight.mission_log()
    (line,) = lines(log, "ERROR envelope.breach: envelope breach: fence:")
    assert line.endswith(
        "envelope breach: fence: 1.0 m outside the geofence at north 51.0 m, east 0.0 m: rtl"
    )
    assert lines(log, "ERROR failsafe.act: failsafe rtl")  # clark analyze reads it
    (later,) = lines(log, "envelope breach: ceiling:")
    assert later.endswith(": rtl not applied (the failsafe rtl holds; a failsafe is applied once)")


def test_two_breaches_in_one_tick_apply_the_first_kinds_action(tmp_path: Path) -> None:
    """Out of the fence and over the ceiling at once: the fence's action, once."""
    config = compiled(tmp_path, "copter", envelope=SQUARE[:-1] + ", ceiling_m: 60}")
    flight = Flight(config)
    _leave(flight, (0, 0, 30))
    out = _leave(flight, (60, 0, 70))
    assert of(out, SetMode) == [SetMode("RTL", 6)]
    breach = flight.runtime.breach
    assert breach is not None and breach.kind == "fence"
    log = lines(flight.mission_log(), "envelope breach:")
    assert [line.split("envelope.breach: ")[1].split(":")[1] for line in log] == [
        " fence",
        " ceiling",
    ]
    assert log[1].endswith(": rtl not applied (the failsafe rtl holds; a failsafe is applied once)")


def test_a_rovers_fence_breach_holds_it(tmp_path: Path) -> None:
    config = compiled(
        tmp_path, "rover", envelope=SQUARE, rover="{use: waypoint, with: {to: [20, 0]}}"
    )
    flight = Flight(config)
    flight.tick(flight.state(0, 0, 0, "MANUAL"))
    flight.tick(flight.state(0, 0, 0, "GUIDED"))
    out = flight.tick(flight.state(-60, 0, 0, "GUIDED"))
    assert of(out, SetMode) == [SetMode("HOLD", 4)]
    assert flight.runtime.failsafe == "hold"


def test_a_breach_ends_only_a_margin_back_inside(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope=SQUARE)
    flight = Flight(config)
    _leave(flight, (0, 0, 30), (50.5, 0, 30), (49.5, 0, 30), (50.5, 0, 30))
    log = flight.mission_log()
    assert len(lines(log, "envelope breach: fence")) == 1  # 0.5 m back in: still in breach
    _leave(flight, (50 - BREACH_CLEAR_M - 0.1, 0, 30))
    assert len(lines(flight.mission_log(), "envelope breach over: fence")) == 1


def test_a_ceiling_breach(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope="{ceiling_m: 60}")
    flight = Flight(config)
    _leave(flight, (0, 0, 30), (0, 0, 59))
    assert flight.runtime.failsafe is None
    out = _leave(flight, (0, 0, 61))
    assert of(out, SetMode) == [SetMode("RTL", 6)]
    assert "envelope breach: ceiling: 61.0 m above the origin, over the ceiling 60 m: rtl" in (
        flight.mission_log()
    )


def test_the_floor_in_guided_flight_and_not_in_the_climb_to_it(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope="{floor_m: 30, on_breach: land}")
    flight = Flight(config)
    # handed over at 20 m, under the floor: the climb to the target is no breach
    _leave(flight, (0, 0, 20), (0, 0, 25), (0, 0, 31), (0, 0, 35))
    assert flight.runtime.failsafe is None
    out = _leave(flight, (0, 0, 29))
    assert of(out, SetMode) == [SetMode("LAND", 9)]
    assert "envelope breach: floor: 29.0 m above the origin in guided flight, under the floor" in (
        flight.mission_log()
    )


def test_the_floor_is_not_watched_out_of_the_guided_mode(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope="{floor_m: 30}")
    flight = Flight(config)
    _leave(flight, (0, 0, 35))
    for up_m in (25.0, 10.0, 2.0):  # landing in LAND: exempt
        flight.tick(flight.state(0, 0, up_m, "LAND"))
    assert flight.runtime.failsafe is None
    assert lines(flight.mission_log(), "envelope breach") == []


def test_endurance(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", edit=envelope_set(endurance_s=5.0))
    flight = Flight(config)
    out: list[Command] = []
    for _ in range(50):  # armed for 4.9 s
        out += _leave(flight, (0, 0, 30))
    assert flight.runtime.failsafe is None
    out = _leave(flight, (0, 0, 30), (0, 0, 30))
    assert of(out, SetMode) == [SetMode("RTL", 6)]
    assert "envelope breach: endurance: armed for 5 s, over its endurance of 5 s: rtl" in (
        flight.mission_log()
    )


def test_time_disarmed_does_not_count_against_endurance(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", edit=envelope_set(endurance_s=5.0))
    flight = Flight(config)
    for _ in range(100):
        flight.tick(flight.state(0, 0, 30, armed=False), ready=False)
    for _ in range(40):
        _leave(flight, (0, 0, 30))
    assert flight.runtime.envelope_watch is not None
    assert flight.runtime.envelope_watch.armed_s == pytest.approx(3.9)
    assert flight.runtime.failsafe is None


def test_a_near_miss_holds_once(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter")
    flight = Flight(config)
    _leave(flight, (0, 0, 30), peers=(flight.peer("rover", 0, 20, 0.0),))
    out = _leave(flight, (0, 0, 4), peers=(flight.peer("rover", 0, 2, 0.0),))
    assert of(out, SetMode) == [SetMode("LOITER", 5)]  # on_near_miss: hold
    breach = flight.runtime.breach
    assert breach is not None and (breach.kind, breach.peer) == ("separation", "rover")
    assert (
        "envelope breach: separation: rover 4.5 m away (3-D), inside the 5 m separation: hold"
        in (flight.mission_log())
    )


def test_a_moving_peers_report_is_carried_to_now(tmp_path: Path) -> None:
    """A report 0.5 s old of a rover driving at us at 4 m/s is 2 m behind where it is."""
    config = compiled(tmp_path, "copter")
    flight = Flight(config)
    _leave(flight, (0, 0, 30))
    # 6.5 m away when it reported, heading west (270 deg) toward the copter at 4 m/s
    report = flight.peer("rover", 0, 6.5, 0.0, speed_m_s=4.0, heading_deg=270.0)
    out = flight.tick(flight.state(0, 0, 0.5), report)
    assert not of(out, SetMode)  # 6.5 m: outside the 5 m
    for _ in range(4):  # no new report; 0.5 s later it is 4.5 m away if it drove on
        out += flight.tick(flight.state(0, 0, 0.5))
    assert of(out, SetMode) == [SetMode("LOITER", 5)]
    assert "where its last report puts it now, inside the 5 m separation" in (flight.mission_log())


def test_a_peer_standing_still_is_not_carried_anywhere(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter")
    flight = Flight(config)
    _leave(flight, (0, 0, 30))
    report = flight.peer("rover", 0, 6.5, 0.0, speed_m_s=0.2, heading_deg=270.0)
    out = flight.tick(flight.state(0, 0, 0.5), report)
    for _ in range(9):
        out += flight.tick(flight.state(0, 0, 0.5))
    assert not of(out, SetMode) and flight.runtime.failsafe is None


def test_only_peers_that_could_close_within_a_second_are_carried_forward(
    tmp_path: Path,
) -> None:
    """A prediction is skipped only for a peer that a second of its speed cannot bring
    inside the separation (plus PREDICT_NEAR_M to spare): a truck 200 m off at 4 m/s is
    not carried, a plane 130 m off at 30 m/s is."""
    config = compiled(tmp_path, "copter")
    flight = Flight(config)
    _leave(flight, (0, 0, 30))
    flight.tick(flight.state(0, 0, 30), flight.peer("rover", 0, 200, 0.0, speed_m_s=4.0))
    fixes = flight.runtime._peer_positions.fixes(flight.t + 0.5, (0.0, 0.0))
    assert [f.predicted for f in fixes] == [False]
    flight.tick(flight.state(0, 0, 30), flight.peer("rover", 0, 130, 0.0, speed_m_s=30.0))
    fixes = flight.runtime._peer_positions.fixes(flight.t + 0.5, (0.0, 0.0))
    assert [f.predicted for f in fixes] == [False, True]


def test_height_keeps_vehicles_apart(tmp_path: Path) -> None:
    """3-D: a copter 10 m over the rover is no near miss."""
    config = compiled(tmp_path, "copter")
    flight = Flight(config)
    _leave(flight, (0, 0, 10), (0, 0, 10), peers=(flight.peer("rover", 0, 0, 0.0),))
    assert flight.runtime.failsafe is None


def test_a_stale_report_is_no_near_miss(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter")
    flight = Flight(config)
    _leave(flight, (0, 20, 30), peers=(flight.peer("rover", 0, 0, 0.0),))
    for _ in range(31):  # 3.1 s later the rover's last report is stale
        _leave(flight, (0, 20, 30))
    _leave(flight, (0, 0, 2))  # over where the rover was 3.2 s ago
    assert flight.runtime.failsafe is None


def test_a_disarmed_vehicle_has_no_near_miss(tmp_path: Path) -> None:
    """Parked side by side, disarmed, nothing moves; armed again, a peer 2 m off is one."""
    config = compiled(tmp_path, "rover", copter=HOLD)
    flight = Flight(config)
    far = flight.peer("copter", 0, 50, 0)
    flight.tick(flight.state(0, 0, 0, "HOLD"), far)  # armed by its pilot: it starts (hold)
    for _ in range(5):  # disarmed by its pilot; the copter lands beside it
        out = flight.tick(
            flight.state(0, 0, 0, "HOLD", armed=False), flight.peer("copter", 0, 2, 0)
        )
        assert of(out, SetMode) == []
    assert flight.runtime.failsafe is None
    out = flight.tick(flight.state(0, 0, 0, "HOLD"), flight.peer("copter", 0, 2, 0))
    breach = flight.runtime.breach
    assert breach is not None and breach.kind == "separation"
    assert of(out, SetMode) == [SetMode("HOLD", 4)]


def test_a_pilot_who_took_the_vehicle_is_not_fought(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope=SQUARE)
    flight = Flight(config)
    _leave(flight, (0, 0, 30), (10, 0, 30))  # the engine put it in GUIDED
    flight.tick(flight.state(20, 0, 30, "ALT_HOLD"))  # the pilot's switch
    out = flight.tick(flight.state(60, 0, 30, "ALT_HOLD"))
    assert of(out, SetMode) == [] and of(out, Goto) == []
    assert flight.runtime.failsafe == "rtl" and flight.runtime.breach is not None
    log = flight.mission_log()
    assert (
        "failsafe rtl: no mode sent: the vehicle is in ALT_HOLD, a mode the engine did not" in log
    )
    for _ in range(10):  # the behaviour stays stopped: nothing more is commanded
        out = flight.tick(flight.state(60, 0, 30, "ALT_HOLD"))
        assert of(out, SetMode) == [] and of(out, Goto) == []


def test_a_breach_before_the_behavior_starts_is_logged_only(tmp_path: Path) -> None:
    config = compiled(tmp_path, "copter", envelope="{ceiling_m: 60}")
    flight = Flight(config)
    for _ in range(5):  # the autopilot is not ready: the launch gate is closed
        out = flight.tick(flight.state(0, 0, 70, "ALT_HOLD"), ready=False)
        assert of(out, SetMode) == [] and of(out, Goto) == []
    log = flight.mission_log()
    (line,) = lines(log, "envelope breach: ceiling")
    assert "logged only (the behaviour has not started, the engine commands nothing)" in line
    # Ready with the breach in force: the behaviour does not start, and the pilot's
    # mode (not the engine's) is not fought.
    out = flight.tick(flight.state(0, 0, 70, "ALT_HOLD"))
    assert of(out, SetMode) == [] and of(out, Goto) == []
    assert flight.runtime.behavior_started and flight.runtime.failsafe == "rtl"
    assert flight.runtime.machine is not None and not flight.runtime.machine.running


def test_a_breach_while_the_autopilot_is_lost_sends_its_mode_on_the_return(
    tmp_path: Path,
) -> None:
    """Its time armed runs on while it is silent; the RTL goes when it is heard again."""
    config = compiled(tmp_path, "copter", edit=envelope_set(endurance_s=6.0))
    flight = Flight(config)
    for _ in range(20):  # 2 s of flight
        _leave(flight, (0, 0, 30))
    for _ in range(45):  # then silent: lost after 3 s, over its endurance at 6 s
        out = flight.tick(ready=False)
        assert of(out, SetMode) == [] and of(out, Goto) == []
    assert flight.runtime.autopilot_lost and flight.runtime.failsafe == "rtl"
    breach = flight.runtime.breach
    assert breach is not None and breach.kind == "endurance"
    back = flight.runtime.deliver(flight.state(0, 0, 30), flight.t)
    assert back == [SetMode("RTL", 6)]
    out = flight.tick(flight.state(0, 0, 30), AutopilotHeartbeat("GUIDED", 4, True))
    assert of(out, SetMode) == []


def test_a_doublet_on_the_pilots_mode_is_stopped_and_its_channel_released(
    tmp_path: Path,
) -> None:
    """The Super Cub's excitation flies in the pilot's FBWA: a breach releases the stick."""
    text = PLANE_MISSION.replace(
        "    behavior: {use: waypoint, with: {to: [100, 0, 60], tolerance_m: 100}}\n",
        "    behavior: {use: doublet, with: {channel: aileron, amplitude_us: 100, width_s: 5}}\n",
    ).replace("envelope:\n", "envelope:\n  ceiling_m: 100\n")
    config = compiled(tmp_path, "cub", text=text)
    flight = Flight(config)
    out = flight.tick(flight.state(0, 0, 60, "FBWA"))
    assert of(out, RcOverride)
    out = flight.tick(flight.state(0, 0, 101, "FBWA"))
    assert of(out, SetMode) == []  # FBWA is the pilot's
    assert RcOverride({1: 0}) in of(out, RcOverride)  # handed back to the pilot
    assert flight.runtime.failsafe == "rtl"


# ----------------------------------------------------------------------- the pieces


def test_the_mode_owner() -> None:
    owner = ModeOwner()
    owner.mode_reported("MANUAL")
    assert not owner.engine_holds  # the pilot's, at boot
    owner.engine_asked("GUIDED")
    assert not owner.engine_holds  # asked, not granted: still the pilot's MANUAL
    owner.mode_reported("GUIDED")
    assert owner.engine_holds
    owner.mode_reported("LOITER")
    assert not owner.engine_holds  # someone else's
    owner.engine_asked("LOITER")
    assert owner.engine_holds  # the engine asked for the mode it is in


def _logger(stream: io.StringIO) -> logging.Logger:
    logger = logging.getLogger(f"test_runtime_envelope.{id(stream)}")
    logger.handlers = [logging.StreamHandler(stream)]
    logger.propagate = False
    logger.setLevel(logging.INFO)
    return logger
