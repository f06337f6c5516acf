"""Missions: upload, download, clear and the current item; AUTO flying a rover's waypoints
and a copter's takeoff, waypoint and landing.

The protocol as a ground station sees it (measured on SITL): MISSION_COUNT is answered
with MISSION_REQUEST (#40, not MISSION_REQUEST_INT) item by item, then MISSION_ACK and
"Flight plan received"; the count includes home (item 0, always the current home);
MISSION_CURRENT's total leaves home out; after MISSION_CLEAR_ALL the count is 0.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from typing import Any

import pytest
from flight import disarmed, distance_m, here, moved, track, within
from harness import Peer, backends
from modesweep import Step, arm, command_texts, fast_heartbeats, set_mode
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

WAYPOINT = mavlink2.MAV_CMD_NAV_WAYPOINT
TAKEOFF = mavlink2.MAV_CMD_NAV_TAKEOFF
LAND = mavlink2.MAV_CMD_NAV_LAND
RELATIVE = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT

Item = tuple[int, float, float, float]
"""(MAV_CMD, latitude, longitude, metres above home) of an item to upload."""


def item_int(peer: Peer, seq: int, item: Item) -> Any:
    command, lat, lon, up_m = item
    frame = mavlink2.MAV_FRAME_GLOBAL if seq == 0 else RELATIVE
    return mavlink2.MAVLink_mission_item_int_message(
        peer.spec.system_id,
        1,
        seq,
        frame,
        command,
        0,
        1,
        0,
        0,
        0,
        0,
        round(lat * 1e7),
        round(lon * 1e7),
        up_m,
        mavlink2.MAV_MISSION_TYPE_MISSION,
    )


def upload(peer: Peer, items: Sequence[Item]) -> tuple[list[str], Any, tuple[str, ...]]:
    """Upload ``items`` (item 0 is home's place, replaced by the autopilot's home).

    Returns:
        The message type of each request, the MISSION_ACK, and the texts it caused.
    """
    mark = peer.mark()
    peer.send(
        mavlink2.MAVLink_mission_count_message(
            peer.spec.system_id, 1, len(items), mavlink2.MAV_MISSION_TYPE_MISSION
        )
    )
    requests: list[str] = []

    def asks(msg: Any) -> bool:
        """MISSION_REQUEST(_INT) or MISSION_ACK"""
        return msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK")

    while True:
        msg = peer.wait_for(asks, 5.0)
        if msg.get_type() == "MISSION_ACK":
            peer.run_for(0.5)
            return requests, msg, command_texts(peer.texts_since(mark))
        requests.append(msg.get_type())
        peer.send(item_int(peer, msg.seq, items[msg.seq]))


def download(peer: Peer) -> list[Any]:
    """The mission as MISSION_REQUEST_LIST and MISSION_REQUEST_INT read it back."""
    peer.send(mavlink2.MAVLink_mission_request_list_message(peer.spec.system_id, 1, 0))
    count = peer.wait_for("MISSION_COUNT", 5.0).count
    items = []
    for seq in range(count):
        peer.send(mavlink2.MAVLink_mission_request_int_message(peer.spec.system_id, 1, seq, 0))
        items.append(peer.wait_for("MISSION_ITEM_INT", 5.0, where=lambda m, s=seq: m.seq == s))
    return items


def clear(peer: Peer) -> Any:
    """MISSION_CLEAR_ALL; returns the MISSION_ACK."""
    peer.send(mavlink2.MAVLink_mission_clear_all_message(peer.spec.system_id, 1, 0))
    return peer.wait_for("MISSION_ACK", 5.0)


def mission_current(peer: Peer) -> tuple[int, int, int, int]:
    msg = peer.wait_for("MISSION_CURRENT", 3.0)
    return int(msg.seq), int(msg.total), int(msg.mission_state), int(msg.mission_mode)


@pytest.fixture
def missions(peer: Peer) -> Iterator[Peer]:
    """The peer with home set and MISSION_CURRENT at 2 Hz; the mission cleared after."""
    peer.wait_for("HOME_POSITION", 40.0, since=0)
    peer.message_interval("MISSION_CURRENT", 500_000)
    try:
        yield peer
    finally:
        clear(peer)
        peer.message_interval("MISSION_CURRENT", 0)


AFTER_UPLOAD = {
    "rover": mavlink2.MISSION_STATE_NOT_STARTED,
    "copter": mavlink2.MISSION_STATE_COMPLETE,
    "plane": mavlink2.MISSION_STATE_COMPLETE,
}
"""MISSION_CURRENT's state after an upload, once AUTO was tried with no mission: ArduCopter
(entered) and ArduPlane (entered, then RTL) completed the empty mission, and a complete
mission stays complete across a new upload; ArduRover refused AUTO."""


def test_upload_download_set_current_and_clear(missions: Peer) -> None:
    peer = missions
    manual = str(peer.spec.autopilot["manual_mode"])
    peer.set_mode("AUTO")  # with no mission (see AFTER_UPLOAD)
    peer.set_mode(manual)
    home = peer.wait_for("HOME_POSITION", 40.0, since=0)
    lat0, lon0 = home.latitude / 1e7, home.longitude / 1e7
    items: list[Item] = [(WAYPOINT, 1.0, 1.0, 123.0)]  # home's place: ignored
    items += [(WAYPOINT, *moved(lat0, lon0, 30.0 * n, 0.0), 10.0) for n in (1, 2, 3)]
    requests, ack, texts = upload(peer, items)
    assert requests == ["MISSION_REQUEST"] * 4
    assert ack.type == mavlink2.MAV_MISSION_ACCEPTED
    assert "6:Flight plan received" in texts
    back = download(peer)
    mark = peer.mark()
    peer.command_long(mavlink2.MAV_CMD_GET_HOME_POSITION)
    home = peer.wait_for("HOME_POSITION", 1.0, since=mark)  # home now (it moves)
    assert len(back) == 4
    assert back[0].frame == mavlink2.MAV_FRAME_GLOBAL
    assert abs(back[0].x - home.latitude) <= 2 and abs(back[0].y - home.longitude) <= 2
    for sent, got in zip(items[1:], back[1:], strict=True):
        assert (got.command, got.frame) == (WAYPOINT, RELATIVE)
        assert (got.x, got.y) == (round(sent[1] * 1e7), round(sent[2] * 1e7))
        assert got.z == pytest.approx(10.0)
    _seq, total, state, mode = mission_current(peer)
    assert (total, state, mode) == (3, AFTER_UPLOAD[peer.kind], 0)
    # The current item, by command: within the mission, or DENIED.
    ack = peer.command_long(mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT, 2)
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    peer.run_for(0.6)
    assert mission_current(peer)[0] == 2
    ack = peer.command_long(mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT, 9)
    assert ack.result == mavlink2.MAV_RESULT_DENIED
    # Cleared: nothing, not even home.
    assert clear(peer).type == mavlink2.MAV_MISSION_ACCEPTED
    peer.send(mavlink2.MAVLink_mission_request_list_message(peer.spec.system_id, 1, 0))
    assert peer.wait_for("MISSION_COUNT", 5.0).count == 0
    peer.run_for(0.6)
    assert mission_current(peer) == (0, 0, mavlink2.MISSION_STATE_NO_MISSION, 0)


ROVER_MISSION_S = 26.6
"""SITL: from arming in AUTO to "Mission Complete" on the rover's 3 waypoints (WP_SPEED 3)."""


def texts_of(peer: Peer, mark: int) -> list[str]:
    return [f"{s.severity}:{s.text}" for s in peer.texts_since(mark)]


@backends(kinds=("rover",))
def test_rover_drives_a_mission_in_auto(rover: Peer) -> None:
    peer = rover
    peer.message_interval("MISSION_CURRENT", 500_000)
    start = here(peer)
    o = (start.lat_deg, start.lon_deg)
    plan = [moved(*o, 20.0, 0.0), moved(*o, 20.0, 20.0), moved(*o, 5.0, 5.0)]
    try:
        upload(peer, [(WAYPOINT, *o, 0.0)] + [(WAYPOINT, *p, 0.0) for p in plan])
        mark = peer.mark()
        assert peer.set_mode("AUTO").result == mavlink2.MAV_RESULT_ACCEPTED
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
        armed_s = peer.now_s
        done = peer.wait_for(
            "STATUSTEXT", 120.0, where=lambda m: m.text == "Mission Complete", since=mark
        )
        reached = [m.seq for _, m in peer.history[mark:] if m.get_type() == "MISSION_ITEM_REACHED"]
        assert reached == [1, 2, 3]
        assert texts_of(peer, mark) == [
            "6:Mission: 1 WP",
            "6:Throttle armed",
            "6:Reached waypoint #1",
            "6:Mission: 2 WP",
            "6:Reached waypoint #2",
            "6:Mission: 3 WP",
            "6:Reached waypoint #3",
            "5:Mission Complete",
        ]
        assert within(peer.time_of(done) - armed_s, ROVER_MISSION_S)
        # It stops at the last waypoint and stays there in AUTO, armed, the mission complete.
        peer.run_for(3.0)
        end = here(peer)
        assert distance_m((end.lat_deg, end.lon_deg), plan[-1]) < 1.5
        assert end.ground_speed_m_s < 0.1
        assert mission_current(peer) == (3, 3, mavlink2.MISSION_STATE_COMPLETE, 1)
        assert peer.mode_name(peer.heartbeat().custom_mode) == "AUTO"
        assert peer.is_armed()
    finally:
        clear(peer)
        peer.message_interval("MISSION_CURRENT", 0)


COPTER_MISSION_S = 43.9
"""SITL: from MISSION_START to the disarm after the copter's mission (WPNAV_SPEED 500)."""
MISSION_TEXTS = ("Mission:", "Reached", "Disarming")
"""The texts of a mission's progress (others, such as the EKF's, come and go)."""


@backends(kinds=("copter",))
def test_copter_flies_a_takeoff_waypoint_land_mission_in_auto(copter: Peer) -> None:
    peer = copter
    peer.message_interval("MISSION_CURRENT", 500_000)
    start = here(peer)
    o = (start.lat_deg, start.lon_deg)
    far = moved(*o, 40.0, 0.0)
    try:
        upload(
            peer,
            [(WAYPOINT, *o, 0.0), (TAKEOFF, 0, 0, 10.0), (WAYPOINT, *far, 10.0), (LAND, 0, 0, 0)],
        )
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED  # in GUIDED: not in AUTO
        mark = peer.mark()
        assert peer.set_mode("AUTO").result == mavlink2.MAV_RESULT_ACCEPTED
        peer.run_for(2.0)
        assert max(f.up_m for f in track(peer, mark)) < 0.1  # waits for MISSION_START
        start_ack = peer.command_long(mavlink2.MAV_CMD_MISSION_START, 0, 0)
        assert start_ack.result == mavlink2.MAV_RESULT_ACCEPTED
        started_s = peer.time_of(start_ack)
        peer.wait_for("HEARTBEAT", 120.0, where=disarmed)
        peer.run_for(1.0)
        # Takeoff done, waypoint reached (the landing's end is the disarm), and after it
        # the mission starts over, waiting in AUTO for the next arming and start.
        reached = [m.seq for _, m in peer.history[mark:] if m.get_type() == "MISSION_ITEM_REACHED"]
        assert reached == [1, 2]
        said = [t for t in texts_of(peer, mark) if t.split(":", 1)[1].startswith(MISSION_TEXTS)]
        assert said == [
            "6:Mission: 1 Takeoff",
            "6:Mission: 2 WP",
            "6:Reached command #2",
            "6:Mission: 3 Land",
            "6:Disarming motors",
            "6:Mission: 1 Takeoff",
        ]
        disarm = next(s for s in peer.texts_since(mark) if s.text == "Disarming motors")
        assert within(disarm.time_s - started_s, COPTER_MISSION_S)
        fixes = track(peer, mark)
        end = fixes[-1]
        assert distance_m((end.lat_deg, end.lon_deg), far) < 1.5  # landed at the waypoint
        assert max(f.up_m for f in fixes) <= 10.5
        assert mission_current(peer) == (1, 3, mavlink2.MISSION_STATE_ACTIVE, 1)
        assert peer.mode_name(peer.heartbeat().custom_mode) == "AUTO"
    finally:
        clear(peer)
        peer.message_interval("MISSION_CURRENT", 0)


AUTO_RULES: dict[str, list[tuple[str, Step]]] = {
    "rover": [
        ("set AUTO", Step(0, "AUTO", False, ("6:Mission: 1 WP",))),
    ],
    "copter": [
        ("set AUTO", Step(0, "AUTO", False, ("6:Mission: 1 WP",))),
        ("arm", Step(4, "AUTO", False, ("2:Arm: AUTO mode not armable",))),
        ("set STABILIZE", Step(0, "STABILIZE", False, ())),
        ("arm", Step(0, "STABILIZE", True, ("6:Arming motors",))),
        (
            "set AUTO",
            Step(
                4,
                "STABILIZE",
                True,
                ("2:Auto: Missing Takeoff Cmd", "4:Mode change to AUTO failed: init failed"),
            ),
        ),
    ],
    "plane": [
        ("set AUTO", Step(0, "AUTO", False, ("6:Mission: 1 WP",))),
    ],
}
"""With a mission of one waypoint (no takeoff), on the ground, from the manual mode:
measured on SITL."""


def test_auto_with_a_mission_is_entered_and_armed_as_each_firmware_rules(missions: Peer) -> None:
    peer = missions
    peer.wait_ready()
    home = peer.wait_for("HOME_POSITION", 40.0, since=0)
    o = (home.latitude / 1e7, home.longitude / 1e7)
    upload(peer, [(WAYPOINT, *o, 0.0), (WAYPOINT, *moved(*o, 30.0, 0.0), 10.0)])
    fast_heartbeats(peer, True)
    observed = []
    try:
        for what, _ in AUTO_RULES[peer.kind]:
            verb, _, mode = what.partition(" ")
            observed.append((what, set_mode(peer, mode) if verb == "set" else arm(peer)))
    finally:
        peer.disarm()
        set_mode(peer, str(peer.spec.autopilot["manual_mode"]))
        fast_heartbeats(peer, False)
    assert observed == AUTO_RULES[peer.kind]
