"""A station's command sent again until it takes, and acted on once (runtime/command_delivery.py).

The cooperative-follow example's 200-run campaign lost the operator's single
``activate`` in a radio's bad spell in two runs; the station now sends it again, with
the same stamp, until the vehicle's Behavior State shows it, and the vehicle ignores a
copy of a command it acted on.
"""

from __future__ import annotations

from collections.abc import Sequence

from test_runtime import GPS0, Peer, config_of, of, run, vehicle

from clark_engine.link.codec import Codec
from clark_engine.link.messages import (
    ActivateController,
    AgentType,
    BehaviorState,
    ModeChangeRequest,
)
from clark_engine.runtime.command_delivery import COMMAND_SENDS, ActedOn, took_effect
from clark_engine.runtime.commands import SendPacket, SetMode
from clark_engine.runtime.events import AutopilotHeartbeat, PacketReceived, StationCommand
from clark_engine.runtime.runtime import AgentRuntime


def test_a_vehicle_acts_on_a_command_once_whichever_copy_comes() -> None:
    slash_b = AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    run(
        slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("MANUAL", 0, True),
        station.heartbeat(0.0), slash_a.heartbeat(0.0, slash_a.status(0.0, 30.6380, -96.4787)),
    )  # fmt: skip
    assert slash_b.machine is not None

    def send(t: float, *messages: object) -> None:
        (data,) = station.codec.encode(list(messages), 3, 256)  # type: ignore[arg-type]
        run(slash_b, t, PacketReceived(data), AutopilotHeartbeat("HOLD", 4, True))

    activate = ActivateController(1, GPS0 + 100, 3, True)
    send(0.1, activate)
    assert slash_b.machine.active_paths() == ("chase",)
    send(0.2, ActivateController(1, GPS0 + 200, 3, False))  # the operator's deactivate
    assert slash_b.machine.active_paths() == ("idle",)
    # A copy of the first activate (a packet of its own, a fresh counter) comes late: it
    # was acted on already, so Slash B stays idle.
    send(0.3, activate)
    assert slash_b.machine.active_paths() == ("idle",)
    send(0.4, ActivateController(1, GPS0 + 400, 3, True))  # a new one acts
    assert slash_b.machine.active_paths() == ("chase",)


def test_a_copy_of_a_mode_request_does_not_undo_a_later_mode() -> None:
    slash_b = AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))
    station = Peer(521, 1, AgentType.MCS)
    request = ModeChangeRequest(1, GPS0, 3, 0)  # MANUAL on ArduRover
    out = run(
        slash_b, 0.0, vehicle(0.0), AutopilotHeartbeat("HOLD", 4, True),
        station.heartbeat(0.0, request),
    )  # fmt: skip
    assert SetMode("MANUAL", 0) in of(out, SetMode)
    out = run(slash_b, 5.0, AutopilotHeartbeat("HOLD", 4, True), station.heartbeat(5.0, request))
    assert SetMode("MANUAL", 0) not in of(out, SetMode)


def _sent(out: Sequence[object], to: str) -> list[object]:
    packets = [c for c in out if isinstance(c, SendPacket) and c.destination == to]
    return [m for p in packets for m in Codec(521, 3).decode(p.data).messages]


def mission_log(runtime: AgentRuntime) -> str:
    return runtime.logbook.streams.mission.getvalue()  # type: ignore[attr-defined,no-any-return]


def test_the_station_sends_a_command_again_until_it_takes() -> None:
    mcs = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    slash_b = Peer(521, 3, AgentType.VEHICLE)
    first = _sent(mcs.deliver(StationCommand("activate", "slash_b"), 0.0), "slash_b")
    assert first == [ActivateController(1, GPS0, 3, True)]
    mcs.deliver(PacketReceived(slash_b.heartbeat(0.2).data), 0.2)
    assert _sent(mcs.tick(0.5), "slash_b") == []  # not yet due
    again = _sent(mcs.tick(1.0), "slash_b")
    assert again == first  # the same command, the same stamp
    # Its Behavior State shows the activation: no more copies.
    state = BehaviorState(3, GPS0 + 1200, ("chase",), "activate")
    mcs.deliver(PacketReceived(slash_b.heartbeat(1.2, state).data), 1.2)
    assert [_sent(mcs.tick(t), "slash_b") for t in (2.0, 3.0, 4.0)] == [[], [], []]
    assert "activate slash_b: took after 2 sends" in mission_log(mcs)


def test_an_older_activation_repeated_does_not_confirm_a_new_one() -> None:
    # Slash B already showed an activation; the operator deactivates and activates it
    # again. Its periodic Behavior State still repeating the old activation (the same
    # states, the same event) is no sign that the new one took: the station sends it again.
    mcs = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    slash_b = Peer(521, 3, AgentType.VEHICLE)
    old = BehaviorState(3, GPS0, ("chase",), "activate")
    mcs.deliver(PacketReceived(slash_b.heartbeat(0.1, old).data), 0.1)
    first = _sent(mcs.deliver(StationCommand("activate", "slash_b"), 0.5), "slash_b")
    repeat = BehaviorState(3, GPS0 + 1000, ("chase",), "activate")
    mcs.deliver(PacketReceived(slash_b.heartbeat(1.0, repeat).data), 1.0)
    assert _sent(mcs.tick(1.5), "slash_b") == first
    # The same rule is the station view's (station/view_model.py calls took_effect too).
    record = mcs.fleet.record(3)
    assert record is not None and record.sample(BehaviorState) is not None
    before = record.sample(BehaviorState)
    assert not took_effect("activate", record, 0.5, behavior_before=before)
    fresh = BehaviorState(3, GPS0 + 1800, ("chase", "near"), "activate")
    mcs.deliver(PacketReceived(slash_b.heartbeat(1.8, fresh).data), 1.8)
    assert took_effect("activate", record, 0.5, behavior_before=before)
    assert not took_effect("deactivate", record, 0.5, behavior_before=before)


def test_the_station_gives_up_after_a_few_copies() -> None:
    mcs = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    sends = len(_sent(mcs.deliver(StationCommand("activate", "slash_b"), 0.0), "slash_b"))
    for k in range(1, 10):
        sends += len(_sent(mcs.tick(float(k)), "slash_b"))
    assert sends == COMMAND_SENDS
    log = mission_log(mcs)
    assert f"activate slash_b: not seen to take after {COMMAND_SENDS} sends" in log


def test_a_new_command_replaces_the_unconfirmed_one() -> None:
    mcs = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    mcs.deliver(StationCommand("activate", "slash_b"), 0.0)
    mcs.deliver(StationCommand("deactivate", "slash_b"), 0.5)
    again = _sent(mcs.tick(1.5), "slash_b")
    assert again == [ActivateController(1, GPS0 + 500, 3, False)]  # the deactivate alone


def test_the_memory_of_commands_is_bounded() -> None:
    acted = ActedOn(kept=3)
    keys = [(1, "activate", 3, 1, GPS0 + k) for k in range(5)]
    assert all(acted.first_time(k) for k in keys)
    assert not acted.first_time(keys[-1])
    assert acted.first_time(keys[0])  # forgotten: the oldest went first
    assert acted.first_time((1, "activate", 3, 1, 0)) and acted.first_time((1, "activate", 3, 1, 0))
