"""The fleet table: records on heartbeat, latest values and flags, timeouts, link statistics."""

from __future__ import annotations

import csv
import io
import statistics

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clark_engine.link.errors import (
    BadTag,
    BadVersion,
    ForeignMission,
    MalformedPacket,
    ReplayedPacket,
    TruncatedPacket,
)
from clark_engine.link.fleet import (
    MAX_FOREIGN_REPORTS,
    MAX_RECENT_UNKNOWN,
    AgentFound,
    AgentLost,
    CsvValue,
    FleetTable,
    ForeignAgent,
)
from clark_engine.link.link_stats import COUNTER_WINDOW, MAX_COUNTED_GAP, LinkStats
from clark_engine.link.messages import (
    MESSAGE_NAMES,
    AgentAttitude,
    AgentStatus,
    AgentType,
    Condition,
    Heartbeat,
    Message,
    PictureData,
)
from clark_engine.link.packet import MAX_COUNTER, Packet

MISSION = 7
OWN = 2
GPS_MS = 1_400_000_000_000  # a GPS time in ms, far from zero


def hb(
    agent: int,
    t_ms: int = GPS_MS,
    mission: int = MISSION,
    kind: AgentType = AgentType.VEHICLE,
    condition: Condition = Condition.OK,
) -> Heartbeat:
    return Heartbeat(agent, t_ms, mission, kind, condition)


def status(agent: int, t_ms: int = GPS_MS, lat_deg: float = 30.6, mode: int = 4) -> AgentStatus:
    return AgentStatus(agent, t_ms, lat_deg, -96.4, 12.5, 3.0, 0.1, 90.0, mode)


def attitude(agent: int, t_ms: int = GPS_MS) -> AgentAttitude:
    return AgentAttitude(agent, t_ms, 1.5, -2.0, 90.0)


def packet(sender: int, counter: int, *messages: Message, authenticated: bool = True) -> Packet:
    return Packet(
        MISSION, sender, 0, counter, authenticated, tuple(messages), 16 + 20 * len(messages)
    )


@pytest.fixture
def table() -> FleetTable:
    return FleetTable(OWN, MISSION, heartbeat_timeout_s=3.0, expected={1: "mcs", 3: "slash_b"})


def test_record_only_on_first_heartbeat(table: FleetTable) -> None:
    assert table.receive(packet(3, 1, status(3)), 0.0, GPS_MS) == []
    assert table.record(3) is None
    assert table.read(3, AgentStatus) is None
    stats = table.stats(3)
    assert stats is not None and stats.packets == 1 and stats.messages == {"agent_status": 1}

    events = table.receive(packet(3, 2, hb(3)), 1.0, GPS_MS)
    assert events == [AgentFound(3, "slash_b", AgentType.VEHICLE, rejoined=False)]
    record = table.record(3)
    assert record is not None and record.found_s == 1.0 and record.last_heartbeat_s == 1.0
    assert table.read(3, AgentStatus) is None  # the earlier status was not kept
    assert table.receive(packet(3, 3, hb(3)), 2.0, GPS_MS) == []  # found once
    assert [r.agent_id for r in table.agents()] == [3]


def test_first_heartbeat_stores_the_rest_of_its_bundle_whatever_the_order(
    table: FleetTable,
) -> None:
    table.receive(packet(3, 1, status(3), hb(3)), 0.0, GPS_MS)
    assert table.peek(3, AgentStatus) == status(3)


def test_without_peer_table_agent_added_on_heartbeat_with_empty_name() -> None:
    table = FleetTable(OWN, MISSION, heartbeat_timeout_s=3.0)
    table.receive(packet(9, 5, status(9)), 0.0, GPS_MS)
    assert table.stats(9) is None
    assert table.unattributed.packets == 1
    events = table.receive(packet(9, 6, hb(9, kind=AgentType.MCS), status(9)), 1.0, GPS_MS)
    assert events == [AgentFound(9, "", AgentType.MCS, rejoined=False)]
    stats = table.stats(9)
    assert stats is not None and stats.packets == 1 and stats.lost == 0
    assert table.unattributed.packets == 1
    table.receive(packet(9, 8, status(9)), 2.0, GPS_MS)
    assert stats.lost == 1  # counted from the packet that added it


def test_latest_value_receive_time_and_new_flag(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3), status(3, GPS_MS, 30.1)), 10.0, GPS_MS)
    assert table.is_new(3, AgentStatus)
    assert table.peek(3, AgentStatus) == status(3, GPS_MS, 30.1)
    assert table.is_new(3, AgentStatus)  # peek does not clear
    assert table.read(3, AgentStatus) == status(3, GPS_MS, 30.1)
    assert not table.is_new(3, AgentStatus)
    assert table.read(3, AgentStatus) == status(3, GPS_MS, 30.1)  # still there, not new

    table.receive(packet(3, 2, status(3, GPS_MS + 500, 30.2)), 10.5, GPS_MS + 520)
    assert table.is_new(3, AgentStatus)
    record = table.record(3)
    assert record is not None
    sample = record.sample(AgentStatus)
    assert sample is not None
    assert sample.received_s == 10.5 and sample.gps_time_ms == GPS_MS + 500
    assert sample.counter == 2 and sample.authenticated
    assert sample.value.lat_deg == 30.2
    assert table.is_new(3, Heartbeat) and not table.is_new(3, AgentAttitude)
    assert table.read(3, AgentAttitude) is None
    assert table.read(99, AgentStatus) is None and not table.is_new(99, AgentStatus)


def test_reordered_packet_does_not_overwrite_newer_value(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3)), 0.0, GPS_MS)
    table.receive(packet(3, 3, status(3, lat_deg=30.3)), 1.0, GPS_MS)
    table.read(3, AgentStatus)
    table.receive(packet(3, 2, status(3, lat_deg=30.2), attitude(3)), 1.1, GPS_MS)
    assert table.peek(3, AgentStatus) == status(3, lat_deg=30.3)
    assert not table.is_new(3, AgentStatus)
    assert table.peek(3, AgentAttitude) == attitude(3)  # nothing newer of that type


def test_own_packets_ignored(table: FleetTable) -> None:
    assert table.receive(packet(OWN, 1, hb(OWN), status(OWN)), 0.0, GPS_MS) == []
    assert table.agents() == [] and table.stats(OWN) is None
    assert table.unattributed.packets == 0


def test_message_claiming_another_agent_is_dropped(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3), status(1), hb(1)), 0.0, GPS_MS)
    assert table.record(1) is None
    assert table.peek(3, AgentStatus) is None
    stats = table.stats(3)
    assert stats is not None and stats.misattributed == 2 and stats.messages == {"heartbeat": 1}


def test_timeout_reported_once_then_found_again(table: FleetTable) -> None:
    table.receive(packet(1, 1, hb(1, kind=AgentType.MCS), status(1)), 0.0, GPS_MS)
    assert table.check_timeouts(3.0) == []  # not longer than the timeout yet
    assert table.check_timeouts(3.25) == [AgentLost(1, "mcs", AgentType.MCS, 3.25)]
    assert table.check_timeouts(4.0) == []
    record = table.record(1)
    assert record is not None and record.lost
    assert table.peek(1, AgentStatus) == status(1)  # last data kept

    table.receive(packet(1, 2, status(1, lat_deg=31.0)), 5.0, GPS_MS)
    assert record.lost  # only a heartbeat brings it back
    assert table.peek(1, AgentStatus) == status(1, lat_deg=31.0)
    events = table.receive(packet(1, 3, hb(1, kind=AgentType.MCS)), 6.0, GPS_MS)
    assert events == [AgentFound(1, "mcs", AgentType.MCS, rejoined=True)]
    assert not record.lost
    assert table.check_timeouts(9.0) == []
    assert [e.agent_id for e in table.check_timeouts(9.5)] == [1]


def test_timeouts_only_for_silent_agents(table: FleetTable) -> None:
    table.receive(packet(1, 1, hb(1)), 0.0, GPS_MS)
    table.receive(packet(3, 1, hb(3)), 2.0, GPS_MS)
    table.receive(packet(3, 2, status(3)), 4.5, GPS_MS)  # not a heartbeat
    assert [e.agent_id for e in table.check_timeouts(4.0)] == [1]
    assert [e.agent_id for e in table.check_timeouts(5.5)] == [3]


def test_foreign_heartbeat_reported_once_and_never_added(table: FleetTable) -> None:
    events = table.receive(packet(3, 1, hb(3, mission=8), status(3)), 0.0, GPS_MS)
    assert events == [ForeignAgent(3, "slash_b", 8)]
    assert table.receive(packet(3, 2, hb(3, mission=8)), 1.0, GPS_MS) == []
    assert table.receive(packet(3, 3, hb(3)), 2.0, GPS_MS) == []  # contradicted itself: never
    assert table.record(3) is None and table.agents() == []
    stats = table.stats(3)
    assert stats is not None and stats.foreign == 3


def test_foreign_heartbeat_from_known_agent_stops_its_updates(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3), status(3, lat_deg=30.1)), 0.0, GPS_MS)
    events = table.receive(packet(3, 2, hb(3, mission=9), status(3, lat_deg=30.2)), 1.0, GPS_MS)
    assert events == [ForeignAgent(3, "slash_b", 9)]
    assert table.peek(3, AgentStatus) == status(3, lat_deg=30.1)
    assert [e.agent_id for e in table.check_timeouts(3.5)] == [3]


def test_counter_gaps_count_losses_and_late_packets_fill_them() -> None:
    stats = _stats_after([10, 11, 14, 15])
    assert (stats.lost, stats.packets, stats.duplicates) == (2, 4, 0)
    assert stats.loss_ratio == pytest.approx(2 / 6)
    stats = _stats_after([10, 11, 14, 13, 15, 12])
    assert (stats.lost, stats.packets, stats.duplicates) == (0, 6, 0)
    assert stats.loss_ratio == 0.0


def test_duplicates_counted_once_and_not_applied(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3)), 0.0, GPS_MS)
    table.receive(packet(3, 3, status(3, lat_deg=30.3)), 1.0, GPS_MS)
    table.read(3, AgentStatus)
    for counter in (3, 1, 3):
        assert table.receive(packet(3, counter, hb(3), status(3)), 2.0, GPS_MS) == []
    table.note_error(ReplayedPacket("replay", sender_id=3, mission_id=MISSION), 2.0)
    stats = table.stats(3)
    assert stats is not None
    assert (stats.duplicates, stats.packets, stats.lost) == (4, 2, 1)
    assert not table.is_new(3, AgentStatus)
    record = table.record(3)
    assert record is not None and record.last_heartbeat_s == 0.0  # a duplicate proves nothing


def test_packet_before_the_first_seen_is_no_fill() -> None:
    stats = _stats_after([100, 99, 101])
    assert (stats.lost, stats.packets, stats.duplicates) == (0, 3, 0)
    stats = _stats_after([100, 99, 99])
    assert stats.duplicates == 1


def test_packet_older_than_the_window_is_applied_in_arrival_order(table: FleetTable) -> None:
    table.receive(packet(3, 1000, hb(3), status(3, lat_deg=30.1)), 0.0, GPS_MS)
    old = 1000 - COUNTER_WINDOW
    table.receive(packet(3, old, status(3, lat_deg=30.0)), 1.0, GPS_MS)
    stats = table.stats(3)
    assert stats is not None and (stats.out_of_window, stats.duplicates) == (1, 0)
    assert table.peek(3, AgentStatus) == status(3, lat_deg=30.0)
    window_edge = _stats_after([1000, 1000 - COUNTER_WINDOW + 1, 1000 - COUNTER_WINDOW + 1])
    assert (window_edge.duplicates, window_edge.out_of_window) == (1, 0)


def test_huge_counter_jump_is_a_resync_not_losses() -> None:
    stats = _stats_after([5, 5 + MAX_COUNTED_GAP + 1, 5 + MAX_COUNTED_GAP + 3])
    assert (stats.resyncs, stats.lost) == (1, 1)
    stats = _stats_after([5, 5 + MAX_COUNTED_GAP])
    assert (stats.resyncs, stats.lost) == (0, MAX_COUNTED_GAP - 1)


def test_48_bit_counters_near_the_top() -> None:
    top = MAX_COUNTER
    stats = _stats_after([top - 10, top - 7, top - 8, top])
    assert (stats.lost, stats.packets, stats.duplicates) == (7, 4, 0)  # 11 sent, 4 came
    stats = _stats_after([top - 3, top, top])
    assert (stats.lost, stats.duplicates) == (2, 1)


def test_latency_statistics_exact() -> None:
    table = FleetTable(OWN, MISSION, 3.0, {3: "slash_b"})
    latencies_ms = [40, 15, 90, 25, 60]
    for i, latency_ms in enumerate(latencies_ms, start=1):
        stamp = GPS_MS + 1000 * i
        table.receive(packet(3, i, hb(3, stamp)), float(i), stamp + latency_ms)
    stats = table.stats(3)
    assert stats is not None and stats.latency_count == 5
    assert stats.latency_mean_ms == statistics.mean(latencies_ms) == 46
    assert stats.latency_std_ms == pytest.approx(statistics.stdev(latencies_ms), rel=1e-12)
    assert (stats.latency_min_ms, stats.latency_max_ms) == (15, 90)


def test_latency_skips_unknown_times_and_picture_capture_stamps(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3)), 0.0, None)  # receiver has no GPS time yet
    table.receive(packet(3, 2, status(3, t_ms=0)), 1.0, GPS_MS)  # unstamped
    picture = PictureData(3, GPS_MS - 5000, 30.6, -96.4, 50.0, image_index=1)
    table.receive(packet(3, 3, picture, attitude(3, GPS_MS - 30)), 2.0, GPS_MS)
    stats = table.stats(3)
    assert stats is not None and stats.latency_count == 1 and stats.latency_mean_ms == 30
    assert stats.latency_std_ms is None
    assert table.peek(3, PictureData) == picture


def test_negative_latency_is_kept_to_show_clock_skew(table: FleetTable) -> None:
    table.receive(packet(3, 1, hb(3, GPS_MS + 20)), 0.0, GPS_MS)
    stats = table.stats(3)
    assert stats is not None and stats.latency_min_ms == -20


def test_note_error_counts_against_the_claimed_sender(table: FleetTable) -> None:
    assert table.note_error(BadTag("forged", sender_id=3, mission_id=MISSION), 1.0) == []
    table.note_error(BadTag("forged", sender_id=3, mission_id=MISSION), 2.0)
    table.note_error(MalformedPacket("bad bundle", sender_id=3), 2.5)
    table.note_error(BadVersion("v9", sender_id=3), 2.6)
    table.note_error(TruncatedPacket("short"), 3.0)  # no header: no sender
    table.note_error(BadTag("forged", sender_id=42, mission_id=MISSION), 3.0)
    stats = table.stats(3)
    assert stats is not None
    assert (stats.bad_tags, stats.malformed, stats.packets) == (2, 2, 0)
    assert stats.last_rejected_s == 2.6
    assert (table.unattributed.malformed, table.unattributed.bad_tags) == (1, 1)
    assert table.record(3) is None and table.stats(42) is None


def test_foreign_mission_errors_reported_once_per_sender_and_mission(table: FleetTable) -> None:
    first = table.note_error(ForeignMission("other", sender_id=3, mission_id=8), 0.0)
    assert first == [ForeignAgent(3, "slash_b", 8)]
    assert table.note_error(ForeignMission("other", sender_id=3, mission_id=8), 1.0) == []
    assert table.note_error(ForeignMission("other", sender_id=3, mission_id=9), 1.0) == [
        ForeignAgent(3, "slash_b", 9)
    ]
    assert table.note_error(ForeignMission("other", sender_id=50, mission_id=8), 1.0) == [
        ForeignAgent(50, "", 8)
    ]
    assert table.note_error(ForeignMission("other"), 1.0) == []  # no sender to name
    # the same pair seen again inside a packet of ours is not reported twice
    assert table.receive(packet(3, 1, hb(3, mission=8)), 2.0, GPS_MS) == []
    assert table.agents() == []
    stats = table.stats(3)
    assert stats is not None and stats.foreign == 4
    assert table.unattributed.foreign == 2


def test_foreign_reports_are_bounded(table: FleetTable) -> None:
    events = [
        event
        for mission in range(100, 100 + MAX_FOREIGN_REPORTS + 50)
        for event in table.note_error(ForeignMission("x", sender_id=5, mission_id=mission), 0.0)
    ]
    assert len(events) == MAX_FOREIGN_REPORTS
    assert table.unattributed.foreign == MAX_FOREIGN_REPORTS + 50


def test_a_sender_that_left_another_mission_joins_on_its_heartbeat(table: FleetTable) -> None:
    table.note_error(ForeignMission("other", sender_id=3, mission_id=8), 0.0)
    events = table.receive(packet(3, 1, hb(3)), 1.0, GPS_MS)
    assert events == [AgentFound(3, "slash_b", AgentType.VEHICLE, rejoined=False)]


def test_csv_rows_stable(table: FleetTable) -> None:
    header = table.csv_header()
    assert header == FleetTable.csv_header() and len(header) == len(set(header))
    assert header[:6] == [
        "agent_id",
        "name",
        "agent_type",
        "condition",
        "lost",
        "since_heartbeat_s",
    ]
    for name in MESSAGE_NAMES.values():
        assert f"rx_{name}" in header
    table.receive(packet(1, 1, hb(1, kind=AgentType.MCS)), 0.0, GPS_MS)
    table.receive(packet(3, 1, hb(3, condition=Condition.DEGRADED), status(3)), 1.0, GPS_MS + 10)
    table.receive(packet(3, 2, attitude(3)), 2.0, GPS_MS + 30)
    rows = table.csv_rows(4.0)
    assert rows == table.csv_rows(4.0)
    assert [len(row) for row in rows] == [len(header)] * 2
    by_column = [dict(zip(header, row, strict=True)) for row in rows]
    station, cub = by_column
    assert (cub["agent_id"], cub["name"], cub["agent_type"]) == (3, "slash_b", "vehicle")
    assert (cub["condition"], cub["lost"], cub["since_heartbeat_s"]) == ("degraded", 0, 3.0)
    assert (cub["lat_deg"], cub["heading_deg"], cub["mode"], cub["status_age_s"]) == (
        30.6,
        90.0,
        4,
        3.0,
    )
    assert (cub["roll_deg"], cub["pitch_deg"], cub["yaw_deg"]) == (1.5, -2.0, 90.0)
    assert (cub["packets"], cub["rx_agent_status"], cub["rx_agent_attitude"]) == (2, 1, 1)
    assert (cub["lost_packets"], cub["loss_ratio"], cub["since_packet_s"]) == (0, 0.0, 2.0)
    assert (cub["latency_count"], cub["latency_min_ms"], cub["latency_max_ms"]) == (3, 10, 30)
    assert cub["since_rejected_s"] == ""
    assert (station["agent_id"], station["name"], station["agent_type"]) == (1, "mcs", "mcs")
    assert station["lat_deg"] == station["roll_deg"] == station["latency_std_ms"] == ""
    table.check_timeouts(10.0)
    assert [row[header.index("lost")] for row in table.csv_rows(10.0)] == [1, 1]


def test_tables_share_nothing() -> None:
    a = FleetTable(1, MISSION, 3.0)
    b = FleetTable(2, MISSION, 3.0)
    a.receive(packet(3, 1, hb(3)), 0.0, GPS_MS)
    assert b.agents() == [] and b.unattributed.packets == 0


def test_timeout_must_be_positive() -> None:
    with pytest.raises(ValueError, match="heartbeat_timeout_s"):
        FleetTable(OWN, MISSION, 0.0)


def _stats_after(counters: list[int]) -> LinkStats:
    """Link statistics of peer 3 after packets with these counters (first one adds it)."""
    table = FleetTable(OWN, MISSION, 3.0)
    for counter in counters:
        table.receive(packet(3, counter, hb(3)), 0.0, GPS_MS)
    stats = table.stats(3)
    assert stats is not None
    return stats


def csv_text(rows: list[list[CsvValue]]) -> str:
    buffer = io.StringIO()
    csv.writer(buffer, lineterminator="\n").writerows(rows)
    return buffer.getvalue()


EVENT = st.one_of(
    # (kind, agent, counter step, GPS lateness in ms, a figure)
    st.tuples(
        st.just("heartbeat"),
        st.sampled_from([1, 3, 4]),
        st.integers(-3, 4),
        st.integers(-50, 400),
        st.floats(-1e3, 1e3, allow_nan=False),
    ),
    st.tuples(
        st.just("status"),
        st.sampled_from([1, 3, 4]),
        st.integers(-3, 4),
        st.integers(-50, 400),
        st.floats(-1e3, 1e3, allow_nan=False),
    ),
    st.tuples(
        st.just("attitude"),
        st.sampled_from([3, 4]),
        st.integers(-3, 4),
        st.integers(0, 400),
        st.floats(-180, 180, allow_nan=False),
    ),
    st.tuples(st.just("error"), st.sampled_from([3, 4, 9]), st.just(0), st.just(0), st.just(0.0)),
    st.tuples(st.just("wait"), st.just(0), st.just(0), st.just(0), st.floats(0.01, 5.0)),
)


@settings(max_examples=60, deadline=None)
@given(st.lists(EVENT, max_size=40))
def test_csv_rows_as_text_write_the_same_csv(
    events: list[tuple[str, int, int, int, float]],
) -> None:
    """The cached text cells of csv_rows(text=True) write what the values write, byte for byte."""
    table = FleetTable(OWN, MISSION, heartbeat_timeout_s=3.0, expected={1: "mcs", 3: "slash_b"})
    now_s = 0.0
    counters = {1: 100, 3: 100, 4: 100, 9: 100}
    for kind, agent, step, late_ms, figure in events:
        if kind == "wait":
            now_s += figure
            table.check_timeouts(now_s)
        elif kind == "error":
            table.note_error(BadTag("forged", sender_id=agent, mission_id=MISSION), now_s)
        else:
            counters[agent] = max(0, counters[agent] + step)
            stamp = GPS_MS + round(now_s * 1000) - late_ms
            message: Message = (
                hb(agent, stamp)
                if kind == "heartbeat"
                else status(agent, stamp, lat_deg=figure / 10)
                if kind == "status"
                else AgentAttitude(agent, stamp, figure, -figure, 0.0)
            )
            table.receive(
                packet(agent, counters[agent], message), now_s, GPS_MS + round(now_s * 1000)
            )
        assert csv_text(table.csv_rows(now_s, text=True)) == csv_text(table.csv_rows(now_s))


def test_csv_rows_as_text_follow_every_change(table: FleetTable) -> None:
    """Each kept group of text cells is made again when its values change."""
    steps: list[tuple[float, Packet | None]] = [
        (0.0, packet(3, 1, hb(3), status(3, lat_deg=30.1))),
        (0.5, packet(3, 2, status(3, GPS_MS + 500, lat_deg=30.2))),  # a new status
        (0.7, packet(3, 3, attitude(3, GPS_MS + 650))),
        (0.9, packet(3, 4, AgentAttitude(3, GPS_MS + 880, -4.0, 2.5, 180.0))),  # new attitude
        (1.0, packet(1, 7, hb(1, GPS_MS + 900, kind=AgentType.MCS))),
        (1.2, None),  # a forged packet: a counter moves, nothing else
        (1.4, packet(3, 9, hb(3, GPS_MS + 1300))),  # four packets lost: loss ratio moves
        (9.0, None),
    ]
    written: list[str] = []
    for now_s, received in steps:
        if received is None:
            table.note_error(BadTag("forged", sender_id=3, mission_id=MISSION), now_s)
            table.check_timeouts(now_s)
        else:
            table.receive(received, now_s, GPS_MS + round(now_s * 1000))
        text = csv_text(table.csv_rows(now_s, text=True))
        assert text == csv_text(table.csv_rows(now_s))
        written.append(text)
    assert "30.2" in written[1] and "30.1" not in written[1]
    assert "-4.0" in written[3]
    assert len(set(written)) == len(written)


# ------------------------------------------- unauthenticated counters (issue 10, item 5)


def _unkeyed_stats_after(counters: list[int]) -> LinkStats:
    """Link statistics of peer 3 after unauthenticated packets with these counters."""
    table = FleetTable(OWN, MISSION, 3.0, {3: "slash_b"})
    for counter in counters:
        table.receive(packet(3, counter, hb(3), authenticated=False), 0.0, GPS_MS)
    stats = table.stats(3)
    assert stats is not None
    return stats


@pytest.mark.parametrize("garbled", [1 << 40, 10 + 5_000, 10 + COUNTER_WINDOW + 1])
def test_one_garbled_counter_ahead_does_not_spoil_the_statistics(garbled: int) -> None:
    # One counter garbled on the way (a flipped bit) between two runs of genuine ones: the
    # codec's window restarts on the next genuine packet, and so must the loss accounting.
    stats = _unkeyed_stats_after([*range(1, 11), garbled, *range(11, 301)])
    assert (stats.lost, stats.out_of_window, stats.resyncs) == (0, 0, 0)
    assert stats.outliers == 1 and stats.packets == 301
    assert stats.loss_ratio == 0.0


def test_one_garbled_counter_behind_does_not_spoil_the_statistics() -> None:
    stats = _unkeyed_stats_after([*range(1000, 1011), 3, *range(1011, 1100)])
    assert (stats.lost, stats.resyncs, stats.outliers) == (0, 0, 0)
    assert stats.out_of_window == 1  # the garbled counter itself, as a straggler would be


def test_unkeyed_sender_restart_is_confirmed_by_the_next_packet() -> None:
    # A sender without a counter store restarts at 1: a new sequence, not 100 stragglers.
    stats = _unkeyed_stats_after([*range(500, 600), *range(1, 101)])
    assert (stats.lost, stats.out_of_window, stats.resyncs, stats.outliers) == (0, 0, 1, 0)
    jumped = _unkeyed_stats_after([*range(1, 11), *range(5_010, 5_020)])
    assert (jumped.lost, jumped.out_of_window, jumped.outliers) == (4_999, 0, 0)


def test_authenticated_jump_is_trusted_at_once() -> None:
    # A tag vouches for the counter: no confirmation needed.
    stats = _stats_after([1, 1 + COUNTER_WINDOW + 5])
    assert (stats.lost, stats.outliers) == (COUNTER_WINDOW + 4, 0)


# ------------------------------------------------ senders not in the mission (item 4)


def test_forged_ids_never_get_a_record(table: FleetTable) -> None:
    # Heartbeats of our mission from 5,000 ids that are not in its peer table.
    events = []
    for n, forged in enumerate(range(100, 5_100)):
        events += table.receive(packet(forged, n + 1, hb(forged), status(forged)), 0.0, GPS_MS)
    assert events == [] and table.agents() == []
    assert all(table.stats(forged) is None for forged in range(100, 5_100))
    assert table.unknown_packets == 5_000 and table.unattributed.packets == 5_000
    assert list(table.recent_unknown) == list(range(5_100 - MAX_RECENT_UNKNOWN, 5_100))
    assert table.csv_rows(0.0) == []
    # The peers of the mission are still admitted as before.
    assert table.receive(packet(3, 1, hb(3)), 0.0, GPS_MS) == [
        AgentFound(3, "slash_b", AgentType.VEHICLE, rejoined=False)
    ]


def test_unknown_senders_rejected_packets_are_counted_in_the_same_place(
    table: FleetTable,
) -> None:
    table.note_error(BadTag("forged", sender_id=4000, mission_id=MISSION), 1.0)
    table.receive(packet(4000, 1, hb(4000)), 2.0, GPS_MS)
    table.receive(packet(4001, 1, hb(4001)), 2.0, GPS_MS)
    table.receive(packet(4000, 2, hb(4000)), 3.0, GPS_MS)
    assert table.unknown_packets == 4 and table.unattributed.bad_tags == 1
    assert dict(table.recent_unknown) == {4001: 1, 4000: 3}  # least recently heard first
    assert table.agents() == []


def test_a_table_without_a_peer_table_admits_every_sender_of_the_mission() -> None:
    # (Tools replaying a message log; the runtime always gives the peer table.)
    table = FleetTable(OWN, MISSION, 3.0)
    table.receive(packet(40, 1, hb(40)), 0.0, GPS_MS)
    assert [r.agent_id for r in table.agents()] == [40] and table.unknown_packets == 0
