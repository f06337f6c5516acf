"""The station view's page over an hour of a 10-agent rehearsal: the browser's memory.

Issue 12, item 5: "browser memory after an hour of a 10-agent rehearsal". A generated
mission (written to a temporary folder) of a station and nine vehicles that move for the
whole run, after the repository's missions:

- ``anaconda``: the survey of ``anaconda_survey.yaml`` (``survey_with_photos``), looping,
  a photo every 5 s (720 Picture Data an hour, each a marker on the page's map);
- ``f450``: takes off (``copter_takeoff_land.yaml``) and flies a looping 40 m square
  at 10 m;
- ``slash_0`` ... ``slash_6``: looping ``waypoint_tour``\\ s of 20 x 30 m at 2 m/s
  (``cooperative_follow.yaml``'s Slash A);
- telemetry as those missions declare it: heartbeat 1 Hz, Agent Status 2 Hz (the
  plane 1 Hz), Behavior State 1 Hz: about 19 track points a second on the page.

``clark dry-run MISSION --realtime --station --view 127.0.0.1:0 --until S`` rehearses
it at wall-clock speed and serves the page; one headless Chromium page
(``/usr/bin/chromium`` through Playwright, a fresh profile, the flags of
:mod:`bench_station`) stays open on it the whole time. Every ``--every-s`` (60) the
script samples:

- the page's JavaScript heap, as it is (CDP ``Performance.getMetrics``
  ``JSHeapUsedSize``) and after a forced garbage collection (CDP
  ``HeapProfiler.collectGarbage``): what the page really holds;
- the renderer's resident memory (``VmRSS`` from ``/proc``; the page's renderer is the
  busiest of the profile's renderer processes) and all the browser's processes' together
  (their proportional set sizes, ``Pss`` in ``smaps_rollup``, so shared pages count once);
- the DOM: element count, the SVG paths on the map, the mission-log lines, and CDP's
  ``Nodes``, ``JSEventListeners`` and ``LayoutObjects``;
- what the page was sent (Playwright's ``framereceived``): state frames, track points
  and photos so far, and the track points the page holds at most (5000 per agent);
- the page's handling of each state in the minute (p50, p99, max; the probe of
  :mod:`bench_station`) and the renderer's CPU;
- the rehearsal process's RSS and CPU, and the machine's load and steal.

Each sample is printed as it is taken (the output of a long run can be watched), then
the series and the end figures with the growth per hour over the second half.

Run: ``python benchmarks/bench_station_memory.py`` (an hour); ``--minutes 5`` for a
shorter run. Needs Playwright and ``/usr/bin/chromium``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import re
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
for _path in (ROOT, Path(__file__).resolve().parent):
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))

from bench_run import cpu_times, machine_text  # noqa: E402
from bench_station import (  # noqa: E402
    CHROMIUM,
    CHROMIUM_FLAGS,
    PAGE_PROBE,
    PROBE_RESET,
    Drain,
    browser_pids,
    percentile,
    process_cpu_s,
    rss_mb,
    stop_process,
)

_URL = re.compile(r"station view at (http://\S+)")
MAX_TRACK_POINTS_PAGE = 5000
"""The page's own bound on track points per agent (``MAX_TRACK_POINTS`` in app.js)."""

PAGE_COUNTS = """
(() => ({
  elements: document.getElementsByTagName("*").length,
  paths: document.querySelectorAll(".leaflet-overlay-pane path").length,
  log_items: document.querySelectorAll("#mission-log li").length,
  tooltips: document.querySelectorAll(".leaflet-tooltip").length,
  connection: (document.getElementById("connection") || {}).textContent || "",
  memory_used: performance.memory ? performance.memory.usedJSHeapSize : null,
}))()
"""
"""DOM counts the page has; ``performance.memory`` (coarse in Chromium without flags)."""


def mission_text(duration_s: float) -> str:
    """The 10-agent mission: a station, a surveying plane, a copter and seven rovers."""
    photos_min = int(duration_s / 5 * 0.8)
    lines = [
        "clark: 1",
        "mission:",
        "  id: 4246",
        "  name: bench-station-memory",
        "  description: The station view's hour-long rehearsal, 10 agents.",
        "  loop_hz: 10",
        "  heartbeat_timeout_s: 3",
        "  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}",
        "agents:",
        "  mcs:",
        "    id: 1",
        "    profile: mcs_laptop",
        '    hardware: {radio: {address: "0013A20040A1B201"}}',
        "    telemetry: {heartbeat: 1}",
        "  anaconda:",
        "    id: 2",
        "    profile: anaconda",
        '    hardware: {radio: {address: "0013A20040A1B202"}}',
        "    position: [0, 0, 60]",
        "    launch: {airborne: true}",
        "    telemetry: {heartbeat: 1, agent_status: 1, behavior_state: 1}",
        "    behavior:",
        "      use: survey_with_photos",
        "      with:",
        "        interval_s: 5",
        "        loop: true",
        "        tolerance_m: 75",
        "        waypoints: [[0, 0, 60], [400, 0, 60], [400, 150, 60], [0, 150, 60], "
        "[0, 300, 60], [400, 300, 60]]",
        "  f450:",
        "    id: 3",
        "    profile: dji_f450",
        '    hardware: {radio: {address: "0013A20040A1B203"}}',
        "    position: [-60, 0]",
        "    launch: {armed_by: engine}",
        "    telemetry: {heartbeat: 1, agent_status: 2, behavior_state: 1}",
        "    behavior:",
        "      initial: climb",
        "      states:",
        "        climb: {use: takeoff, with: {alt_m: 10}, transitions: {done: tour}}",
        "        tour:",
        "          use: waypoint_tour",
        "          with: {loop: true, tolerance_m: 2, speed_m_s: 3, waypoints: "
        "[[-60, 0, 10], [-60, 40, 10], [-100, 40, 10], [-100, 0, 10]]}",
    ]
    for k in range(7):
        north, agent_id = -120 + 40 * k, 4 + k
        square = [(north, -60), (north + 20, -60), (north + 20, -90), (north, -90)]
        points = ", ".join(f"[{n}, {e}]" for n, e in square)
        lines += [
            f"  slash_{k}:",
            f"    id: {agent_id}",
            "    profile: traxxas_slash",
            f'    hardware: {{radio: {{address: "0013A20040A1B2{agent_id:02X}"}}}}',
            f"    position: [{north}, -60]",
            "    telemetry: {heartbeat: 1, agent_status: 2, behavior_state: 1}",
            "    behavior:",
            "      use: waypoint_tour",
            f"      with: {{loop: true, tolerance_m: 2, speed_m_s: 2, waypoints: [{points}]}}",
        ]
    lines += [
        f"sim: {{duration_s: {duration_s:g}, seed: 1}}",
        "checks:",
        f"  - {{name: a photo every 5 s, photos: {{agent: anaconda, min: {photos_min}}}}}",
        "  - {name: no failsafe, no_failsafe: {}}",
    ]
    return "\n".join(lines) + "\n"


@dataclass
class Sample:
    """One minute's figures."""

    minute: float
    heap_mb: float
    heap_after_gc_mb: float
    heap_total_mb: float
    renderer_rss_mb: float
    browser_rss_mb: float
    elements: int
    paths: int
    log_items: int
    nodes: int
    listeners: int
    layout_objects: int
    frames: int
    track_points: int
    track_held: int
    photos: int
    handle_p50_ms: float
    handle_p99_ms: float
    handle_max_ms: float
    renderer_cpu: float
    rehearsal_rss_mb: float
    rehearsal_cpu: float
    connection: str
    load: float
    machine: str


@dataclass
class Received:
    """What the page was sent, from Playwright's ``framereceived``."""

    frames: int = 0
    photos: int = 0
    size_bytes: int = 0

    def __post_init__(self) -> None:
        self.points: dict[int, int] = {}

    @property
    def track_points(self) -> int:
        return sum(self.points.values())

    @property
    def track_held(self) -> int:
        """Track points the page holds, by its own bound (5000 per agent)."""
        return sum(min(n, MAX_TRACK_POINTS_PAGE) for n in self.points.values())

    def take(self, payload: str | bytes) -> None:
        if not isinstance(payload, str) or not payload.startswith('{"type":"state"'):
            return
        message = json.loads(payload)
        self.frames += 1
        self.size_bytes += len(payload)
        for point in message.get("track", ()):
            agent = int(point["agent"])
            self.points[agent] = self.points.get(agent, 0) + 1
        self.photos += len(message.get("photos", ()))


def pss_mb(pid: int) -> float:
    """A process's proportional set size in MB (shared pages split among their users)."""
    for line in Path(f"/proc/{pid}/smaps_rollup").read_text().splitlines():
        if line.startswith("Pss:"):
            return int(line.split()[1]) / 1024
    return float("nan")


def page_renderer(pids: dict[int, str]) -> int | None:
    """The page's renderer: of the profile's renderer processes, the one with most CPU.

    A headless Chromium keeps other renderers (a spare one, its own UI's) that sit idle;
    the page's draws five states a second.
    """
    best: tuple[float, int | None] = (-1.0, None)
    for pid, kind in pids.items():
        if kind != "renderer":
            continue
        with contextlib.suppress(OSError, IndexError):
            cpu = process_cpu_s(pid)
            if cpu > best[0]:
                best = (cpu, pid)
    return best[1]


def renderer_rss(pids: dict[int, str]) -> tuple[float, float, int | None]:
    """(the page's renderer's RSS, all the browser's processes' PSS, that renderer's pid)."""
    pid = page_renderer(pids)
    total = 0.0
    for other in pids:
        with contextlib.suppress(OSError, ValueError):
            total += pss_mb(other)
    rss = float("nan")
    if pid is not None:
        with contextlib.suppress(OSError):
            rss = rss_mb(pid)
    return rss, total, pid


async def run(args: argparse.Namespace, samples: list[Sample]) -> None:
    """The rehearsal, the page and the samples (appended to ``samples`` as they are taken).

    Everything started here is stopped on every way out.
    """
    duration_s = args.minutes * 60
    work = Path(tempfile.mkdtemp(prefix="clark-bench-station-memory-"))
    mission = work / "mission.yaml"
    mission.write_text(mission_text(duration_s + 120), encoding="utf-8")
    rehearsal: subprocess.Popen[str] | None = None
    context: Any = None
    playwright_cm: Any = None
    try:
        rehearsal = subprocess.Popen(
            [
                sys.executable,
                "-m",
                "clark_engine",
                "dry-run",
                str(mission),
                "--realtime",
                "--station",
                "--view",
                "127.0.0.1:0",
                "--view-hz",
                f"{args.view_hz:g}",
                "--until",
                f"{duration_s + 120:g}",
            ],
            cwd=ROOT,
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        io = Drain(rehearsal)
        found = await io.wait_for(_URL)
        if found is None:
            io.join()
            raise RuntimeError(f"no station view URL: {''.join(io.out + io.err)[-2000:]}")
        url = found[1]
        print(f"rehearsal: pid {rehearsal.pid}, view at {url}", flush=True)
        from playwright.async_api import async_playwright

        user_data = str(work / "chromium")
        playwright_cm = async_playwright()
        pw = await playwright_cm.__aenter__()
        context = await pw.chromium.launch_persistent_context(
            user_data,
            executable_path=CHROMIUM,
            args=list(CHROMIUM_FLAGS),
            viewport={"width": 1400, "height": 900},
        )
        page = context.pages[0] if context.pages else await context.new_page()
        await page.add_init_script(PAGE_PROBE)
        received = Received()

        def on_websocket(ws: Any) -> None:
            ws.on("framereceived", received.take)

        page.on("websocket", on_websocket)
        await page.goto(url)
        cdp = await context.new_cdp_session(page)
        await cdp.send("Performance.enable")
        await cdp.send("HeapProfiler.enable")
        start = time.monotonic()
        print(
            "min | heap MB (after GC) | renderer RSS MB | browser PSS MB | DOM elements | "
            "map paths | log | track points held (sent) | photos | handling p50/p99/max ms | "
            "renderer CPU | rehearsal RSS MB, CPU | machine",
            flush=True,
        )
        pids = browser_pids(user_data)
        renderer_pid = renderer_rss(pids)[2]
        cpu0 = process_cpu_s(renderer_pid) if renderer_pid else 0.0
        rehearsal_cpu0 = process_cpu_s(rehearsal.pid)
        machine0 = cpu_times()
        t_prev = start
        k = 0
        while True:
            k += 1
            due = start + k * args.every_s
            if due - start > duration_s + 1e-6:
                break
            await asyncio.sleep(max(0.0, due - time.monotonic()))
            if rehearsal.poll() is not None:
                raise RuntimeError(f"the rehearsal ended early: {''.join(io.err)[-2000:]}")
            now = time.monotonic()
            metrics = {
                m["name"]: m["value"] for m in (await cdp.send("Performance.getMetrics"))["metrics"]
            }
            await cdp.send("HeapProfiler.collectGarbage")
            after = {
                m["name"]: m["value"] for m in (await cdp.send("Performance.getMetrics"))["metrics"]
            }
            probe = await page.evaluate(PROBE_RESET)
            counts = await page.evaluate(PAGE_COUNTS)
            pids = browser_pids(user_data)
            renderer_mb, browser_mb, pid = renderer_rss(pids)
            if pid != renderer_pid:  # the page moved to another renderer: start its CPU over
                renderer_pid = pid
                cpu0 = process_cpu_s(pid) if pid else 0.0
            cpu1 = process_cpu_s(renderer_pid) if renderer_pid else 0.0
            rehearsal_cpu1 = process_cpu_s(rehearsal.pid)
            machine1 = cpu_times()
            sample = Sample(
                minute=(now - start) / 60,
                heap_mb=metrics.get("JSHeapUsedSize", 0.0) / 1e6,
                heap_after_gc_mb=after.get("JSHeapUsedSize", 0.0) / 1e6,
                heap_total_mb=after.get("JSHeapTotalSize", 0.0) / 1e6,
                renderer_rss_mb=renderer_mb,
                browser_rss_mb=browser_mb,
                elements=int(counts["elements"]),
                paths=int(counts["paths"]),
                log_items=int(counts["log_items"]),
                nodes=int(after.get("Nodes", 0)),
                listeners=int(after.get("JSEventListeners", 0)),
                layout_objects=int(after.get("LayoutObjects", 0)),
                frames=received.frames,
                track_points=received.track_points,
                track_held=received.track_held,
                photos=received.photos,
                handle_p50_ms=percentile(probe["handle_ms"], 0.5),
                handle_p99_ms=percentile(probe["handle_ms"], 0.99),
                handle_max_ms=max(probe["handle_ms"], default=float("nan")),
                renderer_cpu=(cpu1 - cpu0) / (now - t_prev),
                rehearsal_rss_mb=rss_mb(rehearsal.pid),
                rehearsal_cpu=(rehearsal_cpu1 - rehearsal_cpu0) / (now - t_prev),
                connection=str(counts["connection"]),
                load=os.getloadavg()[0],
                machine=machine_text(machine0, machine1),
            )
            cpu0, rehearsal_cpu0, machine0, t_prev = cpu1, rehearsal_cpu1, machine1, now
            samples.append(sample)
            print(line_of(sample), flush=True)
    finally:
        if context is not None:
            with contextlib.suppress(Exception):
                await context.close()
        if playwright_cm is not None:
            with contextlib.suppress(Exception):
                await playwright_cm.__aexit__(None, None, None)
        stop_process(rehearsal, grace_s=30.0)
        shutil.rmtree(work, ignore_errors=True)


def line_of(s: Sample) -> str:
    """One sample as a row of the printed series."""
    return (
        f"{s.minute:5.1f} | {s.heap_mb:6.1f} ({s.heap_after_gc_mb:5.1f}) | "
        f"{s.renderer_rss_mb:6.0f} | {s.browser_rss_mb:6.0f} | {s.elements:6d} | {s.paths:5d} | "
        f"{s.log_items:3d} | {s.track_held:6d} ({s.track_points}) | {s.photos:4d} | "
        f"{s.handle_p50_ms:.1f}/{s.handle_p99_ms:.1f}/{s.handle_max_ms:.1f} | "
        f"{s.renderer_cpu * 100:4.1f}% | {s.rehearsal_rss_mb:.0f}, "
        f"{s.rehearsal_cpu * 100:.1f}% | load {s.load:.2f}, {s.machine}"
        + ("" if s.connection == "live" else f" | page says {s.connection!r}")
    )


def summarise(samples: Sequence[Sample]) -> None:
    """The end figures, and how fast each one grew over the second half of the run."""
    if not samples:
        print("no samples")
        return
    end = samples[-1]
    half = [s for s in samples if s.minute >= end.minute / 2] or [end]

    def per_hour(values: Sequence[float]) -> float:
        """Least-squares slope over the second half, per hour."""
        xs = [s.minute / 60 for s in half]
        if len(xs) < 2:
            return float("nan")
        mean_x, mean_y = statistics.fmean(xs), statistics.fmean(values)
        sxx = sum((x - mean_x) ** 2 for x in xs)
        return sum((x - mean_x) * (y - mean_y) for x, y in zip(xs, values, strict=True)) / sxx

    print(f"\nafter {end.minute:.1f} min ({end.frames} states received by the page):")
    rows = (
        ("JS heap, MB", end.heap_mb, [s.heap_mb for s in half]),
        ("JS heap after a forced GC, MB", end.heap_after_gc_mb, [s.heap_after_gc_mb for s in half]),
        ("renderer RSS, MB", end.renderer_rss_mb, [s.renderer_rss_mb for s in half]),
        ("all browser processes' PSS, MB", end.browser_rss_mb, [s.browser_rss_mb for s in half]),
        ("DOM elements", end.elements, [float(s.elements) for s in half]),
        ("SVG paths on the map", end.paths, [float(s.paths) for s in half]),
        ("track points held by the page", end.track_held, [float(s.track_held) for s in half]),
        ("photos received", end.photos, [float(s.photos) for s in half]),
        ("handling p99, ms", end.handle_p99_ms, [s.handle_p99_ms for s in half]),
        ("rehearsal RSS, MB", end.rehearsal_rss_mb, [s.rehearsal_rss_mb for s in half]),
    )
    for name, value, values in rows:
        print(f"  {name}: {value:.1f} (second half: {per_hour(values):+.1f} per hour)")
    first = samples[0]
    print(
        f"  first sample ({first.minute:.1f} min): heap {first.heap_after_gc_mb:.1f} MB after "
        f"GC, renderer {first.renderer_rss_mb:.0f} MB, {first.elements} DOM elements"
    )
    print("\nseries (JSON):")
    for s in samples:
        print(json.dumps(asdict(s)))


def main(argv: Sequence[str] | None = None) -> int:
    """Parse the options, run, print the series; SIGTERM and Ctrl-C stop it cleanly."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=60.0, help="how long (60)")
    parser.add_argument("--every-s", type=float, default=60.0, help="between samples (60)")
    parser.add_argument("--view-hz", type=float, default=5.0)
    args = parser.parse_args(argv)
    load = os.getloadavg()
    print(
        f"machine: {os.cpu_count()} cores, load average {load[0]:.2f} {load[1]:.2f} "
        f"{load[2]:.2f}; {args.minutes:g} min, a sample every {args.every_s:g} s, view "
        f"{args.view_hz:g} Hz; bench pid {os.getpid()}",
        flush=True,
    )

    samples: list[Sample] = []

    async def guarded() -> None:
        task = asyncio.current_task()
        loop = asyncio.get_running_loop()
        assert task is not None
        for signum in (signal.SIGTERM, signal.SIGINT):
            loop.add_signal_handler(signum, task.cancel)
        await run(args, samples)

    try:
        asyncio.run(guarded())
    except asyncio.CancelledError:
        print("stopped by a signal; the samples so far:", flush=True)
        summarise(samples)
        return 1
    summarise(samples)
    return 0


if __name__ == "__main__":
    sys.exit(main())
