"""Varied values: distributions in a mission, one draw per run, ``--vary`` to fix them."""

from __future__ import annotations

import io
import re
from pathlib import Path

import pytest

from clark_engine.cli import main
from clark_engine.dryrun.command import run_dry_run
from clark_engine.errors import UsageError
from clark_engine.mission.variation import (
    NORMAL_TAIL_SD,
    VaryError,
    draw_run,
    mission_varied_fields,
    parse_vary,
    resolve_mission,
    sim_schema,
)
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parents[1]
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"

VARIED_SIM = (
    "sim: {duration_s: 170, seed: 1, radio_loss: {uniform: [0, 0.2]}, "
    "gps_noise_m: {normal: {mean: 1, sd: 0.5}}}\n"
    "faults:\n"
    "  - link_drop: {between: [slash_a, slash_b], from_s: {uniform: [10, 20]}, "
    "to_s: {choice: [30, 40]}, chance: 0.5}\n"
)


def _mission(tmp_path: Path, sim_text: str = VARIED_SIM) -> Path:
    """cooperative_follow with its ``sim:`` mapping (one line or a block) replaced by
    ``sim_text`` (its includes resolve beside it)."""
    text = FOLLOW.read_text()
    block = re.search(r"^sim:.*\n(?:[ \t]+.*\n)*", text, flags=re.M)
    assert block is not None, "the example has a sim: mapping"
    path = FOLLOW.parent / f"_test_variation_{tmp_path.name}.yaml"
    path.write_text(text[: block.start()] + sim_text + text[block.end() :])
    return path


@pytest.fixture
def varied(tmp_path: Path) -> object:
    path = _mission(tmp_path)
    yield path
    path.unlink()


def test_draws_are_seeded_per_value_and_do_not_shift_when_one_is_added() -> None:
    schema = sim_schema()
    one = {"radio_loss": {"uniform": [0, 0.2]}}
    two = {"radio_latency_s": {"uniform": [0, 1]}, "radio_loss": {"uniform": [0, 0.2]}}
    _, _, _, first = draw_run(schema, one, [], seed=7)
    _, _, _, again = draw_run(schema, one, [], seed=7)
    _, _, _, both = draw_run(schema, two, [], seed=7)
    _, _, _, other = draw_run(schema, one, [], seed=8)
    assert first == again
    assert both["sim.radio_loss"] == first["sim.radio_loss"]
    assert other["sim.radio_loss"] != first["sim.radio_loss"]
    assert 0 <= first["sim.radio_loss"] <= 0.2


def test_normal_draws_stay_in_the_tail_bound_and_the_field_range() -> None:
    schema = sim_schema()
    sim = {"radio_loss": {"normal": {"mean": 0.05, "sd": 0.2}}}
    values = [draw_run(schema, sim, [], seed=s)[3]["sim.radio_loss"] for s in range(300)]
    assert all(0.0 <= v <= 0.05 + NORMAL_TAIL_SD * 0.2 for v in values)
    assert min(values) == 0.0  # a normal around 0.05 with sd 0.2 is clipped at the share's 0
    assert max(values) <= 1.0


def test_a_chance_injects_the_fault_in_about_that_share_of_runs() -> None:
    faults = [{"kill": {"agent": "a", "at_s": {"uniform": [10, 20]}, "chance": 0.3}}]
    injected = 0
    for seed in range(400):
        _, kept, resolved, drawn = draw_run(sim_schema(), {}, faults, seed)
        assert drawn["faults.0.kill.injected"] is bool(kept)
        if kept:
            injected += 1
            assert "chance" not in resolved[0]["kill"]
            assert 10 <= resolved[0]["kill"]["at_s"] <= 20
    assert 0.22 < injected / 400 < 0.38  # 400 fixed seeds: a fixed count, not a flaky one


def test_a_mission_without_variation_is_flown_as_it_is() -> None:
    plain = ROOT / "missions" / "single_vehicle_mode_change.yaml"
    mission = validate_file(plain, str(plain)).mission
    assert mission is not None
    same, drawn = resolve_mission(mission, seed=5)
    assert same is mission and drawn == {}


def test_vary_fixes_values_and_refuses_what_the_mission_does_not_vary(varied: Path) -> None:
    mission = validate_file(varied, str(varied)).mission
    assert mission is not None
    fields = mission_varied_fields(mission)
    fixed = parse_vary(
        ["sim.radio_loss=0.05", "faults.0.link_drop.injected=true", "sim.radio_latency_s=0.01"],
        fields,
    )
    resolved, drawn = resolve_mission(mission, 3, fixed)
    assert resolved.sim["radio_loss"] == 0.05 and resolved.sim["radio_latency_s"] == 0.01
    assert drawn["faults.0.link_drop.injected"] is True and len(resolved.faults) == 1
    with pytest.raises(VaryError, match=r"no such value to vary; it has: sim\.radio_loss"):
        parse_vary(["sim.wind_mps=3"], fields)
    with pytest.raises(VaryError, match=r"outside 0\.\.1"):
        parse_vary(["sim.radio_loss=1.5"], fields)
    with pytest.raises(VaryError, match="true or false"):
        parse_vary(["faults.0.link_drop.injected=maybe"], fields)
    with pytest.raises(VaryError, match="PATH=VALUE"):
        parse_vary(["sim.radio_loss"], fields)


def test_validate_names_a_backwards_uniform_and_a_window_a_draw_could_reverse(
    tmp_path: Path,
) -> None:
    text = VARIED_SIM.replace("[0, 0.2]", "[0.2, 0]").replace("[30, 40]", "[15, 40]")
    path = _mission(tmp_path, text)
    try:
        validation = validate_file(path, str(path))
    finally:
        path.unlink()
    errors = {(f.code, f.message) for f in validation.findings if f.is_error}
    assert (
        "E-VALUE",
        "{uniform: [0.2, 0]} runs backwards; write the lower end first: [0, 0.2]",
    ) in errors
    assert any(
        code == "E-FAULT-WINDOW" and "from_s can be as late as 20 s and to_s as early as 15 s" in m
        for code, m in errors
    )


def test_a_dry_run_reports_its_draw_and_vary_reproduces_it(varied: Path) -> None:
    err = io.StringIO()
    first = run_dry_run(
        varied, seed=3, until_s=60.0, report=None, speed=None, out=io.StringIO(), err=err
    )
    assert set(first.drawn) == {
        "sim.radio_loss",
        "sim.gps_noise_m",
        "faults.0.link_drop.from_s",
        "faults.0.link_drop.to_s",
        "faults.0.link_drop.injected",
    }
    assert "drawn for seed 3: sim.radio_loss=" in err.getvalue()
    assert first.result is not None
    texts = [f"{path}={str(v).lower()}" for path, v in first.drawn.items()]
    # Another seed, every value fixed to the first run's draw: the same world. (The seed
    # still draws the tick phases and the radio's dice, so compare what was drawn.)
    fixed = run_dry_run(
        varied,
        seed=3,
        until_s=60.0,
        report=None,
        speed=None,
        out=io.StringIO(),
        err=io.StringIO(),
        vary=texts,
    )
    assert fixed.drawn == first.drawn
    assert [r.observed for r in fixed.results] == [r.observed for r in first.results]


def test_the_report_lists_the_draw(varied: Path, tmp_path: Path) -> None:
    run_dry_run(
        varied,
        seed=4,
        until_s=20.0,
        report=tmp_path / "out",
        speed=None,
        out=io.StringIO(),
        err=io.StringIO(),
    )
    summary = (tmp_path / "out" / "summary.md").read_text()
    assert "## Drawn values" in summary and "| `sim.radio_loss` |" in summary


def test_cli_vary_errors_are_usage_errors(varied: Path, capsys: pytest.CaptureFixture[str]) -> None:
    code = main(["dry-run", str(varied), "--until", "1", "--vary", "sim.nothing=1"])
    assert code == 2
    assert "--vary 'sim.nothing': the mission has no such value" in capsys.readouterr().err
    with pytest.raises(UsageError):
        run_dry_run(varied, seed=1, until_s=1.0, report=None, speed=None, vary=["sim.radio_loss=x"])
