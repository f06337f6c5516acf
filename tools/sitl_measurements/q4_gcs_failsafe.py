"""Q4: the GCS (heartbeat) failsafe on each vehicle, in the autopilot's own time.

    .venv/bin/python tools/sitl_measurements/q4_gcs_failsafe.py rover|copter|plane --out out/

The ground station speaks as sysid 255. From the very start it sends HEARTBEATs as sysid
245 (a "companion") as well, so that the cases below can stop one and keep the other:

  D  disarmed (copter, rover: MANUAL; plane: MANUAL, FS_LONG_ACTN=1): 255 stops
  G  copter armed on the ground in GUIDED: 255 stops
  H  moving in GUIDED (copter hovering at 10 m, also with FS_GCS_TIMEOUT=2; rover driving
     with FS_ACTION 2 and 1; plane loitering at a reposition point with FS_LONG_ACTN 1 and
     0, and in LOITER with 0): 255 stops (245 keeps on), then resumes
  C  MAV_GCS_SYSID=245: 245 stops while 255 keeps on: does the failsafe fire?
  X  rover in HOLD: 245 (the watched sysid) stops

For each: the delay from the watched sysid's last heartbeat to the failsafe STATUSTEXT,
its text and severity, the mode and arming after, and the texts and mode once the
heartbeats resume. Times: t_last_hb is the autopilot time the last heartbeat of the
watched sysid was sent at; t_text the time the failsafe STATUSTEXT arrived.
Whether it fires when MAV_GCS_SYSID was never heard is q4_never_seen.py.

Writes q4_<vehicle>.jsonl and q4_<vehicle>.json in the output folder.
Findings: docs/sitl-measurements.md, section 4.
"""

from __future__ import annotations

import json
import sys
from collections.abc import Sequence
from typing import Any

from gcs import ORIGIN, Gcs, Msg, Options, mav, offset, parse_args, write_json

PARAMS = {
    "rover": ("FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "FS_ACTION", "FS_TIMEOUT", "FS_OPTIONS"),
    "copter": ("FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "FS_OPTIONS"),
    "plane": (
        "FS_GCS_ENABL",
        "FS_LONG_ACTN",
        "FS_LONG_TIMEOUT",
        "FS_SHORT_ACTN",
        "FS_SHORT_TIMEOUT",
    ),
}
"""The failsafe parameters whose defaults are recorded, per vehicle."""


def measure(g: Gcs, options: Options) -> None:
    """Run the cases for ``g``'s vehicle and write what each showed."""
    vehicle = g.vehicle
    g.hb_sysids = [245]
    res: dict[str, Any] = {"vehicle": vehicle}
    lat0, lon0 = ORIGIN.lat_deg, ORIGIN.lon_deg
    modes: list[tuple[float, int, bool]] = []

    def record_mode(t: float, m: Msg) -> None:
        """Keep each change of mode or arming (from HEARTBEAT)."""
        if m.get_type() == "HEARTBEAT":
            now = (m.custom_mode, bool(m.base_mode & 128))
            if not modes or modes[-1][1:] != now:
                modes.append((t, *now))

    g.on_msg.append(record_mode)

    def modes_since(t0: float) -> list[tuple[float, int, bool]]:
        """The mode and arming changes at or after ``t0``."""
        return [(t, m, a) for t, m, a in modes if t >= t0]

    def stop_and_watch(
        label: str,
        keep: list[int],
        watched: int,
        within_s: float = 30.0,
        resume: list[int] | None = None,
        after_s: float = 10.0,
    ) -> None:
        """Stop the heartbeats of ``watched`` (keep ``keep``), wait for a failsafe text, resume.

        Args:
            label: The case's key in the results.
            keep: The system ids that go on sending heartbeats.
            watched: The system id whose heartbeats stop (the one the delay is measured from).
            within_s: How long to wait for a STATUSTEXT with "failsafe" in it.
            resume: The system ids that send heartbeats afterwards (None: no resume step).
            after_s: How long to watch after resuming.
        """
        g.run_for(1.5)
        g.hb_sysids = keep
        t_stop = g.last_hb_sent.get(watched)
        t0 = g.now
        fs = g.wait_for(
            "STATUSTEXT", within_s, lambda m: "failsafe" in m.text.lower(), raise_=False
        )
        out: dict[str, Any] = {
            "t_last_hb": t_stop,
            "t_text": None if fs is None else g.now,
            "text": None if fs is None else fs.text,
            "severity": None if fs is None else fs.severity,
        }
        if fs is not None and t_stop is not None:
            out["delay_s"] = round(g.now - t_stop, 2)
        g.run_for(3)
        out["mode_after"] = g.mode()
        out["armed_after"] = g.armed()
        out["texts"] = g.texts_since(t0)
        out["modes"] = modes_since(t0)
        if resume is not None:
            t1 = g.now
            g.hb_sysids = resume
            g.hb_due = g.now
            g.run_for(after_s)
            out["resume_t"] = t1
            out["after_resume_texts"] = g.texts_since(t1)
            out["after_resume_mode"] = g.mode()
        res[label] = out
        print(label, json.dumps(out, default=str), flush=True)

    g.start(
        streams=(
            ("GLOBAL_POSITION_INT", 2),
            ("SYS_STATUS", 1),
            ("EKF_STATUS_REPORT", 1),
            ("HOME_POSITION", 1),
        )
    )
    g.wait_ready(150)
    names = (*PARAMS[vehicle], "MAV_GCS_SYSID", "MAV_OPTIONS")
    res["defaults"] = {n: g.param_get(n).param_value for n in names}
    print("defaults", res["defaults"], flush=True)

    if vehicle == "copter":
        g.param_set("FS_GCS_ENABLE", 1)
        # disarmed, heard then lost (phase D)
        g.hb_sysids = [245, 255]
        g.run_for(3)
        stop_and_watch(
            "D_disarmed", keep=[245], watched=255, within_s=15, resume=[245, 255], after_s=5
        )
        # armed on the ground
        g.set_mode("GUIDED")
        g.arm_when_ready(60)
        stop_and_watch(
            "G_armed_on_ground", keep=[245], watched=255, within_s=15, resume=[245], after_s=3
        )
        # 255 has been heard now: "never heard" needs a fresh vehicle (q4_never_seen.py)
        g.hb_sysids = [245, 255]
        g.set_mode("GUIDED")
        g.arm_when_ready(60)
        g.command_long(mav.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, 0, 0, 0, 10)
        g.run_for(15)
        stop_and_watch("H_hover_guided_10m", keep=[245], watched=255, resume=[245, 255], after_s=8)
        g.set_mode("GUIDED")
        g.goto(lat0, lon0, 10)
        g.run_for(10)
        g.param_set("FS_GCS_TIMEOUT", 2)
        stop_and_watch("H2_timeout_2s", keep=[245], watched=255, resume=[245, 255], after_s=5)
        g.param_set("FS_GCS_TIMEOUT", 5)
        g.set_mode("GUIDED")
        g.goto(lat0, lon0, 10)
        g.run_for(10)
        g.param_set("MAV_GCS_SYSID", 245)
        g.run_for(2)
        stop_and_watch(
            "C_companion_245_lost_255_on", keep=[255], watched=245, resume=[245, 255], after_s=5
        )
        g.set_mode("LAND")
        g.wait_for("HEARTBEAT", 90, lambda m: not (m.base_mode & 128), raise_=False)

    elif vehicle == "rover":
        g.param_set("FS_GCS_ENABLE", 1)
        g.set_mode("MANUAL")
        g.hb_sysids = [245, 255]
        g.run_for(3)
        stop_and_watch(
            "D_disarmed_manual", keep=[245], watched=255, within_s=15, resume=[245, 255], after_s=5
        )
        g.set_mode("GUIDED")
        g.arm_when_ready(60)
        la, lo = offset(lat0, lon0, 300, 0)
        g.goto(la, lo, 0)
        g.run_for(5)
        stop_and_watch(
            "H_guided_driving_FS_ACTION_2", keep=[245], watched=255, resume=[245, 255], after_s=5
        )
        g.param_set("FS_ACTION", 1)
        g.set_mode("GUIDED")
        g.goto(la, lo, 0)
        g.run_for(5)
        stop_and_watch(
            "H_guided_driving_FS_ACTION_1", keep=[245], watched=255, resume=[245, 255], after_s=5
        )
        g.set_mode("GUIDED")
        g.goto(la, lo, 0)
        g.run_for(3)
        g.param_set("MAV_GCS_SYSID", 245)
        g.run_for(2)
        stop_and_watch(
            "C_companion_245_lost_255_on", keep=[255], watched=245, resume=[245, 255], after_s=5
        )
        g.set_mode("HOLD")
        g.hb_sysids = [245, 255]
        g.run_for(2)
        stop_and_watch(
            "X_in_HOLD", keep=[255], watched=245, within_s=15, resume=[245, 255], after_s=3
        )

    elif vehicle == "plane":
        g.param_set("FS_GCS_ENABL", 1)
        g.param_set("FS_LONG_ACTN", 1)
        g.hb_sysids = [245, 255]
        g.run_for(3)
        stop_and_watch(
            "D_disarmed_manual", keep=[245], watched=255, within_s=15, resume=[245, 255], after_s=5
        )
        g.set_mode("TAKEOFF")
        g.arm_when_ready(60)
        g.run_for(40)
        la, lo = offset(lat0, lon0, 300, 0)

        def reposition() -> Msg:
            """DO_REPOSITION (GUIDED) to 80 m above home, 300 m north of the origin."""
            return g.command_int(
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

        reposition()
        g.run_for(10)
        stop_and_watch(
            "H_guided_FS_LONG_ACTN_1", keep=[245], watched=255, resume=[245, 255], after_s=8
        )
        g.param_set("FS_LONG_ACTN", 0)
        reposition()
        g.run_for(10)
        stop_and_watch(
            "H_guided_FS_LONG_ACTN_0", keep=[245], watched=255, resume=[245, 255], after_s=8
        )
        g.set_mode("LOITER")
        g.run_for(5)
        stop_and_watch(
            "H_loiter_FS_LONG_ACTN_0", keep=[245], watched=255, resume=[245, 255], after_s=8
        )
        g.param_set("FS_LONG_ACTN", 1)
        reposition()
        g.run_for(5)
        g.param_set("MAV_GCS_SYSID", 245)
        g.run_for(2)
        stop_and_watch(
            "C_companion_245_lost_255_on", keep=[255], watched=245, resume=[245, 255], after_s=8
        )

    res["all_modes"] = modes
    write_json(options.out / f"q4_{vehicle}.json", res)


def main(argv: Sequence[str] | None = None) -> int:
    """Run the measurement on the vehicle named on the command line."""
    options = parse_args(__doc__, argv)
    with Gcs(options, options.vehicle, f"q4_{options.vehicle}") as g:
        measure(g, options)
    print(f"results in {options.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
