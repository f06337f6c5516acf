"""What arrives over the air is bounded: queues, commands and log lines (issue 18, items 4-5).

On an unkeyed mission (every shipped example) nothing is authenticated: anyone in range
can send packets that claim to be the station, a peer, or an agent not in the mission at
all. Each test floods one runtime built from a compiled example with 10^4 such packets,
made by the real ClarkLink codec and delivered as PacketReceived events on a virtual
clock, and counts what piles up: pending activations, queued events, commands, and the
lines and rows of the logs. No test measures time (benchmarks/flood_runtime.py does).
"""

from __future__ import annotations

import re
from pathlib import Path

import pytest
from test_runtime import GPS0, READY, ROOT, Peer, config_of, of, vehicle

from clark_engine.link.auth import generate_key_file, load_key
from clark_engine.link.codec import Codec
from clark_engine.link.messages import (
    ActivateController,
    AgentStatus,
    AgentType,
    Heartbeat,
    ModeChangeRequest,
)
from clark_engine.runtime.commands import SetMode
from clark_engine.runtime.events import AutopilotHeartbeat, PacketReceived
from clark_engine.runtime.logbook import AIR_LINES_PER_INTERVAL, AIR_SUMMARY_S
from clark_engine.runtime.packets_in import MAX_SCHEDULED_ACTIVATIONS
from clark_engine.runtime.runtime import AgentRuntime

FLOOD = 10_000


def slash_b() -> AgentRuntime:
    return AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))


def mission_lines(runtime: AgentRuntime) -> list[str]:
    return runtime.logbook.streams.mission.getvalue().splitlines()  # type: ignore[attr-defined]


def interface_lines(runtime: AgentRuntime) -> list[str]:
    return runtime.logbook.streams.interface.getvalue().splitlines()  # type: ignore[attr-defined]


def message_rows(runtime: AgentRuntime) -> list[str]:
    return runtime.logbook.streams.messages.getvalue().splitlines()[1:]  # type: ignore[attr-defined]


def tick(runtime: AgentRuntime, t: float, *events: object) -> list[object]:
    """A ready autopilot in HOLD at ``t``, the events, then a tick."""
    out: list[object] = list(runtime.deliver(READY, t))
    out += runtime.deliver(vehicle(t, mode="HOLD", custom_mode=4), t)
    out += runtime.deliver(AutopilotHeartbeat("HOLD", 4, True), t)
    for event in events:
        out += runtime.deliver(event, t)  # type: ignore[arg-type]
    out += runtime.tick(t)
    return out


def started(runtime: AgentRuntime, station: Peer) -> float:
    """Run the behaviour (idle) with the station heard; the time reached."""
    for k in range(3):
        tick(runtime, k / 10, station.heartbeat(k / 10))
    assert runtime.machine is not None and runtime.machine.active_paths() == ("idle",)
    return 0.2


def activation(codec: Codec, target: int, active: bool, start_ms: int) -> PacketReceived:
    (data,) = codec.encode([ActivateController(codec.agent_id, GPS0, target, active, start_ms)], 0)
    return PacketReceived(data)


# -- item 4: delayed activations ---------------------------------------------------------


def test_forged_timed_activations_stay_bounded_and_the_genuine_one_still_fires() -> None:
    """10^4 forged timed activations, all different, after the station's genuine one."""
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = started(runtime, station)
    genuine = activation(station.codec, 3, True, GPS0 + 2_000)
    tick(runtime, t, genuine)
    forger = Codec(521, 1)  # claims the station's id: nothing tells it apart, unkeyed
    lines_before = len(mission_lines(runtime))
    for k in range(FLOOD):
        target = (0, 3)[k % 2]
        runtime.deliver(activation(forger, target, k % 3 != 0, GPS0 + 60_000 + k), t)
    assert len(runtime._intake.scheduled) <= MAX_SCHEDULED_ACTIVATIONS
    # The genuine one was received first and is never evicted by the flood.
    assert any(
        when == GPS0 + 2_000 and what == "activate" for when, what, *_ in runtime._intake.scheduled
    )
    for k in range(3, 22):
        tick(runtime, k / 10, station.heartbeat(k / 10))
    assert runtime.machine is not None and runtime.machine.active_paths() == ("chase",)
    written = len(mission_lines(runtime)) - lines_before
    assert written < 100, "\n".join(mission_lines(runtime)[-20:])


def test_repeated_timed_activations_coalesce_into_one() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = started(runtime, station)
    for _ in range(FLOOD):
        runtime.deliver(activation(station.codec, 3, True, GPS0 + 5_000), t)
    assert len(runtime._intake.scheduled) == 1
    runtime.tick(t)
    # A tick's work does not grow with the flood: what it scans is the bounded list.
    assert len(runtime._events) == 0 and len(runtime._intake.scheduled) == 1


def test_a_flood_of_immediate_activations_queues_each_kind_once_per_tick() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = started(runtime, station)
    forger = Codec(521, 1)
    for k in range(FLOOD):
        runtime.deliver(activation(forger, (0, 3)[k % 2], True, 0), t)
    assert runtime._events.count("activate") == 1
    tick(runtime, t)
    assert runtime.machine is not None and runtime.machine.active_paths() == ("chase",)


def test_forged_mode_requests_reach_the_autopilot_a_bounded_number_of_times() -> None:
    """Each SetMode is a MAVLink command the autopilot adapter tracks until answered."""
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = started(runtime, station)
    forger = Codec(521, 1)
    out: list[object] = []
    for _ in range(FLOOD):
        (data,) = forger.encode([ModeChangeRequest(1, GPS0, 3, 0)], 0)
        out += runtime.deliver(PacketReceived(data), t)
    assert len(of(out, SetMode)) == 1
    out = []
    for k in range(FLOOD):  # several modes in turn
        (data,) = forger.encode([ModeChangeRequest(1, GPS0, 3, (0, 4, 15)[k % 3])], 0)
        out += runtime.deliver(PacketReceived(data), t + 0.1)
    assert sorted(c.mode for c in of(out, SetMode)) == ["GUIDED", "HOLD"]  # type: ignore[attr-defined]
    # The vehicle reports another mode: a new request (a new stamp) is news again; a copy
    # of one acted on is not (runtime/command_delivery.py).
    out = tick(runtime, t + 0.2)
    out += runtime.deliver(vehicle(t + 0.2, mode="MANUAL", custom_mode=0), t + 0.2)
    (data,) = forger.encode([ModeChangeRequest(1, GPS0, 3, 4)], 0)
    assert of(runtime.deliver(PacketReceived(data), t + 0.2), SetMode) == []
    (data,) = forger.encode([ModeChangeRequest(1, GPS0 + 200, 3, 4)], 0)
    assert of(runtime.deliver(PacketReceived(data), t + 0.2), SetMode) == [SetMode("HOLD", 4)]


def test_timed_activation_lines_are_summarised() -> None:
    """The mission log keeps a few lines whole and one summary per interval."""
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = started(runtime, station)
    forger = Codec(521, 1)
    before = len(mission_lines(runtime))
    for k in range(FLOOD):
        runtime.deliver(activation(forger, 3, True, GPS0 + 60_000 + k), t)
    k = 3
    while k / 10 < t + AIR_SUMMARY_S + 0.5:
        tick(runtime, k / 10, station.heartbeat(k / 10))
        k += 1
    new = mission_lines(runtime)[before:]
    assert len(new) < 50 + AIR_LINES_PER_INTERVAL, "\n".join(new[-20:])
    summaries = [line for line in new if "not logged one by one" in line]
    assert summaries, "\n".join(new)
    # Every one is counted (but the few whose counters the station had used: duplicates).
    counted = re.search(r"\((\d+) in all", summaries[0])
    assert counted is not None and FLOOD - 5 <= int(counted[1]) <= FLOOD, summaries


# -- item 5: packets from agents not in the mission, keyed or not ------------------------


@pytest.mark.parametrize("keyed", [False, True])
def test_a_flood_from_ids_not_in_the_mission_writes_a_bounded_log(
    keyed: bool, tmp_path: Path
) -> None:
    key = None
    if keyed:
        text = (
            (ROOT / "missions" / "cooperative_follow.yaml")
            .read_text(encoding="utf-8")
            .replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n", 1)
        )
        generate_key_file(tmp_path / "coop.key")
        key = load_key(tmp_path / "coop.key")
        runtime = AgentRuntime(
            config_of("cooperative_follow.yaml", "slash_b", text, tmp_path), key=key
        )
    else:
        runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    station.codec = Codec(521, 1, key)
    started(runtime, station)
    mission_before, rows_before = len(mission_lines(runtime)), len(message_rows(runtime))
    interface_before = len(interface_lines(runtime))
    senders = [Codec(521, 1000 + i, key) for i in range(50)]
    k = 3
    for n in range(FLOOD):
        codec = senders[n % len(senders)]
        me = codec.agent_id
        messages = [
            Heartbeat(me, GPS0, 521, AgentType.MCS),
            AgentStatus(me, GPS0, 30.6, -96.4, 0.0, 1.0, 0.0, 90.0, 4),
            ActivateController(me, GPS0, 0, True),
        ]
        (data,) = codec.encode(messages, 0)  # type: ignore[arg-type]
        runtime.deliver(PacketReceived(data), k / 10)
        if n % 500 == 499:  # 500 packets a tick, 20 ticks a flood: 2 s
            tick(runtime, k / 10, station.heartbeat(k / 10))
            k += 1
    while k / 10 < 2.5 + AIR_SUMMARY_S:
        tick(runtime, k / 10, station.heartbeat(k / 10))
        k += 1
    assert runtime.fleet.unknown_packets == FLOOD  # every one counted
    new_rows = [r for r in message_rows(runtime)[rows_before:] if ",#" in r]
    assert len(new_rows) <= 3 * AIR_LINES_PER_INTERVAL, new_rows[:20]
    new_lines = mission_lines(runtime)[mission_before:]
    assert len(new_lines) < 50, "\n".join(new_lines[-20:])
    assert runtime.machine is not None and runtime.machine.active_paths() == ("idle",)
    interface = interface_lines(runtime)[interface_before:]
    assert len(interface) < 50, "\n".join(interface[-20:])
    summary = [line for line in interface if "packets from agents not in the mission" in line]
    assert summary and "not logged one by one" in summary[0], "\n".join(interface)
    assert f"{FLOOD} in all" in summary[0]
    ignored = [line for line in new_lines if "commands not obeyed" in line]
    assert ignored and f"{FLOOD} in all" in ignored[0], "\n".join(new_lines)


def test_commands_from_a_peer_that_is_not_a_station_are_logged_within_bounds() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = started(runtime, station)
    forger = Codec(521, 2)  # Slash A's id: a vehicle, which commands nobody
    before = len(mission_lines(runtime))
    for _ in range(FLOOD):
        runtime.deliver(activation(forger, 3, True, 0), t)
    new = mission_lines(runtime)[before:]
    ignored = [line for line in new if "only a station commands" in line]
    assert 0 < len(ignored) <= AIR_LINES_PER_INTERVAL


def test_a_flood_in_a_mission_agents_name_writes_rows_at_its_configured_rate_only() -> None:
    """Message-log rows: every genuine one at Slash A's pace, a forger's flood bounded."""
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    slash_a = Peer(521, 2, AgentType.VEHICLE)
    started(runtime, station)
    rows_before = len(message_rows(runtime))
    for k in range(3, 303):  # 30 s of Slash A as configured: heartbeat 1 Hz, status 2 Hz
        t = k / 10
        extra = [slash_a.status(t, 30.6380, -96.4787)] if k % 5 == 0 else []
        events = [slash_a.heartbeat(t, *extra)] if k % 10 == 0 else []
        if k % 5 == 0 and k % 10:
            (data,) = slash_a.codec.encode(extra, 0, 256)  # type: ignore[arg-type]
            events.append(PacketReceived(data))
        tick(runtime, t, station.heartbeat(t), *events)
    genuine = [r for r in message_rows(runtime)[rows_before:] if ",slash_a," in r]
    assert len(genuine) == 30 + 60  # every one written
    forger = Codec(521, 2)  # in Slash A's name
    rows_before = len(message_rows(runtime))
    t = 30.3
    for n in range(FLOOD):
        status = AgentStatus(2, GPS0, 30.6, -96.4, 0.0, 1.0, 0.0, 90.0, 4)
        (data,) = forger.encode([status], 0, 256)
        runtime.deliver(PacketReceived(data), t)
        if n % 1000 == 999:  # 10^4 packets a second
            tick(runtime, t, station.heartbeat(t))
            t = round(t + 0.1, 1)
    for _ in range(int(AIR_SUMMARY_S * 10) + 5):
        tick(runtime, t, station.heartbeat(t))
        t = round(t + 0.1, 1)
    forged = [r for r in message_rows(runtime)[rows_before:] if ",slash_a," in r]
    assert len(forged) <= 2 * AIR_SUMMARY_S * (2 * 3 + 2 * 10), len(forged)
    summary = [line for line in interface_lines(runtime) if "beyond their configured rates" in line]
    assert summary and "slash_a" in summary[0], interface_lines(runtime)[-5:]
