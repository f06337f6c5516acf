"""Q5: how PARAM_SET is answered: echoes, rounding, types, unknown names, refusals.

    .venv/bin/python tools/sitl_measurements/q5_params.py rover|copter|plane --out out/

Each probe sends one PARAM_SET, then listens for 1.5 s without asking anything else (how
many PARAM_VALUEs come, with what value, type, index and count, and which texts), then
reads the parameter back by name (PARAM_REQUEST_READ). The probes: the same value twice,
values outside the parameter's @Range, fractions and overflows of an INT8 parameter, a
parameter sent with another type than its own, MAV_GCS_SYSID and its pre-4.7 names, an
unknown name, an internal-only parameter (MIS_TOTAL), NaN, and a PARAM_SET from another
system id. About 20 s of autopilot time after boot.

Writes q5_<vehicle>.jsonl and q5_<vehicle>_detail.json in the output folder.
Findings: docs/sitl-measurements.md, section 5.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from typing import Any

from gcs import Gcs, Options, mav, parse_args, write_json

R32 = mav.MAV_PARAM_TYPE_REAL32
I8 = mav.MAV_PARAM_TYPE_INT8
I16 = mav.MAV_PARAM_TYPE_INT16
I32 = mav.MAV_PARAM_TYPE_INT32


def measure(g: Gcs, options: Options) -> None:
    """Run every probe on one vehicle and write what each answered."""
    g.start(streams=(("SYS_STATUS", 1),))
    g.run_for(2)
    out: list[dict[str, Any]] = []

    def probe(
        name: str, value: float, ptype: int = R32, sysid: int | None = None, note: str = ""
    ) -> None:
        """PARAM_SET ``name`` (as ``sysid``), listen 1.5 s, read it back; record it all."""
        t0 = g.now
        g.send(
            mav.MAVLink_param_set_message(g.target, 1, name.encode(), float(value), ptype),
            sysid=sysid,
        )
        seen = [m for m in g.run_for(1.5) if m.get_type() == "PARAM_VALUE"]
        texts = g.texts_since(t0)
        rd = g.param_get(name, 2)
        row = {
            "name": name,
            "sent": value,
            "sent_type": ptype,
            "from_sysid": sysid or 255,
            "note": note,
            "echoes": [
                (m.param_id, m.param_value, m.param_type, m.param_index, m.param_count)
                for m in seen
            ],
            "texts": texts,
            "read_back": None if rd is None else (rd.param_value, rd.param_type, rd.param_index),
        }
        out.append(row)
        print(json.dumps(row, default=str), flush=True)

    probe("FENCE_RADIUS", 222.0)
    probe("FENCE_RADIUS", 222.0, note="same value again")
    probe("FENCE_RADIUS", 5.0, note="below @Range 30..10000")
    probe("FENCE_RADIUS", 1e6, note="above @Range")
    probe("FENCE_ACTION", 2.7, I8, note="int8 param, fraction")
    probe("FENCE_ACTION", -2.7, I8, note="negative fraction")
    probe("FENCE_ACTION", 300, I8, note="above int8")
    probe("FENCE_ACTION", 1, R32, note="int8 param sent with REAL32 type")
    probe("FENCE_RADIUS", 250, I8, note="float param sent with INT8 type")
    probe("MAV_GCS_SYSID", 245, I16)
    probe("MAV_GCS_SYSID", 255, I16)
    probe("SYSID_MYGCS", 245, I16, note="the pre-4.7 name")
    probe("SYSID_THISMAV", 1, I16, note="the pre-4.7 name")
    probe("NO_SUCH_PARAM", 1)
    probe("MIS_TOTAL", 5, I16, note="AP_PARAM_FLAG_INTERNAL_USE_ONLY")
    probe("FENCE_RADIUS", float("nan"), note="NaN")
    probe("FENCE_RADIUS", 300.0, sysid=245, note="from another sysid (MAV_OPTIONS 0)")
    probe("FENCE_RADIUS", 300.0)
    write_json(options.out / f"q5_{g.vehicle}_detail.json", out)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the probes on the vehicle named on the command line."""
    options = parse_args(__doc__, argv)
    with Gcs(options, options.vehicle, f"q5_{options.vehicle}") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
