"""The simulated autopilot's fence where the conformance suite does not go.

tests/conformance/test_fence.py holds the simulation to what SITL does (both must
pass). These cover the rest of AC_Fence and each firmware's reaction as ArduPilot's
source has them (docs/sitl-measurements.md, section 3, and libraries/AC_Fence at the SITL
build): the quirks of FENCE_ENABLE, exclusion zones, the union of inclusion zones, the
backup fence that re-fires a breach further out, giving up beyond 100 m, refusing mode
changes in recovery, ArduPlane's GUIDED action, DO_FENCE_ENABLE.
"""

from __future__ import annotations

from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from sim_station import Station

from clark_engine.sim.ardupilot.fence import FenceZones, fence_names
from clark_engine.sim.ardupilot.mission_items import MissionItem

ACCEPTED, FAILED = mavlink2.MAV_RESULT_ACCEPTED, mavlink2.MAV_RESULT_FAILED
NOTICE, INFO, CRITICAL = 5, 6, 2
GEOFENCE = mavlink2.MAV_SYS_STATUS_GEOFENCE
CIRCLE_IN = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION
CIRCLE_OUT = mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION
RETURN_POINT = mavlink2.MAV_CMD_NAV_FENCE_RETURN_POINT


def arm_texts(station: Station) -> list[str]:
    """Try to arm; the CRITICAL texts (the arming must fail)."""
    since = station.now_s
    assert station.arm() == FAILED
    return [t for s, t in station.texts(since) if s == CRITICAL]


def geofence(station: Station) -> tuple[bool, bool, bool]:
    """SYS_STATUS's geofence (present, enabled, healthy), asked for now."""
    answers = station.send(
        mavlink2.MAVLink_command_long_message(
            1,
            1,
            mavlink2.MAV_CMD_REQUEST_MESSAGE,
            0,
            mavlink2.MAVLINK_MSG_ID_SYS_STATUS,
            0,
            0,
            0,
            0,
            0,
            0,
        )
    )
    msg = next(m for m in answers if m.get_type() == "SYS_STATUS")
    return (
        bool(msg.onboard_control_sensors_present & GEOFENCE),
        bool(msg.onboard_control_sensors_enabled & GEOFENCE),
        bool(msg.onboard_control_sensors_health & GEOFENCE),
    )


def fly_copter(station: Station, up_m: float) -> None:
    """A ready copter armed in GUIDED and taken off to ``up_m``."""
    station.ready()
    assert station.mode("GUIDED") == ACCEPTED
    assert station.arm() == ACCEPTED
    assert station.command(mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, up_m) == ACCEPTED
    station.run_until(lambda: station.up_m > up_m - 0.3, 30.0)
    station.run(2.0)


def test_fence_names_as_arducopter_prints_them() -> None:
    assert fence_names(1) == "Max Alt fence"
    assert fence_names(3) == "Max Alt and Circle fences"
    assert fence_names(15) == "Max Alt, Circle, Polygon and Min Alt fences"
    assert fence_names(0) == ""


def test_fence_enable_other_than_0_or_1_re_enables_everything_at_10_hz() -> None:
    # ArduPilot keeps the last FENCE_ENABLE as a bool: 7 never equals it. On a rover (its
    # height above home is +90 m) with every type on, the floor then enables itself at
    # every look (measured: "Min Alt fence enabled (auto enable)" ten times a second).
    station = Station("rover")
    station.ready()
    station.set("FENCE_TYPE", 127)
    station.set("FENCE_ENABLE", 7)
    since = station.now_s
    station.run(2.0)
    count = station.texts(since).count((NOTICE, "Min Alt fence enabled (auto enable)"))
    assert 15 <= count <= 22, count


def test_fence_enable_0_while_breached_leaves_the_breach() -> None:
    station = Station("rover")
    station.ready()
    lat, lon = station.latlon(100.0, 0.0)
    assert station.command(mavlink2.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, lat, lon, 0) == ACCEPTED
    station.set("FENCE_RADIUS", 30)
    station.set("FENCE_TYPE", 2)
    station.set("FENCE_ENABLE", 1)
    station.run(0.5)
    assert geofence(station) == (True, True, False)
    station.set("FENCE_ENABLE", 0)
    station.run(0.5)
    assert geofence(station) == (True, False, False)  # still breached, as measured
    since = station.now_s
    assert station.mode("HOLD") == ACCEPTED
    assert (INFO, "Manual recovery started") in station.texts(since)
    assert station.arm() == ACCEPTED  # the pre-arm check looks only at fences that are on


def test_a_rover_entering_an_exclusion_circle_holds() -> None:
    station = Station("rover")
    station.ready()
    assert station.upload_fence([(CIRCLE_OUT, 10.0, 40.0, 0.0)]) == mavlink2.MAV_MISSION_ACCEPTED
    for name, value in (("FENCE_TYPE", 4), ("FENCE_ACTION", 2), ("AVOID_ENABLE", 0)):
        station.set(name, value)
    station.set("FENCE_ENABLE", 1)
    assert station.mode("GUIDED") == ACCEPTED
    assert station.arm() == ACCEPTED
    station.goto(60.0, 0.0, 0.0)
    station.run_until(lambda: station.mode_now == "HOLD", 40.0)
    assert 29.5 <= station.north_m() <= 32.0  # the exclusion circle's edge is 30 m north


def test_a_rover_stops_short_of_an_exclusion_circle_with_avoidance() -> None:
    station = Station("rover")
    station.ready()
    assert station.upload_fence([(CIRCLE_OUT, 10.0, 40.0, 0.0)]) == mavlink2.MAV_MISSION_ACCEPTED
    station.set("FENCE_TYPE", 4)
    station.set("FENCE_ENABLE", 1)
    assert station.mode("GUIDED") == ACCEPTED
    assert station.arm() == ACCEPTED
    station.goto(60.0, 0.0, 0.0)
    station.run(40.0)
    assert station.mode_now == "GUIDED"
    assert 26.5 <= station.north_m() <= 28.5  # FENCE_MARGIN (2 m) short of 30 m


def test_inclusion_zones_intersect_unless_fence_options_bit_1() -> None:
    station = Station("rover")
    station.ready()
    zones = [(CIRCLE_IN, 20.0, 0.0, 0.0), (CIRCLE_IN, 20.0, 200.0, 0.0)]
    assert station.upload_fence(zones) == mavlink2.MAV_MISSION_ACCEPTED
    station.set("FENCE_TYPE", 4)
    station.set("FENCE_ENABLE", 1)
    station.run(0.5)
    # Inside the first circle, outside the second: outside their intersection ...
    assert "Arm: Vehicle breaching Polygon fence" in arm_texts(station)
    # ... inside their union.
    station.set("FENCE_OPTIONS", 2)
    station.run(0.5)
    assert station.arm() == ACCEPTED


def test_fence_zones_from_items_keep_each_polygon_and_the_return_point() -> None:
    items = [
        (mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION, 3.0, n, e)
        for n, e in ((0.0, 0.0), (10.0, 0.0), (0.0, 10.0))
    ] + [(RETURN_POINT, 0.0, 5.0, 5.0), (CIRCLE_OUT, 2.0, 1.0, 1.0)]

    zones = FenceZones.from_items(
        [
            MissionItem(
                seq, 0, command, 0, 0, param1, 0, 0, 0, round(n * 1e7), round(e * 1e7), 0, 1
            )
            for seq, (command, param1, n, e) in enumerate(items)
        ],
        lambda lat, lon: (lat, lon),  # the plane in degrees, for the test
    )
    assert len(zones.inclusion_polygons) == 1 and len(zones.exclusion_circles) == 1
    assert zones.return_point == (5.0, 5.0)
    assert zones.breached((1.0, 1.0)) == (True, 2.0)  # at the exclusion circle's centre
    assert zones.breached((3.0, 3.0))[0] is False
    assert zones.breached((20.0, 20.0))[0] is True


def test_copter_report_only_and_the_backup_fence_20_m_higher() -> None:
    # FENCE_ACTION 0 reports each new breach and does nothing; a breached ceiling fires
    # again once the copter is 20 m above where it first breached it.
    station = Station("copter")
    fly_copter(station, 10.0)
    station.goto(0.0, 0.0, 45.0)  # the fence still off: taken
    for name, value in (("FENCE_TYPE", 1), ("FENCE_ALT_MAX", 20), ("FENCE_ACTION", 0)):
        station.set(name, value)
    station.set("FENCE_ENABLE", 1)
    heights = []
    for _ in range(2):
        since = station.now_s + 0.01
        station.run_until(lambda s=since: station.text_time("Max Alt fence breached", s), 30.0)
        heights.append(station.up_m)
    assert 20.0 <= heights[0] <= 20.5
    assert 19.5 <= heights[1] - heights[0] <= 20.5
    assert station.mode_now == "GUIDED"


def test_copter_far_outside_lands_and_refuses_modes_with_fence_options_bit_0() -> None:
    station = Station("copter")
    fly_copter(station, 10.0)
    station.goto(150.0, 0.0, 10.0)
    station.run_until(lambda: station.north_m() > 145.0, 60.0)
    for name, value in (("FENCE_TYPE", 2), ("FENCE_RADIUS", 30), ("FENCE_OPTIONS", 1)):
        station.set(name, value)
    since = station.now_s
    station.set("FENCE_ENABLE", 1)
    # 120 m outside, more than AC_FENCE_GIVE_UP_DISTANCE: LAND, whatever FENCE_ACTION says.
    station.run_until(lambda: station.mode_now == "LAND", 2.0)
    assert (NOTICE, "Circle fence breached") in station.texts(since)
    since = station.now_s
    assert station.mode("LOITER") == FAILED
    assert (4, "Mode change to LOITER failed: in fence recovery") in station.texts(since)


def test_copter_guided_target_beyond_the_circle_is_ignored() -> None:
    station = Station("copter")
    fly_copter(station, 10.0)
    station.set("FENCE_TYPE", 2)
    station.set("FENCE_RADIUS", 50)
    station.set("FENCE_ENABLE", 1)
    station.goto(80.0, 0.0, 10.0)
    station.run(10.0)
    assert abs(station.north_m()) < 1.0
    station.goto(40.0, 0.0, 10.0)
    station.run(15.0)
    assert station.north_m() > 35.0


def test_plane_guided_action_flies_to_the_return_point() -> None:
    station = Station("plane")
    station.ready()
    assert station.upload_fence([(RETURN_POINT, 0.0, -50.0, 30.0)]) == 0
    fence = {"FENCE_TYPE": 2, "FENCE_RADIUS": 150, "FENCE_ACTION": 6, "FENCE_ALT_MAX": 100}
    for name, value in fence.items():
        station.set(name, value)
    station.set("FENCE_ENABLE", 1)
    assert station.mode("TAKEOFF") == ACCEPTED
    assert station.arm() == ACCEPTED
    station.run_until(lambda: station.mode_now == "GUIDED", 60.0)
    target = station.autopilot._target  # the guided target it flies to
    assert target is not None
    lat, lon = station.latlon(-50.0, 30.0)
    assert abs(target[0] - lat) < 1e-6 and abs(target[1] - lon) < 1e-6
    # Halfway between the floor and the ceiling, each FENCE_MARGIN inside: (-8 + 98) / 2.
    assert abs(target[2] - 45.0) < 0.5


def test_do_fence_enable() -> None:
    station = Station("plane")  # FENCE_TYPE 4 and no polygon: nothing to enable
    station.ready()
    assert station.command(mavlink2.MAV_CMD_DO_FENCE_ENABLE, 1) == FAILED
    station.set("FENCE_TYPE", 2)
    assert station.command(mavlink2.MAV_CMD_DO_FENCE_ENABLE, 1) == ACCEPTED
    station.run(0.5)
    assert geofence(station) == (True, True, True)
    assert station.autopilot.param("FENCE_ENABLE") == 0  # the parameter is not touched
    assert station.command(mavlink2.MAV_CMD_DO_FENCE_ENABLE, 0) == ACCEPTED
    station.run(0.5)
    assert geofence(station) == (True, False, True)
    assert station.command(mavlink2.MAV_CMD_DO_FENCE_ENABLE, 9) == FAILED
