"""Print when a surveying vehicle came within its tolerance of each waypoint of a survey.

From a dry run's report (``clark dry-run MISSION --report DIR``, simulated or with
``--autopilot sitl``): the station's fleet log (``DIR/logs/<station>.fleet.csv``) has
every vehicle's reported position. Given the waypoints of the survey (north, east in
metres from the mission origin) and the tolerance, it prints the time each was reached
in turn and the leg before it: the figures of docs/performance.md's plane survey table.

Run: python benchmarks/bench_survey_legs.py REPORT_DIR [MISSION] [AGENT]
(defaults: missions/anaconda_survey.yaml and its surveying agent, anaconda; no
assertions)
"""

from __future__ import annotations

import csv
import math
import sys
from pathlib import Path
from typing import Any

import yaml

M_PER_DEG = 111_194.93
"""Metres per degree of latitude (the sphere of radius 6 371 km)."""


def survey_of(mission: dict[str, Any], agent: str) -> tuple[list[tuple[float, float]], float]:
    """The first state's waypoints (north, east) and tolerance of ``agent``."""
    behavior = mission["agents"][agent]["behavior"]
    state = behavior["states"][behavior["initial"]]
    given = state["with"]
    points = [(float(p[0]), float(p[1])) for p in given["waypoints"]]
    return points, float(given.get("tolerance_m", 5.0))


def main(argv: list[str]) -> int:
    """Print the legs; 2 on a usage error."""
    if not argv or len(argv) > 3:
        print(__doc__.strip().splitlines()[-3], file=sys.stderr)
        return 2
    report = Path(argv[0])
    mission_path = Path(argv[1] if len(argv) > 1 else "missions/anaconda_survey.yaml")
    agent = argv[2] if len(argv) > 2 else "anaconda"
    mission = yaml.safe_load(mission_path.read_text(encoding="utf-8"))
    origin = mission["mission"]["origin"]
    lat0, lon0 = float(origin["lat"]), float(origin["lon"])
    points, tolerance_m = survey_of(mission, agent)
    logs = sorted((report / "logs").glob("*.fleet.csv"))
    rows = [
        row
        for path in logs
        for row in csv.DictReader(path.open(encoding="utf-8"))
        if row["name"] == agent and row["lat_deg"] and path.name != f"{agent}.fleet.csv"
    ]
    if not rows:
        print(f"no position of {agent} in {report / 'logs'}", file=sys.stderr)
        return 2
    rows.sort(key=lambda r: float(r["now_s"]))
    k, last = 0, None
    for row in rows:
        t = float(row["now_s"])
        north = (float(row["lat_deg"]) - lat0) * M_PER_DEG
        east = (float(row["lon_deg"]) - lon0) * M_PER_DEG * math.cos(math.radians(lat0))
        if last is None:
            print(f"first position at {t:.1f} s: ({north:.0f}, {east:.0f}) m")
            last = t
        if k < len(points) and math.hypot(north - points[k][0], east - points[k][1]) < tolerance_m:
            where = f"({points[k][0]:g}, {points[k][1]:g})"
            print(f"waypoint {k} {where} at {t:6.1f} s, leg {t - last:5.1f} s")
            last, k = t, k + 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
