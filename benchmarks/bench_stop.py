"""``clark run``'s clean stop under a double Ctrl-C, and how long it waits for the autopilot.

Serves slash_b's autopilot (``clark autopilot-sim``: the simulated one, or ArduRover
SITL with ``--autopilot sitl``), then starts ``clark run`` for slash_b on it (UDP radio
on loopback, no peer) ``--runs`` times. Each run gets a SIGINT once the autopilot's
safety set-up took (or after ``--settle-s`` with the simulated autopilot's short boot)
and, with ``--second``, a second SIGINT a random 0 to ``--gap-ms`` later. It prints,
per outcome, how many runs ended so: the exit status (-2: ended by the SIGINT itself, as
the process was exiting), whether stderr held a traceback, whether the vehicle was sent
to its terminal mode; and the stop's wait for the autopilot's answers (from the
interface log). docs/performance.md, "A second Ctrl-C during clark run's stop".

    python benchmarks/bench_stop.py --runs 16 --second            # the race
    python benchmarks/bench_stop.py --runs 3 --autopilot sitl     # the answers' time
"""

from __future__ import annotations

import argparse
import random
import re
import signal
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "cooperative_follow.yaml"
TIMEOUT_S = 150.0


def clark(*args: str) -> subprocess.Popen[str]:
    """``python -m clark_engine ARGS`` from the checkout, its output piped."""
    return subprocess.Popen(
        [sys.executable, "-m", "clark_engine", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=ROOT,
    )


def wait_for(path: Path, words: str, process: subprocess.Popen[str], limit_s: float) -> bool:
    """True once ``path`` holds ``words``; False after ``limit_s`` or if the process ended."""
    deadline = time.monotonic() + limit_s
    while time.monotonic() < deadline and process.poll() is None:
        if path.exists() and words in path.read_text(encoding="utf-8"):
            return True
        time.sleep(0.05)
    return False


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--runs", type=int, default=16)
    parser.add_argument("--second", action="store_true", help="a second SIGINT in each run")
    parser.add_argument("--gap-ms", type=float, default=20.0)
    parser.add_argument("--autopilot", choices=("sim", "sitl"), default="sim")
    parser.add_argument("--settle-s", type=float, default=1.0)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args()
    served = ["autopilot-sim", str(MISSION), "--agent", "slash_b", "--autopilot", args.autopilot]
    if args.autopilot == "sim":
        served += ["--listen", "127.0.0.1:0", "--ready-s", "1"]
    sim = clark(*served)
    assert sim.stdout is not None
    connection = None
    while connection is None:
        line = sim.stdout.readline()
        if not line:
            print(sim.communicate()[1], file=sys.stderr)
            return 1
        found = re.search(r"--autopilot-connection (\S+)", line)
        connection = found.group(1) if found else None
    rng = random.Random(args.seed)
    outcomes: Counter[tuple[int, bool, bool]] = Counter()
    answered_ms: list[float] = []
    try:
        with tempfile.TemporaryDirectory() as folder:
            for k in range(args.runs):
                logs = Path(folder) / f"run{k}"
                run = clark(
                    "run", str(MISSION), "--agent", "slash_b", "--radio", "udp",
                    "--radio-address", "127.0.0.1:0", "--no-payload", "--plain",
                    "--autopilot-connection", connection, "--logs", str(logs),
                )  # fmt: skip
                interface = logs / "slash_b.interface.log"
                if args.autopilot == "sitl":
                    wait_for(interface, "every parameter took", run, TIMEOUT_S)
                else:
                    wait_for(interface, "real-time shell: loop at", run, TIMEOUT_S)
                    time.sleep(args.settle_s)
                run.send_signal(signal.SIGINT)
                if args.second:
                    time.sleep(rng.uniform(0.0, args.gap_ms / 1000))
                    if run.poll() is None:
                        run.send_signal(signal.SIGINT)
                _out, err = run.communicate(timeout=TIMEOUT_S)
                mission_log = (logs / "slash_b.mission.log").read_text(encoding="utf-8")
                held = "terminated; vehicle to HOLD" in mission_log
                outcomes[(run.returncode, "Traceback" in err, held)] += 1
                said = re.search(r"the autopilot answered in ([0-9.]+) s", interface.read_text())
                if said:
                    answered_ms.append(float(said.group(1)) * 1000)
    finally:
        sim.send_signal(signal.SIGINT)
        sim.communicate(timeout=60)
    print(f"{args.runs} runs, autopilot {args.autopilot}, second SIGINT: {args.second}")
    for (code, traceback, held), n in sorted(outcomes.items()):
        print(f"  exit {code:4d}  traceback {'yes' if traceback else 'no ':3s}  "
              f"HOLD sent {'yes' if held else 'no'}: {n}")  # fmt: skip
    if answered_ms:
        print(
            f"  the autopilot answered the stop in {min(answered_ms):.0f}-"
            f"{max(answered_ms):.0f} ms ({len(answered_ms)} runs)"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
