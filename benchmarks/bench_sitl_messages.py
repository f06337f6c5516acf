"""What a SITL run parses and what it costs: MAVLink messages by link and kind, engine CPU.

One ``clark dry-run --autopilot sitl`` of a mission in this process. Printed: the messages
the SITL backend's own link parsed by kind, the frames the engine's link handed the
engine's adapter (and the simulated pilot), the engine's CPU time and SITL's (the
children's), and the wall time. Session 6 measured with it that RC_CHANNELS and
SERVO_OUTPUT_RAW were half the backend's messages in a run that records no signal (now
streamed only when a doublet or sweep records one), and the cost of holding the engine's
link to the run's time (docs/performance.md, "SITL's messages at the run's time").

Needs SITL: ``--sitl PATH`` or ``$CLARK_SITL``; takes instances from
``$CLARK_SITL_INSTANCES`` (a free one of 150-199 by default).

Run: python benchmarks/bench_sitl_messages.py [--sitl PATH] [--speedup X] [MISSION]
(default: missions/copter_takeoff_land.yaml at 10)
"""

from __future__ import annotations

import argparse
import collections
import io
import os
import resource
import sys
import time
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent


def main() -> int:
    """Fly the mission once on SITL; print the counts and the CPU."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "mission", nargs="?", default=str(ROOT / "missions/copter_takeoff_land.yaml")
    )
    parser.add_argument(
        "--sitl", default=os.environ.get("CLARK_SITL", str(ROOT.parent / "shared/ardupilot-sitl"))
    )
    parser.add_argument("--speedup", type=float, default=10.0)
    args = parser.parse_args()
    from clark_engine.dryrun import sitl_backend
    from clark_engine.dryrun.command import run_dry_run
    from clark_engine.sitl.launcher import SitlInstall

    own: collections.Counter[str] = collections.Counter()
    link: collections.Counter[str] = collections.Counter()
    note, release = sitl_backend.SitlBackend._note, sitl_backend.SitlBackend._release

    def counted_note(self: Any, msg: Any) -> None:
        own[msg.get_type()] += 1
        note(self, msg)

    def counted_release(self: Any, until_s: float) -> bytes:
        data = release(self, until_s)
        link.update(m.get_type() for m in self.heard)
        return data

    sitl_backend.SitlBackend._note = counted_note  # type: ignore[method-assign]
    sitl_backend.SitlBackend._release = counted_release  # type: ignore[method-assign]
    install = SitlInstall.find(
        args.sitl, instances=os.environ.get("CLARK_SITL_INSTANCES", "150-199")
    )
    cpu_s, wall_s = time.process_time(), time.perf_counter()
    run_dry_run(
        Path(args.mission), seed=None, until_s=None, report=None, speed=None, sitl=install,
        sitl_speedup=args.speedup, out=io.StringIO(), err=io.StringIO(), quiet=True,
    )  # fmt: skip
    cpu_s, wall_s = time.process_time() - cpu_s, time.perf_counter() - wall_s
    children = resource.getrusage(resource.RUSAGE_CHILDREN)
    print(f"{Path(args.mission).name} on SITL at {args.speedup:g}x: {wall_s:.1f} s wall")
    print(f"  engine CPU {cpu_s:.2f} s, SITL CPU {children.ru_utime + children.ru_stime:.2f} s")
    for name, counts in (("backend's own link", own), ("engine's link", link)):
        top = ", ".join(f"{kind} {n}" for kind, n in counts.most_common(8))
        print(f"  {name}: {sum(counts.values())} messages ({top})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
