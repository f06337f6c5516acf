"""The autopilot's own geofence: what it reports, what it refuses, and its breach actions.

Measured on SITL (docs/sitl-measurements.md, section 3; ArduPilot's AC_Fence and each firmware's
fence.cpp): the fence can be switched on while disarmed, and SYS_STATUS's geofence bit
and FENCE_STATUS then say so; arming is refused with the fence's own words while it is
misconfigured or breached; FENCE_TYPE takes effect only when FENCE_ENABLE changes;
ArduCopter and ArduPlane refuse guided destinations outside it; a breach is detected at
the limit (altitudes above home, the circle around home, uploaded zones) and acted on at
once: ArduCopter says "Max Alt fence breached" and turns to RTL, ArduRover turns to RTL
or HOLD without a word, and the mode change starts ten seconds of "manual recovery".
ArduRover's avoidance (AVOID_ENABLE, on by default) stops it FENCE_MARGIN short of a
circle fence instead.

Every scenario puts the parameters back, and clears what it uploaded.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from typing import Any

from flight import disarmed, distance_m, fix_of, goto, here, moved, streaming, takeoff, track
from harness import Peer, backends
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

NOTICE, INFO, CRITICAL = (
    mavlink2.MAV_SEVERITY_NOTICE,
    mavlink2.MAV_SEVERITY_INFO,
    mavlink2.MAV_SEVERITY_CRITICAL,
)
GEOFENCE = mavlink2.MAV_SYS_STATUS_GEOFENCE
FENCE_STATUS_US = 500_000
CIRCLE_TYPE = {"rover": 2, "copter": 3, "plane": 2}
"""A FENCE_TYPE with a fence that exists without an upload (copter: ceiling and circle)."""
MITIGATION = {
    "rover": mavlink2.FENCE_MITIGATE_NONE,
    "copter": mavlink2.FENCE_MITIGATE_NONE,
    "plane": mavlink2.FENCE_MITIGATE_UNKNOWN,
}
"""FENCE_STATUS.breach_mitigation while nothing limits the vehicle: ArduRover and ArduCopter
report their avoidance (none now), ArduPlane has none to report."""


@contextmanager
def params(peer: Peer, values: dict[str, float]) -> Iterator[Peer]:
    """The parameters set in order, and put back in reverse order (FENCE_ENABLE first off)."""
    before = {name: peer.param_get(name).param_value for name in values}
    try:
        for name, value in values.items():
            peer.param_set(name, value)
        yield peer
    finally:
        for name in reversed(list(before)):
            peer.param_set(name, before[name])


def geofence_bits(peer: Peer) -> tuple[bool, bool, bool]:
    """SYS_STATUS's geofence bit: (present, enabled, healthy), from the next report."""
    msg = peer.wait_for("SYS_STATUS", 2.5)
    return (
        bool(msg.onboard_control_sensors_present & GEOFENCE),
        bool(msg.onboard_control_sensors_enabled & GEOFENCE),
        bool(msg.onboard_control_sensors_health & GEOFENCE),
    )


def fence_status(peer: Peer, within_s: float = 2.0) -> tuple[int, int, int, int]:
    """(breach_status, breach_count, breach_type, breach_mitigation) of the next FENCE_STATUS."""
    msg = peer.wait_for("FENCE_STATUS", within_s)
    return (
        int(msg.breach_status),
        int(msg.breach_count),
        int(msg.breach_type),
        int(msg.breach_mitigation),
    )


def texts(peer: Peer, mark: int) -> list[tuple[int, str]]:
    return [(s.severity, s.text) for s in peer.texts_since(mark)]


def arm_refusals(peer: Peer) -> list[str]:
    """Try to arm; the CRITICAL "Arm: ..." texts of the refusal (it must be refused).

    After a moment: ArduPilot takes a new FENCE_ENABLE into account at 10 Hz.
    """
    peer.run_for(0.3)
    mark = peer.mark()
    ack = peer.arm()
    assert ack.result == mavlink2.MAV_RESULT_FAILED, "armed"
    peer.run_for(0.5)
    return [s.text for s in peer.texts_since(mark) if s.severity == CRITICAL]


def arming_texts(peer: Peer) -> list[str]:
    """Try to arm; the CRITICAL texts of a refusal ([] when it armed: disarmed again)."""
    peer.run_for(0.3)
    mark = peer.mark()
    if peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED:
        assert peer.disarm().result == mavlink2.MAV_RESULT_ACCEPTED
        return []
    peer.run_for(0.5)
    return [s.text for s in peer.texts_since(mark) if s.severity == CRITICAL]


def mode_now(peer: Peer) -> str:
    return peer.mode_name(peer.heartbeat().custom_mode)


def home_of(peer: Peer) -> tuple[float, float, float]:
    """Home (lat, lon, altitude AMSL) as HOME_POSITION says, asked for now."""
    mark = peer.mark()
    peer.command_long(mavlink2.MAV_CMD_GET_HOME_POSITION)
    msg = peer.wait_for("HOME_POSITION", 2.0, since=mark)
    return msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000


def reposition(peer: Peer, lat: float, lon: float, up_m: float) -> Any:
    """DO_REPOSITION (COMMAND_INT, above home, into GUIDED); returns the COMMAND_ACK."""
    peer.send(
        mavlink2.MAVLink_command_int_message(
            peer.spec.system_id,
            1,
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mavlink2.MAV_CMD_DO_REPOSITION,
            0,
            0,
            -1,
            mavlink2.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE,
            0,
            0,
            round(lat * 1e7),
            round(lon * 1e7),
            up_m,
        )
    )

    def acks_it(msg: Any) -> bool:
        return bool(msg.command == mavlink2.MAV_CMD_DO_REPOSITION)

    return peer.wait_for("COMMAND_ACK", 3.0, where=acks_it)


def upload_fence(peer: Peer, corners: Sequence[tuple[float, float]]) -> Any:
    """One inclusion polygon as the fence list (mission type 1); returns the MISSION_ACK."""
    fence = mavlink2.MAV_MISSION_TYPE_FENCE
    peer.send(mavlink2.MAVLink_mission_count_message(peer.spec.system_id, 1, len(corners), fence))

    def asks(msg: Any) -> bool:
        return msg.get_type() in ("MISSION_REQUEST", "MISSION_REQUEST_INT", "MISSION_ACK")

    while True:
        msg = peer.wait_for(asks, 5.0)
        if msg.get_type() == "MISSION_ACK":
            return msg
        lat, lon = corners[msg.seq]
        peer.send(
            mavlink2.MAVLink_mission_item_int_message(
                peer.spec.system_id,
                1,
                msg.seq,
                mavlink2.MAV_FRAME_GLOBAL,
                mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
                0,
                1,
                len(corners),
                0,
                0,
                0,
                round(lat * 1e7),
                round(lon * 1e7),
                0,
                fence,
            )
        )


def clear_fence(peer: Peer) -> None:
    fence = mavlink2.MAV_MISSION_TYPE_FENCE
    peer.send(mavlink2.MAVLink_mission_clear_all_message(peer.spec.system_id, 1, fence))
    peer.wait_for("MISSION_ACK", 5.0)


# -- on the ground -------------------------------------------------------------------------


def test_an_enabled_fence_shows_in_sys_status_and_fence_status(peer: Peer) -> None:
    peer.wait_for("HOME_POSITION", 40.0, since=0)
    peer.message_interval("FENCE_STATUS", FENCE_STATUS_US)
    try:
        with params(peer, {"FENCE_TYPE": CIRCLE_TYPE[peer.kind]}):
            # Off: no FENCE_STATUS at all; the fence exists (present) but is not enabled.
            mark = peer.mark()
            peer.run_for(1.5)
            assert not [m for _, m in peer.history[mark:] if m.get_type() == "FENCE_STATUS"]
            assert geofence_bits(peer) == (True, False, True)
            with params(peer, {"FENCE_ENABLE": 1}):
                peer.run_for(0.5)
                assert geofence_bits(peer) == (True, True, True)
                assert fence_status(peer) == (0, 0, 0, MITIGATION[peer.kind])
                # FENCE_ACTION 0 (report only): still on, but SYS_STATUS calls it disabled.
                with params(peer, {"FENCE_ACTION": 0}):
                    assert geofence_bits(peer) == (True, False, True)
            peer.run_for(0.5)
            mark = peer.mark()
            peer.run_for(1.5)
            assert not [m for _, m in peer.history[mark:] if m.get_type() == "FENCE_STATUS"]
    finally:
        peer.message_interval("FENCE_STATUS", 0)


def test_arming_refused_with_fences_enabled_but_none_selected(peer: Peer) -> None:
    with params(peer, {"FENCE_TYPE": 0, "FENCE_ENABLE": 1}):
        assert "Arm: Fences enabled, but none selected" in arm_refusals(peer)
    # ArduPlane's default FENCE_TYPE is the uploaded polygons only: with none uploaded, the
    # same refusal (measured); elsewhere the default has a fence that exists. (ArduPilot
    # looks at FENCE_ENABLE at 10 Hz: switched off and on again in between, the fences
    # would stay as they were, none.)
    peer.run_for(0.5)
    with params(peer, {"FENCE_ENABLE": 1}):
        peer.run_for(0.5)
        if peer.kind == "plane":
            assert "Arm: Fences enabled, but none selected" in arm_refusals(peer)
            assert geofence_bits(peer)[0] is False
        else:
            assert geofence_bits(peer) == (True, True, True)


@backends("fresh_peer")
def test_a_circle_fence_needs_a_position_to_arm(fresh_peer: Peer) -> None:
    peer = fresh_peer  # seconds after boot: no GPS fix, no home
    peer.param_set("FENCE_TYPE", CIRCLE_TYPE[peer.kind])
    peer.param_set("FENCE_ENABLE", 1)
    assert "Arm: Fence requires position" in arm_refusals(peer)


@backends("fresh_peer")
def test_fence_type_takes_effect_when_fence_enable_changes(fresh_peer: Peer) -> None:
    peer = fresh_peer
    peer.wait_for("HOME_POSITION", 40.0, since=0)
    lat, lon, alt = home_of(peer)
    # Home 100 m away (locked there by DO_SET_HOME), a 30 m circle that is not yet on.
    far = moved(lat, lon, 100.0, 0.0)
    ack = peer.command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, *far, alt)
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    peer.param_set("FENCE_RADIUS", 30)
    peer.param_set("FENCE_TYPE", 1)
    peer.param_set("FENCE_ENABLE", 1)
    peer.run_for(1.0)
    assert not [t for t in arming_texts(peer) if "breaching" in t]
    # Adding the circle to FENCE_TYPE while the fence is on changes nothing...
    peer.param_set("FENCE_TYPE", 3)
    peer.run_for(1.0)
    assert not [t for t in arming_texts(peer) if "breaching" in t]
    assert geofence_bits(peer)[2] is True
    # ... until FENCE_ENABLE is toggled: then the circle is on, and breached. (Each change
    # must last a tenth of a second: ArduPilot looks at FENCE_ENABLE at 10 Hz.)
    peer.param_set("FENCE_ENABLE", 0)
    peer.run_for(0.3)
    peer.param_set("FENCE_ENABLE", 1)
    peer.run_for(1.0)
    assert "Arm: Vehicle breaching Circle fence" in arm_refusals(peer)
    assert geofence_bits(peer) == (True, True, False)
    peer.message_interval("FENCE_STATUS", FENCE_STATUS_US)
    breached, count, kind, _ = fence_status(peer)
    assert (breached, kind) == (1, mavlink2.FENCE_BREACH_BOUNDARY)
    assert count >= 1


@backends(kinds=("copter", "plane"))
def test_reposition_outside_the_fence_is_refused(peer: Peer) -> None:
    peer.wait_for("HOME_POSITION", 40.0, since=0)
    lat, lon, _ = home_of(peer)
    with params(peer, {"FENCE_TYPE": 2, "FENCE_RADIUS": 300, "FENCE_ENABLE": 1}):
        peer.run_for(0.3)  # ArduPilot's fence loop (10 Hz) takes the new FENCE_ENABLE in
        mode = mode_now(peer)
        ack = reposition(peer, *moved(lat, lon, 600.0, 0.0), 50.0)
        # ArduPlane DENIED; ArduCopter FAILED (its guided destination check), both before
        # any mode change.
        refused = {"plane": mavlink2.MAV_RESULT_DENIED, "copter": mavlink2.MAV_RESULT_FAILED}
        assert ack.result == refused[peer.kind]
        assert mode_now(peer) == mode


@backends(kinds=("copter",))
def test_copter_fence_auto_enabled_while_armed(copter: Peer) -> None:
    peer = copter
    with params(peer, {"FENCE_TYPE": 1, "FENCE_AUTOENABLE": 3}):
        assert geofence_bits(peer)[1] is False
        mark = peer.mark()
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
        peer.run_for(0.5)
        said = texts(peer, mark)
        assert (NOTICE, "Max Alt fence auto-enabled") in said
        assert said.index((NOTICE, "Max Alt fence auto-enabled")) < said.index(
            (INFO, "Arming motors")
        )
        assert geofence_bits(peer)[1] is True
        assert peer.param_get("FENCE_ENABLE").param_value == 0  # the parameter stays off
        mark = peer.mark()
        assert peer.disarm().result == mavlink2.MAV_RESULT_ACCEPTED
        peer.run_for(0.5)
        assert (NOTICE, "Max Alt fence auto-disabled") in texts(peer, mark)
        assert geofence_bits(peer)[1] is False


# -- breaches ------------------------------------------------------------------------------

CEILING_M = 20.0
HOVER_M = 10.0


@backends(kinds=("copter",))
def test_copter_altitude_fence_refuses_targets_and_turns_to_rtl_on_a_breach(
    copter: Peer,
) -> None:
    peer = copter
    peer.message_interval("FENCE_STATUS", FENCE_STATUS_US)
    fence = {"FENCE_TYPE": 1, "FENCE_ALT_MAX": CEILING_M, "FENCE_ACTION": 1, "FENCE_ENABLE": 1}
    try:
        with params(peer, fence):
            assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
            assert takeoff(peer, HOVER_M).result == mavlink2.MAV_RESULT_ACCEPTED
            peer.wait_for("EXTENDED_SYS_STATE", 25.0, where=lambda m: m.landed_state == 2)
            start = here(peer)
            spot = (start.lat_deg, start.lon_deg)
            # A guided target above the ceiling is refused without a word: it stays put.
            mark = peer.mark()
            goto(peer, *spot, CEILING_M + 10)
            peer.run_for(4.0)
            assert max(f.up_m for f in track(peer, mark)) < HOVER_M + 0.7
            # DO_REPOSITION above it FAILED; below it ACCEPTED and flown.
            assert reposition(peer, *spot, CEILING_M + 10).result == mavlink2.MAV_RESULT_FAILED
            assert reposition(peer, *spot, 15.0).result == mavlink2.MAV_RESULT_ACCEPTED
            peer.wait_for("GLOBAL_POSITION_INT", 20.0, where=lambda m: m.relative_alt > 14_500)
            # The fence off, a climb past the ceiling, the fence on again on the way up.
            peer.param_set("FENCE_ENABLE", 0)
            peer.run_for(0.3)  # (taken into account at 10 Hz)
            goto(peer, *spot, CEILING_M + 10)
            peer.wait_for("GLOBAL_POSITION_INT", 20.0, where=lambda m: m.relative_alt > 16_500)
            mark = peer.mark()
            on_s = peer.time_of(peer.param_set("FENCE_ENABLE", 1))
            breached = peer.wait_for(
                "STATUSTEXT", 10.0, where=lambda m: m.text == "Max Alt fence breached", since=mark
            )
            assert breached.severity == NOTICE
            high = next(
                (
                    t
                    for t, m in peer.history[mark:]
                    if m.get_type() == "GLOBAL_POSITION_INT" and m.relative_alt >= CEILING_M * 1000
                ),
                peer.time_of(breached),
            )
            # Checked at 25 Hz, acted on at once (SITL: 34 ms after the first report at 20 m).
            assert peer.time_of(breached) - max(high, on_s) <= 0.5
            rtl = peer.wait_for(
                "HEARTBEAT", 2.0, where=lambda m: peer.mode_name(m.custom_mode) == "RTL"
            )
            assert peer.time_of(rtl) - peer.time_of(breached) <= 1.1
            said = texts(peer, mark)
            assert said.index((NOTICE, "Max Alt fence breached")) < said.index(
                (INFO, "Manual recovery started")
            )
            status = peer.wait_for(
                "FENCE_STATUS", 2.0, where=lambda m: m.breach_status == 1, since=mark
            )
            assert status.breach_type == mavlink2.FENCE_BREACH_MAXALT
            assert status.breach_count >= 1
            assert geofence_bits(peer) == (True, True, False)
            # A mode change is allowed (ArduCopter's FENCE_OPTIONS 0) and starts a
            # recovery; going down through the ceiling clears the breach.
            mark = peer.mark()
            assert peer.set_mode("LAND").result == mavlink2.MAV_RESULT_ACCEPTED
            cleared = peer.wait_for(
                "STATUSTEXT", 30.0, where=lambda m: m.text == "Fence breach cleared", since=mark
            )
            assert cleared.severity == NOTICE
            # (The simulation reports its GPS's 5 Hz fixes, which trail its fence's estimate
            # by up to a fix: 1.5 m/s down, 0.3 m.)
            below = fix_of(peer.wait_for("GLOBAL_POSITION_INT", 1.0))
            assert below.up_m < CEILING_M + 0.3
            peer.wait_for("HEARTBEAT", 60.0, where=disarmed)
    finally:
        peer.message_interval("FENCE_STATUS", 0)


RADIUS_M = 50.0


@backends(kinds=("rover",))
def test_rover_stops_short_of_a_circle_fence_then_breaches_it_and_returns(rover: Peer) -> None:
    peer = rover
    peer.message_interval("FENCE_STATUS", FENCE_STATUS_US)
    lat, lon, _ = home_of(peer)
    beyond = moved(lat, lon, 120.0, 0.0)
    fence = {"FENCE_TYPE": 2, "FENCE_RADIUS": RADIUS_M, "FENCE_ACTION": 1, "FENCE_ENABLE": 1}
    try:
        with params(peer, {**fence, "AVOID_ENABLE": 3}):
            assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
            assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
            mark = peer.mark()
            goto(peer, *beyond, 0.0)
            # Avoidance stops it FENCE_MARGIN (2 m) short of the circle, still in GUIDED:
            # SITL stopped at 48.09 m.
            peer.wait_for(
                "GLOBAL_POSITION_INT", 40.0, where=lambda m: fix_of(m).ground_speed_m_s > 1.0
            )
            peer.wait_for(
                "GLOBAL_POSITION_INT", 60.0, where=lambda m: fix_of(m).ground_speed_m_s < 0.1
            )
            peer.run_for(2.0)
            stop = here(peer)
            assert 47.0 <= distance_m((stop.lat_deg, stop.lon_deg), (lat, lon)) < RADIUS_M - 0.5
            assert mode_now(peer) == "GUIDED"
            assert fence_status(peer) == (0, 0, 0, mavlink2.FENCE_MITIGATE_VEL_LIMIT)
            assert not [m for _, m in peer.history[mark:] if m.get_type() == "MISSION_ITEM_REACHED"]
            # Without avoidance it drives on: at the circle, RTL without a "breached" text.
            peer.param_set("AVOID_ENABLE", 0)
            peer.set_mode("HOLD")
            peer.run_for(1.0)
            peer.set_mode("GUIDED")
            mark = peer.mark()
            goto(peer, *beyond, 0.0)
            rtl = peer.wait_for(
                "HEARTBEAT", 30.0, where=lambda m: peer.mode_name(m.custom_mode) == "RTL"
            )
            out = next(
                (
                    t
                    for t, m in peer.history[mark:]
                    if m.get_type() == "GLOBAL_POSITION_INT"
                    and distance_m((m.lat / 1e7, m.lon / 1e7), (lat, lon)) >= RADIUS_M
                ),
                peer.time_of(rtl),
            )
            assert peer.time_of(rtl) - out <= 1.2  # checked at 10 Hz (SITL: 0.2 s)
            said = texts(peer, mark)
            assert (INFO, "Manual recovery started") in said
            assert not [t for _, t in said if "breached" in t]
            status = peer.wait_for(
                "FENCE_STATUS", 2.0, where=lambda m: m.breach_status == 1, since=mark
            )
            assert status.breach_type == mavlink2.FENCE_BREACH_BOUNDARY
            assert geofence_bits(peer) == (True, True, False)
            # RTL drives it back inside: the breach clears without a word.
            peer.wait_for("FENCE_STATUS", 30.0, where=lambda m: m.breach_status == 0)
            assert not [t for _, t in texts(peer, mark) if "cleared" in t]
            peer.set_mode("HOLD")
            peer.disarm()
    finally:
        peer.message_interval("FENCE_STATUS", 0)


POLYGON_HALF_M = 20.0


@backends(kinds=("rover",))
def test_rover_polygon_fence_breach_holds_and_blocks_arming(rover: Peer) -> None:
    peer = rover
    lat, lon, _ = home_of(peer)
    corners = [
        moved(lat, lon, n * POLYGON_HALF_M, e * POLYGON_HALF_M)
        for n, e in ((1, -1), (1, 1), (-1, 1), (-1, -1))
    ]
    fence = {"FENCE_TYPE": 4, "FENCE_ACTION": 2, "FENCE_ENABLE": 1}
    mark = peer.mark()
    assert upload_fence(peer, corners).type == mavlink2.MAV_MISSION_ACCEPTED
    try:
        peer.run_for(0.5)
        assert (mavlink2.MAV_SEVERITY_DEBUG, "Fence Indexed OK") in texts(peer, mark)
        with params(peer, {**fence, "AVOID_ENABLE": 0}):
            assert geofence_bits(peer) == (True, True, True)
            assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
            assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
            mark = peer.mark()
            mark_s = peer.now_s
            goto(peer, *moved(lat, lon, 0.0, 60.0), 0.0)
            hold = peer.wait_for(
                "HEARTBEAT", 30.0, where=lambda m: peer.mode_name(m.custom_mode) == "HOLD"
            )
            at = fix_of(peer.wait_for("GLOBAL_POSITION_INT", 1.0))
            east = distance_m((lat, at.lon_deg), (lat, lon))
            # SITL: 0.86 m past. The simulated fence sees the true position, its reports
            # are GPS fixes up to 0.2 s old: at 3 m/s the report may be 0.6 m short of
            # the edge that was breached (docs/autopilot-fidelity.md, the fence).
            assert POLYGON_HALF_M - 0.6 <= east <= POLYGON_HALF_M + 2.5, east
            assert peer.time_of(hold) >= mark_s
            assert (INFO, "Manual recovery started") in texts(peer, mark)
            # Stopped outside, disarmed: arming is refused while it breaches the polygon.
            peer.run_for(3.0)
            assert peer.disarm().result == mavlink2.MAV_RESULT_ACCEPTED
            peer.run_for(1.0)
            assert "Arm: Vehicle breaching Polygon fence" in arm_refusals(peer)
            # MAV_CMD_DO_FENCE_ENABLE 0 switches every fence off and forgets the breach
            # (FENCE_ENABLE alone would leave it recorded).
            ack = peer.command_long(mavlink2.MAV_CMD_DO_FENCE_ENABLE, 0)
            assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
            peer.run_for(0.5)
            assert geofence_bits(peer) == (True, False, True)
            assert peer.param_get("FENCE_ENABLE").param_value == 1
    finally:
        clear_fence(peer)


PLANE_RADIUS_M = 150.0
PLANE_PARAMS = {"AIRSPEED_CRUISE": 18.0, "WP_LOITER_RAD": 80.0, "TKOFF_ALT": 50.0}
"""The flight's shape, the same on both (see test_plane.py); TAKEOFF flies 200 m north."""


@backends("fresh_peer", kinds=("plane",))
def test_plane_circle_fence_breach_returns_and_refuses_mode_changes(fresh_peer: Peer) -> None:
    peer = fresh_peer
    peer.wait_ready()
    lat, lon, _ = home_of(peer)
    fence = {"FENCE_TYPE": 2, "FENCE_RADIUS": PLANE_RADIUS_M, "FENCE_ACTION": 1}
    with params(peer, {**PLANE_PARAMS, **fence, "FENCE_ENABLE": 1}), streaming(peer):
        peer.message_interval("FENCE_STATUS", FENCE_STATUS_US)
        # TAKEOFF flies north past the circle while it climbs: "Circle fence breached",
        # RTL, and the fence's mode change starts a manual recovery.
        assert peer.set_mode("TAKEOFF").result == mavlink2.MAV_RESULT_ACCEPTED
        mark = peer.mark()
        assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
        breached = peer.wait_for(
            "STATUSTEXT", 60.0, where=lambda m: m.text == "Circle fence breached", since=mark
        )
        assert breached.severity == NOTICE
        out = next(
            (
                t
                for t, m in peer.history[mark:]
                if m.get_type() == "GLOBAL_POSITION_INT"
                and distance_m((m.lat / 1e7, m.lon / 1e7), (lat, lon)) >= PLANE_RADIUS_M
            ),
            peer.time_of(breached),
        )
        assert peer.time_of(breached) - out <= 0.8  # checked at 3 Hz (SITL: 0.2 s)
        rtl = peer.wait_for(
            "HEARTBEAT", 2.0, where=lambda m: peer.mode_name(m.custom_mode) == "RTL", since=mark
        )
        assert peer.time_of(rtl) - peer.time_of(breached) <= 1.1
        assert (INFO, "Manual recovery started") in texts(peer, mark)
        status = peer.wait_for("FENCE_STATUS", 2.0, where=lambda m: m.breach_status == 1)
        assert status.breach_type == mavlink2.FENCE_BREACH_BOUNDARY
        # While breached, in the fence's RTL, no mode change (ArduPlane's FENCE_OPTIONS 1).
        mark = peer.mark()
        assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_FAILED
        assert (NOTICE, "Mode change to GUIDED denied, in fence recovery") in texts(peer, mark)
        # Back inside, the breach clears without a word (ArduPlane says nothing while in
        # the fence's RTL), and modes may change again.
        peer.wait_for("FENCE_STATUS", 60.0, where=lambda m: m.breach_status == 0)
        assert not [t for _, t in texts(peer, mark) if "cleared" in t]
        assert peer.set_mode("LOITER").result == mavlink2.MAV_RESULT_ACCEPTED
