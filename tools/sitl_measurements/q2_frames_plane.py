"""Q2 (plane): MAV_CMD_DO_REPOSITION frames; SET_POSITION_TARGET_GLOBAL_INT in GUIDED.

    .venv/bin/python tools/sitl_measurements/q2_frames_plane.py --out out/

Which frames does ArduPlane take for a guided target? This takes off in TAKEOFF mode
(TKOFF_ALT 50), then sends DO_REPOSITION (param2 = MAV_DO_REPOSITION_FLAGS_CHANGE_MODE) as
COMMAND_INT in frames 5 (GLOBAL_INT, AMSL), 0 (GLOBAL), 6 (GLOBAL_RELATIVE_ALT_INT), 3 and
an unknown frame 1, and as COMMAND_LONG; then a SET_POSITION_TARGET_GLOBAL_INT with a far
lat/lon and a new altitude (ArduPlane takes only the altitude). For each it records the
ack, the mode, the height reached after 40 s and the distance to the point.

Writes q2_plane.jsonl and q2_plane.json in the output folder.
Findings: docs/sitl-measurements.md, section 2.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Options, dist_m, mav, offset, parse_args, write_json


def measure(g: Gcs, options: Options) -> None:
    """Take off, reposition in each frame and form, then change only the altitude."""
    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 5),
            ("SYS_STATUS", 1),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
            ("POSITION_TARGET_GLOBAL_INT", 2),
            ("NAV_CONTROLLER_OUTPUT", 2),
        )
    )
    g.wait_ready(150)
    res: dict[str, Any] = {}
    g.set_mode("TAKEOFF")
    g.arm_when_ready()
    g.run_for(40)
    home = g.last["HOME_POSITION"]
    home_amsl = home.altitude / 1000.0
    res["home_amsl_after_arm"] = home_amsl
    res["after_takeoff"] = (g.pos(), g.mode())
    print("after takeoff", res["after_takeoff"], "home", home_amsl, flush=True)
    lat0, lon0 = ORIGIN.lat_deg, ORIGIN.lon_deg
    change_mode = mav.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE

    def repo(
        label: str, frame: int, north: float, east: float, z: float, settle: float = 40.0
    ) -> None:
        """DO_REPOSITION (COMMAND_INT) to a point north/east of the origin; record the result."""
        la, lo = offset(lat0, lon0, north, east)
        t0 = g.now
        ack = g.command_int(
            mav.MAV_CMD_DO_REPOSITION, frame, -1, change_mode, 0, 0, la * 1e7, lo * 1e7, z
        )
        g.run_for(settle)
        p = g.pos()
        pt = g.last.get("POSITION_TARGET_GLOBAL_INT")
        res[label] = {
            "ack": None if ack is None else ack.result,
            "mode": g.mode(),
            "alt_amsl": p[2],
            "rel": p[3],
            "dist_to_target_m": round(dist_m(p[0], p[1], la, lo), 1),
            "target": None if pt is None else (pt.coordinate_frame, pt.lat_int, pt.lon_int, pt.alt),
            "texts": g.texts_since(t0),
        }
        print(label, res[label], flush=True)

    repo("R1 frame5 GLOBAL_INT z=home+80", mav.MAV_FRAME_GLOBAL_INT, 400, 0, home_amsl + 80)
    repo("R2 frame0 GLOBAL z=home+60", mav.MAV_FRAME_GLOBAL, 0, 400, home_amsl + 60)
    repo("R3 frame6 REL_INT z=90", mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, -400, 0, 90)
    repo("R4 frame3 REL z=70", mav.MAV_FRAME_GLOBAL_RELATIVE_ALT, 0, -400, 70)
    repo("R5 frame1 unknown", mav.MAV_FRAME_LOCAL_NED, 400, 400, 70, settle=5)
    # COMMAND_LONG form
    la, lo = offset(lat0, lon0, 400, 0)
    ack = g.command_long(
        mav.MAV_CMD_DO_REPOSITION, -1, change_mode, 0, 0, la, lo, home_amsl + 70, raise_=False
    )
    res["R6 COMMAND_LONG"] = {"ack": None if ack is None else ack.result}
    print("R6", res["R6 COMMAND_LONG"], flush=True)
    # SET_POSITION_TARGET_GLOBAL_INT with a far lat/lon and a new relative alt
    g.run_for(5)
    before = g.pos()
    la, lo = offset(lat0, lon0, -1500, -1500)
    g.goto(la, lo, 110, frame=mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, mask=0x0FF8)
    g.run_for(40)
    p = g.pos()
    pt = g.last.get("POSITION_TARGET_GLOBAL_INT")
    res["S1 SET_POSITION_TARGET_GLOBAL_INT rel 110, far latlon"] = {
        "before": before,
        "after": p,
        "dist_to_sent_latlon_m": round(dist_m(p[0], p[1], la, lo), 1),
        "target": None if pt is None else (pt.coordinate_frame, pt.lat_int, pt.lon_int, pt.alt),
    }
    print("S1", res["S1 SET_POSITION_TARGET_GLOBAL_INT rel 110, far latlon"], flush=True)
    write_json(options.out / "q2_plane.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a plane."""
    options = parse_args(__doc__, argv, vehicles=("plane",))
    with Gcs(options, "plane", "q2_plane") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
