"""What a declared wind costs the simulated vehicles: steps per second with and without.

Run: ``python benchmarks/bench_wind.py``. Prints, for the F450 and the Super Cub flying a
guided leg, the model's steps per CPU second in still air, in a steady wind, and in a
wind with turbulence and gusts (the turbulence draws two normals per 0.02 s step).
"""

from __future__ import annotations

import random
import time
from pathlib import Path

import yaml

from clark_engine.mission.geo import LocalPoint, Origin, to_global
from clark_engine.sim.ardupilot.airframes.factory import make_vehicle
from clark_engine.sim.wind import WindConfig, WindField

ROOT = Path(__file__).resolve().parent.parent
ORIGIN = Origin(30.6372, -96.4787, 90.0)
STEPS = 20_000
DT_S = 0.02


def part(kind: str, name: str) -> dict[str, object]:
    return dict(yaml.safe_load((ROOT / "hardware_profiles" / kind / f"{name}.yaml").read_text()))


def rate(pair: tuple[str, str], wind: WindConfig | None) -> float:
    """Model steps per CPU second for a guided leg in ``wind``."""
    vehicle = make_vehicle(
        part("airframes", pair[0]),
        part("autopilots", pair[1]),
        None,
        ORIGIN,
        (0.0, 0.0, 50.0),
        random.Random(1),
        mode="GUIDED",
    )
    if wind is not None:
        vehicle.set_wind(WindField(wind, 1))
    lat, lon, alt = to_global(LocalPoint(5000.0, 3000.0, 60.0), ORIGIN)
    vehicle.goto(lat, lon, alt, None)
    start = time.process_time()
    for _ in range(STEPS):
        vehicle.step(DT_S)
    return STEPS / (time.process_time() - start)


def main() -> None:
    winds = {
        "still air": None,
        "steady 6 m/s": WindConfig(speed_mps=6.0, from_deg=250.0),
        "6 m/s, turbulence 1.5, gusts": WindConfig(
            speed_mps=6.0, from_deg=250.0, turbulence_mps=1.5, gust_mps=3.0, gust_every_s=20.0
        ),
    }
    for label, pair in (
        ("F450", ("dji_f450_airframe", "pixhawk_arducopter")),
        ("Super Cub", ("super_cub_airframe", "pixhawk_arduplane")),
    ):
        for name, wind in winds.items():
            print(f"{label:10s} {name:32s} {rate(pair, wind):9.0f} steps/s")


if __name__ == "__main__":
    main()
