"""Probe: a plane flying straight and level north, then LOITER; its track in the entry frame.

Prints, every second for ``--watch`` seconds after LOITER is asked for, where the plane
is relative to the point and course it entered LOITER on (metres along the entry course
and to its right), on the simulated autopilot or ArduPilot SITL (the conformance
harness's backends). Used to fit the simulated plane's loiter entry to ArduPlane's.

    PYTHONPATH=.:tests/conformance python benchmarks/probe_plane_loiter.py sitl-plane
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "conformance"))

from flight import FLIGHT_STREAMS, fix_of, flight_params, moved, offset_m, streaming
from harness import open_peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

PARAMS = {
    "AIRSPEED_CRUISE": 15.0,
    "AIRSPEED_MIN": 9.0,
    "AIRSPEED_MAX": 22.0,
    "WP_LOITER_RAD": 60.0,
    "WP_RADIUS": 90.0,
    "NAVL1_PERIOD": 17.0,
    "NAVL1_DAMPING": 0.75,
    "ROLL_LIMIT_DEG": 45.0,
    "TKOFF_ALT": 60.0,
}


def seen(peer: Any, mark: int, kind: str) -> list[Any]:
    """The messages of one kind since a mark."""
    return [m for _, m in peer.history[mark:] if m.get_type() == kind]


def main() -> int:
    """Fly the probe on the backend named on the command line; print the track."""
    parser = argparse.ArgumentParser()
    parser.add_argument("backend")
    parser.add_argument("--watch", type=float, default=40.0)
    parser.add_argument("--straight", type=float, default=35.0)
    args = parser.parse_args()
    peer = open_peer(args.backend)
    try:
        peer.wait_ready()
        streams = dict(FLIGHT_STREAMS, ATTITUDE=100_000, NAV_CONTROLLER_OUTPUT=100_000)
        with flight_params(peer, PARAMS), streaming(peer, streams):
            assert peer.set_mode("TAKEOFF").result == mavlink2.MAV_RESULT_ACCEPTED
            assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
            peer.wait_for("EXTENDED_SYS_STATE", 60.0, where=lambda m: m.landed_state == 2)
            home = peer.wait_for("HOME_POSITION", 5.0, since=0)
            far = moved(home.latitude / 1e7, home.longitude / 1e7, 3000.0, 0.0)
            from test_plane import reposition

            assert reposition(peer, *far, 60.0).result == mavlink2.MAV_RESULT_ACCEPTED
            peer.run_for(args.straight)
            mark = peer.mark()
            ack = peer.set_mode("LOITER")
            t0 = peer.time_of(ack)
            peer.run_for(args.watch)
            fixes = [fix_of(m) for m in seen(peer, mark, "GLOBAL_POSITION_INT")]
            vfr = [m for _, m in peer.history[mark:] if m.get_type() == "VFR_HUD"]
            entry = min(fixes, key=lambda f: abs(f.t_s - t0))
            course = math.atan2(entry.east_m_s, entry.north_m_s)
            print(
                f"# {args.backend}: LOITER at {t0:.2f} s, course {math.degrees(course):.1f} deg, "
                f"speed {entry.ground_speed_m_s:.1f} m/s, up {entry.up_m:.1f} m"
            )
            nxt = 0.0
            for f in fixes:
                dt = f.t_s - entry.t_s
                if dt + 1e-6 < nxt:
                    continue
                n, e = offset_m(entry.lat_deg, entry.lon_deg, f.lat_deg, f.lon_deg)
                along = n * math.cos(course) + e * math.sin(course)
                right = -n * math.sin(course) + e * math.cos(course)
                trk = math.degrees(math.atan2(f.east_m_s, f.north_m_s) - course) % 360
                print(
                    f"{dt:5.1f} {along:8.1f} {right:8.1f} r={math.hypot(along, right):6.1f} "
                    f"trk={trk:6.1f} v={f.ground_speed_m_s:5.1f} up={f.up_m:5.1f}"
                )
                nxt += 1.0
            att = [m for _, m in peer.history[mark:] if m.get_type() == "ATTITUDE"]
            nav = [m for _, m in peer.history[mark:] if m.get_type() == "NAV_CONTROLLER_OUTPUT"]
            late = [math.degrees(m.roll) for m in att[len(att) // 2 :]]
            print("# roll at 0..12 s", [round(math.degrees(m.roll)) for m in att[:130:5]])
            print("# nav_roll at 0..12 s", [round(m.nav_roll) for m in nav[:130:5]])
            if late:
                asked = [m.nav_roll for m in nav[len(nav) // 2 :]] or [0.0]
                print(
                    f"# second half: roll {sum(late) / len(late):.1f} deg, nav_roll "
                    f"{sum(asked) / len(asked):.1f}"
                )
            print("# airspeeds", [round(m.airspeed, 1) for m in vfr[:: max(len(vfr) // 10, 1)]])
    finally:
        peer.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
