"""Faults: one grammar for ``--fault`` and the mission's ``faults:``, checked by one set of rules.

Issue 10, item 8: faults that broke a rule (a share of 1.5, a link from an agent to itself)
crashed the dry run with a traceback, and a mission's own bad fault passed ``clark
validate``. The grammar is fuzzed: whatever the text, the parser answers with a fault that
keeps every rule and fits the mission schema, or with a :class:`FaultError`.
"""

from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clark_engine.cli import main
from clark_engine.dryrun.command import parse_fault
from clark_engine.errors import UsageError
from clark_engine.mission.faults import (
    FAULT_KINDS,
    FaultError,
    fault_problems,
    parse_fault_text,
)
from clark_engine.mission.schemas import validator
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parents[1]
FOLLOW = ROOT / "missions" / "cooperative_follow.yaml"
FAULT_SCHEMA = {
    "$schema": "https://json-schema.org/draft/2020-12/schema",
    "$ref": "#/$defs/fault",
    "$defs": validator("mission").schema["$defs"],
}

MISSION = """\
clark: 1
mission: {{id: 1, name: demo, loop_hz: 10, origin: {{lat: 30.6372, lon: -96.4787, alt_amsl_m: 0}}}}
agents:
  mcs: {{id: 1, profile: mcs_laptop, telemetry: {{heartbeat: 1}}}}
  slash: {{id: 2, profile: traxxas_slash, telemetry: {{heartbeat: 1, agent_status: {rate}}}}}
faults:
  - {fault}
"""


def _mission(
    tmp_path: Path, fault: str = "{kill: {agent: slash, at_s: 3}}", rate: str = "1"
) -> Path:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION.format(fault=fault, rate=rate), encoding="utf-8")
    return path


@pytest.mark.parametrize(
    ("text", "says"),
    [
        ("corrupt:1.5@0-4", "from 0 to 1"),
        ("corrupt:-0.5@0-4", "from 0 to 1"),
        ("link_drop:mcs,mcs@1-2", "'mcs' twice"),
        ("station_silent@30-10", "reversed window"),
        ("kill:slash_a@1..2", "is not a fault"),
        ("corrupt:nan@0-4", "is not a fault"),
        ("kill:slash_a@" + "9" * 400, "is not a fault"),
        ("kil:slash_a@3", "did you mean kill"),
    ],
)
def test_bad_cli_fault_exits_2_with_a_message(
    text: str, says: str, capsys: pytest.CaptureFixture[str]
) -> None:
    """Each of these was a traceback (or "not a fault" for a reversed window)."""
    code = main(["dry-run", str(FOLLOW), "--until", "1", "--fault", text])
    err = capsys.readouterr().err
    assert code == 2
    assert says in err
    assert "Traceback" not in err


def test_reversed_window_is_named_not_called_garbled() -> None:
    with pytest.raises(UsageError, match="reversed window") as caught:
        parse_fault("station_silent@30-10")
    assert "is not a fault" not in caught.value.message


def test_mission_fault_linking_an_agent_to_itself_is_a_finding(tmp_path: Path) -> None:
    """It passed validate, then crashed the dry run."""
    path = _mission(tmp_path, "{link_drop: {between: [slash, slash], from_s: 1, to_s: 2}}")
    result = validate_file(path, "m.yaml")
    assert [f.code for f in result.errors] == ["E-FAULT-LINK"]
    assert result.errors[0].location.line == 7
    assert main(["validate", str(path)]) == 1


def test_mission_fault_is_refused_before_the_dry_run(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _mission(tmp_path, "{link_drop: {between: [slash, slash], from_s: 1, to_s: 2}}")
    assert main(["dry-run", str(path), "--until", "3"]) == 1
    assert "E-FAULT-LINK" in capsys.readouterr().err


@pytest.mark.parametrize("rate", ["1e-320", "1e-300", "4e-324"])
def test_vanishing_telemetry_rate_is_a_finding(rate: str, tmp_path: Path) -> None:
    """1e-320 Hz overflowed the divider (OverflowError in mission/agent_checks.py)."""
    result = validate_file(_mission(tmp_path, rate=rate), "m.yaml")
    assert [f.code for f in result.errors] == ["E-RATE"]
    assert "once a day" in result.errors[0].message


def test_mission_and_cli_share_the_rules() -> None:
    for text in ("corrupt:1.5@0-4", "link_drop:a,a@1-2", "station_silent@3-1"):
        with pytest.raises(FaultError):
            parse_fault_text(text)
    assert [p.code for p in fault_problems({"corrupt": {"share": 1.5}})] == ["E-VALUE"]
    assert [p.code for p in fault_problems({"link_drop": {"between": ["a", "a"]}})] == [
        "E-FAULT-LINK"
    ]
    assert [p.code for p in fault_problems({"station_silent": {"from_s": 3, "to_s": 1}})] == [
        "E-FAULT-WINDOW"
    ]


def test_corrupt_without_a_window_lasts_the_whole_run() -> None:
    """As in a mission, where corrupt's window is optional."""
    assert parse_fault_text("corrupt:0.2") == {"corrupt": {"share": 0.2}}


# -- fuzzing ------------------------------------------------------------------------------

_NAMES = st.from_regex(r"\A[a-z][a-z0-9_]{0,8}\Z")
_TIMES = st.floats(min_value=0, max_value=1e6, allow_nan=False).map(lambda t: f"{t:.3f}")
_PIECES = st.sampled_from(
    [*FAULT_KINDS, ":", "@", "-", ",", ".", "e", "nan", "inf", "1", "0.5", "-1", " ", "x"]
)


@st.composite
def fault_texts(draw: st.DrawFn) -> str:
    """Text near the grammar: well-formed faults, and pieces of them shuffled together."""
    if draw(st.booleans()):
        return "".join(draw(st.lists(_PIECES | _NAMES | _TIMES, max_size=8)))
    kind = draw(st.sampled_from(FAULT_KINDS))
    window = f"@{draw(_TIMES)}-{draw(_TIMES)}"
    if kind == "kill":
        return f"kill:{draw(_NAMES)}@{draw(_TIMES)}"
    if kind == "link_drop":
        return f"link_drop:{draw(_NAMES)},{draw(_NAMES)}{window}"
    if kind == "station_silent":
        return f"station_silent{window}"
    if kind == "autopilot_disconnect":
        return f"autopilot_disconnect:{draw(_NAMES)}{window}"
    share = draw(st.floats(allow_nan=True, allow_infinity=True))
    return f"corrupt:{share}{window if draw(st.booleans()) else ''}"


def _assert_sound(fault: dict[str, object]) -> None:
    from jsonschema import Draft202012Validator

    assert not list(Draft202012Validator(FAULT_SCHEMA).iter_errors(fault))
    assert fault_problems(fault) == []
    ((_, body),) = fault.items()
    assert isinstance(body, dict)
    for key in ("at_s", "from_s", "to_s", "share"):
        if key in body:
            assert math.isfinite(body[key])


@settings(max_examples=300, deadline=None)
@given(fault_texts() | st.text(max_size=40))
def test_fault_grammar_answers_a_sound_fault_or_a_fault_error(text: str) -> None:
    try:
        fault = parse_fault_text(text)
    except FaultError as exc:
        assert exc.message
        return
    _assert_sound(fault)


@settings(max_examples=100, deadline=None)
@given(
    _NAMES,
    st.floats(min_value=0, max_value=1e5, allow_nan=False),
    st.floats(min_value=0, max_value=1e5, allow_nan=False),
)
def test_well_formed_faults_parse_unless_reversed(name: str, a: float, b: float) -> None:
    text = f"autopilot_disconnect:{name}@{a!r}-{b!r}".replace("e+", "e")
    if "e" in f"{a!r}{b!r}":
        return  # exponents are not part of the grammar
    if b <= a:
        with pytest.raises(FaultError, match="reversed window"):
            parse_fault_text(text)
    else:
        assert parse_fault_text(text) == {
            "autopilot_disconnect": {"agent": name, "from_s": a, "to_s": b}
        }


def test_invalid_corpus_cases_exist() -> None:
    """The corpus carries item 8's mission cases (tests/test_corpus.py runs them)."""
    for name in ("fault_link_to_itself.yaml", "telemetry_rate_vanishing.yaml"):
        assert (ROOT / "tests" / "invalid" / name).is_file()


def test_mission_text_helper_is_valid(tmp_path: Path) -> None:
    assert validate_file(_mission(tmp_path), "m.yaml").ok, textwrap.dedent(MISSION)
