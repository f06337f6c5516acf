"""Bad numbers and paths in a mission: a finding with a place and a fix, never a traceback.

Issue 18, item 6. A fuzzer found `clark validate` raising on a 6,000-character include
path (``OSError: File name too long``) and on huge integers in a position, the origin's
altitude and a fault time (``OverflowError``), and `clark dry-run` raising on missions
that validated: an altitude of 4294967295 overflowed pymavlink's GLOBAL_POSITION_INT, and
a huge number in a check's target. Each is reproduced here through the command a user
types, then the language's rule that keeps the whole class away: every number has a
physical range and every path a length limit (checked over the shipped schemas), and a
fuzz test that pushes the example missions' numbers to extremes through validate,
compile and a short dry run.
"""

from __future__ import annotations

import copy
import io
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from clark_engine.cli import main
from clark_engine.dryrun.command import run_dry_run
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.schemas import SCHEMA_NAMES, schema_text
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = {p.name: p for p in sorted((ROOT / "missions").glob("*.yaml"))}
DATA = {name: yaml.safe_load(p.read_text(encoding="utf-8")) for name, p in MISSIONS.items()}
HUGE = 10**400  # past every float: float(HUGE) raises OverflowError


def _write(tmp_path: Path, data: dict[str, Any], name: str = "m.yaml") -> Path:
    path = tmp_path / name
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
    return path


def _mission(name: str = "cooperative_follow.yaml") -> dict[str, Any]:
    return copy.deepcopy(DATA[name])


def _validate(
    capsys: pytest.CaptureFixture[str], path: Path | str, code: int = 1
) -> tuple[str, str]:
    """`clark validate PATH`: the exit code, and no traceback in what it printed."""
    assert main(["validate", str(path)]) == code
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return out, err


def _finding(out: str, code: str) -> str:
    """The one line of ``out`` carrying ``code``; it names the file and a line."""
    lines = [line for line in out.splitlines() if f"[{code}]" in line]
    assert lines, out
    assert lines[0].split(":")[1].isdigit(), lines[0]  # file:line:column: ...
    return lines[0]


# --- clark validate: the reported crashes ------------------------------------------------


def test_a_6000_character_include_path_is_a_finding(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission()
    data["include"] = {"behaviors": ["a" * 6000]}
    out, _ = _validate(capsys, _write(tmp_path, data))
    line = _finding(out, "E-INCLUDE-PATH")
    assert "6000 characters" in line and "at most" in line
    assert len(line) < 600  # the path is not quoted back whole


def test_a_folder_name_over_255_bytes_is_a_finding(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission()
    data["include"] = {"hardware_profiles": ["mine/" + "é" * 200]}  # 400 bytes, 205 characters
    out, _ = _validate(capsys, _write(tmp_path, data))
    assert "255 bytes" in _finding(out, "E-INCLUDE-PATH")


def test_a_long_key_file_is_a_finding(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    data = _mission()
    data["mission"]["key_file"] = "k" * 5000
    out, _ = _validate(capsys, _write(tmp_path, data))
    assert "5000 characters long; write at most 1024" in _finding(out, "E-VALUE")


def test_a_mission_path_too_long_for_the_system_is_a_usage_error(
    capsys: pytest.CaptureFixture[str],
) -> None:
    _, err = _validate(capsys, "m" * 6000 + ".yaml", code=2)
    assert "too long" in err


@pytest.mark.parametrize(
    ("where", "value"),
    [
        (("agents", "slash_b", "position"), [HUGE, 0]),
        (("agents", "slash_b", "position"), [0, 0, -HUGE]),
        (("agents", "slash_a", "behavior", "with", "waypoints", 1), [HUGE, 0]),
        (("mission", "origin", "alt_amsl_m"), HUGE),
        (("checks", 0, "by_s"), HUGE),
        (("checks", 0, "distance_m", "max"), HUGE),
    ],
    ids=["position", "position-up", "waypoint", "origin-altitude", "check-time", "check-max"],
)
def test_huge_integers_are_out_of_range(
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    where: tuple[Any, ...],
    value: Any,
) -> None:
    data = _mission()
    parent: Any = data
    for part in where[:-1]:
        parent = parent[part]
    parent[where[-1]] = value
    out, _ = _validate(capsys, _write(tmp_path, data))
    line = _finding(out, "E-RANGE")
    assert "at most" in line and len(line) < 400  # a 401-digit number is not written out


def test_a_huge_fault_time_is_out_of_range(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission("fault_lost_peer.yaml")
    data["faults"][0]["kill"]["at_s"] = HUGE
    data["faults"][1]["autopilot_disconnect"]["to_s"] = HUGE
    out, _ = _validate(capsys, _write(tmp_path, data))
    assert len([line for line in out.splitlines() if "[E-RANGE]" in line]) == 2


def test_a_check_tolerance_too_big_for_a_float_is_out_of_range(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission("copter_takeoff_land.yaml")
    reached = next(c for c in data["checks"] if "reached" in c)
    reached["reached"]["tolerance_m"] = HUGE
    out, _ = _validate(capsys, _write(tmp_path, data))
    _finding(out, "E-RANGE")


def test_a_hex_integer_longer_than_python_prints_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """0x with 5,000 digits is an int Python reads but will not turn into decimal text."""
    text = MISSIONS["cooperative_follow.yaml"].read_text(encoding="utf-8")
    text = text.replace("alt_amsl_m: 90", "alt_amsl_m: 0x" + "f" * 5000)
    path = tmp_path / "m.yaml"
    path.write_text(text, encoding="utf-8")
    out, _ = _validate(capsys, path)
    assert "about 6021 digits" in _finding(out, "E-YAML-VALUE")


def test_fault_rules_take_a_huge_time_without_raising() -> None:
    """The fuzzer's fault-time crash, where it was: float(10**400) in the fault rules."""
    from clark_engine.mission.faults import fault_problems

    problems = fault_problems({"kill": {"agent": "slash_a", "at_s": HUGE}})
    assert [p.code for p in problems] == ["E-FAULT-WINDOW"]


@pytest.mark.parametrize(
    "args",
    [("--fault", "kill:slash_a@99999999"), ("--until", "1e300")],
    ids=["fault-time", "until"],
)
def test_dry_run_options_past_the_longest_run_are_usage_errors(
    capsys: pytest.CaptureFixture[str], args: tuple[str, str]
) -> None:
    """The command line's times have the language's range: 1e300 s would never finish."""
    try:
        code = main(["dry-run", str(MISSIONS["fault_lost_peer.yaml"]), "--quiet", *args])
    except SystemExit as stopped:  # argparse's own usage errors
        code = int(stopped.code or 0)
    _, err = capsys.readouterr()
    assert code == 2 and "Traceback" not in err
    assert "1000000" in err


# --- clark dry-run: missions that validated, then raised ---------------------------------


def _dry_run(capsys: pytest.CaptureFixture[str], path: Path) -> str:
    code = main(["dry-run", str(path), "--until", "2", "--quiet"])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    assert code == 1, out + err
    return out + err


def test_an_altitude_of_4294967295_is_refused_before_the_dry_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission("supercub_sysid.yaml")
    data["agents"]["cub"]["position"] = [0, 0, 4294967295]
    data["agents"]["cub"]["launch"] = {"armed_by": "pilot", "airborne": True}
    text = _dry_run(capsys, _write(tmp_path, data))
    assert "[E-RANGE]" in text and "m.yaml:" in text


def test_an_origin_altitude_of_1_797e308_is_refused_before_the_dry_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission()
    data["mission"]["origin"]["alt_amsl_m"] = 1.797e308
    text = _dry_run(capsys, _write(tmp_path, data))
    assert "[E-RANGE]" in text and "9000 m" in text


def test_a_huge_check_target_is_refused_before_the_dry_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    data = _mission()
    data["checks"].append(
        {"name": "far", "reached": {"agent": "slash_b", "to": [1e20, 3e19], "tolerance_m": 1e300}}
    )
    text = _dry_run(capsys, _write(tmp_path, data))
    assert "[E-RANGE]" in text and "m.yaml:" in text


def test_a_position_east_of_a_polar_origin_stays_on_the_globe(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """22 m from a pole, 40 m east is 100 degrees of longitude: wrapped past 180, not refused.

    Found by the fuzzer: it validated, then the compiled config's longitude (out of
    -180..180) was refused by the dry run as "not a valid compiled agent config".
    """
    data = _mission()
    data["mission"]["origin"]["lat"] = -89.9998  # 22 m from the South Pole
    data["agents"]["slash_b"]["position"] = [15, -10]
    data["checks"] = []
    code = main(["dry-run", str(_write(tmp_path, data)), "--until", "1", "--quiet"])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err and "compiled agent config" not in out + err
    assert code == 0, out + err


# --- the rule that keeps it so -----------------------------------------------------------


def _numbers(node: Any, where: str) -> Iterator[tuple[str, dict[str, Any]]]:
    """Every schema (with its place) that accepts a number or an integer."""
    if isinstance(node, dict):
        kinds = node.get("type")
        kinds = kinds if isinstance(kinds, list) else [kinds]
        if "number" in kinds or "integer" in kinds:
            yield where, node
        for key, value in node.items():
            yield from _numbers(value, f"{where}/{key}")
    elif isinstance(node, list):
        for i, value in enumerate(node):
            yield from _numbers(value, f"{where}/{i}")


@pytest.mark.parametrize("name", ["mission", "behavior", "hardware-profile"])
def test_every_number_of_the_language_has_a_range(name: str) -> None:
    """A number without both bounds lets 1e308 or 10**400 through to the arithmetic."""
    import json

    schema = json.loads(schema_text(name))
    unbounded = [
        where
        for where, node in _numbers(schema, "#")
        if not ({"minimum", "exclusiveMinimum"} & set(node))
        or not ({"maximum", "exclusiveMaximum"} & set(node))
    ]
    assert not unbounded, f"{len(unbounded)} numbers without a range: {unbounded[:10]}"
    assert name in SCHEMA_NAMES


def test_every_path_a_mission_names_has_a_length_limit() -> None:
    import json

    schema = json.loads(schema_text("mission"))
    props = schema["properties"]
    key_file = props["mission"]["properties"]["key_file"]
    folders = [
        props["include"]["properties"][k]["items"] for k in ("behaviors", "hardware_profiles")
    ]
    for path_schema in (key_file, *folders):
        assert path_schema.get("maxLength", 10**9) <= 1024


# --- fuzz: extremes through validate, compile and a short dry run -------------------------

EXTREMES: list[Any] = [
    0,
    -1,
    1,
    0.5,
    4294967295,
    2**31,
    -(2**63),
    10**20,
    HUGE,
    -HUGE,
    1.797e308,
    -1.797e308,
    5e-324,
    "nan",
    "inf",
    "-.inf",
    "x" * 6000,
    "a/" * 3000,
]


def _scalar_paths(node: Any, prefix: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    """Paths of every number or string in a mission (where a fuzzer puts an extreme)."""
    if isinstance(node, dict):
        return [p for k, v in node.items() for p in _scalar_paths(v, (*prefix, k))]
    if isinstance(node, list):
        return [p for i, v in enumerate(node) for p in _scalar_paths(v, (*prefix, i))]
    if isinstance(node, int | float | str) and not isinstance(node, bool):
        return [prefix]
    return []


@st.composite
def extreme_missions(draw: st.DrawFn) -> tuple[str, str]:
    """(example mission's name, its text with one to three values pushed to extremes)."""
    name = draw(st.sampled_from(sorted(DATA)))
    data = copy.deepcopy(DATA[name])
    paths = _scalar_paths(data)
    for _ in range(draw(st.integers(min_value=1, max_value=3))):
        path = draw(st.sampled_from(paths))
        parent: Any = data
        for part in path[:-1]:
            parent = parent[part]
        parent[path[-1]] = draw(st.sampled_from(EXTREMES))
    return name, yaml.safe_dump(data, sort_keys=False)


def run_extreme(text: str, until_s: float = 2.0) -> str:
    """Validate, compile and (when valid) dry-run a mission text; which stage it got to.

    Raises whatever the engine raises: the caller counts that as a crash.
    """
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "fuzz.yaml"
        path.write_text(text, encoding="utf-8")
        result = validate_file(path, "fuzz.yaml")
        for finding in result.findings:
            assert finding.message and finding.location.line is not None
        if result.mission is None:
            return "invalid"
        compile_mission(result.mission)
        outcome = run_dry_run(
            path,
            seed=0,
            until_s=until_s,
            report=None,
            speed=None,
            out=io.StringIO(),
            err=io.StringIO(),
            quiet=True,
        )
        assert outcome.exit_code in (0, 1), outcome.exit_code
        return "ran"


#: Examples per run in the suite; CLARK_FUZZ_EXAMPLES=2000 (or benchmarks/fuzz_validate.py
#: --dry-run) for a long one.
FUZZ_EXAMPLES = int(os.environ.get("CLARK_FUZZ_EXAMPLES", "12"))


@settings(
    max_examples=FUZZ_EXAMPLES,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow],
)
@given(extreme_missions())
def test_extreme_numbers_give_findings_not_crashes(case: tuple[str, str]) -> None:
    run_extreme(case[1])


def test_the_widest_position_the_schema_accepts_packs_into_mavlink() -> None:
    """The ranges are what keeps GLOBAL_POSITION_INT from overflowing: checked at their edges.

    An altitude of 4294967295 m once validated and then broke the dry run's
    ``global_position_int_encode`` ('i' format requires ... <= 2147483647). With the
    ranges, the highest point a mission can name (the origin 9 km above sea level, 10 km
    above it, 100 km from an origin at the pole and the antimeridian, and a follower's
    offset of as much again) still packs, in the sim's units (1e-7 degrees, millimetres).
    """
    from pymavlink.dialects.v20 import ardupilotmega as mavlink2

    from clark_engine.mission.geo import LocalPoint, Origin, to_global
    from clark_engine.mission.schema_source.common import (
        ALTITUDE_RANGE_M,
        ORIGIN_AMSL_RANGE_M,
        POSITION_LIMIT_M,
    )

    mav = mavlink2.MAVLink(None, srcSystem=1, srcComponent=1)
    for origin_lat, north_m in ((89.9, 2 * POSITION_LIMIT_M), (-89.9, -2 * POSITION_LIMIT_M)):
        origin = Origin(origin_lat, 180.0, ORIGIN_AMSL_RANGE_M[1])
        lat, lon, _up = to_global(LocalPoint(north_m, 2 * POSITION_LIMIT_M, 0.0), origin)
        for up_m in (2 * ALTITUDE_RANGE_M[0], 2 * ALTITUDE_RANGE_M[1]):
            amsl_m = ORIGIN_AMSL_RANGE_M[1] + up_m
            mav.global_position_int_encode(
                0,
                round(lat * 1e7),
                round(lon * 1e7),
                round(amsl_m * 1000),
                round(up_m * 1000),
                0,
                0,
                0,
                0,
            ).pack(mav)
