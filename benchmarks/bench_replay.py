"""``clark replay``: how long a large run's logs take to load, and a seek to answer.

Why: the replay loads a run once and answers every seek from memory
(:mod:`clark_engine.station.replay`); the issue asks that an hour of 10 agents stay usable:
loading in seconds, a seek well under a second.

The logs are generated, as the logbook writes them (docs/logs.md): a station ``mcs``
whose fleet CSV holds one row per vehicle per tick (``--loop-hz``, 10 by default) with
each vehicle's Agent Status arriving at ``--status-hz`` (5 by default: 180,000 arrivals
for an hour of 10 vehicles, 360,000 rows at 10 Hz), a mission log with a line every few
seconds, and each vehicle's mission log with a state change every 10 s. No mission is
given (the logs alone), so what is measured is the replay's own reading and indexing;
``--checks`` adds ``clark analyze --checks``'s rebuild, which reads every fleet CSV
again, and is not measured here.

Measured, on this machine:

- **load**: :func:`~clark_engine.station.replay.load_replay`, wall-clock, best of
  ``--repeat``;
- **seek**: what the server does for a page that jumps to a random time: the
  ``[reset, state]`` frame built and encoded as JSON (the tracks up to then, thinned to
  2,000 points per agent, the latest 500 log lines, the agents' rows), median and
  worst of ``--seeks`` random times;
- **step**: what a playing page costs per update (a 0.2 s step at 20x: 4 s of new
  track points), median and worst;
- the sizes of a seek's and a step's JSON.

Run: ``.venv/bin/python benchmarks/bench_replay.py [--hours 1] [--vehicles 10]``.
"""

from __future__ import annotations

import argparse
import csv
import json
import random
import statistics
import sys
import tempfile
import time
from pathlib import Path

from clark_engine.link.fleet import FleetTable
from clark_engine.station.replay import load_replay

HEADER = ["now_s", *FleetTable.csv_header()]
GPS_EPOCH_MS = 1_451_260_818_000


def _line(t_s: float, level: str, event: str, message: str) -> str:
    return f"t={t_s:.3f} gps_ms={GPS_EPOCH_MS + round(1000 * t_s)} {level} {event}: {message}\n"


def _header_line(agent: str, agent_id: int, role: str) -> str:
    return (
        f"t=0.000 gps_ms=- INFO log.open: logbook opened: clark_engine=0.1.0 "
        f"mission=bench mission_id=7 agent={agent} agent_id={agent_id} role={role} "
        "loop_hz=10.0 period_s=0.1 level=INFO\n"
    )


def write_logs(
    folder: Path, *, hours: float, vehicles: int, loop_hz: float, status_hz: float
) -> int:
    """A station's and its vehicles' logs for ``hours`` of a run; returns the fleet rows."""
    duration_s = hours * 3600.0
    ticks = int(duration_s * loop_hz)
    names = [f"v{k}" for k in range(2, vehicles + 2)]
    index = {column: i for i, column in enumerate(HEADER)}
    rows = 0
    with (folder / "mcs.fleet.csv").open("w", newline="", encoding="utf-8") as stream:
        writer = csv.writer(stream)
        writer.writerow(HEADER)
        base = [""] * len(HEADER)
        for tick in range(1, ticks + 1):
            now_s = tick / loop_hz
            for k, name in enumerate(names):
                row = list(base)
                arrival_s = int(now_s * status_hz) / status_hz
                angle = 0.01 * arrival_s + k
                row[index["now_s"]] = repr(now_s)
                row[index["agent_id"]] = str(k + 2)
                row[index["name"]] = name
                row[index["agent_type"]] = "vehicle"
                row[index["condition"]] = "ok"
                row[index["lost"]] = "0"
                row[index["since_heartbeat_s"]] = repr(now_s - int(now_s))
                row[index["lat_deg"]] = repr(30.6372 + 0.0005 * (k + 1) * (1 + 0.2 * angle % 1))
                row[index["lon_deg"]] = repr(-96.4787 + 0.0005 * (k + 1) * (angle % 1))
                row[index["alt_m"]] = "0.0"
                row[index["ground_speed_m_s"]] = "2.5"
                row[index["climb_rate_m_s"]] = "0.0"
                row[index["heading_deg"]] = repr(round(angle * 57.3 % 360, 1))
                row[index["mode"]] = "15"
                row[index["status_age_s"]] = repr(now_s - arrival_s)
                row[index["packets"]] = str(int(now_s * (status_hz + 1)))
                row[index["lost_packets"]] = "0"
                row[index["loss_ratio"]] = "0.0"
                row[index["latency_mean_ms"]] = "12.5"
                for column in ("bad_tags", "malformed", "duplicates"):
                    row[index[column]] = "0"
                writer.writerow(row)
                rows += 1
    with (folder / "mcs.mission.log").open("w", encoding="utf-8") as stream:
        stream.write(_header_line("mcs", 1, "mcs"))
        for k in range(int(duration_s / 3)):
            stream.write(_line(3.0 * k, "INFO", "fleet.found", f"note {k}"))
    for k, name in enumerate(names):
        with (folder / f"{name}.mission.log").open("w", encoding="utf-8") as stream:
            stream.write(_header_line(name, k + 2, "vehicle"))
            state = "idle"
            for j in range(int(duration_s / 10)):
                target = "chase" if state == "idle" else "idle"
                stream.write(
                    _line(
                        10.0 * j + 0.1 * k,
                        "INFO",
                        "behavior.change",
                        f"toggle: {state} -> {target} (active: {target})",
                    )
                )
                state = target
    return rows


def main(argv: list[str] | None = None) -> int:
    """Generate the logs, load them, seek; print the figures."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--hours", type=float, default=1.0)
    parser.add_argument("--vehicles", type=int, default=10)
    parser.add_argument("--loop-hz", type=float, default=10.0)
    parser.add_argument("--status-hz", type=float, default=5.0)
    parser.add_argument("--repeat", type=int, default=3, help="loads; the best is reported")
    parser.add_argument("--seeks", type=int, default=50)
    parser.add_argument("--seed", type=int, default=1)
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory(prefix="bench-replay-") as tmp:
        folder = Path(tmp)
        started = time.perf_counter()
        rows = write_logs(
            folder,
            hours=args.hours,
            vehicles=args.vehicles,
            loop_hz=args.loop_hz,
            status_hz=args.status_hz,
        )
        size_mb = sum(p.stat().st_size for p in folder.iterdir()) / 1e6
        print(
            f"logs: {args.hours:g} h, {args.vehicles} vehicles, fleet CSV {rows} rows at "
            f"{args.loop_hz:g} Hz, Agent Status at {args.status_hz:g} Hz; {size_mb:.0f} MB "
            f"(written in {time.perf_counter() - started:.1f} s)"
        )
        loads = []
        replay = None
        for _ in range(args.repeat):
            started = time.perf_counter()
            replay, _load = load_replay(folder)
            loads.append(time.perf_counter() - started)
        assert replay is not None
        points = len(replay.reset(replay.end_s)["track"])
        print(
            f"load: best {min(loads):.2f} s, worst {max(loads):.2f} s of {args.repeat} "
            f"(span {replay.start_s:.0f}-{replay.end_s:.0f} s; a reset at the end sends "
            f"{points} track points)"
        )
        draw = random.Random(args.seed)
        seeks, steps, seek_bytes, step_bytes = [], [], [], []
        for _ in range(args.seeks):
            t_s = draw.uniform(replay.start_s, replay.end_s)
            started = time.perf_counter()
            text = [json.dumps(m, separators=(",", ":")) for m in replay.frame(t_s, None)]
            seeks.append(time.perf_counter() - started)
            seek_bytes.append(sum(map(len, text)))
            started = time.perf_counter()
            text = [json.dumps(m, separators=(",", ":")) for m in replay.frame(t_s + 4.0, t_s)]
            steps.append(time.perf_counter() - started)
            step_bytes.append(sum(map(len, text)))
        print(
            f"seek (reset + state, JSON encoded): median {1000 * statistics.median(seeks):.0f} ms, "
            f"worst {1000 * max(seeks):.0f} ms; {statistics.median(seek_bytes) / 1e3:.0f} kB"
        )
        print(
            f"step (4 s of play, JSON encoded): median {1000 * statistics.median(steps):.1f} ms, "
            f"worst {1000 * max(steps):.1f} ms; {statistics.median(step_bytes) / 1e3:.0f} kB"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
