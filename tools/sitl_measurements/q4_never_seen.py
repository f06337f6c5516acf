"""Q4 (never heard): does the GCS failsafe fire when MAV_GCS_SYSID was never heard?

    .venv/bin/python tools/sitl_measurements/q4_never_seen.py rover|copter|plane --out out/

Heartbeats come only from sysid 245 (MAV_GCS_SYSID stays 255) from the connection on.
The failsafe is enabled, the vehicle armed and moving (copter: takeoff to 10 m; rover:
driving 400 m north; plane: enabled only once flying in GUIDED, because enabled before
arming it fires on the ground at once), and 40 s of its time pass. Then ONE heartbeat
from 255 is sent and nothing more: the failsafe should follow the timeout later.

Writes q4n_<vehicle>.jsonl and q4n_<vehicle>.json in the output folder.
Findings: docs/sitl-measurements.md, section 4.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Options, mav, offset, parse_args, write_json


def measure(g: Gcs, options: Options) -> None:
    """Fly 40 s with the failsafe on and 255 never heard, then send one 255 heartbeat."""
    vehicle = g.vehicle
    g.hb_sysids = [245]
    res: dict[str, Any] = {"vehicle": vehicle}
    lat0, lon0 = ORIGIN.lat_deg, ORIGIN.lon_deg
    g.start(streams=(("GLOBAL_POSITION_INT", 2), ("SYS_STATUS", 1), ("EKF_STATUS_REPORT", 1)))
    g.wait_ready(150)
    if vehicle == "copter":
        g.param_set("FS_GCS_ENABLE", 1)
        g.set_mode("GUIDED")
        g.arm_when_ready(60)
        g.command_long(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    elif vehicle == "rover":
        g.param_set("FS_GCS_ENABLE", 1)
        g.set_mode("GUIDED")
        g.arm_when_ready(60)
        la, lo = offset(lat0, lon0, 400, 0)
        g.goto(la, lo, 0)
    else:
        # ArduPlane: enabled only once flying (enabled before arming, it fires on the ground
        # at once, switches TAKEOFF to RTL and arming is refused: "Arm: RTL mode not armable")
        g.set_mode("TAKEOFF")
        g.arm_when_ready(60)
        g.run_for(35)
        la, lo = offset(lat0, lon0, 300, 0)
        g.command_int(
            mav.MAV_CMD_DO_REPOSITION,
            mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            -1,
            1,
            0,
            0,
            la * 1e7,
            lo * 1e7,
            80,
        )
        g.run_for(5)
        g.param_set("FS_LONG_ACTN", 1)
        g.param_set("FS_GCS_ENABL", 1)
        res["plane_fs_enabled_at"] = g.now
    t0 = g.now
    g.run_for(40)
    res["never_heard_40s"] = {
        "t0": t0,
        "t1": g.now,
        "mode": g.mode(),
        "armed": g.armed(),
        "texts": g.texts_since(t0),
    }
    print("never heard:", res["never_heard_40s"], flush=True)
    # one heartbeat from 255, then silence from 255
    t1 = g.now
    g.send(
        mav.MAVLink_heartbeat_message(
            mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE, 3
        ),
        sysid=255,
    )
    fs = g.wait_for("STATUSTEXT", 30, lambda m: "failsafe" in m.text.lower(), raise_=False)
    res["one_heartbeat"] = {
        "t_sent": t1,
        "t_text": g.now if fs else None,
        "text": fs and fs.text,
        "delay_s": round(g.now - t1, 2) if fs else None,
    }
    g.run_for(3)
    res["one_heartbeat"]["mode_after"] = g.mode()
    print("one heartbeat:", res["one_heartbeat"], flush=True)
    write_json(options.out / f"q4n_{vehicle}.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on the vehicle named on the command line."""
    options = parse_args(__doc__, argv)
    with Gcs(options, options.vehicle, f"q4n_{options.vehicle}") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
