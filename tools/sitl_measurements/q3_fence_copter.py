"""Q3 (copter): the altitude fence, guided targets against it, pre-arm checks, auto-enable.

    .venv/bin/python tools/sitl_measurements/q3_fence_copter.py --out out/

Phases (all times in the autopilot's own clock):

  P0 circle fence enabled before the GPS fix -> arm attempt: which PreArm/Arm texts
  P1 disarmed: FENCE_ENABLE=1 TYPE=1 ALT_MAX=20 ACTION=1; SYS_STATUS geofence bits;
     FENCE_STATUS
  P2 home moved 100 m away with DO_SET_HOME, circle fence radius 30 -> "Vehicle breaching..."
  P3 takeoff to 10 m; a guided target at 40 m (above the ceiling): refused?; DO_REPOSITION
     to 40 m and to 15 m
  P4 fence off, target 40 m, fence on again above 16.5 m -> breach height, texts, mode,
     FENCE_STATUS; a mode change during the breach; RTL, landing and the breach cleared
  P5 FENCE_AUTOENABLE=3 with FENCE_ENABLE=0: arm/disarm texts and bits; DO_FENCE_ENABLE
     while disarmed

Writes q3_copter.jsonl and q3_copter.json in the output folder.
Findings: docs/sitl-measurements.md, section 3.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Msg, Options, mav, offset, parse_args, write_json

GEOFENCE = mav.MAV_SYS_STATUS_GEOFENCE


def measure(g: Gcs, options: Options) -> None:
    """Run phases P0 to P5 on one copter and write what each showed."""
    res: dict[str, Any] = {}

    def geofence_bits() -> dict[str, bool]:
        """The next SYS_STATUS's geofence present/enabled/healthy bits."""
        s = g.wait_for("SYS_STATUS", 3)
        return {
            "present": bool(s.onboard_control_sensors_present & GEOFENCE),
            "enabled": bool(s.onboard_control_sensors_enabled & GEOFENCE),
            "healthy": bool(s.onboard_control_sensors_health & GEOFENCE),
        }

    def fence_status() -> dict[str, Any] | None:
        """The latest FENCE_STATUS (None before one came)."""
        m = g.last.get("FENCE_STATUS")
        return (
            None
            if m is None
            else {
                "t": g.now,
                "breach_status": m.breach_status,
                "breach_count": m.breach_count,
                "breach_type": m.breach_type,
                "breach_time": m.breach_time,
                "mitigation": m.breach_mitigation,
            }
        )

    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 5),
            ("SYS_STATUS", 2),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
            ("FENCE_STATUS", 1),
        )
    )
    # P0: fence (circle) enabled at once, before the GPS fix
    t0 = g.now
    for name, v in (("FENCE_TYPE", 2), ("FENCE_ENABLE", 1)):
        g.param_set(name, v)
    g.run_for(1)
    res["P0_geofence_bits_before_fix"] = geofence_bits()
    g.set_mode("GUIDED")
    ack = g.arm()
    g.run_for(1)
    res["P0_arm_before_fix"] = {"t": g.now, "ack": ack.result, "texts": g.texts_since(t0)}
    print("P0", res["P0_arm_before_fix"], res["P0_geofence_bits_before_fix"], flush=True)
    g.param_set("FENCE_ENABLE", 0)
    g.wait_ready(150)
    g.run_for(2)

    # P1: the altitude fence, enabled while disarmed
    t0 = g.now
    res["P1_geofence_bits_fence_off"] = geofence_bits()
    for name, v in (
        ("FENCE_TYPE", 1),
        ("FENCE_ALT_MAX", 20),
        ("FENCE_ACTION", 1),
        ("FENCE_ENABLE", 1),
    ):
        pv = g.param_set(name, v)
        res.setdefault("P1_param_echo", {})[name] = None if pv is None else pv.param_value
    g.run_for(3)
    res["P1_geofence_bits_fence_on_disarmed"] = geofence_bits()
    res["P1_fence_status"] = fence_status()
    res["P1_texts"] = g.texts_since(t0)
    print(
        "P1",
        res["P1_geofence_bits_fence_off"],
        res["P1_geofence_bits_fence_on_disarmed"],
        res["P1_fence_status"],
        flush=True,
    )

    # P2: outside a circle fence before arming (home moved 100 m north)
    t0 = g.now
    g.param_set("FENCE_TYPE", 3)  # alt max + circle
    g.param_set("FENCE_RADIUS", 30)
    hla, hlo = offset(ORIGIN.lat_deg, ORIGIN.lon_deg, 100, 0)
    ack = g.command_int(
        mav.MAV_CMD_DO_SET_HOME,
        mav.MAV_FRAME_GLOBAL,
        0,
        0,
        0,
        0,
        hla * 1e7,
        hlo * 1e7,
        ORIGIN.alt_m + 0.09,
    )
    g.run_for(2)
    res["P2_set_home_ack"] = None if ack is None else ack.result
    res["P2_geofence_bits"] = geofence_bits()
    res["P2_fence_status"] = fence_status()
    ack = g.arm()
    g.run_for(1)
    res["P2_arm"] = {"ack": ack.result, "texts": g.texts_since(t0)}
    print("P2", res["P2_set_home_ack"], res["P2_geofence_bits"], res["P2_arm"], flush=True)
    # home back to the vehicle
    g.command_long(mav.MAV_CMD_DO_SET_HOME, 1)
    g.run_for(2)
    g.param_set("FENCE_TYPE", 1)
    g.param_set("FENCE_RADIUS", 150)
    g.run_for(2)
    res["P2_after_home_back_bits"] = geofence_bits()

    # P3: takeoff to 10 m and guided targets above the ceiling
    t0 = g.now
    g.set_mode("GUIDED")
    g.arm_when_ready(60)
    g.command_long(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
    g.run_for(15)
    res["P3_after_takeoff"] = g.pos()
    la, lo = offset(ORIGIN.lat_deg, ORIGIN.lon_deg, 20, 0)
    g.goto(la, lo, 40)
    g.run_for(15)
    res["P3_after_target_40m"] = {"pos": g.pos(), "mode": g.mode(), "texts": g.texts_since(t0)}
    rel_int = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
    ack = g.command_int(mav.MAV_CMD_DO_REPOSITION, rel_int, -1, 1, 0, 0, la * 1e7, lo * 1e7, 40)
    g.run_for(10)
    res["P3_reposition_40m"] = {"ack": None if ack is None else ack.result, "pos": g.pos()}
    ack = g.command_int(mav.MAV_CMD_DO_REPOSITION, rel_int, -1, 1, 0, 0, la * 1e7, lo * 1e7, 15)
    g.run_for(10)
    res["P3_reposition_15m"] = {"ack": None if ack is None else ack.result, "pos": g.pos()}
    print(
        "P3",
        res["P3_after_takeoff"],
        res["P3_after_target_40m"],
        res["P3_reposition_40m"],
        res["P3_reposition_15m"],
        flush=True,
    )

    # P4: fence off, climb toward 40 m, fence back on above 16.5 m
    t0 = g.now
    g.param_set("FENCE_ENABLE", 0)
    g.goto(la, lo, 40)
    g.wait_for("GLOBAL_POSITION_INT", 30, lambda m: m.relative_alt > 16500)
    g.param_set("FENCE_ENABLE", 1)
    t_on = g.now
    samples: list[tuple[float, float]] = []

    def sample(t: float, m: Msg) -> None:
        """Keep every relative_alt, to find the first at or above the ceiling."""
        if m.get_type() == "GLOBAL_POSITION_INT":
            samples.append((t, m.relative_alt / 1000.0))

    g.on_msg.append(sample)
    txt = g.wait_for("STATUSTEXT", 30, lambda m: "breach" in m.text.lower())
    t_b = g.now
    alt_at_text = g.pos()[3]
    g.run_for(3)
    res["P4"] = {
        "fence_on_at": t_on,
        "breach_text_t": t_b,
        "breach_text": txt.text,
        "severity": txt.severity,
        "rel_alt_at_text": alt_at_text,
        "mode_3s_later": g.mode(),
        "fence_status": fence_status(),
        "bits": geofence_bits(),
    }
    first_over = next(((t, a) for t, a in samples if a >= 20.0), None)
    res["P4"]["first_GPI_at_or_over_20m"] = first_over
    print("P4", res["P4"], flush=True)
    # follow the RTL down: when is the breach cleared?
    t1 = g.now
    g.set_mode("GUIDED")  # mode change during breach (FENCE_OPTIONS 0 on copter)
    g.run_for(2)
    res["P4_mode_change_during_breach"] = {"mode": g.mode(), "texts": g.texts_since(t1)}
    g.set_mode("RTL")
    g.wait_for("HEARTBEAT", 120, lambda m: not (m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED))
    res["P4_texts"] = g.texts_since(t0)
    res["P4_after_landing"] = {
        "bits": geofence_bits(),
        "fence_status": fence_status(),
        "pos": g.pos(),
    }
    print("P4 texts", res["P4_texts"], res["P4_after_landing"], flush=True)

    # P5: FENCE_AUTOENABLE=3 (only when armed) with FENCE_ENABLE=0
    t0 = g.now
    g.param_set("FENCE_ENABLE", 0)
    g.param_set("FENCE_AUTOENABLE", 3)
    g.run_for(2)
    res["P5_bits_disarmed"] = geofence_bits()
    g.set_mode("GUIDED")
    g.arm_when_ready(60)
    g.run_for(2)
    res["P5_bits_armed"] = geofence_bits()
    res["P5_fence_enable_param_armed"] = g.param_get("FENCE_ENABLE").param_value
    g.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0)
    g.run_for(2)
    res["P5_bits_disarmed_again"] = geofence_bits()
    res["P5_texts"] = g.texts_since(t0)
    print(
        "P5",
        res["P5_bits_disarmed"],
        res["P5_bits_armed"],
        res["P5_bits_disarmed_again"],
        res["P5_texts"],
        flush=True,
    )
    # DO_FENCE_ENABLE while disarmed
    ack = g.command_long(mav.MAV_CMD_DO_FENCE_ENABLE, 1)
    g.run_for(2)
    res["P5_do_fence_enable_disarmed"] = {
        "ack": ack.result,
        "bits": geofence_bits(),
        "FENCE_ENABLE": g.param_get("FENCE_ENABLE").param_value,
    }
    print("P5b", res["P5_do_fence_enable_disarmed"], flush=True)
    write_json(options.out / "q3_copter.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on a copter."""
    options = parse_args(__doc__, argv, vehicles=("copter",))
    with Gcs(options, "copter", "q3_copter") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
