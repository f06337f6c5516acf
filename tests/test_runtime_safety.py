"""Safety rules of the runtime that a shell's clock, boot order or link can break.

Each test drives one runtime built from a compiled example on a virtual clock
(no sleeping), as tests/test_runtime.py does, and pins one rule of
docs/runtime.md#safety: when the station's silence counts, what the clock's
origin does, and what an autopilot that comes back is sent.
"""

from __future__ import annotations

from pathlib import Path

import pytest
from test_runtime import (
    GPS0,
    READY,
    ROOT,
    Peer,
    config_of,
    of,
    vehicle,
)

from clark_engine.link.auth import ReplayStore, generate_key_file, load_key
from clark_engine.link.codec import Codec
from clark_engine.link.messages import ActivateController, AgentType, Heartbeat, Terminate
from clark_engine.runtime.commands import Goto, SetMode
from clark_engine.runtime.events import AutopilotHeartbeat, PacketReceived
from clark_engine.runtime.runtime import AgentRuntime


def run(runtime: AgentRuntime, t: float, *events: object) -> list[object]:
    """Deliver a ready autopilot status and the events at ``t``, then tick."""
    out: list[object] = list(runtime.deliver(READY, t))
    for event in events:
        out += runtime.deliver(event, t)  # type: ignore[arg-type]
    out += runtime.tick(t)
    return out


def slash_b() -> AgentRuntime:
    return AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))


def mission_log(runtime: AgentRuntime) -> str:
    return runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined]


def interface_log(runtime: AgentRuntime) -> str:
    return runtime.logbook.streams.interface.getvalue()  # type: ignore[attr-defined]


# -- item 3: the station's silence and the clock's origin ---------------------------------


@pytest.mark.parametrize("origin_s", [0.0, 86_400.0 + 0.37])
def test_a_monotonic_clock_raises_nothing_on_the_first_tick(origin_s: float) -> None:
    """The shell's first tick, before the autopilot or the station said anything."""
    runtime = slash_b()
    runtime.tick(origin_s)
    assert not runtime.autopilot_lost and runtime.failsafe is None
    assert "mcs_lost" not in mission_log(runtime)
    assert "autopilot silent" not in interface_log(runtime)
    station = Peer(521, 1, AgentType.MCS)
    out = run(
        runtime,
        origin_s + 0.1,
        vehicle(0.1),
        AutopilotHeartbeat("MANUAL", 0, True),
        station.heartbeat(0.1),
    )
    assert SetMode("HOLD", 4) in of(out, SetMode)  # idle: hold, as at origin 0
    assert runtime.failsafe is None and not runtime.autopilot_lost


def test_a_monotonic_clock_still_loses_a_silent_autopilot() -> None:
    runtime = slash_b()
    origin_s = 5_000.0
    station = Peer(521, 1, AgentType.MCS)
    run(runtime, origin_s, station.heartbeat(0.0))  # no autopilot message at all
    for k in range(1, 31):
        run(runtime, origin_s + k / 10, station.heartbeat(k / 10))
    assert not runtime.autopilot_lost  # 3.0 s: not yet past the timeout
    for k in range(31, 36):
        run(runtime, origin_s + k / 10, station.heartbeat(k / 10))
    assert runtime.autopilot_lost


def test_a_vehicle_booted_before_its_station_is_not_stuck_in_hold() -> None:
    """Booted 10 s before its station, still waiting for its pilot: it flies normally."""
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    for k in range(0, 100):  # 10 s without a station; no vehicle state yet: not started
        run(runtime, k / 10, AutopilotHeartbeat("MANUAL", 0, True))
    assert runtime.failsafe is None
    t = 0.0
    for k in range(100, 110):  # the station comes up; the vehicle is ready and armed
        t = k / 10
        run(
            runtime,
            t,
            vehicle(t, mode="HOLD", custom_mode=4),
            AutopilotHeartbeat("HOLD", 4, True),
            station.heartbeat(t),
            slash_a.heartbeat(t, slash_a.status(t, 30.6380, -96.4787)),
        )
    (activate,) = station.codec.encode([ActivateController(1, GPS0, 3, True)], 3, 256)
    out = run(runtime, 11.0, PacketReceived(activate), vehicle(11.0, mode="HOLD", custom_mode=4))
    assert runtime.failsafe is None
    assert runtime.machine is not None and runtime.machine.active_paths() == ("chase",)
    assert SetMode("GUIDED", 15) in of(out, SetMode) and len(of(out, Goto)) == 1


def test_a_station_never_heard_once_the_behavior_runs_raises_mcs_lost() -> None:
    """Silence is counted from the behaviour's start: a behaviour never runs unwatched."""
    runtime = slash_b()
    for k in range(0, 31):
        run(runtime, k / 10, AutopilotHeartbeat("HOLD", 4, True), vehicle(k / 10))
    assert runtime.failsafe is None  # 3.0 s since the start: not yet
    for k in range(31, 36):
        run(runtime, k / 10, AutopilotHeartbeat("HOLD", 4, True), vehicle(k / 10))
    assert runtime.failsafe == "hold"
    assert "no station heard for 3.1 s" in mission_log(runtime)


def test_silence_before_the_behavior_starts_is_counted_from_its_start() -> None:
    """No station for 20 s while the behaviour waits (no vehicle state): no failsafe then."""
    runtime = slash_b()
    for k in range(0, 200):
        run(runtime, k / 10, AutopilotHeartbeat("MANUAL", 0, True))
    assert runtime.failsafe is None and "mcs_lost" not in mission_log(runtime)
    for k in range(200, 231):  # the behaviour starts at 20.0 s
        run(runtime, k / 10, AutopilotHeartbeat("HOLD", 4, True), vehicle(k / 10))
    assert runtime.failsafe is None
    for k in range(231, 236):
        run(runtime, k / 10, AutopilotHeartbeat("HOLD", 4, True), vehicle(k / 10))
    assert runtime.failsafe == "hold"


# -- item 2: an autopilot that comes back gets no stale command ---------------------------


VEHICLE_COMMAND_TYPES = ("Goto", "SetMode", "Arm", "Takeoff", "SetServo", "RcOverride")


def vehicle_commands(out: list[object]) -> list[object]:
    return [c for c in out if type(c).__name__ in VEHICLE_COMMAND_TYPES]


class Scene:
    """Slash B with its station and Slash A talking, its behaviour running in idle (HOLD)."""

    def __init__(self) -> None:
        self.runtime = slash_b()
        self.station = Peer(521, 1, AgentType.MCS)
        self.slash_a = Peer(521, 2, AgentType.VEHICLE)
        self.t = 0.0
        self.tick(vehicle(0.0, mode="HOLD", custom_mode=4), AutopilotHeartbeat("HOLD", 4, True))

    def tick(self, *autopilot: object, station: bool = True) -> list[object]:
        """One tick 0.1 s on: the peers talk (the station unless told not), the autopilot says
        what is given."""
        t = self.t = round(self.t + 0.1, 1)
        peers: list[object] = [self.slash_a.heartbeat(t, self.slash_a.status(t, 30.6380, -96.4787))]
        if station:
            peers.append(self.station.heartbeat(t))
        return run(self.runtime, t, *peers, *autopilot)

    def activate(self) -> list[object]:
        (packet,) = self.station.codec.encode([ActivateController(1, GPS0, 3, True)], 3, 256)
        return run(self.runtime, self.t, PacketReceived(packet))

    def lose_autopilot(self, *, station: bool = True) -> list[object]:
        out: list[object] = []
        while not self.runtime.autopilot_lost:
            out += self.tick(station=station)
        return out


def test_commands_of_the_loss_are_never_replayed_and_a_pilots_mode_is_kept() -> None:
    """Activated while the autopilot is silent; it comes back with the pilot in MANUAL."""
    scene = Scene()
    scene.lose_autopilot()
    out = scene.activate() + scene.tick() + scene.tick()
    assert scene.runtime.machine is not None
    assert scene.runtime.machine.active_paths() == ("chase",)
    assert vehicle_commands(out) == []  # dropped while lost
    # It speaks again: a heartbeat alone does not end the loss (the behaviour has not
    # seen the vehicle yet), its state does; nothing held back is sent.
    out = list(scene.runtime.deliver(AutopilotHeartbeat("HOLD", 4, True), scene.t))
    assert scene.runtime.autopilot_lost and vehicle_commands(out) == []
    back = vehicle(scene.t, mode="HOLD", custom_mode=4)
    out = list(scene.runtime.deliver(back, scene.t))
    assert not scene.runtime.autopilot_lost and vehicle_commands(out) == []
    # The chase's mode request was made while nobody heard it: it is not carried out
    # later, whatever the mode; the vehicle stays in the pilot's mode (HOLD, then MANUAL).
    later: list[object] = []
    for k in range(30):
        mode, number = ("HOLD", 4) if k < 10 else ("MANUAL", 0)
        later += scene.tick(vehicle(scene.t, mode=mode, custom_mode=number))
    assert of(later, SetMode) == []
    assert "autopilot heard again" in interface_log(scene.runtime)


def test_a_state_entered_after_the_return_commands_as_usual() -> None:
    scene = Scene()
    scene.lose_autopilot()
    scene.tick()
    scene.tick(vehicle(scene.t, mode="HOLD", custom_mode=4))  # back
    assert not scene.runtime.autopilot_lost
    out = scene.activate() + scene.tick(vehicle(scene.t, mode="HOLD", custom_mode=4))
    assert SetMode("GUIDED", 15) in of(out, SetMode) and len(of(out, Goto)) >= 1


def test_a_failsafe_during_the_loss_holds_the_vehicle_when_it_returns() -> None:
    """The station falls silent while the autopilot is lost: hold, sent on its return."""
    scene = Scene()
    scene.activate()
    scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15))
    scene.lose_autopilot()
    out: list[object] = []
    while scene.runtime.failsafe is None:
        out += scene.tick(station=False)
    assert vehicle_commands(out) == []  # the failsafe's SetMode could not be sent
    for _ in range(5):
        scene.tick(station=False)
    out = list(scene.runtime.deliver(vehicle(scene.t, mode="GUIDED", custom_mode=15), scene.t))
    out += scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15), station=False)
    assert vehicle_commands(out) == [SetMode("HOLD", 4)]  # no Goto from before the failsafe
    out = []
    for _ in range(20):
        out += scene.tick(vehicle(scene.t, mode="HOLD", custom_mode=4), station=False)
    assert vehicle_commands(out) == []


def test_a_failsafe_before_the_loss_is_not_sent_again_on_the_return() -> None:
    """Held before the loss; the pilot took MANUAL meanwhile: the return changes nothing."""
    scene = Scene()
    scene.activate()
    scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15))
    out: list[object] = []
    while scene.runtime.failsafe is None:
        out += scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15), station=False)
    out += scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15), station=False)
    assert SetMode("HOLD", 4) in of(out, SetMode)
    scene.lose_autopilot(station=False)
    out = scene.tick(vehicle(scene.t, mode="MANUAL", custom_mode=0), station=False)
    for _ in range(20):
        out += scene.tick(vehicle(scene.t, mode="MANUAL", custom_mode=0), station=False)
    assert not scene.runtime.autopilot_lost and vehicle_commands(out) == []


def test_a_failsafe_after_the_return_is_sent_at_once() -> None:
    scene = Scene()
    scene.activate()
    scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15))
    scene.lose_autopilot()
    scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15))  # back
    out: list[object] = []
    while scene.runtime.failsafe is None:
        out += scene.tick(vehicle(scene.t, mode="GUIDED", custom_mode=15), station=False)
    assert of(out, SetMode) == [SetMode("HOLD", 4)]


# -- item 6: what arrives over the air cannot write the logs -------------------------------


def message_rows(runtime: AgentRuntime) -> list[str]:
    text: str = runtime.logbook.streams.messages.getvalue()  # type: ignore[attr-defined]
    return text.splitlines()[1:]


def test_a_terminate_reason_cannot_forge_a_log_line() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    forged = "bye\nt=9.999 gps_ms=1 ERROR runtime._timeouts: forged\x1b[2J" + "x" * 120
    run(runtime, 0.1, station.heartbeat(0.1, Terminate(1, GPS0, 0, forged)))
    assert runtime.terminated
    lines = mission_log(runtime).splitlines()
    assert all(line.startswith("t=") for line in lines)
    (line,) = [line for line in lines if "terminate from mcs" in line]
    assert "\\x0a" in line or "\\n" in line
    assert "\x1b" not in mission_log(runtime)
    assert len(line) < 800  # bounded (the packet bounds it too)


def test_rejected_packets_are_counted_and_summarised_not_logged_one_by_one() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    before_interface = len(interface_log(runtime))
    before_rows = len(message_rows(runtime))
    junk = bytes(range(40))
    t = 0.0
    for k in range(1, 301):  # 30 s: ten floods of 100 packets a second
        t = k / 10
        for _ in range(10):
            runtime.deliver(PacketReceived(junk), t)
        run(runtime, t, AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(t))
    written = len(interface_log(runtime)) - before_interface
    rejected_rows = [r for r in message_rows(runtime)[before_rows:] if r.startswith("rejected")]
    assert written < 3000 * 177 / 50  # far below a line per packet
    assert 0 < len(rejected_rows) <= 100
    summaries = [
        line
        for line in interface_log(runtime).splitlines()
        if "rejected" in line and "packets" in line
    ]
    assert summaries, interface_log(runtime)[-2000:]
    assert any("rejected 1000 packets" in line for line in summaries)


def test_a_packet_with_more_messages_than_its_agent_sends_is_rejected() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    run(runtime, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(0.0))
    rows_before = len(message_rows(runtime))
    tiny = [Heartbeat(2, GPS0, 521, AgentType.VEHICLE) for _ in range(200)]
    packets = slash_a.codec.encode(tiny, 0, 256)  # type: ignore[arg-type]
    stuffed = packets[0]
    assert len(Codec(521, 99).decode(stuffed).messages) > 2 + 8  # Slash A sends 2 kinds
    run(runtime, 0.1, PacketReceived(stuffed))
    new_rows = message_rows(runtime)[rows_before:]
    assert not [r for r in new_rows if r.startswith("received")]
    assert [r for r in new_rows if r.startswith("rejected") and "TooManyMessages" in r]
    assert runtime.fleet.record(2) is None  # nothing of it was taken
    # an honest bundle from the same agent is taken
    (honest,) = slash_a.codec.encode(
        [Heartbeat(2, GPS0, 521, AgentType.VEHICLE), slash_a.status(0.2, 30.6, -96.4)], 0, 256
    )
    run(runtime, 0.2, PacketReceived(honest))
    assert runtime.fleet.record(2) is not None


# -- issue 10 item 1, end to end: a restarted agent and a recorded Terminate --------------


def test_a_restarted_agent_is_not_terminated_by_a_recorded_terminate(tmp_path: Path) -> None:
    """An agent built with a replay store refuses, after a crash and restart, the station's
    Terminate it already acted on, played back from a recording; a new one still acts."""
    text = (
        (ROOT / "missions" / "cooperative_follow.yaml")
        .read_text(encoding="utf-8")
        .replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n", 1)
    )
    generate_key_file(tmp_path / "coop.key")
    key = load_key(tmp_path / "coop.key")
    config = config_of("cooperative_follow.yaml", "slash_b", text, tmp_path)
    station = Codec(521, 1, key)
    (recorded,) = station.encode(
        [Heartbeat(1, GPS0, 521, AgentType.MCS), Terminate(1, GPS0, 0, "end")], 0, 256
    )

    def boot() -> AgentRuntime:
        return AgentRuntime(config, key=key, replay_store=ReplayStore(tmp_path / "b.replay"))

    first = boot()
    run(first, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), PacketReceived(recorded))
    assert first.terminated
    again = boot()  # a crash: nothing saved on the way out
    run(again, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True), PacketReceived(recorded))
    assert not again.terminated
    (fresh,) = station.encode(
        [Heartbeat(1, GPS0, 521, AgentType.MCS), Terminate(1, GPS0, 0, "again")], 0, 256
    )
    # The station's next genuine packet acts at once: one packet heard before the crash
    # reserved nothing beyond it (issue 18 item 1; tests/test_link_replay_restart.py).
    run(again, 0.1, PacketReceived(fresh))
    assert again.terminated


def test_a_vehicle_run_without_its_autopilot_on_purpose_logs_no_error() -> None:
    """``clark run --no-autopilot``: lost as any silent autopilot, said once, as information."""
    runtime = AgentRuntime(
        config_of("cooperative_follow.yaml", "slash_b"), autopilot_connected=False
    )
    for k in range(60):  # 6 s: past the autopilot's timeout
        runtime.tick(k * 0.1)
    assert runtime.autopilot_lost
    log = interface_log(runtime)
    assert "ERROR" not in log and "autopilot silent" not in log
    assert log.count("no autopilot (testing mode): treated as lost") == 1


def test_an_activate_no_state_takes_is_said_to_be_ignored() -> None:
    """Slash A's tour has no activate transition: the station's activate is logged as
    received and then as ignored, saying why (before: received, then nothing)."""
    runtime = AgentRuntime(config_of("cooperative_follow.yaml", "slash_a"))
    station = Peer(521, 1, AgentType.MCS)
    for k in range(20):
        t = k / 10
        run(runtime, t, vehicle(t), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(t))
    assert runtime.machine is not None and runtime.machine.running
    (activate,) = station.codec.encode([ActivateController(1, GPS0 + 2000, 2, True)], 2, 256)
    run(runtime, 2.0, PacketReceived(activate), vehicle(2.0), station.heartbeat(2.0))
    log = mission_log(runtime)
    assert "activate from mcs" in log
    assert "activate: ignored: no active state takes it (active: " in log


def test_an_activate_after_a_failsafe_is_said_to_be_ignored() -> None:
    runtime = slash_b()
    for k in range(36):  # no station: mcs_lost at 3.1 s, the failsafe holds the vehicle
        run(runtime, k / 10, AutopilotHeartbeat("HOLD", 4, True), vehicle(k / 10))
    assert runtime.failsafe == "hold"
    station = Peer(521, 1, AgentType.MCS)
    (activate,) = station.codec.encode([ActivateController(1, GPS0 + 4000, 3, True)], 3, 256)
    run(runtime, 4.0, station.heartbeat(4.0), PacketReceived(activate), vehicle(4.0))
    log = mission_log(runtime)
    assert "activate from mcs" in log
    assert "activate: ignored: the failsafe hold holds (a failsafe is final" in log
