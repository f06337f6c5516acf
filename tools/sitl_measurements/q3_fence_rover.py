"""Q3 (rover): circle fence with and without avoidance; polygon inclusion fence breach.

    .venv/bin/python tools/sitl_measurements/q3_fence_rover.py --out out/

  R1 FENCE_TYPE=2 RADIUS=50 ACTION=1 ENABLE=1, AVOID_ENABLE at its default (3): drive in
     GUIDED to 120 m north: where does it stop, is a breach recorded?
  R2 AVOID_ENABLE=0, drive on: breach distance, mode, texts, FENCE_STATUS, SYS_STATUS;
     then what RTL does over 40 s
  R3 polygon inclusion fence (square of +-40 m, uploaded with the mission protocol as
     MAV_MISSION_TYPE_FENCE), FENCE_TYPE=4, ACTION=2 (Hold): back home, then drive east
     towards 100 m: breach, mode; then disarm and try to arm outside.

Writes q3_rover.jsonl and q3_rover.json in the output folder.
Findings: docs/sitl-measurements.md, section 3.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Msg, Options, dist_m, mav, offset, parse_args, write_json

GEOFENCE = mav.MAV_SYS_STATUS_GEOFENCE


def measure(g: Gcs, options: Options) -> None:
    """Run cases R1 to R3 on one rover and write what each showed."""
    res: dict[str, Any] = {}
    lat0, lon0 = ORIGIN.lat_deg, ORIGIN.lon_deg

    def bits() -> dict[str, bool]:
        """The next SYS_STATUS's geofence present/enabled/healthy bits."""
        s = g.wait_for("SYS_STATUS", 3)
        return {
            "present": bool(s.onboard_control_sensors_present & GEOFENCE),
            "enabled": bool(s.onboard_control_sensors_enabled & GEOFENCE),
            "healthy": bool(s.onboard_control_sensors_health & GEOFENCE),
        }

    def fstat() -> dict[str, int] | None:
        """The latest FENCE_STATUS (None before one came)."""
        m = g.last.get("FENCE_STATUS")
        return (
            None
            if m is None
            else {
                "breach_status": m.breach_status,
                "breach_count": m.breach_count,
                "breach_type": m.breach_type,
                "breach_time": m.breach_time,
                "mitigation": m.breach_mitigation,
            }
        )

    def home_dist() -> float:
        """The latest position's distance from the origin (m, to 1 cm)."""
        p = g.pos()
        return round(dist_m(lat0, lon0, p[0], p[1]), 2)

    track: list[tuple[float, float]] = []
    modes: list[tuple[float, int]] = []

    def record(t: float, m: Msg) -> None:
        """Keep every distance from the origin, and each mode change."""
        if m.get_type() == "GLOBAL_POSITION_INT" and m.lat != 0:
            track.append((t, round(dist_m(lat0, lon0, m.lat / 1e7, m.lon / 1e7), 2)))
        if m.get_type() == "HEARTBEAT" and (not modes or modes[-1][1] != m.custom_mode):
            modes.append((t, m.custom_mode))

    g.on_msg.append(record)
    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 5),
            ("SYS_STATUS", 2),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
            ("FENCE_STATUS", 2),
        )
    )
    g.wait_ready(150)
    res["R0_bits_default"] = bits()

    # R1 circle fence, avoidance on (default)
    t0 = g.now
    for n, v in (("FENCE_TYPE", 2), ("FENCE_RADIUS", 50), ("FENCE_ACTION", 1), ("FENCE_ENABLE", 1)):
        g.param_set(n, v)
    g.run_for(2)
    res["R1_bits_enabled_disarmed"] = bits()
    res["R1_AVOID_ENABLE"] = g.param_get("AVOID_ENABLE").param_value
    g.set_mode("GUIDED")
    g.arm_when_ready(60)
    la, lo = offset(lat0, lon0, 120, 0)
    g.goto(la, lo, 0)
    g.run_for(60)
    res["R1"] = {
        "home_dist": home_dist(),
        "mode": g.mode(),
        "fence_status": fstat(),
        "bits": bits(),
        "texts": g.texts_since(t0),
    }
    print("R1", res["R1"], flush=True)

    # R2 avoidance off: breach
    t0 = g.now
    g.param_set("AVOID_ENABLE", 0)
    g.set_mode("HOLD")
    g.run_for(1)
    g.set_mode("GUIDED")
    g.goto(la, lo, 0)
    m = g.wait_for(None, 60, lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode != 15)
    res["R2"] = {
        "mode_change_t": g.now,
        "new_mode": m.custom_mode,
        "home_dist_at_mode_change": home_dist(),
    }
    g.run_for(2)
    res["R2"].update({"fence_status": fstat(), "bits": bits(), "texts": g.texts_since(t0)})
    first_out = next(((t, d) for t, d in track if t >= t0 and d >= 50), None)
    res["R2"]["first_GPI_at_or_beyond_50m"] = first_out
    print("R2", res["R2"], flush=True)
    g.run_for(40)
    res["R2_later"] = {
        "home_dist": home_dist(),
        "mode": g.mode(),
        "fence_status": fstat(),
        "bits": bits(),
        "texts": g.texts_since(t0),
    }
    print("R2 later", res["R2_later"], flush=True)

    # R3 polygon inclusion fence
    t0 = g.now
    g.set_mode("HOLD")
    g.param_set("FENCE_ENABLE", 0)
    corners = [offset(lat0, lon0, n, e) for n, e in ((40, -40), (40, 40), (-40, 40), (-40, -40))]
    items = [
        mav.MAVLink_mission_item_int_message(
            g.target,
            1,
            0,
            mav.MAV_FRAME_GLOBAL,
            mav.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            0,
            1,
            4,
            0,
            0,
            0,
            int(a * 1e7),
            int(b * 1e7),
            0,
            mav.MAV_MISSION_TYPE_FENCE,
        )
        for a, b in corners
    ]
    ack = g.upload(items, mav.MAV_MISSION_TYPE_FENCE)
    res["R3_upload_ack"] = ack.type
    g.param_set("FENCE_TYPE", 4)
    g.param_set("FENCE_ACTION", 2)
    g.param_set("FENCE_ENABLE", 1)
    g.run_for(2)
    res["R3_FENCE_TOTAL"] = g.param_get("FENCE_TOTAL").param_value
    res["R3_bits_before"] = bits()
    res["R3_home_dist_before"] = home_dist()
    res["R3_fence_status_before"] = fstat()
    print(
        "R3 before",
        res["R3_upload_ack"],
        res["R3_bits_before"],
        res["R3_home_dist_before"],
        res["R3_fence_status_before"],
        g.texts_since(t0),
        flush=True,
    )
    # back home first if outside, then east
    g.set_mode("GUIDED")
    g.goto(lat0, lon0, 0)
    g.run_for(40)
    t1 = g.now
    res["R3_back_home"] = {
        "home_dist": home_dist(),
        "mode": g.mode(),
        "fence_status": fstat(),
        "texts": g.texts_since(t0),
    }
    print("R3 back", res["R3_back_home"], flush=True)
    g.set_mode("GUIDED")
    la, lo = offset(lat0, lon0, 0, 100)
    g.goto(la, lo, 0)
    m = g.wait_for(None, 60, lambda m: m.get_type() == "HEARTBEAT" and m.custom_mode != 15)
    res["R3"] = {"mode_change_t": g.now, "new_mode": m.custom_mode, "pos": g.pos()}

    p = g.pos()
    res["R3"]["east_m"] = round(dist_m(lat0, lon0, lat0, p[1]), 2)
    g.run_for(3)
    res["R3"].update({"fence_status": fstat(), "bits": bits(), "texts": g.texts_since(t1)})
    print("R3", res["R3"], flush=True)
    g.run_for(5)
    g.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    g.run_for(2)
    t2 = g.now
    ack = g.arm()
    g.run_for(3)
    res["R3_arm_outside"] = {"ack": ack.result, "texts": g.texts_since(t2), "bits": bits()}
    print("R3 arm outside", res["R3_arm_outside"], flush=True)
    res["modes"] = modes
    write_json(options.out / "q3_rover.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a rover."""
    options = parse_args(__doc__, argv, vehicles=("rover",))
    with Gcs(options, "rover", "q3_rover") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
