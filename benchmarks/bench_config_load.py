"""CPU time to load (and prove) a compiled agent config, and to build an agent's runtime.

What ``clark run`` does before its first tick: ``load_config`` reads the JSON, checks it
against the agent-config schema (every state's parameters against its primitive's own
schema), checks what a schema cannot say, and builds every state's runtime primitive
once (docs/runtime.md#loading-a-config); then ``AgentRuntime`` is built from it (the
tick phases and the telemetry schedule resolved to methods). Every example mission is
compiled once into a temporary folder; each of its configs is then loaded ``REPEATS``
times, the validator cached as in a process that loads one config after another (the
first load of a process also builds the validator: printed apart).

Printed: per mission, its agents, the mean CPU milliseconds per config load, and per
``AgentRuntime`` built from a loaded config. Process time, the best of ``ROUNDS``
rounds (a shared machine's noise only ever adds).

Run: python benchmarks/bench_config_load.py
"""

from __future__ import annotations

import contextlib
import functools
import io
import tempfile
import time
from pathlib import Path

from clark_engine.cli import main
from clark_engine.runtime.config import AgentConfig, load_config
from clark_engine.runtime.runtime import AgentRuntime

ROOT = Path(__file__).resolve().parent.parent
REPEATS = 20
ROUNDS = 5


def build_runtime(loaded: dict[Path, AgentConfig], path: Path) -> AgentRuntime:
    """The runtime of one loaded config (what ``clark run`` builds next)."""
    return AgentRuntime(loaded[path])


def best_ms(action: object, configs: list[Path]) -> float:
    """Best of ROUNDS of the mean CPU ms per call of ``action(path)`` over ``configs``."""
    best = float("inf")
    for _ in range(ROUNDS):
        start = time.process_time()
        for _ in range(REPEATS):
            for path in configs:
                action(path)  # type: ignore[operator]
        best = min(best, (time.process_time() - start) / (REPEATS * len(configs)) * 1e3)
    return best


def main_bench() -> None:
    """Compile every example, then time loading its configs and building runtimes."""
    with tempfile.TemporaryDirectory() as tmp:
        folders: list[tuple[str, list[Path]]] = []
        for mission in sorted((ROOT / "missions").glob("*.yaml")):
            out = Path(tmp) / mission.stem
            quiet = io.StringIO()
            with contextlib.redirect_stdout(quiet), contextlib.redirect_stderr(quiet):
                assert main(["compile", str(mission), "-o", str(out), "-q"]) == 0
            folders.append((mission.stem, sorted(out.glob("*/*.json"))))
        first = folders[0][1][0]
        start = time.process_time()
        load_config(first)
        print(
            f"first load of the process (builds the validator): "
            f"{(time.process_time() - start) * 1e3:.1f} ms"
        )
        print("CPU ms per config (process time, best of rounds)")
        print(f"{'mission':<30} {'agents':>6} {'load ms':>8} {'runtime ms':>10}")
        total_load = total_runtime = 0.0
        count = 0
        for name, configs in folders:
            load = best_ms(load_config, configs)
            loaded = {path: load_config(path) for path in configs}
            runtime = best_ms(functools.partial(build_runtime, loaded), configs)
            total_load += load * len(configs)
            total_runtime += runtime * len(configs)
            count += len(configs)
            print(f"{name:<30} {len(configs):>6} {load:>8.2f} {runtime:>10.2f}")
        print(
            f"{'mean per config':<30} {count:>6} {total_load / count:>8.2f} "
            f"{total_runtime / count:>10.2f}"
        )


if __name__ == "__main__":
    main_bench()
