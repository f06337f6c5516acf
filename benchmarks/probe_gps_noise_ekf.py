"""Probe: what ArduPilot reports of a noisy GPS (GLOBAL_POSITION_INT is its EKF's estimate).

The simulated autopilot reports each GPS fix as it is (``sim.gps_noise_m``: 0.5 m per axis,
fresh at every 5 Hz fix, by default in a dry run). ArduPilot SITL's GPS has no horizontal
noise of its own, so this probe gives it some: an ArduRover SITL at rest, disarmed, and
every 0.2 s of its time a fresh Gaussian offset (``--noise`` m per axis) in its GPS glitch
parameters (SIM_GPS1_GLTCH_X/_Y, as the dry run plays ``sim.gps_error`` to SITL). Printed,
for GLOBAL_POSITION_INT and GPS_RAW_INT at 10 Hz: the spread north and east, the mean step
between reports and the autocorrelation of north after 0.5, 1 and 3 s. With ``--jump M``
(repeatable), then a jump of the GPS by M m north: when each report has moved 10, 50 and
90 % of it (ArduPilot's EKF smooths a small jump and rejects a large one for a while).

    PYTHONPATH=.:tests/conformance CLARK_SITL_INSTANCES=200-229 \\
        python benchmarks/probe_gps_noise_ekf.py [--noise 0.5] [--seconds 40] [--jump 1]
"""

from __future__ import annotations

import argparse
import itertools
import math
import random
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "conformance"))

from flight import GPS_FIX_PERIOD_S as FIX_PERIOD_S
from flight import autocorrelation, offset_m, streaming
from flight import gps_glitch as glitch
from harness import Peer, open_peer


def record(
    peer: Peer, seconds: float, noise_m: float, seed: int
) -> dict[str, list[tuple[float, float]]]:
    """``seconds`` of reports with a fresh GPS error every fix; (north, east) m per message type."""
    rng = random.Random(seed)
    mark = peer.mark()
    t0_s = peer.now_s
    fixes = 0
    while peer.now_s < t0_s + seconds:
        due_s = t0_s + fixes * FIX_PERIOD_S
        if due_s > peer.now_s:
            peer.run_for(due_s - peer.now_s)
        if noise_m > 0.0:
            glitch(peer, rng.gauss(0.0, noise_m), rng.gauss(0.0, noise_m))
        fixes += 1
    out: dict[str, list[tuple[float, float]]] = {}
    for kind in ("GLOBAL_POSITION_INT", "GPS_RAW_INT"):
        points = [
            (m.lat / 1e7, m.lon / 1e7) for _, m in peer.history[mark:] if m.get_type() == kind
        ]
        points = points[len(points) // 8 :]  # the EKF settles on the noise first
        lat0 = statistics.fmean(p[0] for p in points)
        lon0 = statistics.fmean(p[1] for p in points)
        out[kind] = [offset_m(lat0, lon0, lat, lon) for lat, lon in points]
    return out


def describe(name: str, points: list[tuple[float, float]]) -> str:
    """One line of figures for a series of (north, east) reports at 10 Hz."""
    north = [n for n, _ in points]
    east = [e for _, e in points]
    steps = [math.dist(a, b) for a, b in itertools.pairwise(points)]
    return (
        f"{name}: {len(points)} reports, spread north {statistics.pstdev(north):.3f} m, east "
        f"{statistics.pstdev(east):.3f} m, mean step {statistics.fmean(steps):.3f} m, "
        f"autocorrelation after 0.5 s {autocorrelation(north, 5):.2f}, 1 s "
        f"{autocorrelation(north, 10):.2f}, 3 s {autocorrelation(north, 30):.2f}"
    )


def step_response(peer: Peer, step_m: float, seconds: float) -> str:
    """Jump SITL's GPS ``step_m`` north at once: when each report has moved 10, 50, 90 %."""
    before = peer.last["GLOBAL_POSITION_INT"]
    lat0, lon0 = before.lat / 1e7, before.lon / 1e7
    mark = peer.mark()
    t0_s = peer.now_s
    glitch(peer, step_m, 0.0)
    peer.run_for(seconds)
    seen: dict[tuple[str, float], float] = {}
    for _, m in peer.history[mark:]:
        kind = m.get_type()
        if kind not in ("GLOBAL_POSITION_INT", "GPS_RAW_INT"):
            continue
        north_m, _ = offset_m(lat0, lon0, m.lat / 1e7, m.lon / 1e7)
        for share in (0.1, 0.5, 0.9):
            if (kind, share) not in seen and north_m >= share * step_m:
                seen[kind, share] = peer.time_of(m) - t0_s
    glitch(peer, 0.0, 0.0)
    peer.run_for(seconds)
    moved = ", ".join(
        f"{kind} {share:.0%} after {seen[kind, share]:.1f} s" if (kind, share) in seen else
        f"{kind} {share:.0%} not in {seconds:g} s"
        for kind in ("GPS_RAW_INT", "GLOBAL_POSITION_INT")
        for share in (0.1, 0.5, 0.9)
    )  # fmt: skip
    return f"a {step_m:g} m jump: {moved}"


def main() -> int:
    """Measure SITL's reports without and with the noise; print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--noise", type=float, default=0.5, help="GPS error per axis, m")
    parser.add_argument("--seconds", type=float, default=40.0, help="of SITL's time, noisy")
    parser.add_argument("--seed", type=int, default=7)
    parser.add_argument(
        "--jump", type=float, action="append", default=[], help="then a GPS jump of this, m"
    )
    args = parser.parse_args()
    peer = open_peer("sitl-rover")
    try:
        peer.wait_ready()
        streams = {"GLOBAL_POSITION_INT": 100_000, "GPS_RAW_INT": 100_000}
        with streaming(peer, streams):
            peer.run_for(3.0)
            for label, noise_m, seconds in (
                ("quiet", 0.0, 15.0),
                ("noisy", args.noise, args.seconds),
            ):
                series = record(peer, seconds, noise_m, args.seed)
                for kind, points in series.items():
                    print(describe(f"{label} {kind}", points), flush=True)
            glitch(peer, 0.0, 0.0)
            peer.run_for(3.0)
            for step_m in args.jump:
                print(step_response(peer, step_m, 25.0), flush=True)
    finally:
        peer.close()
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
