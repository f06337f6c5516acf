"""Q1: the altitude fields over boot, arming and flight; also a parameter dump and Q5 probes.

    .venv/bin/python tools/sitl_measurements/q1_altitude.py rover|copter|plane --out out/

Boots one vehicle and logs GLOBAL_POSITION_INT, GPS_RAW_INT, HOME_POSITION and
GPS_GLOBAL_ORIGIN (5 Hz, asked right after the first HEARTBEAT) and the EKF flags at
each change, through boot, the GPS fix, home, the EKF origin, arming and a short flight
(copter: takeoff to 10 m, 60 m north, land; rover: 40 s towards a point 80 m north and
40 m east; plane: TAKEOFF mode, loiter, RTL). Before arming it dumps every parameter and
probes PARAM_SET with a few values out of range, of the wrong type or unknown.

Writes, in the output folder: q1_<vehicle>.jsonl (every message),
q1_<vehicle>_timeline.txt (the altitude fields at each change), params_<vehicle>.json
(every parameter: value, type, index, count) and q5_<vehicle>.json (the PARAM_SET probes).
Findings: docs/sitl-measurements.md, sections 1 and 5.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Msg, Options, mav, offset, parse_args, write_json

STREAMS = (
    ("GLOBAL_POSITION_INT", 5),
    ("GPS_RAW_INT", 5),
    ("SYS_STATUS", 1),
    ("EKF_STATUS_REPORT", 2),
    ("HOME_POSITION", 1),
    ("GPS_GLOBAL_ORIGIN", 1),
)


def measure(g: Gcs, options: Options) -> None:
    """Boot, dump the parameters, probe PARAM_SET, arm and fly; write the results."""
    vehicle = g.vehicle
    rows: list[str] = []
    state: dict[str, Any] = {
        "gpi": None,
        "gps": None,
        "home": None,
        "origin": None,
        "fix": None,
        "ekf": None,
    }

    def fmt(t: float, ev: str) -> str:
        """One timeline row: the event and every altitude field as last seen."""
        gp, gr, hp = state["gpi"], state["gps"], state["home"]
        origin = state["origin"] if state["origin"] is not None else "-"
        return (
            f"{t:8.2f} {ev:38s} GPI.alt={gp[0] if gp else '-':>9} "
            f"rel={gp[1] if gp else '-':>9} "
            f"GPS_RAW.alt={gr[0] if gr else '-':>9} fix={gr[1] if gr else '-'} "
            f"HOME.alt={hp if hp is not None else '-':>8} ORIGIN.alt={origin} "
            f"ekf=0x{state['ekf'] or 0:x} mode={g.mode()} armed={g.armed()}"
        )

    def watch(t: float, m: Msg) -> None:
        """Add a timeline row when an altitude field moves by more than 0.5 m, or on a text."""
        typ = m.get_type()
        ev = None
        if typ == "GLOBAL_POSITION_INT":
            new = (m.alt / 1000.0, m.relative_alt / 1000.0)
            old = state["gpi"]
            if old is None or abs(new[0] - old[0]) > 0.5 or abs(new[1] - old[1]) > 0.5:
                ev = f"GPI lat={m.lat / 1e7:.5f} lon={m.lon / 1e7:.5f}"
                state["gpi"] = new
        elif typ == "GPS_RAW_INT":
            new = (m.alt / 1000.0, m.fix_type)
            old = state["gps"]
            if old is None or old[1] != new[1] or abs(new[0] - old[0]) > 0.5:
                ev = f"GPS_RAW fix_type={m.fix_type} sats={m.satellites_visible}"
                state["gps"] = new
        elif typ == "HOME_POSITION":
            alt = m.altitude / 1000.0
            if state["home"] is None or abs(alt - state["home"]) > 0.05:
                ev = f"HOME lat={m.latitude / 1e7:.5f}"
                state["home"] = alt
        elif typ == "GPS_GLOBAL_ORIGIN":
            alt = m.altitude / 1000.0
            if state["origin"] is None or abs(alt - state["origin"]) > 0.05:
                ev = "GPS_GLOBAL_ORIGIN"
                state["origin"] = alt
        elif typ == "EKF_STATUS_REPORT":
            if state["ekf"] != m.flags:
                state["ekf"] = m.flags
                ev = "EKF flags"
        elif typ == "STATUSTEXT":
            ev = f"TEXT {m.text}"
        if ev:
            rows.append(fmt(t, ev))

    g.on_msg.append(watch)
    g.start(streams=STREAMS)
    rows.append(fmt(g.now, f"streams {g.stream_results}"))
    g.wait_ready(150)
    rows.append(fmt(g.now, "READY (EKF abs pos + prearm ok)"))
    g.run_for(3)

    # ---- parameter dump (Q3/Q4 parameter lists) and Q5 PARAM_SET behaviour
    params = g.param_list(90)
    write_json(
        options.out / f"params_{vehicle}.json",
        {
            k: {
                "value": v.param_value,
                "type": v.param_type,
                "index": v.param_index,
                "count": v.param_count,
            }
            for k, v in sorted(params.items())
        },
    )
    rows.append(fmt(g.now, f"param list: {len(params)} params"))

    q5: list[dict[str, Any]] = []

    def probe(name: str, value: float, ptype: int = mav.MAV_PARAM_TYPE_REAL32) -> None:
        """Read, PARAM_SET and read again one parameter; record the echo and the texts."""
        before = g.param_get(name, 2)
        t0 = g.now
        echo = g.param_set(name, value, ptype, within_s=3)
        after = g.param_get(name, 2)
        q5.append(
            {
                "name": name,
                "sent": value,
                "ptype_sent": ptype,
                "before": None if before is None else before.param_value,
                "echo": None
                if echo is None
                else (
                    echo.param_value,
                    echo.param_type,
                    echo.param_index,
                    echo.param_count,
                    round(g.now - t0, 3),
                ),
                "after": None if after is None else after.param_value,
                "texts": g.texts_since(t0),
            }
        )
        print("Q5", q5[-1], flush=True)

    int8 = mav.MAV_PARAM_TYPE_INT8
    probe("FENCE_RADIUS", 123.0)
    probe("FENCE_RADIUS", 5.0)  # below range (30..10000)
    probe("FENCE_RADIUS", 50000.0)  # above range
    probe("FENCE_ENABLE", 7.0, int8)  # 0..1 in metadata
    probe("FENCE_TYPE", 255.0, int8)
    probe("NO_SUCH_PARAM", 1.0)
    probe("FENCE_ALT_MAX", -5.0)
    probe("FENCE_RADIUS", 150.0 if vehicle != "plane" else 300.0)
    probe("FENCE_ENABLE", 0.0, int8)
    probe("FENCE_TYPE", params["FENCE_TYPE"].param_value if "FENCE_TYPE" in params else 7, int8)
    write_json(options.out / f"q5_{vehicle}.json", q5)

    # ---- arm and move
    lat0, lon0 = ORIGIN.lat_deg, ORIGIN.lon_deg
    if vehicle == "copter":
        g.set_mode("GUIDED")
        g.arm_when_ready()
        rows.append(fmt(g.now, "ARMED"))
        g.run_for(1)
        ack = g.command_long(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
        rows.append(fmt(g.now, f"NAV_TAKEOFF 10 ack={ack.result}"))
        g.run_for(25)
        rows.append(fmt(g.now, "after takeoff+25s"))
        la, lo = offset(lat0, lon0, 60, 0)
        g.goto(la, lo, 10)
        g.run_for(20)
        rows.append(fmt(g.now, "after 60 m move at 10 m rel"))
        g.set_mode("LAND")
        g.wait_for("HEARTBEAT", 90, lambda m: not (m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED))
        rows.append(fmt(g.now, "landed+disarmed"))
    elif vehicle == "rover":
        g.set_mode("GUIDED")
        g.arm_when_ready()
        rows.append(fmt(g.now, "ARMED"))
        la, lo = offset(lat0, lon0, 80, 40)
        g.goto(la, lo, 0)
        g.run_for(40)
        rows.append(fmt(g.now, "after 40 s drive"))
        g.set_mode("HOLD")
        g.run_for(3)
    elif vehicle == "plane":
        tk = g.param_get("TKOFF_ALT")
        rows.append(fmt(g.now, f"TKOFF_ALT={tk.param_value if tk else None}"))
        g.set_mode("TAKEOFF")
        g.run_for(1)
        g.arm_when_ready()
        rows.append(fmt(g.now, "ARMED in TAKEOFF"))
        g.run_for(60)
        rows.append(fmt(g.now, "TAKEOFF +60s"))
        g.set_mode("LOITER")
        g.run_for(20)
        rows.append(fmt(g.now, "LOITER +20s"))
        g.set_mode("RTL")
        g.run_for(10)

    (options.out / f"q1_{vehicle}_timeline.txt").write_text("\n".join(rows) + "\n")
    print("\n".join(rows))


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on the vehicle named on the command line."""
    options = parse_args(__doc__, argv)
    with Gcs(options, options.vehicle, f"q1_{options.vehicle}") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
