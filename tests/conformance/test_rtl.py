"""RTL, and home moving with the vehicle: a rover drives home and stops there in RTL; a
copter climbs to RTL_ALT, returns, lands and disarms. (A plane circles home:
test_plane.py.)

Home here is where the firmware puts it by itself: ArduRover moves it to where it is
disarmed, ArduCopter to where it is armed (test_home.py, which locks it with
DO_SET_HOME, runs after this file).
"""

from __future__ import annotations

import pytest
from flight import (
    ROVER_SPEED_M_S,
    disarmed,
    distance_m,
    first,
    fix_of,
    goto,
    here,
    landed_states,
    moved,
    takeoff,
    track,
    within,
)
from harness import Peer, backends
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

TAKEOFF_M = 10.0

ROVER_LEG_M = 25.0
ROVER_RTL_S = 16.2
"""SITL: RTL 25 m back the way it came (WP_SPEED 3, RTL_SPEED 0), to 'Reached destination'
(16.2-18.9 s: it overshoots and comes back before it says so)."""
COPTER_AWAY_M = 40.0
COPTER_RTL_S = 48.7
"""SITL: RTL from 40 m away at 10 m (RTL_ALT 15 m, WPNAV_SPEED 500) to 'Disarming motors'."""
RTL_ALT_M = 15.0


def reached(peer: Peer, target: tuple[float, float], within_s: float, radius_m: float) -> None:
    """Wait until the vehicle is within ``radius_m`` of ``target`` and stopped."""

    def there(msg: object) -> bool:
        """there, stopped"""
        f = fix_of(msg)
        return distance_m((f.lat_deg, f.lon_deg), target) < radius_m and f.ground_speed_m_s < 0.1

    peer.wait_for("GLOBAL_POSITION_INT", within_s, where=there)


ROVER_WP_RADIUS_M = 2.0
"""ArduRover's WP_RADIUS default: it stops anywhere within 2 m of a guided target (on a
loaded machine SITL at 10x stopped 1.56 m short)."""


@backends(kinds=("rover",))
def test_rover_home_moves_at_disarm_and_rtl_drives_there(rover: Peer) -> None:
    peer = rover
    start = here(peer)
    assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
    spot = moved(start.lat_deg, start.lon_deg, ROVER_LEG_M, 0.0)
    goto(peer, *spot, 0.0)
    reached(peer, spot, 40.0, ROVER_WP_RADIUS_M)
    parked = here(peer)
    # Disarmed, ArduRover moves home to where it is, at its altitude above sea level.
    mark = peer.mark()
    assert peer.disarm().result == mavlink2.MAV_RESULT_ACCEPTED
    home = peer.wait_for("HOME_POSITION", 2.0, since=mark)
    assert distance_m((home.latitude / 1e7, home.longitude / 1e7), parked[1:3]) < 0.5
    assert home.altitude / 1000 == pytest.approx(peer.spec.home.alt_m, abs=0.5)
    # Away and back by RTL: it drives home, says so and stays there in RTL, armed.
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
    away = moved(parked.lat_deg, parked.lon_deg, 0.0, ROVER_LEG_M)
    goto(peer, *away, 0.0)
    reached(peer, away, 60.0, ROVER_WP_RADIUS_M)
    mark = peer.mark()
    ack = peer.set_mode("RTL")
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    said = peer.wait_for(
        "STATUSTEXT", 60.0, where=lambda m: m.text == "Reached destination", since=mark
    )
    assert said.severity == mavlink2.MAV_SEVERITY_INFO
    assert within(peer.time_of(said) - peer.time_of(ack), ROVER_RTL_S, slower=1.5)
    peer.run_for(2.0)
    end = here(peer)
    assert distance_m((end.lat_deg, end.lon_deg), parked[1:3]) < 1.5
    hb = peer.heartbeat()
    assert peer.mode_name(hb.custom_mode) == "RTL"
    assert hb.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED
    fixes = track(peer, mark)
    assert max(f.ground_speed_m_s for f in fixes) <= ROVER_SPEED_M_S * 1.15  # SITL: 3.36


@backends(kinds=("copter",))
def test_copter_rtl_climbs_returns_lands_and_disarms(copter: Peer) -> None:
    peer = copter
    mark = peer.mark()
    assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
    # ArduCopter moves home to where it arms.
    start = here(peer)
    home = peer.wait_for("HOME_POSITION", 2.0, since=mark)
    assert distance_m((home.latitude / 1e7, home.longitude / 1e7), start[1:3]) < 0.5
    peer.run_for(0.5)
    assert takeoff(peer, TAKEOFF_M).result == mavlink2.MAV_RESULT_ACCEPTED
    peer.wait_for("EXTENDED_SYS_STATE", 20.0, where=lambda m: m.landed_state == 2)
    away = moved(start.lat_deg, start.lon_deg, COPTER_AWAY_M, 0.0)
    goto(peer, *away, TAKEOFF_M)

    def there(msg: object) -> bool:
        """over the point"""
        f = fix_of(msg)
        return distance_m((f.lat_deg, f.lon_deg), away) < 1.0

    peer.wait_for("GLOBAL_POSITION_INT", 40.0, where=there)
    peer.run_for(2.0)
    mark = peer.mark()
    ack = peer.set_mode("RTL")
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED
    rtl_s = peer.time_of(ack)
    peer.wait_for("HEARTBEAT", 90.0, where=disarmed)
    fixes = track(peer, mark)
    disarms = [s for s in peer.texts_since(mark) if s.text == "Disarming motors"]
    assert len(disarms) == 1
    took_s = disarms[0].time_s - rtl_s
    top = max(f.up_m for f in fixes)
    leaving = first(fixes, lambda f: distance_m((f.lat_deg, f.lon_deg), away) > 1.0)
    end = fixes[-1]
    assert within(took_s, COPTER_RTL_S)
    assert top == pytest.approx(RTL_ALT_M, abs=0.5)
    assert leaving is not None and leaving.up_m >= RTL_ALT_M - 1.0  # climbs first
    assert distance_m((end.lat_deg, end.lon_deg), start[1:3]) < 1.5
    assert end.up_m < 0.2
    assert [s for _, s in landed_states(peer, mark)] == [2, 4, 1]
    assert peer.mode_name(peer.heartbeat().custom_mode) == "RTL"
