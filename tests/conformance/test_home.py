"""Home: when each firmware sets it by itself, and MAV_CMD_DO_SET_HOME.

Measured on SITL (seconds after boot): ArduRover sets home at its first GPS fix (10.05 s)
with the wrong altitude (0.19 m above mean sea level, not the ground's 90 m), and moves
it to where it is at every disarm; ArduCopter sets it with its EKF origin (20 s) and
moves it at every arming; ArduPlane sets it at its first fix (10.1 s) and sends it again
every 6 s while disarmed, following its GPS. ArduRover's home also follows a disarmed
rover that moved 0.5 m from it (checked once a second).
"""

from __future__ import annotations

import itertools

import pytest
from flight import distance_m, moved
from harness import Peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

FIRST_HOME_S = {"rover": 10.05, "copter": 20.0, "plane": 10.1}
FIRST_HOME_ALT_M = {"rover": 0.19, "copter": 90.09, "plane": 90.0}
"""HOME_POSITION.altitude of the first home (m above mean sea level), at a 90 m origin."""
PLANE_HOME_PERIOD_S = 6.0
ROVER_HOME_MIN_CHANGE_M = 0.45
"""ArduRover's DISTANCE_HOME_MINCHANGE (0.5 m), less what HOME_POSITION's rounding loses."""


def test_home_comes_when_the_firmware_sets_it(peer: Peer) -> None:
    first = peer.wait_for("HOME_POSITION", 40.0, since=0)
    at_s = peer.time_of(first)
    assert at_s == pytest.approx(FIRST_HOME_S[peer.kind], abs=1.0)
    assert first.altitude / 1000 == pytest.approx(FIRST_HOME_ALT_M[peer.kind], abs=0.5)
    assert distance_m((first.latitude / 1e7, first.longitude / 1e7), peer.spec.home[:2]) < 1.0


def test_arduplane_sends_home_every_6_s_while_disarmed(peer: Peer) -> None:
    peer.wait_for("HOME_POSITION", 40.0, since=0)
    mark = peer.mark()
    peer.run_for(3 * PLANE_HOME_PERIOD_S + 1.0)
    homes = [t for t, m in peer.history[mark:] if m.get_type() == "HOME_POSITION"]
    if peer.kind == "plane":
        assert len(homes) in (3, 4), homes
        gaps = [b - a for a, b in itertools.pairwise(homes)]
        assert all(g == pytest.approx(PLANE_HOME_PERIOD_S, abs=0.3) for g in gaps), gaps
    elif peer.kind == "rover":
        # ArduRover sends home only when it moved it: once a second while disarmed, home
        # follows the rover when it is 0.5 m away (DISTANCE_HOME_MINCHANGE), as a rover
        # still rolling after a disarm, or SITL's EKF drifting over minutes, brings about.
        places = [
            (m.latitude / 1e7, m.longitude / 1e7)
            for _t, m in peer.history
            if m.get_type() == "HOME_POSITION"
        ]
        moves = [distance_m(a, b) for a, b in itertools.pairwise(places[-len(homes) - 1 :])]
        assert all(move >= ROVER_HOME_MIN_CHANGE_M for move in moves[-len(homes) :]), moves
    else:
        assert homes == []


def test_get_home_position_once_home_is_set(peer: Peer) -> None:
    peer.wait_for("HOME_POSITION", 40.0, since=0)
    mark = peer.mark()
    ack = peer.command_long(mavlink2.MAV_CMD_GET_HOME_POSITION)
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    peer.wait_for("HOME_POSITION", 1.0, since=mark)


FLOAT32_DEG = 2e-6
"""COMMAND_LONG carries degrees as float32: 2e-6 degrees (0.2 m) apart near 30 degrees."""


def test_do_set_home_to_a_point_and_to_here(peer: Peer) -> None:
    peer.wait_ready()  # DO_SET_HOME to here needs a position
    first = peer.wait_for("HOME_POSITION", 40.0, since=0)
    lat, lon = moved(first.latitude / 1e7, first.longitude / 1e7, 30.0, 30.0)
    alt_m = 95.0
    try:
        mark = peer.mark()
        ack = peer.command_long(mavlink2.MAV_CMD_DO_SET_HOME, 0, 0, 0, 0, lat, lon, alt_m)
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
        home = peer.wait_for("HOME_POSITION", 1.0, since=mark)
        assert home.latitude / 1e7 == pytest.approx(lat, abs=FLOAT32_DEG)
        assert home.longitude / 1e7 == pytest.approx(lon, abs=FLOAT32_DEG)
        assert home.altitude == pytest.approx(alt_m * 1000, abs=10)
        texts = [s.text for s in peer.texts_since(mark)]
        said = f"Set HOME to {lat:.5f} {lon:.5f} at {alt_m:.2f}m"
        assert texts == ([said] if peer.kind == "rover" else []), texts  # ArduRover says it
    finally:
        mark = peer.mark()
        ack = peer.command_long(mavlink2.MAV_CMD_DO_SET_HOME, 1)
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    home = peer.wait_for("HOME_POSITION", 1.0, since=mark)
    position = peer.wait_for("GPS_RAW_INT", 2.0)  # (ArduCopter streams no positions unasked)
    assert (
        distance_m(
            (home.latitude / 1e7, home.longitude / 1e7), (position.lat / 1e7, position.lon / 1e7)
        )
        < 1.0
    )
