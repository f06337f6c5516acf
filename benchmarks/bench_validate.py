"""Time validate + compile for every example mission and a generated 100-agent mission.

Prints, for each: agents, best and median wall time over repeated runs (in one
process, after a warm-up), and the time of `clark validate` on one example in a
fresh interpreter (start-up included, as a user sees it). Also the alias bomb:
time and peak memory to reject it.

Run: python benchmarks/bench_validate.py   (or make bench)
"""

from __future__ import annotations

import contextlib
import statistics
import subprocess
import sys
import tempfile
import time
import tracemalloc
from collections.abc import Callable
from pathlib import Path

from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.yaml_loader import YamlLoadError, load_yaml
from clark_engine.validation import validate_file

sys.path.insert(0, str(Path(__file__).resolve().parent))
from fleet import fleet_mission

ROOT = Path(__file__).resolve().parent.parent


def timed(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Best and median seconds of ``repeat`` runs after one warm-up."""
    fn()
    runs = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        runs.append(time.perf_counter() - start)
    return min(runs), statistics.median(runs)


def validate_and_compile(path: Path) -> int:
    result = validate_file(path, path.name)
    if result.mission is None:
        raise SystemExit(
            f"{path} is invalid:\n" + "\n".join(f.format_text() for f in result.findings)
        )
    return len(compile_mission(result.mission))


def alias_bomb() -> str:
    lines = ['a: &a ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        prev, cur = chr(96 + i), chr(97 + i)
        lines.append(f"{cur}: &{cur} [" + ",".join([f"*{prev}"] * 9) + "]")
    return "\n".join(lines) + "\n"


def main() -> None:
    print(f"{'mission':<36}{'agents':>7}{'best ms':>10}{'median ms':>11}")
    for path in sorted((ROOT / "missions").glob("*.yaml")):
        agents = validate_and_compile(path)
        best, median = timed(lambda p=path: validate_and_compile(p), repeat=20)
        print(f"{path.name:<36}{agents:>7}{best * 1e3:>10.1f}{median * 1e3:>11.1f}")
    with tempfile.TemporaryDirectory() as tmp:
        for size in (10, 50, 100):
            path = Path(tmp) / f"fleet_{size}.yaml"
            path.write_text(fleet_mission(size), encoding="utf-8")
            agents = validate_and_compile(path)
            best, median = timed(lambda p=path: validate_and_compile(p), repeat=5)
            print(
                f"{'generated ' + path.name:<36}{agents:>7}{best * 1e3:>10.1f}{median * 1e3:>11.1f}"
            )

    example = ROOT / "missions" / "supercub_sysid.yaml"
    runs = []
    for _ in range(7):
        start = time.perf_counter()
        proc = subprocess.run(
            [sys.executable, "-m", "clark_engine", "validate", str(example)],
            capture_output=True,
            check=False,
        )
        runs.append(time.perf_counter() - start)
        assert proc.returncode == 0, proc.stdout
    print(
        f"\n`clark validate {example.name}` in a fresh interpreter: "
        f"best {min(runs) * 1e3:.0f} ms, median {statistics.median(runs) * 1e3:.0f} ms"
    )

    bomb = alias_bomb()
    tracemalloc.start()
    start = time.perf_counter()
    with contextlib.suppress(YamlLoadError):
        load_yaml(bomb, "bomb.yaml")
    elapsed = time.perf_counter() - start
    _, peak = tracemalloc.get_traced_memory()
    tracemalloc.stop()
    print(
        f"alias bomb ({len(bomb)} bytes, 10^9 expansions): rejected in {elapsed * 1e3:.1f} ms, "
        f"peak {peak / 1e6:.2f} MB traced"
    )


if __name__ == "__main__":
    main()
