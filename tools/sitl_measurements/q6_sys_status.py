"""Q6: SYS_STATUS's sensor bits over boot, with the fence on and off, armed and disarmed.

    .venv/bin/python tools/sitl_measurements/q6_sys_status.py rover|copter|plane --out out/

Asks for SYS_STATUS at 5 Hz from the first HEARTBEAT, and records every change of its
present, enabled and health bit fields (with the bits that changed, by name) while the
vehicle boots and gets ready, while FENCE_ENABLE is 1 then 0 again (its default fence,
nothing uploaded), and while it is armed (forced where the pre-arm checks would refuse)
and disarmed. Also reads ARMING_CHECK (MAVProxy says "Arming checks disabled" on arming
unless it is 1 or has every check bit) and the FENCE_STATUS messages that come.

Writes q6_<vehicle>.jsonl and q6_<vehicle>_sys_status.json in the output folder.
Findings: docs/autopilot-fidelity.md (SYS_STATUS).
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Any

from gcs import Gcs, Options, mav, parse_args, write_json


def bit_names(mask: int) -> list[str]:
    """The MAV_SYS_STATUS_SENSOR names of the bits set in ``mask``."""
    entries = mav.enums["MAV_SYS_STATUS_SENSOR"]
    return [
        e.name.replace("MAV_SYS_STATUS_", "")
        for b, e in entries.items()
        if b & mask and b & (b - 1) == 0
    ]


def measure(g: Gcs, options: Options) -> None:
    """Record SYS_STATUS's bit changes over the phases the docstring names."""
    changes: list[dict[str, Any]] = []
    phase = ["boot"]
    last: list[tuple[int, int, int] | None] = [None]

    def on_msg(t: float, m: Any) -> None:
        if m.get_type() == "FENCE_STATUS":
            changes.append({"t": round(t, 2), "phase": phase[0], "FENCE_STATUS": m.to_dict()})
        if m.get_type() != "SYS_STATUS":
            return
        bits = (
            m.onboard_control_sensors_present,
            m.onboard_control_sensors_enabled,
            m.onboard_control_sensors_health,
        )
        before = last[0]
        last[0] = bits
        if bits == before:
            return
        row: dict[str, Any] = {
            "t": round(t, 2),
            "phase": phase[0],
            "present": hex(bits[0]),
            "enabled": hex(bits[1]),
            "health": hex(bits[2]),
        }
        if before is None:
            row["present_bits"] = bit_names(bits[0])
            row["enabled_bits"] = bit_names(bits[1])
            row["health_bits"] = bit_names(bits[2])
        else:
            for i, field in enumerate(("present", "enabled", "health")):
                row[f"{field}+"] = bit_names(bits[i] & ~before[i])
                row[f"{field}-"] = bit_names(before[i] & ~bits[i])
        changes.append(row)
        print(row, flush=True)

    g.on_msg.append(on_msg)
    g.start(streams=(("SYS_STATUS", 5), ("EKF_STATUS_REPORT", 1)))
    arming_check = g.param_get("ARMING_CHECK")
    g.wait_ready()
    g.run_for(3)
    phase[0] = "ready"
    g.run_for(2)
    phase[0] = "fence on"
    g.param_set("FENCE_ENABLE", 1, mav.MAV_PARAM_TYPE_INT8)
    g.run_for(3)
    phase[0] = "fence off"
    g.param_set("FENCE_ENABLE", 0, mav.MAV_PARAM_TYPE_INT8)
    g.run_for(3)
    phase[0] = "armed"
    ack = g.arm()
    if ack.result != 0:
        ack = g.arm(force=True)
    g.run_for(3)
    phase[0] = "disarmed"
    g.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, 0, 21196)
    g.run_for(3)
    write_json(
        options.out / f"q6_{g.vehicle}_sys_status.json",
        {
            "ARMING_CHECK": None
            if arming_check is None
            else (arming_check.param_value, arming_check.param_type),
            "arm_result": int(ack.result),
            "changes": changes,
        },
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Measure the vehicle named on the command line."""
    options = parse_args(__doc__, argv)
    with Gcs(options, options.vehicle, f"q6_{options.vehicle}") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
