"""Q2 (copter): SET_POSITION_TARGET_GLOBAL_INT frames and NAV_TAKEOFF frames in GUIDED.

    .venv/bin/python tools/sitl_measurements/q2_frames_copter.py --out out/

Does ArduCopter fly an AMSL target (MAV_FRAME_GLOBAL_INT) to the same height as the
equivalent above-home one? This arms in GUIDED, tries NAV_TAKEOFF as COMMAND_INT in frames
6, 5 and 3 (10 m), then flies targets in MAV_FRAME_GLOBAL_RELATIVE_ALT_INT (6, 20 m above
home), MAV_FRAME_GLOBAL_INT (5, home + 30 m AMSL), MAV_FRAME_GLOBAL (0, home + 20 m), an
unknown frame (1), and last the usual mistake: a relative height (15) sent in the AMSL
frame. It records the settled heights (25 s each) and POSITION_TARGET_GLOBAL_INT.

Writes q2_copter.jsonl and q2_copter.json in the output folder.
Findings: docs/sitl-measurements.md, section 2.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Options, mav, offset, parse_args, write_json


def measure(g: Gcs, options: Options) -> None:
    """Take off, fly the targets in each frame, record where the copter settles."""
    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 5),
            ("SYS_STATUS", 1),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
            ("POSITION_TARGET_GLOBAL_INT", 2),
        )
    )
    g.wait_ready(150)
    home = g.wait_for("HOME_POSITION", 10)
    home_amsl = home.altitude / 1000.0
    print("home AMSL", home_amsl)
    res: dict[str, Any] = {"home_amsl": home_amsl}
    g.set_mode("GUIDED")
    g.arm_when_ready()

    # NAV_TAKEOFF via COMMAND_INT in frame 6 (GLOBAL_RELATIVE_ALT_INT) and 3 (GLOBAL_RELATIVE_ALT)
    a6 = g.command_int(mav.MAV_CMD_NAV_TAKEOFF, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, z=10)
    a5 = g.command_int(mav.MAV_CMD_NAV_TAKEOFF, mav.MAV_FRAME_GLOBAL_INT, z=home_amsl + 10)
    a3 = g.command_int(mav.MAV_CMD_NAV_TAKEOFF, mav.MAV_FRAME_GLOBAL_RELATIVE_ALT, z=10)
    res["takeoff_command_int"] = {
        "frame6": a6 and a6.result,
        "frame5": a5 and a5.result,
        "frame3": a3 and a3.result,
    }
    print("takeoff acks", res["takeoff_command_int"])
    if not a3 or a3.result != 0:
        g.command_long(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    g.run_for(20)
    print("after takeoff", g.pos())
    res["after_takeoff"] = g.pos()

    def settle(label: str, seconds: float = 25.0) -> None:
        """Wait ``seconds``, then record the position, mode and the reported target."""
        g.run_for(seconds)
        p = g.pos()
        pt = g.last.get("POSITION_TARGET_GLOBAL_INT")
        res[label] = {
            "lat": p[0],
            "lon": p[1],
            "alt_amsl": p[2],
            "rel": p[3],
            "mode": g.mode(),
            "armed": g.armed(),
            "target": None if pt is None else (pt.coordinate_frame, pt.lat_int, pt.lon_int, pt.alt),
        }
        print(label, res[label], flush=True)

    lat0, lon0 = ORIGIN.lat_deg, ORIGIN.lon_deg
    la, lo = offset(lat0, lon0, 30, 0)
    g.goto(la, lo, 20, frame=mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT)
    settle("A frame6 rel=20")
    la, lo = offset(lat0, lon0, 30, 30)
    g.goto(la, lo, home_amsl + 30, frame=mav.MAV_FRAME_GLOBAL_INT)
    settle("B frame5 amsl=home+30")
    la, lo = offset(lat0, lon0, 0, 30)
    g.goto(la, lo, home_amsl + 20, frame=mav.MAV_FRAME_GLOBAL)
    settle("C frame0 amsl=home+20")
    t0 = g.now
    la, lo = offset(lat0, lon0, 0, 0)
    g.goto(la, lo, 25, frame=mav.MAV_FRAME_LOCAL_NED)
    settle("D frame1 (unknown) alt=25", 10)
    res["D_texts"] = g.texts_since(t0)
    # the mistake: a relative height sent in the AMSL frame
    t0 = g.now
    g.goto(la, lo, 15, frame=mav.MAV_FRAME_GLOBAL_INT)
    settle("E frame5 alt=15 (=75 m below home)", 40)
    res["E_texts"] = g.texts_since(t0)
    write_json(options.out / "q2_copter.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a copter."""
    options = parse_args(__doc__, argv, vehicles=("copter",))
    with Gcs(options, "copter", "q2_copter") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
