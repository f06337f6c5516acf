"""AgentRuntime.terminate: the shell's way to run one agent's own terminate sequence.

As tests/test_runtime_safety.py does, each test drives one runtime built from a
compiled example on a virtual clock and pins one rule of the public method the
real-time shell calls when it stops (SIGINT, SIGTERM, ``--until``): thesis 7.3.5's
sequence for this agent only, its commands returned, nothing of it twice.
"""

from __future__ import annotations

from test_runtime import GPS0, READY, Peer, config_of, of, vehicle

from clark_engine.link.codec import Codec
from clark_engine.link.messages import AgentType, Heartbeat, Terminate
from clark_engine.runtime.commands import CloseInterfaces, SendPacket, SetMode
from clark_engine.runtime.events import AutopilotHeartbeat
from clark_engine.runtime.runtime import AgentRuntime


def run(runtime: AgentRuntime, t: float, *events: object) -> list[object]:
    """Deliver a ready autopilot status and the events at ``t``, then tick."""
    out: list[object] = list(runtime.deliver(READY, t))
    for event in events:
        out += runtime.deliver(event, t)  # type: ignore[arg-type]
    out += runtime.tick(t)
    return out


def mission_log(runtime: AgentRuntime) -> str:
    return runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]


def started_slash_b(station: Peer | None = None) -> AgentRuntime:
    runtime = AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))
    station = station or Peer(521, 1, AgentType.MCS)
    run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    return runtime


def messages(commands: list[object], mission_id: int = 521) -> list[object]:
    """Every ClarkLink message in the packets among ``commands``."""
    found: list[object] = []
    for packet in of(commands, SendPacket):
        found += Codec(mission_id, 99).decode(packet.data).messages  # type: ignore[attr-defined]
    return found


def test_terminate_runs_the_sequence_and_returns_its_commands() -> None:
    runtime = started_slash_b()
    out: list[object] = list(runtime.terminate(0.5, "SIGTERM"))
    assert runtime.terminated
    assert of(out, SetMode) == [SetMode("HOLD", 4)]  # the Slash's terminal mode
    (beat,) = messages(out)
    assert isinstance(beat, Heartbeat) and beat.condition.name == "TERMINATED"
    assert out[-1] == CloseInterfaces()
    assert runtime.logbook.closed


def test_the_reason_and_the_time_reach_the_mission_log() -> None:
    runtime = started_slash_b()
    runtime.terminate(1.25, "real-time shell stopping (SIGINT)")
    lines = [line for line in mission_log(runtime).splitlines() if "terminat" in line]
    assert any("terminating: real-time shell stopping (SIGINT)" in line for line in lines)
    assert all("t=1.250" in line for line in lines), lines


def test_terminate_is_for_this_agent_only() -> None:
    """A station's terminate stops the station; it never commands the fleet to stop."""
    mcs = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    mcs.tick(0.0)
    out: list[object] = list(mcs.terminate(0.1, "SIGTERM"))
    assert mcs.terminated
    found = messages(out)
    assert not [m for m in found if isinstance(m, Terminate)], found
    assert [m for m in found if isinstance(m, Heartbeat)]
    assert of(out, SetMode) == []  # a station has no vehicle
    assert out[-1] == CloseInterfaces()


def test_terminate_twice_or_after_the_station_did_returns_nothing() -> None:
    runtime = started_slash_b()
    assert runtime.terminate(0.2, "first")
    assert runtime.terminate(0.3, "second") == []
    station = Peer(521, 1, AgentType.MCS)
    other = started_slash_b(station)
    run(other, 0.1, station.heartbeat(0.1, Terminate(1, GPS0 + 100, 0, "test over")))
    assert other.terminated and other.terminate(0.2, "SIGTERM") == []


def test_a_lost_autopilot_gets_no_terminal_mode_but_the_links_close() -> None:
    station = Peer(521, 1, AgentType.MCS)
    runtime = started_slash_b(station)
    for k in range(1, 40):  # the autopilot silent for 3.9 s
        run(runtime, k / 10, station.heartbeat(k / 10))
    assert runtime.autopilot_lost
    out: list[object] = list(runtime.terminate(4.0, "SIGTERM"))
    assert of(out, SetMode) == []  # nobody hears it: not sent
    assert CloseInterfaces() in out and messages(out)


def test_behavior_started_follows_the_launch_gate() -> None:
    runtime = AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))
    runtime.tick(0.0)  # no autopilot yet: the launch gate is shut
    assert not runtime.behavior_started
    run(runtime, 0.1, vehicle(0.1), AutopilotHeartbeat("MANUAL", 0, True))
    assert runtime.behavior_started
    runtime.terminate(0.2, "SIGTERM")
    assert runtime.behavior_started  # it started; terminated says it is over
