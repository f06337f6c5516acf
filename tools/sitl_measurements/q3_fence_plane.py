"""Q3 (plane): circle fence breach, DO_REPOSITION outside the fence, mode change in recovery.

    .venv/bin/python tools/sitl_measurements/q3_fence_plane.py --out out/

  A FENCE_ENABLE=1 with the default FENCE_TYPE (4, polygon) and no polygon: arm attempt
  B FENCE_TYPE=2 RADIUS=300 ACTION=1: takeoff (TAKEOFF mode flies on north past 300 m, so
    the first breach comes during the climb); DO_REPOSITION 600 m north (outside), then
    250 m north (inside; the 80 m loiter circle crosses 300 m): breach, texts, mode,
    FENCE_STATUS; GUIDED asked for during the recovery; the breach cleared; LOITER after.

Writes q3_plane.jsonl and q3_plane.json in the output folder.
Findings: docs/sitl-measurements.md, section 3.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Msg, Options, dist_m, mav, offset, parse_args, write_json

GEOFENCE = mav.MAV_SYS_STATUS_GEOFENCE


def measure(g: Gcs, options: Options) -> None:
    """Run cases A and B on one plane and write what each showed."""
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

    def fstat() -> tuple[int, int, int, int] | None:
        """The latest FENCE_STATUS: breach status, count, type and time (None before one)."""
        m = g.last.get("FENCE_STATUS")
        return (
            None if m is None else (m.breach_status, m.breach_count, m.breach_type, m.breach_time)
        )

    def home_dist() -> float:
        """The latest position's distance from the origin (m, to 0.1 m)."""
        p = g.pos()
        return round(dist_m(lat0, lon0, p[0], p[1]), 1)

    track: list[tuple[float, float]] = []
    modes: list[tuple[float, int]] = []

    def record(t: float, m: Msg) -> None:
        """Keep every distance from the origin, and each mode change."""
        if m.get_type() == "GLOBAL_POSITION_INT" and m.lat != 0:
            track.append((t, round(dist_m(lat0, lon0, m.lat / 1e7, m.lon / 1e7), 1)))
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
    res["defaults"] = {
        n: g.param_get(n).param_value
        for n in ("FENCE_TYPE", "FENCE_ACTION", "FENCE_RADIUS", "FENCE_OPTIONS", "FENCE_AUTOENABLE")
    }
    res["bits_default"] = bits()
    # A
    t0 = g.now
    g.param_set("FENCE_ENABLE", 1)
    g.run_for(2)
    g.set_mode("TAKEOFF")
    ack = g.arm()
    g.run_for(2)
    res["A"] = {"ack": ack.result, "texts": g.texts_since(t0), "bits": bits()}
    print("A", res["A"], flush=True)
    # B
    g.param_set("FENCE_ENABLE", 0)
    g.param_set("FENCE_TYPE", 2)
    g.param_set("FENCE_ACTION", 1)
    g.param_set("FENCE_ENABLE", 1)
    g.run_for(2)
    res["B_bits_disarmed"] = bits()
    g.arm_when_ready(60)
    g.run_for(35)
    res["B_after_takeoff"] = {"home_dist": home_dist(), "pos": g.pos(), "mode": g.mode()}
    print("B takeoff", res["B_after_takeoff"], flush=True)
    t0 = g.now
    rel_int = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    la, lo = offset(lat0, lon0, 600, 0)
    ack = g.command_int(mav.MAV_CMD_DO_REPOSITION, rel_int, -1, 1, 0, 0, la * 1e7, lo * 1e7, 60)
    g.run_for(2)
    res["B_reposition_outside"] = {
        "ack": None if ack is None else ack.result,
        "mode": g.mode(),
        "texts": g.texts_since(t0),
    }
    print("B outside", res["B_reposition_outside"], flush=True)
    la, lo = offset(lat0, lon0, 250, 0)
    ack = g.command_int(mav.MAV_CMD_DO_REPOSITION, rel_int, -1, 1, 0, 0, la * 1e7, lo * 1e7, 60)
    res["B_reposition_inside_ack"] = None if ack is None else ack.result
    txt = g.wait_for("STATUSTEXT", 120, lambda m: "breach" in m.text.lower())
    t_b = g.now
    res["B_breach"] = {
        "t": t_b,
        "text": txt.text,
        "severity": txt.severity,
        "home_dist": home_dist(),
    }
    res["B_breach"]["first_GPI_at_or_beyond_300"] = next(
        ((t, d) for t, d in track if t >= t0 and d >= 300), None
    )
    g.run_for(2)
    res["B_breach"].update(
        {
            "mode": g.mode(),
            "fence_status": fstat(),
            "bits": bits(),
            "texts": g.texts_since(t_b - 0.5),
        }
    )
    print("B breach", res["B_breach"], flush=True)
    t1 = g.now
    ack = g.set_mode("GUIDED")
    g.run_for(2)
    res["B_mode_change_in_recovery"] = {
        "ack": ack.result,
        "mode": g.mode(),
        "texts": g.texts_since(t1),
    }
    print("B mode change", res["B_mode_change_in_recovery"], flush=True)
    t2 = g.now
    g.wait_for("FENCE_STATUS", 120, lambda m: m.breach_status == 0)
    res["B_cleared"] = {
        "t": g.now,
        "fence_status_cleared_at": g.now,
        "home_dist": home_dist(),
        "mode": g.mode(),
    }
    g.run_for(2)
    res["B_cleared"].update({"fence_status": fstat(), "bits": bits(), "texts": g.texts_since(t2)})
    print("B cleared", res["B_cleared"], flush=True)
    t3 = g.now
    ack = g.set_mode("LOITER")
    g.run_for(2)
    res["B_mode_change_after_clear"] = {
        "ack": ack.result,
        "mode": g.mode(),
        "texts": g.texts_since(t3),
    }
    print("B after", res["B_mode_change_after_clear"], flush=True)
    res["modes"] = modes
    write_json(options.out / "q3_plane.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a plane."""
    options = parse_args(__doc__, argv, vehicles=("plane",))
    with Gcs(options, "plane", "q3_plane") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
