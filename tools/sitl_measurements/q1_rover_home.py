"""Q1 (rover): when does ArduRover's home altitude, and so relative_alt, get corrected?

    .venv/bin/python tools/sitl_measurements/q1_rover_home.py --out out/

ArduRover sets home while its AHRS is still DCM, at the barometric altitude (about 0 m),
so relative_alt reads about +90 m on a 90 m field. This boots a rover and arms it in
GUIDED (does arming move home?), drives 30 m north, disarms away from home
(Rover::update_home moves home while disarmed once it is 0.5 m away), then sends
MAV_CMD_DO_SET_HOME param1=1 (use the current location). At each step it records
HOME_POSITION.altitude, GLOBAL_POSITION_INT alt and relative_alt, the mode and arming.

Writes q1_rover_home.jsonl and q1_rover_home.json in the output folder.
Findings: docs/sitl-measurements.md, section 1.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Options, mav, offset, parse_args, write_json


def measure(g: Gcs, options: Options) -> None:
    """Arm, drive, disarm away from home, DO_SET_HOME; snapshot home and altitudes."""
    res: dict[str, Any] = {}

    def snap(label: str) -> None:
        """Listen 1.5 s, then record home, the position's altitudes, arming and mode."""
        g.run_for(1.5)
        h = g.last.get("HOME_POSITION")
        p = g.pos()
        res[label] = {
            "t": g.now,
            "home_alt": None if h is None else h.altitude / 1000,
            "home_lat": None if h is None else h.latitude / 1e7,
            "gpi_alt": p[2],
            "gpi_rel": p[3],
            "armed": g.armed(),
            "mode": g.mode(),
        }
        print(label, res[label], flush=True)

    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 2),
            ("SYS_STATUS", 1),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
        )
    )
    g.wait_ready(150)
    snap("ready")
    g.set_mode("GUIDED")
    g.arm_when_ready(60)
    snap("armed")
    la, lo = offset(ORIGIN.lat_deg, ORIGIN.lon_deg, 30, 0)
    g.goto(la, lo, 0)
    g.run_for(25)
    snap("drove 30 m")
    g.set_mode("HOLD")
    g.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    g.run_for(3)
    snap("disarmed 30 m from home")
    ack = g.command_long(mav.MAV_CMD_DO_SET_HOME, 1)
    snap(f"DO_SET_HOME current (ack {ack.result})")
    write_json(options.out / "q1_rover_home.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a rover."""
    options = parse_args(__doc__, argv, vehicles=("rover",))
    with Gcs(options, "rover", "q1_rover_home") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
