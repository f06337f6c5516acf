"""A compiled config is proved when it loads, not when a state is entered mid-mission.

A hand-edited or version-skewed config (an unknown primitive, a mistyped or unknown
parameter, tick phases that switch the timeouts off) must be refused by ``load_config``
with the file and the JSON path of what is wrong, and ``clark run`` must refuse to start
it (exit 1, a message, no traceback). Each case compiles an example mission into
``tmp_path`` and edits its JSON, as a person or another engine version would.
"""

from __future__ import annotations

import functools
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

from clark_engine.cli import main
from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.config import ConfigError, config_from_dict, load_config

ROOT = Path(__file__).resolve().parent.parent
COPTER = ROOT / "missions" / "copter_takeoff_land.yaml"
SYSID = ROOT / "missions" / "supercub_sysid.yaml"
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"


@functools.cache
def configs_of(mission: Path) -> dict[str, str]:
    """Every agent's compiled config text (what ``clark compile`` writes), compiled once."""
    result = validate_path(mission, mission.name)
    assert result.mission is not None, [f.format_text() for f in result.findings]
    return compile_mission(result.mission)


def compiled(tmp_path: Path, mission: Path, agent: str) -> Path:
    """The agent's config, as ``clark compile`` writes it, in a file of ``tmp_path``."""
    path = tmp_path / f"{agent}.json"
    path.write_text(configs_of(mission)[agent], encoding="utf-8")
    return path


def edit(path: Path, change: Callable[[dict[str, Any]], None]) -> Path:
    """Rewrite the config after ``change`` edited its JSON in place."""
    data = json.loads(path.read_text(encoding="utf-8"))
    change(data)
    path.write_text(json.dumps(data, indent=2), encoding="utf-8")
    return path


def state(data: dict[str, Any], name: str) -> dict[str, Any]:
    """The compiled state called ``name`` (depth first)."""
    pending = [data["machine"]]
    while pending:
        current = pending.pop()
        if current["name"] == name:
            return current
        pending.extend(current["states"])
    raise KeyError(name)


def index_of(data: dict[str, Any], name: str) -> int:
    """The position of a top-level state in the machine's ``states`` list."""
    return [s["name"] for s in data["machine"]["states"]].index(name)


def refused(path: Path) -> str:
    """The message ``load_config`` refuses ``path`` with; it names the file."""
    with pytest.raises(ConfigError) as caught:
        load_config(path)
    message = str(caught.value)
    assert message.startswith(f"{path}: "), message
    return message


def test_an_unknown_primitive_is_refused_at_load(tmp_path: Path) -> None:
    path = compiled(tmp_path, COPTER, "f450")
    edit(path, lambda d: state(d, "climb").update(primitive="teleport"))
    i = index_of(json.loads(path.read_text()), "climb")
    message = refused(path)
    assert f"machine.states.{i}.primitive" in message
    assert "'teleport'" in message and "climb" in message


def test_a_mistyped_parameter_is_refused_at_load(tmp_path: Path) -> None:
    path = compiled(tmp_path, COPTER, "f450")
    edit(path, lambda d: state(d, "climb")["params"].update(alt_m="ten"))
    i = index_of(json.loads(path.read_text()), "climb")
    message = refused(path)
    assert f"machine.states.{i}.params.alt_m: 'ten' is not of type 'number'" in message
    assert "climb" in message


def test_an_unknown_parameter_is_refused_at_load(tmp_path: Path) -> None:
    path = compiled(tmp_path, COPTER, "f450")
    edit(path, lambda d: state(d, "out")["params"].update(speed_ms=5))
    i = index_of(json.loads(path.read_text()), "out")
    message = refused(path)
    assert f"machine.states.{i}.params" in message and "'speed_ms'" in message


def test_a_missing_required_parameter_is_refused_at_load(tmp_path: Path) -> None:
    path = compiled(tmp_path, COPTER, "f450")
    edit(path, lambda d: state(d, "climb")["params"].pop("alt_m"))
    message = refused(path)
    assert "params" in message and "'alt_m' is a required property" in message


def test_a_point_not_resolved_by_the_compiler_is_refused_at_load(tmp_path: Path) -> None:
    """A compiled point has both frames; a mission's [north, east] is not one."""
    path = compiled(tmp_path, COPTER, "f450")
    edit(path, lambda d: state(d, "out")["params"].update(to=[30, 20]))
    i = index_of(json.loads(path.read_text()), "out")
    assert f"machine.states.{i}.params.to" in refused(path)


def test_a_channel_name_instead_of_its_resolved_map_is_refused_at_load(tmp_path: Path) -> None:
    path = compiled(tmp_path, SYSID, "cub")
    data = json.loads(path.read_text())
    doublets = []
    pending = [data["machine"]]
    while pending:
        current = pending.pop()
        if current["primitive"] == "doublet":
            doublets.append(current["name"])
        pending.extend(current["states"])
    edit(path, lambda d: state(d, doublets[0])["params"].update(channel="elevator"))
    assert ".params.channel" in refused(path)


def test_a_follow_target_that_is_not_a_peer_is_refused_at_load(tmp_path: Path) -> None:
    """The compiled config names the followed agent by id: it must be one of its peers."""
    path = compiled(tmp_path, FOLLOW, "slash_b")
    data = json.loads(path.read_text())
    following = [
        s for s in [data["machine"], *data["machine"]["states"]] if s["primitive"] == "follow_agent"
    ]
    assert following
    name = following[0]["name"]
    edit(path, lambda d: state(d, name)["params"]["target"].update(id=999))
    message = refused(path)
    assert ".params.target" in message and "999" in message


@pytest.mark.parametrize(
    ("phases", "expected"),
    [
        ([], "missing 'timeouts', 'machine', 'commands', 'telemetry', 'log'"),
        (["timeouts", "machine", "commands", "telemetry"], "missing 'log'"),
        (["timeouts", "machine", "commands", "telemetry", "log", "log"], "doubled 'log'"),
        (["timeouts", "machine", "machine", "telemetry", "log"], "missing 'commands'; doubled"),
        (["timeouts", "machine", "commands", "telemetry", "logs"], "unknown 'logs'"),
    ],
    ids=["empty", "missing", "doubled-extra", "doubled", "unknown"],
)
def test_tick_phases_must_hold_each_phase_once(
    tmp_path: Path, phases: list[str], expected: str
) -> None:
    path = compiled(tmp_path, COPTER, "f450")
    edit(path, lambda d: d["mission"].update(tick_phases=phases))
    message = refused(path)
    assert f"{path}: mission.tick_phases: the tick phases must be" in message
    assert expected in message


def test_a_condition_on_an_unknown_key_is_refused_at_load(tmp_path: Path) -> None:
    path = compiled(tmp_path, COPTER, "f450")

    def change(data: dict[str, Any]) -> None:
        state(data, "ready")["transitions"][0]["when"] = {"altitude": {"gt": 3}}

    edit(path, change)
    assert ".transitions.0.when" in refused(path)


def test_clark_run_refuses_a_config_that_does_not_load(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = compiled(tmp_path, COPTER, "f450")
    capsys.readouterr()
    edit(path, lambda d: state(d, "climb")["params"].update(alt_m="ten"))
    assert main(["run", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.startswith(f"clark run: error: {path}: machine.states."), err
    assert "'ten' is not of type 'number'" in err
    assert "Traceback" not in err


EXAMPLES = sorted((ROOT / "missions").glob("*.yaml")) + sorted(
    (ROOT / "tests" / "valid").glob("*.yaml")
)


@pytest.mark.parametrize("mission", EXAMPLES, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_every_example_config_loads(mission: Path) -> None:
    """Every compiled config of every example passes load, its primitives built."""
    configs = configs_of(mission)
    assert configs
    for agent, text in configs.items():
        assert config_from_dict(json.loads(text), source=f"{agent}.json").agent == agent


def test_conditions_are_resolved_once_and_decide_as_written(tmp_path: Path) -> None:
    """The runtime resolves each ``when`` when its machine is built; the figures decide."""
    from clark_engine.runtime.events import VehicleState
    from clark_engine.runtime.runtime import AgentRuntime

    runtime = AgentRuntime(load_config(compiled(tmp_path, FOLLOW, "slash_b")))
    ctx = runtime.context
    resolve = runtime._resolve_condition
    assert resolve({})(ctx, 0.0)
    assert not resolve({"altitude_m": {"gt": 5}})(ctx, 0.0)  # no vehicle state: unknown
    assert not resolve({"distance_m": {"to": "slash_a", "lt": 1e9}})(ctx, 0.0)  # no status
    ctx.vehicle = VehicleState(
        gps_time_ms=0,
        lat_deg=30.6,
        lon_deg=-96.4,
        alt_m=12.0,
        ground_speed_m_s=3.0,
        climb_rate_m_s=0.0,
        heading_deg=0.0,
        roll_deg=0.0,
        pitch_deg=0.0,
        yaw_deg=0.0,
        mode="GUIDED",
        custom_mode=15,
        armed=True,
    )
    cases: list[tuple[dict[str, Any], float, bool]] = [
        ({"altitude_m": {"gt": 5}}, 0.0, True),
        ({"altitude_m": {"gt": 5, "lt": 12}}, 0.0, False),
        ({"speed_m_s": {"lt": 3.5}}, 0.0, True),
        ({"in_state_s": {"gt": 10}}, 10.0, False),
        ({"in_state_s": {"gt": 10}}, 10.5, True),
        ({"mode": {"is": "GUIDED"}}, 0.0, True),
        ({"not": {"mode": {"is": "GUIDED"}}}, 0.0, False),
        ({"all": [{"mode": {"is": "GUIDED"}}, {"speed_m_s": {"gt": 4}}]}, 0.0, False),
        ({"any": [{"mode": {"is": "HOLD"}}, {"speed_m_s": {"gt": 2}}]}, 0.0, True),
    ]
    for when, in_state_s, holds in cases:
        assert resolve(when)(ctx, in_state_s) is holds, when


def test_a_runtime_refuses_tick_phases_a_config_was_given_in_code() -> None:
    """The runtime's own guard: a config built with replace() never passed load_config."""
    import dataclasses

    from clark_engine.mission.compiler import agent_config
    from clark_engine.mission.validate import validate_path
    from clark_engine.runtime.config import config_from_dict
    from clark_engine.runtime.runtime import AgentRuntime

    result = validate_path(COPTER, COPTER.name)
    assert result.mission is not None
    config = config_from_dict(agent_config(result.mission, result.mission.agents["f450"]))
    for phases in [(), ("timeouts", "machine", "commands", "telemetry", "telemetry")]:
        with pytest.raises(ConfigError, match=r"mission\.tick_phases: the tick phases must be"):
            AgentRuntime(dataclasses.replace(config, tick_phases=phases))
    reordered = ("telemetry", "log", "timeouts", "machine", "commands")
    assert AgentRuntime(dataclasses.replace(config, tick_phases=reordered)).tick(0.0) is not None
