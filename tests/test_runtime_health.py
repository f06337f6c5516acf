"""Vehicle Health from the runtime: what it says, when it goes, and that nothing breaks it.

A vehicle's runtime fills Vehicle Health from its autopilot's events (AutopilotHealth,
AutopilotText, its heartbeats) and its own failsafe, and sends it at the rate its
telemetry declares; cooperative_follow's rovers send it to the station every 2 s. The
station decodes it with a real codec, as its fleet table would.
"""

from __future__ import annotations

from pathlib import Path

from test_runtime import GPS0, ROOT, Peer, config_of, run, vehicle

from clark_engine.link.codec import Codec
from clark_engine.link.messages import (
    MAX_FAILSAFE_TEXT_BYTES,
    MAX_HEALTH_TEXT_BYTES,
    AgentType,
    PrearmState,
    VehicleHealth,
)
from clark_engine.runtime.commands import SendPacket
from clark_engine.runtime.events import (
    AutopilotHealth,
    AutopilotHeartbeat,
    AutopilotText,
    PacketReceived,
)
from clark_engine.runtime.runtime import AgentRuntime

SITL_HEALTH = AutopilotHealth(
    battery_v=12.6, battery_pct=100, gps_fix_type=6, satellites=10, prearm_ok=True
)
"""What ArduRover SITL reports once it has a fix (docs/clarklink.md, Vehicle Health)."""


def slash_b() -> AgentRuntime:
    return AgentRuntime(config_of("cooperative_follow.yaml", "slash_b"))


def healths(out: list[object]) -> list[VehicleHealth]:
    """Every Vehicle Health the runtime sent to the station (mcs, id 1), decoded."""
    station = Codec(521, 1)
    found: list[VehicleHealth] = []
    for command in out:
        if isinstance(command, SendPacket) and command.destination == "mcs":
            found += [
                m for m in station.decode(command.data).messages if isinstance(m, VehicleHealth)
            ]
    return found


def ticks(runtime: AgentRuntime, start_s: float, end_s: float) -> list[object]:
    """Tick at the mission's 10 Hz from ``start_s`` to ``end_s`` (both included)."""
    out: list[object] = []
    for k in range(round(start_s * 10), round(end_s * 10) + 1):
        out += runtime.tick(k / 10)
    return out


def test_health_goes_to_the_station_every_two_seconds() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    sent: dict[float, list[VehicleHealth]] = {}
    for k in range(0, 41):
        t = k / 10
        out = run(runtime, t, SITL_HEALTH, AutopilotHeartbeat("MANUAL", 0, False))
        out += runtime.deliver(station.heartbeat(t), t)
        if healths(out):
            sent[t] = healths(out)
    assert list(sent) == [0.0, 2.0, 4.0]  # vehicle_health: {rate_hz: 0.5, to: [mcs]}
    (first,) = sent[0.0]
    assert first == VehicleHealth(
        agent_id=3,
        gps_time_ms=first.gps_time_ms,
        armed=False,
        battery_v=12.6,
        battery_pct=100,
        gps_fix_type=6,
        satellites=10,
        prearm=PrearmState.PASSING,
    )


def test_before_the_autopilot_speaks_every_figure_is_unknown() -> None:
    runtime = slash_b()
    (health,) = healths(runtime.tick(0.0))
    assert (health.battery_v, health.battery_pct, health.satellites) == (None, None, None)
    assert health.prearm is PrearmState.UNKNOWN and health.gps_fix_type == 0
    assert not health.armed and not health.autopilot_lost


def test_armed_follows_the_autopilot_heartbeat_even_without_a_position() -> None:
    # Before the GPS fix there is no VehicleState; an operator still sees the arming.
    runtime = slash_b()
    runtime.deliver(AutopilotHeartbeat("MANUAL", 0, True), 0.0)
    (health,) = healths(runtime.tick(0.0))
    assert health.armed
    runtime.deliver(AutopilotHeartbeat("MANUAL", 0, False), 1.0)
    (health,) = healths(ticks(runtime, 0.1, 2.0))
    assert not health.armed


def test_the_latest_warning_is_carried_with_its_age_and_notices_are_not() -> None:
    runtime = slash_b()
    runtime.deliver(AutopilotText(2, "PreArm: Need Position Estimate"), 0.0)
    runtime.deliver(AutopilotText(6, "EKF3 IMU0 origin set"), 0.5)  # INFO: not a warning
    runtime.deliver(AutopilotHealth(prearm_ok=False, gps_fix_type=1, satellites=3), 0.5)
    (health,) = healths(runtime.tick(0.0))
    assert (health.text_severity, health.text) == (2, "PreArm: Need Position Estimate")
    assert health.prearm is PrearmState.FAILING
    *_, health = healths(ticks(runtime, 0.1, 12.0))
    assert health.text == "PreArm: Need Position Estimate" and health.text_age_s == 12
    runtime.deliver(AutopilotText(4, "GPS Glitch"), 12.5)
    (health,) = healths(ticks(runtime, 12.1, 14.0))
    assert (health.text_severity, health.text, health.text_age_s) == (4, "GPS Glitch", 1)


def test_a_hostile_text_is_cut_to_its_bound_and_still_sent() -> None:
    runtime = slash_b()
    runtime.deliver(AutopilotText(0, "\N{SKULL}" * 40 + "\n<script>x</script>"), 0.0)
    (health,) = healths(runtime.tick(0.0))
    assert len(health.text.encode("utf-8")) <= MAX_HEALTH_TEXT_BYTES
    assert health.text == "\N{SKULL}" * 12  # 48 bytes: a 13th would not fit whole
    assert health.text_severity == 0  # EMERGENCY


def test_garbled_figures_are_sent_as_unknown_never_stop_the_tick() -> None:
    runtime = slash_b()
    bad = AutopilotHealth(battery_v=70.0, battery_pct=250, gps_fix_type=77, satellites=300)
    runtime.deliver(bad, 0.0)
    (health,) = healths(runtime.tick(0.0))
    assert (health.battery_v, health.battery_pct, health.satellites) == (None, None, None)
    assert health.gps_fix_type == 0


def test_the_failsafe_in_force_and_why() -> None:
    runtime = slash_b()
    station = Peer(521, 1, AgentType.MCS)
    t = 0.0
    run(runtime, t, vehicle(t), AutopilotHeartbeat("MANUAL", 0, True), station.heartbeat(t))
    out: list[object] = []
    while t < 6.0:  # the station falls silent: mcs_lost after heartbeat_timeout_s (3 s)
        t = round(t + 0.1, 1)
        out += run(runtime, t, AutopilotHeartbeat("HOLD", 4, True))
    assert runtime.failsafe == "hold" and runtime.failsafe_reason == "mcs_lost"
    last = healths(out)[-1]
    assert last.failsafe == "hold: mcs_lost"
    assert len(last.failsafe.encode()) <= MAX_FAILSAFE_TEXT_BYTES
    assert healths(out)[0].failsafe == ""  # at 2 s, before the loss was found


def test_a_lost_autopilot_is_said_with_the_last_figures() -> None:
    runtime = slash_b()
    runtime.deliver(SITL_HEALTH, 0.0)
    runtime.deliver(AutopilotHeartbeat("MANUAL", 0, True), 0.0)
    out = ticks(runtime, 0.0, 4.0)  # the autopilot falls silent (its timeout is 3 s)
    last = healths(out)[-1]
    assert last.autopilot_lost and last.battery_v == 12.6 and last.armed


def test_a_station_sends_no_vehicle_health_even_when_told_to(tmp_path: Path) -> None:
    text = (ROOT / "missions" / "cooperative_follow.yaml").read_text()
    text = text.replace(
        "    telemetry: {heartbeat: 1}\n", "    telemetry: {heartbeat: 1, vehicle_health: 1}\n", 1
    )
    station = AgentRuntime(config_of("cooperative_follow.yaml", "mcs", text, tmp_path))
    listener = Codec(521, 99)
    sent = [
        m
        for c in station.tick(0.0)
        if isinstance(c, SendPacket)
        for m in listener.decode(c.data).messages
    ]
    assert sent and not any(isinstance(m, VehicleHealth) for m in sent)


def test_the_station_s_fleet_table_keeps_the_latest_health() -> None:
    vehicle_runtime = slash_b()
    station = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    for k in range(0, 21):
        t = k / 10
        vehicle_runtime.deliver(AutopilotHealth(battery_v=12.6 - t / 10, battery_pct=99), t)
        for command in vehicle_runtime.tick(t):
            if isinstance(command, SendPacket):
                station.deliver(PacketReceived(command.data), t)
    got = station.fleet.peek(3, VehicleHealth)
    assert got is not None and got.battery_v == 12.4
    row = dict(zip(station.fleet.csv_header(), station.fleet.csv_rows(2.0)[0], strict=True))
    assert row["battery_v"] == 12.4 and row["rx_vehicle_health"] == 2


def test_a_forged_line_in_a_text_stays_one_csv_cell_on_one_line() -> None:
    vehicle_runtime = slash_b()
    station = AgentRuntime(config_of("cooperative_follow.yaml", "mcs"), gps_epoch_ms=GPS0)
    vehicle_runtime.deliver(AutopilotText(4, "ok\n9.9,1,forged,row\r\x1b[31m"), 0.0)
    for command in vehicle_runtime.tick(0.0):
        if isinstance(command, SendPacket):
            station.deliver(PacketReceived(command.data), 0.0)
    row = dict(
        zip(station.fleet.csv_header(), station.fleet.csv_rows(0.1, text=True)[0], strict=True)
    )
    assert row["autopilot_text"] == "ok\\x0a9.9,1,forged,row\\x0d\\x1b[31m"
    assert row["autopilot_severity"] == "4" and row["prearm"] == "unknown"
