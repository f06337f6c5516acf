"""One error must not hide others, nor bring false findings with it (issue 10, item 11).

A transition to ``Home`` (a capitalised state name) used to stop the behaviour's checks at
a bare E-FORMAT: the bad ``initial:`` and the unknown ``use:`` beside it went unreported,
and a dry-run check on the agent said it "has no behaviour". A parameter out of range in a
block (``doublet_width_s: 500``) left the block's states empty, so they "never finish"
(W-DONE-NEVER) and "run no primitive" (E-CHECK-SHAPE). Findings after an error must be
true: later stages skip only what the error makes unknowable.
"""

from __future__ import annotations

from pathlib import Path

from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parents[1]

HOME = """\
clark: 1
mission: {id: 1, name: demo, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 0}}
agents:
  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}
  slash:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1}
    behavior:
      initial: strat
      states:
        start:
          use: waypoint
          with: {to: [10, 0]}
          transitions: {done: Home}
        home:
          use: waypoint
          with: {to: [0, 0]}
          transitions: {done: finished}
        bad:
          use: nosuch
        finished: {final: true}
checks:
  - {name: home, by_s: 60, state: {agent: slash, reached: home}}
"""


def _findings(tmp_path: Path, text: str) -> list[tuple[str, int | None, str]]:
    path = tmp_path / "m.yaml"
    path.write_text(text, encoding="utf-8")
    result = validate_file(path, "m.yaml")
    return [(f.code, f.location.line, f.message) for f in result.findings if f.code != "W-NO-KEY"]


def test_capitalised_target_is_named_and_hides_nothing(tmp_path: Path) -> None:
    found = _findings(tmp_path, HOME)
    assert [(code, line) for code, line, _ in found] == [
        ("E-STATE-UNKNOWN", 10),  # initial: strat
        ("E-STATE-UNKNOWN", 15),  # done: Home
        ("E-BLOCK-UNKNOWN", 21),  # use: nosuch
    ]
    assert "did you mean 'home'?" in found[1][2]
    assert "did you mean 'start'?" in found[0][2]
    assert not any("has no behaviour" in message for _, _, message in found)


def test_a_behavior_too_broken_to_resolve_is_not_said_to_be_missing(tmp_path: Path) -> None:
    broken = HOME.replace("transitions: {done: Home}", "transitions: [done, home]")
    found = _findings(tmp_path, broken)
    assert any(code == "E-TYPE" for code, _, _ in found)
    assert not any("has no behaviour" in message for _, _, message in found)


def test_block_parameter_error_adds_no_false_findings(tmp_path: Path) -> None:
    text = (ROOT / "missions" / "supercub_sysid.yaml").read_text(encoding="utf-8")
    assert "doublet_width_s: 0.5" in text
    found = _findings(tmp_path, text.replace("doublet_width_s: 0.5", "doublet_width_s: 500"))
    assert [code for code, _, _ in found] == ["E-RANGE"], found


def test_unknown_use_state_is_not_said_to_never_finish(tmp_path: Path) -> None:
    text = HOME.replace("initial: strat", "initial: start").replace("done: Home", "done: bad")
    text = text.replace("use: nosuch", "use: nosuch\n          transitions: {done: home}")
    found = _findings(tmp_path, text)
    assert [code for code, _, _ in found] == ["E-BLOCK-UNKNOWN"], found
