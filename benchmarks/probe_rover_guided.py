"""Probe: a rover in GUIDED on the simulated autopilot or ArduPilot SITL; times and tracks.

Three measurements, each on the conformance harness's backends (``sim-rover`` or
``sitl-rover``, WP_SPEED 3 as the rover scenarios set it):

- ``redirect``: drive north at WP_SPEED; 20 m on, send a target 15 m away at 45, 60, 73 and
  100 degrees left of the heading (and the scenario's 10 m behind and 20 m right); seconds
  to within 3 m of it (tests/conformance/test_guided.py's redirect, which pins these).
- ``start``: from a standstill, a target 40 m ahead: the first motion and the speed every
  half second after the target went.
- ``corner``: a square tour as the engine's waypoint_tour drives it (the next corner sent
  within 2 m of the last, 30 m legs turning 90 degrees right): per corner, the speed when
  the next corner went, the slowest speed through the corner, and the seconds to 5 m and
  10 m along the new leg and to within 2 m of the next corner.
- ``chase``: from rest, a goal 3 m beside a leader walking at 1 m/s (test_guided's path,
  or ``--walk``), sent twice a second 2.5 s ahead as follow_agent sends it, then the leader
  stands (test_guided's chase): the times to within 3, 2, 1.5 and 1 m of the moving goal,
  its mean distance over the walk's last 5 s, how far past the standing goal it runs.
- ``step`` (``sim-rover`` only, no autopilot): the CPU time of one 0.05 s step of the
  simulated rover driving GUIDED targets (the model alone, what a dry run pays per rover).

Used to fit the simulated rover's GUIDED model to ArduRover's (docs/autopilot-fidelity.md).
SITL instances follow CLARK_SITL_INSTANCES and the speed-up CLARK_SITL_SPEEDUP_TESTS:

    PYTHONPATH=.:tests/conformance python benchmarks/probe_rover_guided.py sitl-rover
    PYTHONPATH=.:tests/conformance python benchmarks/probe_rover_guided.py sim-rover --what redirect
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "conformance"))

from flight import (
    ROVER_SPEED_M_S,
    Fix,
    distance_m,
    fix_of,
    flight_params,
    goto,
    here,
    moved,
    offset_m,
    streaming,
    track,
)
from harness import Peer, open_peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_guided import (
    CHASE_PATH_M,
    CHASE_SPEED_M_S,
    REDIRECT_TARGETS_M,
    Walk,
    chase,
    drive_and_redirect,
)

TOUR_LEG_M = 30.0
TOUR_TOLERANCE_M = 2.0
CHASE_WALK = ";".join(f"{a:g},{r:g}" for a, r in CHASE_PATH_M)
"""``--walk``: the chase's leader path, corners ``ahead,right;...`` of the rover."""


def rows(fixes: list[Fix], base: tuple[float, float], t0_s: float) -> list[list[float]]:
    """A track as [seconds after t0, north, east, speed, course in degrees] rows."""
    out = []
    for f in fixes:
        north, east = offset_m(*base, f.lat_deg, f.lon_deg)
        course = math.degrees(math.atan2(f.east_m_s, f.north_m_s))
        out.append(
            [
                round(f.t_s - t0_s, 2),
                round(north, 2),
                round(east, 2),
                round(f.ground_speed_m_s, 2),
                round(course),
            ]
        )
    return out


def stop(peer: Peer) -> None:
    """Wait until the rover stands still (where it was sent)."""
    peer.wait_for("GLOBAL_POSITION_INT", 30.0, where=lambda m: fix_of(m).ground_speed_m_s < 0.05)


def probe_redirect(peer: Peer, out: dict[str, Any]) -> None:
    """Every redirect case: time to within 3 m, and the track."""
    for case, (north_m, east_m) in REDIRECT_TARGETS_M.items():
        leg = drive_and_redirect(peer, north_m, east_m)
        print(f"redirect {case:8s} {leg.time_s:6.2f} s", flush=True)
        peer.run_for(4.0)
        fixes = track(peer, 0)
        fixes = [f for f in fixes if leg.sent_s - 2.0 <= f.t_s <= leg.arrived.t_s + 4.0]
        out.setdefault("redirect", {})[case] = {
            "time_s": round(leg.time_s, 2),
            "track": rows(fixes, leg.base, leg.sent_s),
        }
        stop(peer)


def probe_start(peer: Peer, out: dict[str, Any]) -> None:
    """From rest, 40 m ahead: first motion and the ramp."""
    stop(peer)
    peer.run_for(2.0)
    start = here(peer)
    base = (start.lat_deg, start.lon_deg)
    heading = math.radians(peer.wait_for("GLOBAL_POSITION_INT", 2.0).hdg / 100.0)
    target = moved(*base, 40.0 * math.cos(heading), 40.0 * math.sin(heading))
    mark = peer.mark()
    peer.sync()
    sent_s = peer.now_s
    goto(peer, *target, 0.0)
    peer.run_for(8.0)
    fixes = track(peer, mark)
    moving = next((f for f in fixes if f.ground_speed_m_s > 0.05), None)
    first_s = None if moving is None else round(moving.t_s - sent_s, 2)
    ramp = {
        f"{t:.1f}": round(
            min(fixes, key=lambda f, t=t: abs(f.t_s - sent_s - t)).ground_speed_m_s, 2
        )
        for t in (0.5, 1.0, 1.5, 2.0, 2.5, 3.0, 3.5, 4.0, 5.0)
    }
    print(f"start: first motion {first_s} s; speed {ramp}", flush=True)
    out["start"] = {
        "first_motion_s": first_s,
        "speed_m_s": ramp,
        "track": rows(fixes, base, sent_s),
    }
    peer.wait_for(
        "GLOBAL_POSITION_INT",
        40.0,
        where=lambda m: (
            fix_of(m).ground_speed_m_s < 0.05
            and distance_m((fix_of(m).lat_deg, fix_of(m).lon_deg), target) < 3.0
        ),
    )


def probe_corner(peer: Peer, out: dict[str, Any]) -> None:
    """A square ahead and to the right, each corner sent within 2 m of the last."""
    stop(peer)
    start = here(peer)
    base = (start.lat_deg, start.lon_deg)
    yaw = math.radians(peer.wait_for("GLOBAL_POSITION_INT", 2.0).hdg / 100.0)
    corners = ((TOUR_LEG_M, 0.0), (TOUR_LEG_M, TOUR_LEG_M), (0.0, TOUR_LEG_M), (0.0, 0.0))
    legs = []
    mark = peer.mark()
    first_sent = None
    previous: tuple[float, float] | None = None
    for ahead_m, right_m in corners:
        north_m = ahead_m * math.cos(yaw) - right_m * math.sin(yaw)
        east_m = ahead_m * math.sin(yaw) + right_m * math.cos(yaw)
        target = moved(*base, north_m, east_m)
        peer.sync()
        sent_s = peer.now_s
        first_sent = sent_s if first_sent is None else first_sent
        goto(peer, *target, 0.0)
        sent_fix = here(peer)

        def near(msg: object, target: tuple[float, float] = target) -> bool:
            """within the tour's tolerance of the corner"""
            f = fix_of(msg)
            return distance_m((f.lat_deg, f.lon_deg), target) < TOUR_TOLERANCE_M

        reached = fix_of(peer.wait_for("GLOBAL_POSITION_INT", 60.0, where=near))
        leg: dict[str, Any] = {
            "sent_speed_m_s": round(sent_fix.ground_speed_m_s, 2),
            "to_2m_s": round(reached.t_s - sent_s, 2),
        }
        if previous is not None:
            fixes = [f for f in track(peer, mark) if f.t_s >= sent_s]
            leg["slowest_m_s"] = round(min(f.ground_speed_m_s for f in fixes[:40]), 2)
            # Progress along the new leg: from the previous corner toward this one.
            pn, pe = offset_m(*base, *previous)
            tn, te = offset_m(*base, *target)
            un, ue = (tn - pn) / TOUR_LEG_M, (te - pe) / TOUR_LEG_M
            for mark_m in (5.0, 10.0):
                hit = next(
                    (
                        f
                        for f in fixes
                        if (offset_m(*base, f.lat_deg, f.lon_deg)[0] - pn) * un
                        + (offset_m(*base, f.lat_deg, f.lon_deg)[1] - pe) * ue
                        >= mark_m
                    ),
                    None,
                )
                leg[f"to_{mark_m:.0f}m_along_s"] = (
                    None if hit is None else round(hit.t_s - sent_s, 2)
                )
        print(f"corner {len(legs)}: {leg}", flush=True)
        legs.append(leg)
        previous = target
    stop(peer)
    out["corner"] = {"legs": legs, "track": rows(track(peer, mark), base, first_sent or 0.0)}


def probe_chase(peer: Peer, out: dict[str, Any]) -> None:
    """From rest, chase a goal beside a walking leader (test_guided's chase); its figures."""
    stop(peer)
    peer.run_for(2.0)
    path = tuple(tuple(float(v) for v in p.split(",")) for p in CHASE_WALK.split(";"))
    run = chase(peer, Walk(path, CHASE_SPEED_M_S))  # type: ignore[arg-type]
    end = run.fixes[-1]
    figures = {
        "reach_s": {f"{d:g}": None if s is None else round(s, 2) for d, s in run.reach_s.items()},
        "trail_m": round(run.trail_m, 2),
        "past_m": round(run.past_m, 2),
        "end_speed_m_s": round(end.ground_speed_m_s, 2),
    }
    print(f"chase: {figures}", flush=True)
    track_rows = rows(run.fixes, run.base, run.t0_s)
    for row, gap in zip(track_rows, run.gaps_m, strict=True):
        row.append(round(gap, 2))
    out.setdefault("chase", []).append({**figures, "walk": path, "track": track_rows})
    stop(peer)


def step_cost(out: dict[str, Any]) -> None:
    """CPU microseconds per 0.05 s step of a simulated rover driving GUIDED targets."""
    import random

    import yaml

    from clark_engine.mission.geo import LocalPoint, Origin, to_global
    from clark_engine.sim.ardupilot.airframes.factory import make_vehicle

    profiles = Path(__file__).resolve().parents[1] / "hardware_profiles"
    airframe = yaml.safe_load((profiles / "airframes/traxxas_slash_airframe.yaml").read_text())
    autopilot = yaml.safe_load((profiles / "autopilots/pixhawk_ardurover.yaml").read_text())
    origin = Origin(30.6372, -96.4787, 90.0)
    model = make_vehicle(airframe, autopilot, None, origin, (0.0, 0.0), random.Random(1))
    model.set_mode("GUIDED")
    model.configure({"WP_SPEED": ROVER_SPEED_M_S})
    steps = 40_000
    began = time.process_time()
    for i in range(steps):
        if i % 2000 == 0:
            north = 2000.0 if (i // 2000) % 2 == 0 else -2000.0
            lat, lon, alt = to_global(LocalPoint(north, 300.0, 0.0), origin)
            model.goto(lat, lon, alt, None)
        model.step(0.05)
    cost_us = (time.process_time() - began) / steps * 1e6
    print(f"step: {cost_us:.1f} us of CPU per 0.05 s step of a GUIDED rover", flush=True)
    out["step_us"] = round(cost_us, 1)


def main() -> int:
    """Run the probe on the backend named on the command line; print the figures."""
    parser = argparse.ArgumentParser()
    parser.add_argument("backend", choices=("sim-rover", "sitl-rover"))
    parser.add_argument("--what", default="redirect,start,corner")
    parser.add_argument("--out", type=Path, help="write times and tracks here (JSON)")
    parser.add_argument(
        "--keep-logs", action="store_true", help="SITL: keep its folder (DataFlash logs: PSCN/PSCE)"
    )
    parser.add_argument("--walk", default=CHASE_WALK, help="chase: the leader's corners")
    args = parser.parse_args()
    globals()["CHASE_WALK"] = args.walk
    out: dict[str, Any] = {"backend": args.backend}
    if args.what == "step":
        if args.backend != "sim-rover":
            parser.error("--what step measures the simulated rover (sim-rover)")
        step_cost(out)
        if args.out:
            args.out.write_text(json.dumps(out, indent=1))
        return 0
    peer = open_peer(args.backend)
    process = getattr(peer.link, "process", None)
    if args.keep_logs and process is not None:
        process.keep_work = True
        print(f"SITL folder: {process.work_dir}", flush=True)
    try:
        peer.wait_ready()
        with flight_params(peer, {"WP_SPEED": ROVER_SPEED_M_S}), streaming(peer):
            assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
            assert peer.arm().result == mavlink2.MAV_RESULT_ACCEPTED
            for what in args.what.split(","):
                {
                    "redirect": probe_redirect,
                    "start": probe_start,
                    "corner": probe_corner,
                    "chase": probe_chase,
                }[what](peer, out)
            peer.disarm()
    finally:
        peer.close()
    if args.out:
        args.out.write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
