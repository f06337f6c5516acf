"""Floods from the air into one live runtime: what piles up, what a tick costs, the logs' size.

Slash B of cooperative_follow (unkeyed, like every shipped example) runs its behaviour
on a virtual clock with its station heard, logging to real files in a temporary folder.
Two floods, each made by the real ClarkLink codec and delivered as PacketReceived:

1. **Forged timed activations**: N packets claiming the station's id, each an Activate
   Controller for a different GPS time a minute or more ahead (1 ms apart; activate and deactivate,
   for this agent and for every agent), all delivered in one tick.
2. **Agents not in the mission**: a flood at RATE packets/s for SECONDS s (virtual time)
   from 50 ids not in the mission, each packet a heartbeat, a status and an activation.

Printed for each: the tick's wall time before and after the flood (median of 200
ticks), the entries held (timed activations), the peak memory growth (max RSS), and
the bytes and lines of the mission log, the interface log and the message log. No
pass/fail: the figures go to docs/performance.md ("Floods from the air").

Run: python benchmarks/flood_runtime.py [N] [RATE] [SECONDS]
(defaults: 1,000,000 activations; 50,000 packets/s for 20 s). Run it with
PYTHONPATH pointing at another checkout to measure that one.
"""

from __future__ import annotations

import resource
import statistics
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

from clark_engine.link.codec import Codec
from clark_engine.link.messages import ActivateController, AgentStatus, AgentType, Heartbeat
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import config_from_dict
from clark_engine.runtime.events import (
    AutopilotHeartbeat,
    AutopilotStatus,
    LandedState,
    PacketReceived,
    VehicleState,
)
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parent.parent
GPS0 = 1_400_000_000_000
MISSION_ID = 521
STATION_ID = 1
READY = AutopilotStatus(
    gps_fix_type=3,
    position_ok=True,
    prearm_ok=True,
    home=(30.6372, -96.4787, 90.0),
    landed=LandedState.IN_AIR,
)


class Scene:
    """Slash B running idle beside its station, logging to ``folder``."""

    def __init__(self, folder: Path) -> None:
        path = ROOT / "missions" / "cooperative_follow.yaml"
        result = validate_path(path, path.name)
        assert result.mission is not None
        config = config_from_dict(agent_config(result.mission, result.mission.agents["slash_b"]))
        config = replace(config, safety_setup=False)  # no autopilot here to answer it
        self.folder = folder
        self.logbook = Logbook.to_folder(folder, config)
        self.runtime = AgentRuntime(config, logbook=self.logbook)
        self.station = Codec(MISSION_ID, STATION_ID)
        self.t = 0.0
        for _ in range(3):
            self.tick()

    def tick(self) -> float:
        """One tick 0.1 s on, with the station's heartbeat and the autopilot; its wall time."""
        self.t = round(self.t + 0.1, 1)
        t, runtime = self.t, self.runtime
        gps = GPS0 + int(t * 1000)
        state = VehicleState(
            gps, 30.6372, -96.4787, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, "HOLD", 4, True
        )
        (beat,) = self.station.encode(
            [Heartbeat(STATION_ID, gps, MISSION_ID, AgentType.MCS)], 0, 256
        )
        for event in (READY, state, AutopilotHeartbeat("HOLD", 4, True), PacketReceived(beat)):
            runtime.deliver(event, t)
        start = time.perf_counter()
        runtime.tick(t)
        return time.perf_counter() - start

    def tick_ms(self, ticks: int = 200) -> float:
        """Median wall time of ``ticks`` ticks, in ms."""
        return statistics.median(self.tick() for _ in range(ticks)) * 1e3

    def held(self) -> int:
        """Timed activations held (the runtime's private list, read for the figure)."""
        return len(self.runtime._intake.scheduled)

    def log_figures(self) -> str:
        names = self.runtime.config.log_files
        parts = []
        for key, label in (
            ("mission_log", "mission log"),
            ("interface_log", "interface log"),
            ("message_log", "message log"),
        ):
            data = (self.folder / names[key]).read_bytes()
            lines = data.count(b"\n")
            parts.append(f"{label} {len(data) / 1e6:.2f} MB ({lines:,} lines)")
        return "; ".join(parts)


def rss_mb() -> float:
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def timed_activations(count: int) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        scene = Scene(Path(tmp) / "logs")
        before_ms = scene.tick_ms()
        rss_before = rss_mb()
        forger = Codec(MISSION_ID, STATION_ID)
        runtime, t = scene.runtime, scene.t
        start = time.perf_counter()
        for k in range(count):
            target = (0, 3)[k % 2]
            message = ActivateController(STATION_ID, GPS0, target, k % 3 != 0, GPS0 + 60_000 + k)
            (data,) = forger.encode([message], 0, 256)
            runtime.deliver(PacketReceived(data), t)
        took_s = time.perf_counter() - start
        held = scene.held()
        after_ms = scene.tick_ms()
        scene.logbook.close()
        print(
            f"{count:,} forged timed activations in {took_s:.1f} s: held {held:,}; "
            f"tick {before_ms:.3f} ms before, {after_ms:.3f} ms after (median of 200); "
            f"max RSS +{rss_mb() - rss_before:.1f} MB"
        )
        print(f"  {scene.log_figures()}")


def unknown_ids(rate_per_s: int, seconds: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        scene = Scene(Path(tmp) / "logs")
        before_ms = scene.tick_ms()
        rss_before = rss_mb()
        senders = [Codec(MISSION_ID, 1000 + i) for i in range(50)]
        runtime = scene.runtime
        per_tick = int(rate_per_s / 10)
        ticks = int(seconds * 10)
        start = time.perf_counter()
        n = 0
        for _ in range(ticks):
            t = scene.t
            for _ in range(per_tick):
                codec = senders[n % len(senders)]
                me = codec.agent_id
                gps = GPS0 + int(t * 1000)
                messages = [
                    Heartbeat(me, gps, MISSION_ID, AgentType.MCS),
                    AgentStatus(me, gps, 30.6, -96.4, 0.0, 1.0, 0.0, 90.0, 4),
                    ActivateController(me, gps, 0, True),
                ]
                (data,) = codec.encode(messages, 0, 256)  # type: ignore[arg-type]
                runtime.deliver(PacketReceived(data), t)
                n += 1
            scene.tick()
        took_s = time.perf_counter() - start
        after_ms = scene.tick_ms(110)  # past the summary interval
        scene.logbook.close()
        print(
            f"{n:,} packets from 50 ids not in the mission, {rate_per_s:,}/s for {seconds:g} s "
            f"of virtual time, delivered in {took_s:.1f} s: tick {before_ms:.3f} ms before, "
            f"{after_ms:.3f} ms after; max RSS +{rss_mb() - rss_before:.1f} MB"
        )
        print(f"  {scene.log_figures()}")


def main() -> int:
    count = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
    rate = int(sys.argv[2]) if len(sys.argv) > 2 else 50_000
    seconds = float(sys.argv[3]) if len(sys.argv) > 3 else 20.0
    timed_activations(count)
    unknown_ids(rate, seconds)
    return 0


if __name__ == "__main__":
    sys.exit(main())
