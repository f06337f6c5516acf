"""What ArduPilot's whole parameter list costs the dry run: building 50 vehicles, answering.

Prints, each the median of ``--repeat`` runs (default 5), each run in a fresh process, in
CPU seconds of that process (``time.process_time``: on a shared machine wall times move by
tens of per cent from one run to the next):

- ``build``: seconds of ``clark dry-run`` on a generated 50-vehicle fleet (51 agents
  with the station) stopped after 0.1 simulated seconds: validation, compilation,
  building every vehicle and its simulated autopilot, and the first tick (no report);
- ``built``: milliseconds to build 50 simulated rovers (and planes) in one process with
  the dry run's ``build_vehicle`` (model, simulated autopilot, pilot), the first one
  reading the firmware's list;
- ``load``: milliseconds to read one firmware's list from the package, modules already
  imported (the first vehicle of that firmware pays it; the others share it);
- ``answer``: milliseconds of simulated-autopilot work to answer one PARAM_REQUEST_LIST
  with the whole list (1,406 PARAM_VALUEs for ArduPlane), stepping its clock by 20 ms
(the conformance plane, built as the dry run builds it; parsing excluded is not: the
figure includes pymavlink's decoding of the answer, as a ground station would).

Run the same script against another checkout to compare (its engine first on the path):

    PYTHONPATH=/path/to/other/checkout python benchmarks/bench_sim_params.py

``load`` and ``answer`` are left out where the engine has no ``sim/ardupilot/params.py``.
Figures go to docs/performance.md.
"""

from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
AGENTS = 51

_BUILD = """
import io, sys, time
from pathlib import Path
from clark_engine.dryrun.command import run_dry_run
start = time.process_time()
run_dry_run(Path(sys.argv[1]), seed=None, until_s=0.1, report=None, speed=None,
            out=io.StringIO(), err=io.StringIO())
print(time.process_time() - start)
"""

_VEHICLES = """
import sys, time
from pathlib import Path
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import config_from_dict
from clark_engine.dryrun.world import build_vehicle
from clark_engine.validation import validate_file
mission = validate_file(Path(sys.argv[1])).mission
agent = mission.agents["vehicle"]
config = config_from_dict(agent_config(mission, agent))
start = time.process_time()
for _ in range(50):
    build_vehicle(mission, agent, config, 0)
print((time.process_time() - start) * 1e3)
"""

_LOAD = """
import time
from clark_engine.sim.ardupilot.params import sitl_table
start = time.process_time()
sitl_table("arduplane")
print((time.process_time() - start) * 1e3)
"""

_ANSWER = """
import sys, time
from pathlib import Path
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from clark_engine.mission.compiler import agent_config
from clark_engine.runtime.config import config_from_dict
from clark_engine.dryrun.world import build_vehicle
from clark_engine.validation import validate_file
mission = validate_file(Path(sys.argv[1])).mission
agent = mission.agents["vehicle"]
backend, _ = build_vehicle(mission, agent, config_from_dict(agent_config(mission, agent)), 0)
gcs = mavlink2.MAVLink(None, 255, 190)
parser = mavlink2.MAVLink(None)
request = gcs.param_request_list_encode(1, 1).pack(gcs)
now = 3.0
backend.step(now, 0.0)
start = time.process_time()
backend.send(request, now)
values = 0
while values < 1406 and now < 10.0:
    now += 0.02
    data = backend.autopilot.advance(now)
    values += sum(1 for m in parser.parse_buffer(data) or [] if m.get_type() == "PARAM_VALUE")
print((time.process_time() - start) * 1e3)
"""


def run(code: str, *args: str) -> float:
    """Run ``code`` in a fresh interpreter (the caller's PYTHONPATH); the float it prints."""
    with tempfile.TemporaryDirectory() as elsewhere:  # not the current directory's engine
        done = subprocess.run(
            [sys.executable, "-c", code, *args],
            capture_output=True,
            text=True,
            check=False,
            cwd=elsewhere,
        )
    if done.returncode != 0:
        raise RuntimeError(done.stderr.strip().splitlines()[-1])
    return float(done.stdout.strip().splitlines()[-1])


def main() -> None:
    """Print the figures for the engine on the path."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    sys.path.insert(0, str(HERE))
    from fleet import fleet_mission

    with tempfile.TemporaryDirectory() as tmp:
        mission = Path(tmp) / "fleet.yaml"
        mission.write_text(fleet_mission(AGENTS), encoding="utf-8")
        builds = [run(_BUILD, str(mission)) for _ in range(args.repeat)]
    print(
        f"build of {AGENTS - 1} vehicles: {statistics.median(builds):.2f} s CPU "
        f"(runs {', '.join(f'{b:.2f}' for b in builds)})"
    )
    conformance = HERE.parent / "tests" / "conformance" / "missions"
    for kind in ("rover", "plane"):
        made = [run(_VEHICLES, str(conformance / f"{kind}.yaml")) for _ in range(args.repeat)]
        print(f"50 simulated {kind}s built (build_vehicle): {statistics.median(made):.0f} ms")
    try:
        loads = [run(_LOAD) for _ in range(args.repeat)]
    except RuntimeError as exc:
        print(f"load, answer: not measured ({exc})")
        return
    print(f"load of the ArduPlane list: {statistics.median(loads):.1f} ms")
    answers = [run(_ANSWER, str(conformance / "plane.yaml")) for _ in range(args.repeat)]
    print(f"answer to PARAM_REQUEST_LIST (1406 values): {statistics.median(answers):.1f} ms")


if __name__ == "__main__":
    main()
