"""Q3 (copter): pre-arm fence checks, and when a FENCE_TYPE change takes effect.

    .venv/bin/python tools/sitl_measurements/q3_fence_copter_prearm.py --out out/

  A FENCE_TYPE=1 + ENABLE=1, then FENCE_TYPE=3 (add the circle) RADIUS=30 without toggling
    FENCE_ENABLE; home moved 100 m north (DO_SET_HOME): breached? can it arm?
  B FENCE_ENABLE 0 -> 1 (re-reads FENCE_TYPE), home moved again: breach, PreArm text
  C FENCE_ENABLE=0 while breached: SYS_STATUS geofence bits, mode change texts, arming
  D FENCE_TYPE=0 with ENABLE=1; FENCE_TYPE=4 (polygon, none uploaded); ALT_MAX 5 with
    MARGIN 3: PreArm texts

Each arm attempt records the ack, the texts, the geofence bits and FENCE_STATUS, and
disarms again if it armed.

Writes q3_copter_prearm.jsonl and q3_copter_prearm.json in the output folder.
Findings: docs/sitl-measurements.md, section 3.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Options, mav, offset, parse_args, write_json

GEOFENCE = mav.MAV_SYS_STATUS_GEOFENCE


def measure(g: Gcs, options: Options) -> None:
    """Run cases A to D on one copter and write what each arm attempt showed."""
    res: dict[str, Any] = {}

    def bits() -> dict[str, bool]:
        """The next SYS_STATUS's geofence bits, and whether the pre-arm checks pass."""
        s = g.wait_for("SYS_STATUS", 3)
        return {
            "present": bool(s.onboard_control_sensors_present & GEOFENCE),
            "enabled": bool(s.onboard_control_sensors_enabled & GEOFENCE),
            "healthy": bool(s.onboard_control_sensors_health & GEOFENCE),
            "prearm_ok": bool(s.onboard_control_sensors_health & mav.MAV_SYS_STATUS_PREARM_CHECK),
        }

    def fstat() -> tuple[int, int, int, int] | None:
        """The latest FENCE_STATUS: breach status, count, type and time (None before one)."""
        m = g.last.get("FENCE_STATUS")
        return (
            None if m is None else (m.breach_status, m.breach_count, m.breach_type, m.breach_time)
        )

    def move_home(north: float) -> int | None:
        """DO_SET_HOME to ``north`` metres north of the origin; the ack's result."""
        hla, hlo = offset(ORIGIN.lat_deg, ORIGIN.lon_deg, north, 0)
        ack = g.command_int(
            mav.MAV_CMD_DO_SET_HOME, mav.MAV_FRAME_GLOBAL, 0, 0, 0, 0, hla * 1e7, hlo * 1e7, 90.09
        )
        g.run_for(2)
        return None if ack is None else int(ack.result)

    def try_arm(label: str) -> None:
        """Ask to arm; record the ack, texts, bits and FENCE_STATUS; disarm if it armed."""
        t0 = g.now
        ack = g.arm()
        g.run_for(2)
        res[label] = {
            "ack": ack.result,
            "texts": g.texts_since(t0),
            "bits": bits(),
            "fence_status": fstat(),
        }
        if ack.result == 0:
            g.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0)
            g.run_for(2)
        print(label, res[label], flush=True)

    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 2),
            ("SYS_STATUS", 2),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
            ("FENCE_STATUS", 1),
        )
    )
    g.wait_ready(150)
    g.set_mode("GUIDED")
    for n, v in (("FENCE_TYPE", 1), ("FENCE_ALT_MAX", 20), ("FENCE_ENABLE", 1)):
        g.param_set(n, v)
    g.run_for(1)
    # A
    g.param_set("FENCE_TYPE", 3)
    g.param_set("FENCE_RADIUS", 30)
    res["A_set_home_ack"] = move_home(100)
    res["A_home"] = g.last["HOME_POSITION"].latitude
    try_arm("A_arm_after_type_change_without_toggle")
    # B
    g.param_set("FENCE_ENABLE", 0)
    g.run_for(1)
    g.param_set("FENCE_ENABLE", 1)
    move_home(100)
    g.run_for(3)
    try_arm("B_arm_after_toggle")
    # C
    t0 = g.now
    g.param_set("FENCE_ENABLE", 0)
    g.run_for(2)
    res["C_bits_after_disable_while_breached"] = bits()
    res["C_fence_status"] = fstat()
    g.set_mode("LOITER")
    g.set_mode("GUIDED")
    g.run_for(1)
    res["C_texts"] = g.texts_since(t0)
    try_arm("C_arm_fence_disabled_home_away")
    print("C", res["C_bits_after_disable_while_breached"], res["C_texts"], flush=True)
    g.command_long(mav.MAV_CMD_DO_SET_HOME, 1)
    g.run_for(2)
    # D
    g.param_set("FENCE_TYPE", 0)
    g.param_set("FENCE_ENABLE", 1)
    g.run_for(2)
    try_arm("D_type0")
    g.param_set("FENCE_TYPE", 4)
    g.param_set("FENCE_ENABLE", 0)
    g.param_set("FENCE_ENABLE", 1)
    g.run_for(2)
    try_arm("D_type4_no_polygon")
    g.param_set("FENCE_TYPE", 1)
    g.param_set("FENCE_ALT_MAX", 5)
    g.param_set("FENCE_MARGIN", 3)
    g.run_for(2)
    try_arm("D_margin_too_big")
    write_json(options.out / "q3_copter_prearm.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a copter."""
    options = parse_args(__doc__, argv, vehicles=("copter",))
    with Gcs(options, "copter", "q3_copter_prearm") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
