"""Conditions on other agents and block parameters inside ``when:`` (issue 20 item 8).

Checked by ``clark validate`` (each check on bad input, with its code and line), compiled
as written with the parameters put in, and decided at flight time on fresh peer data only.
"""

from __future__ import annotations

import json
from pathlib import Path
from textwrap import dedent

from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.validate import Validation, validate_path

HEAD = """\
clark: 1
mission: {id: 700, name: cond, loop_hz: 10, heartbeat_timeout_s: 3,
          origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
"""


def _validate(tmp_path: Path, text: str, blocks: dict[str, str] | None = None) -> Validation:
    """Validate a mission written to ``tmp_path`` (with block files beside it)."""
    if blocks:
        folder = tmp_path / "blocks"
        folder.mkdir()
        for name, body in blocks.items():
            (folder / f"{name}.yaml").write_text(dedent(body), encoding="utf-8")
    path = tmp_path / "m.yaml"
    path.write_text(HEAD + dedent(text), encoding="utf-8")
    return validate_path(path, "m.yaml")


def _codes(result: Validation) -> list[tuple[str, int | None]]:
    return [(f.code, f.location.line) for f in result.findings]


def _config(result: Validation, agent: str) -> dict[str, object]:
    assert result.mission is not None, [f.format_text() for f in result.findings]
    return json.loads(compile_mission(result.mission, [agent])[agent])  # type: ignore[no-any-return]


# -- block parameters inside when: ----------------------------------------------------------

WAIT_BLOCK = """\
    block: wait_then_go
    description: Hold until a while has passed, then drive to a point.
    parameters:
      type: object
      required: [point]
      properties:
        wait_s: {type: number, description: How long to hold., default: 5}
        point: {type: array, description: Where to go.}
        gap: {description: Anything at all (its type is checked where it is used).}
    machine:
      initial: wait
      states:
        wait:
          use: hold
          transitions:
            activate: {to: go, when: {in_state_s: {gt: $wait_s}}}
        go: {use: waypoint, with: {to: $point}}
"""

ONE_ROVER = """\
include: {behaviors: [blocks]}
agents:
  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}
  rover:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1}
    behavior: {use: wait_then_go, with: WITH}
"""


def test_a_block_parameter_inside_when_is_put_in_at_compile_time(tmp_path: Path) -> None:
    """Before: the block file's schema refused ``gt: $wait_s`` (E-TYPE in the block)."""
    result = _validate(
        tmp_path,
        ONE_ROVER.replace("WITH", "{point: [20, 0], wait_s: 7}"),
        {"wait_then_go": WAIT_BLOCK},
    )
    assert not result.findings, [f.format_text() for f in result.findings]
    config = _config(result, "rover")
    wait = config["machine"]["states"][0]  # type: ignore[index]
    assert wait["transitions"][0]["when"] == {"in_state_s": {"gt": 7}}


def test_a_block_parameter_inside_when_takes_its_default(tmp_path: Path) -> None:
    result = _validate(
        tmp_path, ONE_ROVER.replace("WITH", "{point: [20, 0]}"), {"wait_then_go": WAIT_BLOCK}
    )
    wait = _config(result, "rover")["machine"]["states"][0]  # type: ignore[index]
    assert wait["transitions"][0]["when"] == {"in_state_s": {"gt": 5}}


def test_a_substituted_value_of_the_wrong_type_is_refused_where_it_was_given(
    tmp_path: Path,
) -> None:
    block = WAIT_BLOCK.replace("{gt: $wait_s}", "{gt: $gap}")
    result = _validate(
        tmp_path,
        ONE_ROVER.replace("WITH", "{point: [20, 0], gap: soon}"),
        {"wait_then_go": block},
    )
    assert result.mission is None
    finding = next(f for f in result.findings if f.code == "E-BLOCK-WHEN")
    assert finding.location.file == "m.yaml"
    assert finding.location.line == 11  # the mission's with:, where "soon" was written
    assert "after the block's parameters are put in" in finding.message
    assert "'soon'" in finding.message
    assert [r.line for r in finding.related] == [11]  # the use: of the block
