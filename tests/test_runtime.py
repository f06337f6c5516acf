"""AgentRuntime end to end on a virtual clock: events in, commands and packets out.

Peers are real ClarkLink codecs; the autopilot is a stream of VehicleState and
heartbeat events. Nothing sleeps; every time is given explicitly.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from clark_engine.link.codec import Codec
from clark_engine.link.messages import (
    ActivateController,
    AgentStatus,
    AgentType,
    BehaviorState,
    Heartbeat,
    ModeChangeRequest,
    Terminate,
    VehicleHealth,
)
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import (
    CloseInterfaces,
    Goto,
    RcOverride,
    SendPacket,
    SetMode,
)
from clark_engine.runtime.config import AgentConfig, config_from_dict
from clark_engine.runtime.context import offset_position
from clark_engine.runtime.events import (
    AutopilotHeartbeat,
    AutopilotStatus,
    LandedState,
    PacketReceived,
    RcChannels,
    StationCommand,
    VehicleState,
)
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parent.parent
GPS0 = 1_400_000_000_000


def config_of(
    mission_file: str, agent: str, text: str | None = None, tmp: Path | None = None
) -> AgentConfig:
    path = ROOT / "missions" / mission_file
    if text is not None:
        assert tmp is not None
        path = tmp / mission_file
        path.write_text(text, encoding="utf-8")
    result = validate_path(path, path.name)
    assert result.mission is not None, [f.format_text() for f in result.findings]
    config = config_from_dict(agent_config(result.mission, result.mission.agents[agent]))
    # The autopilot here is a stream of events, which cannot answer the autopilot's safety
    # set-up (tests/test_runtime_autopilot_safety.py): the behaviour starts without it.
    return replace(config, safety_setup=False)


def vehicle(
    t: float,
    lat: float = 30.6372,
    lon: float = -96.4787,
    mode: str = "MANUAL",
    custom_mode: int = 0,
) -> VehicleState:
    return VehicleState(
        GPS0 + int(t * 1000), lat, lon, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, mode, custom_mode, True
    )


class Peer:
    """Another agent: its own codec, sending packets to the runtime under test."""

    def __init__(self, mission_id: int, agent_id: int, agent_type: AgentType) -> None:
        self.codec = Codec(mission_id, agent_id)
        self.id = agent_id
        self.mission_id = mission_id
        self.type = agent_type

    def heartbeat(self, t: float, *extra: object) -> PacketReceived:
        gps = GPS0 + int(t * 1000)
        messages = [Heartbeat(self.id, gps, self.mission_id, self.type), *extra]
        (data,) = self.codec.encode(messages, 0, 256)  # type: ignore[arg-type]
        return PacketReceived(data)

    def status(self, t: float, lat: float, lon: float) -> AgentStatus:
        return AgentStatus(self.id, GPS0 + int(t * 1000), lat, lon, 0.0, 2.0, 0.0, 90.0, 10)


READY = AutopilotStatus(
    gps_fix_type=3,
    position_ok=True,
    prearm_ok=True,
    home=(30.6372, -96.4787, 90.0),
    landed=LandedState.IN_AIR,
)
"""An autopilot that is ready (the launch gate's condition) and flying."""


def run(runtime: AgentRuntime, t: float, *events: object) -> list[object]:
    """Deliver the events (after a ready autopilot status), then tick."""
    out: list[object] = list(runtime.deliver(READY, t))
    for event in events:
        out += runtime.deliver(event, t)  # type: ignore[arg-type]
    out += runtime.tick(t)
    return out


def of(commands: list[object], kind: type) -> list[object]:
    return [c for c in commands if isinstance(c, kind)]


def broadcast(commands: list[object]) -> list[SendPacket]:
    return [c for c in commands if isinstance(c, SendPacket) and c.destination == ""]


@pytest.fixture
def slash_b() -> AgentRuntime:
    return AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))


def test_telemetry_goes_out_bundled_and_decodes(slash_b: AgentRuntime) -> None:
    listener = Codec(521, 99)
    out = run(
        slash_b, 0.0, vehicle(0.0, mode="HOLD", custom_mode=4), AutopilotHeartbeat("HOLD", 4, True)
    )
    (packet,) = broadcast(out)
    decoded = listener.decode(packet.data)
    assert [type(m).__name__ for m in decoded.messages] == ["Heartbeat", "AgentStatus"]
    assert decoded.sender_id == 3 and decoded.destination_id == 0
    # status is due every 5 ticks, heartbeat every 10: tick 5 has status alone
    for k in range(1, 5):
        assert broadcast(run(slash_b, k / 10, AutopilotHeartbeat("HOLD", 4, True))) == []
    (packet,) = broadcast(run(slash_b, 0.5, AutopilotHeartbeat("HOLD", 4, True)))
    assert [type(m).__name__ for m in listener.decode(packet.data).messages] == ["AgentStatus"]


def test_activation_by_the_station_makes_slash_b_follow(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    t = 0.0
    out = run(
        slash_b,
        t,
        vehicle(t),
        AutopilotHeartbeat("MANUAL", 0, True),
        station.heartbeat(t),
        slash_a.heartbeat(t, slash_a.status(t, 30.6380, -96.4787)),
    )
    assert of(out, SetMode) == [SetMode("HOLD", 4)]  # idle: hold
    gps = GPS0
    (activate,) = station.codec.encode([ActivateController(1, gps, 3, True)], 3, 256)
    t = 0.1
    out = run(slash_b, t, PacketReceived(activate), AutopilotHeartbeat("HOLD", 4, True))
    assert SetMode("GUIDED", 15) in of(out, SetMode)
    (goto,) = of(out, Goto)
    assert goto.lat_deg == pytest.approx(30.6380)  # type: ignore[attr-defined]
    assert slash_b.machine is not None and slash_b.machine.active_paths() == ("chase",)
    # arrive within tolerance_m of the goal beside slash_a: done -> parked (hold, final)
    _, east = offset_position(30.6380, -96.4787, 0.0, -3.5)  # the mission's offset
    t = 0.2
    out = run(
        slash_b,
        t,
        vehicle(t, lat=30.63799, lon=east, mode="GUIDED", custom_mode=15),
        AutopilotHeartbeat("GUIDED", 15, True),
    )
    t = 0.3
    out += run(slash_b, t, AutopilotHeartbeat("GUIDED", 15, True))
    assert slash_b.machine.active_paths() == ("parked",)
    assert SetMode("HOLD", 4) in of(out, SetMode)


def test_commands_only_from_a_station(slash_b: AgentRuntime) -> None:
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    (forged,) = slash_a.codec.encode(
        [Heartbeat(2, GPS0, 521, AgentType.VEHICLE), Terminate(2, GPS0, 0, "not a station")], 0, 256
    )
    run(slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), PacketReceived(forged))
    assert not slash_b.terminated


def test_foreign_mission_commands_are_never_acted_on(slash_b: AgentRuntime) -> None:
    stranger = Peer(999, 1, AgentType.MCS)  # same id as our station, another mission
    run(
        slash_b,
        0.0,
        vehicle(0.0),
        AutopilotHeartbeat("MANUAL", 0, True),
        stranger.heartbeat(0.0, Terminate(1, GPS0, 0, "foreign")),
    )
    assert not slash_b.terminated
    assert slash_b.fleet.record(1) is None


def test_terminate_from_the_station(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    run(slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    out = run(slash_b, 0.1, station.heartbeat(0.1, Terminate(1, GPS0 + 100, 0, "test over")))
    assert slash_b.terminated
    assert SetMode("HOLD", 4) in of(out, SetMode)  # the Slash's terminal mode
    assert out[-1] == CloseInterfaces() or CloseInterfaces() in out
    assert slash_b.logbook.closed
    assert run(slash_b, 0.2, vehicle(0.2)) == []


def test_mode_change_request(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    request = ModeChangeRequest(1, GPS0, 3, 0)  # MANUAL on ArduRover
    out = run(
        slash_b,
        0.0,
        vehicle(0.0),
        AutopilotHeartbeat("HOLD", 4, True),
        station.heartbeat(0.0, request),
    )
    assert SetMode("MANUAL", 0) in of(out, SetMode)


def test_lost_peer_and_mcs_lost_failsafe_without_resume(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    run(
        slash_b,
        0.0,
        vehicle(0.0),
        AutopilotHeartbeat("MANUAL", 0, True),
        station.heartbeat(0.0),
        slash_a.heartbeat(0.0),
    )
    out: list[object] = []
    t = 0.0
    while t < 3.5:  # heartbeat_timeout_s is 3: both go silent
        t = round(t + 0.1, 1)
        out += run(slash_b, t, AutopilotHeartbeat("HOLD", 4, True))
    assert slash_b.failsafe == "hold"
    assert SetMode("HOLD", 4) in of(out, SetMode)
    # the station comes back: no automatic resume, activate is not acted on
    t = 3.6
    run(slash_b, t, station.heartbeat(t))
    (activate,) = station.codec.encode([ActivateController(1, GPS0, 3, True)], 3, 256)
    out = run(slash_b, 3.7, PacketReceived(activate), AutopilotHeartbeat("HOLD", 4, True))
    assert slash_b.failsafe == "hold" and of(out, Goto) == []
    lines = slash_b.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]
    assert "lost slash_a" in lines and "mcs_lost" in lines


def test_autopilot_lost_stops_commanding(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    run(slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    out = []
    for k in range(1, 40):  # no autopilot heartbeat for 3.9 s; the station keeps talking
        t = k / 10
        out = run(slash_b, t, station.heartbeat(t))
    assert slash_b._autopilot_lost
    (activate,) = station.codec.encode([ActivateController(1, GPS0, 3, True)], 3, 256)
    out = run(slash_b, 4.0, PacketReceived(activate), station.heartbeat(4.0))
    assert of(out, Goto) == [] and of(out, SetMode) == []  # chase started, nothing commanded
    out = run(slash_b, 4.1, AutopilotHeartbeat("HOLD", 4, True))
    assert slash_b.machine is not None and slash_b.machine.active_paths() == ("chase",)


def test_rc_switch_starts_the_cub_doublet() -> None:
    cub = AgentRuntime(config_of("supercub_sysid_rc.yaml", "cub"))
    low = RcChannels(tuple([1500] * 6 + [1000] + [1500] * 9))
    high = RcChannels(tuple([1500] * 6 + [2000] + [1500] * 9))
    run(
        cub, 0.0, vehicle(0.0, mode="FBWA", custom_mode=5), AutopilotHeartbeat("FBWA", 5, True), low
    )
    assert cub.machine is not None and cub.machine.active_paths() == ("piloted",)
    out = run(cub, 0.1, high, AutopilotHeartbeat("FBWA", 5, True))
    assert cub.machine.active_paths() == ("excite.aileron",)
    overrides = of(out, RcOverride)
    assert overrides == [RcOverride({1: 1650})]  # aileron on RC1: trim 1500 + 150, first tick


def test_station_operator_commands_are_sent_as_clarklink() -> None:
    mcs = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    out = mcs.deliver(StationCommand("activate", "slash_b"), 0.0)
    (packet,) = of(out, SendPacket)
    assert packet.destination == "slash_b" and packet.destination_id == 3  # type: ignore[attr-defined]
    decoded = Codec(521, 3).decode(packet.data)  # type: ignore[attr-defined]
    assert decoded.messages == (ActivateController(1, GPS0, 3, True),)
    out = mcs.deliver(StationCommand("mode", "slash_a", "MANUAL"), 0.1)
    (packet,) = of(out, SendPacket)
    assert Codec(521, 2).decode(packet.data).messages[0] == ModeChangeRequest(1, GPS0 + 100, 2, 0)  # type: ignore[attr-defined]


def test_state_changes_go_to_the_station_as_behavior_state(slash_b: AgentRuntime) -> None:
    station_codec = Codec(521, 1)
    out = run(slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True))
    to_station = [p for p in of(out, SendPacket) if p.destination == "mcs"]  # type: ignore[attr-defined]
    (packet,) = to_station
    # bundled with its Vehicle Health, due to the station in the same tick
    state, health = station_codec.decode(packet.data).messages  # type: ignore[attr-defined]
    assert isinstance(state, BehaviorState) and state.active_states == ("idle",)
    assert isinstance(health, VehicleHealth) and health.agent_id == 3


def test_authenticated_mission_ignores_unauthenticated_commands(tmp_path: Path) -> None:
    text = (
        (ROOT / "missions" / "cooperative_follow.yaml")
        .read_text(encoding="utf-8")
        .replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n", 1)
    )
    from clark_engine.link.auth import generate_key_file, load_key

    generate_key_file(tmp_path / "coop.key")
    key = load_key(tmp_path / "coop.key")
    config = config_of("cooperative_follow.yaml", "slash_b", text, tmp_path)
    runtime = AgentRuntime(config, key=key)
    forger = Codec(521, 1)  # right mission, no key: rejected by the codec (BadTag)
    (data,) = forger.encode([Heartbeat(1, GPS0, 521, AgentType.MCS), Terminate(1, GPS0, 0)], 0, 256)
    run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), PacketReceived(data))
    assert not runtime.terminated
    station = Codec(521, 1, key)
    (data,) = station.encode(
        [Heartbeat(1, GPS0, 521, AgentType.MCS), Terminate(1, GPS0, 0)], 0, 256
    )
    run(runtime, 0.1, PacketReceived(data))
    assert runtime.terminated
    assert key.hex() not in runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]


def test_two_agents_in_one_process_share_nothing() -> None:
    a = AgentRuntime(config_of("cooperative_follow.yaml", "slash_a"))
    b = AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))
    run(a, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True))
    run(b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True))
    assert a.machine is not None and b.machine is not None
    assert a.machine.active_paths() == ("",) and b.machine.active_paths() == ("idle",)
    assert a.fleet is not b.fleet and a.context is not b.context
    assert "slash_a" in a.logbook.mission.name and "slash_b" in b.logbook.mission.name


def _chase_state_sent(runtime: AgentRuntime, out: list[object]) -> bool:
    station = Codec(521, 1)
    for packet in of(out, SendPacket):
        if packet.destination == "mcs":  # type: ignore[attr-defined]
            for message in station.decode(packet.data).messages:  # type: ignore[attr-defined]
                if isinstance(message, BehaviorState) and message.active_states == ("chase",):
                    return True
    return False


def test_phase_order_comes_from_the_config() -> None:
    config = config_of("cooperative_follow.yaml", "slash_b")
    assert config.tick_phases == ("timeouts", "machine", "commands", "telemetry", "log")
    for phases, same_tick in [
        (config.tick_phases, True),
        (("telemetry", "timeouts", "machine", "commands", "log"), False),
    ]:
        runtime = AgentRuntime(replace(config, tick_phases=phases))
        station = Peer(521, 1, AgentType.MCS)
        run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True))
        (activate,) = station.codec.encode([ActivateController(1, GPS0, 3, True)], 3, 256)
        out = run(runtime, 0.1, PacketReceived(activate), AutopilotHeartbeat("HOLD", 4, True))
        # with telemetry before the machine, the state change goes out a tick later
        assert _chase_state_sent(runtime, out) is same_tick
        if not same_tick:
            assert _chase_state_sent(
                runtime, run(runtime, 0.2, AutopilotHeartbeat("HOLD", 4, True))
            )


def test_a_split_bundle_is_logged_packet_by_packet() -> None:
    config = config_of("cooperative_follow.yaml", "slash_b")
    runtime = AgentRuntime(config)
    runtime.max_packet_bytes = 40  # room for 24 bundle bytes: heartbeat (20) and status (21) split
    out = run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True))
    packets = broadcast(out)
    assert len(packets) == 2
    rows = [
        line.split(",")
        for line in runtime.logbook.streams.messages.getvalue().splitlines()  # type: ignore[attr-defined]
        if line.startswith("sent,") and ",*," in line
    ]
    assert [(r[4], r[5], r[6]) for r in rows] == [
        ("1", str(len(packets[0].data)), "heartbeat"),
        ("2", str(len(packets[1].data)), "agent_status"),
    ]


def test_a_behavior_that_handles_mcs_lost_overrides_the_failsafe(tmp_path: Path) -> None:
    text = (
        (ROOT / "missions" / "cooperative_follow.yaml")
        .read_text(encoding="utf-8")
        .replace(
            "idle: {use: hold, transitions: {activate: chase}}",
            "idle: {use: hold, transitions: {activate: chase, mcs_lost: chase}}",
        )
    )
    runtime = AgentRuntime(config_of("cooperative_follow.yaml", "slash_b", text, tmp_path))
    station = Peer(521, 1, AgentType.MCS)
    run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    for k in range(1, 36):
        run(runtime, k / 10, AutopilotHeartbeat("HOLD", 4, True))
    assert runtime.failsafe is None
    assert runtime.machine is not None and runtime.machine.active_paths() == ("chase",)


def test_a_station_never_heard_is_lost_too(slash_b: AgentRuntime) -> None:
    """Once the behaviour runs (here from the first tick), a station never heard is lost."""
    for k in range(0, 36):
        run(slash_b, k / 10, AutopilotHeartbeat("HOLD", 4, True), vehicle(k / 10))
    assert slash_b.failsafe == "hold"


def test_commands_dropped_while_the_autopilot_was_silent_are_not_sent_on_its_return(
    slash_b: AgentRuntime,
) -> None:
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    run(
        slash_b,
        0.0,
        vehicle(0.0),
        AutopilotHeartbeat("MANUAL", 0, True),
        station.heartbeat(0.0),
        slash_a.heartbeat(0.0, slash_a.status(0.0, 30.6380, -96.4787)),
    )
    for k in range(1, 40):  # the autopilot goes silent; peers keep talking
        t = k / 10
        run(
            slash_b,
            t,
            station.heartbeat(t),
            slash_a.heartbeat(t, slash_a.status(t, 30.6380, -96.4787)),
        )
    assert slash_b.autopilot_lost
    (activate,) = station.codec.encode([ActivateController(1, GPS0, 3, True)], 3, 256)
    out = run(slash_b, 4.0, PacketReceived(activate), station.heartbeat(4.0))
    assert of(out, Goto) == [] and of(out, SetMode) == []
    out = list(slash_b.deliver(vehicle(4.1, mode="HOLD", custom_mode=4), 4.1))  # back
    assert not slash_b.autopilot_lost and out == []  # nothing of the silent time
    out = run(slash_b, 4.1)
    assert of(out, SetMode) == []  # the chase's mode request was made unheard: void


def test_activation_at_a_gps_time(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    run(slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    later = GPS0 + 2000  # two seconds from now
    (activate,) = station.codec.encode([ActivateController(1, GPS0, 3, True, later)], 3, 256)
    run(slash_b, 0.1, PacketReceived(activate), AutopilotHeartbeat("HOLD", 4, True))
    assert slash_b.machine is not None and slash_b.machine.active_paths() == ("idle",)
    for k in range(2, 22):
        run(slash_b, k / 10, AutopilotHeartbeat("HOLD", 4, True), station.heartbeat(k / 10))
    assert slash_b.machine.active_paths() == ("chase",)


def test_terminate_sends_a_last_terminated_heartbeat(slash_b: AgentRuntime) -> None:
    station = Peer(521, 1, AgentType.MCS)
    run(slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    out = run(slash_b, 0.1, station.heartbeat(0.1, Terminate(1, GPS0 + 100, 0)))
    (last,) = broadcast(out)
    (beat,) = Codec(521, 99).decode(last.data).messages
    assert isinstance(beat, Heartbeat) and beat.condition.name == "TERMINATED"
