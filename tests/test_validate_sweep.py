"""A sweep at the Nyquist rate (issue 10, item 9).

A 5 Hz sine sampled at 10 Hz is sampled at its zero crossings: the dry run commanded a flat
1500 us, validation raised only W-SWEEP-SAMPLES and the ``signal`` check passed with
"largest error 0 us", because it compared the output with the waveform's own samples.
Reaching loop_hz / 2 is now an error, and the check compares with the intended waveform.
"""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any, cast

import pytest

from clark_engine.expectations.evaluate import evaluate, expected_signal, sweep_fidelity
from clark_engine.expectations.recording import Recording, StateEntry
from clark_engine.mission.geo import Origin
from clark_engine.runtime.config import AgentConfig, StateSpec
from clark_engine.validation import validate_file

MISSION = """\
clark: 1
mission: {{id: 1, name: demo, loop_hz: 10, origin: {{lat: 30.6372, lon: -96.4787, alt_amsl_m: 0}}}}
agents:
  cub:
    id: 2
    profile: super_cub
    telemetry: {{heartbeat: 1}}
    behavior: {{use: elevator_sweep, with: {{f_start_hz: {f}, f_stop_hz: {f}}}}}
"""

CHANNEL = {
    "name": "elevator",
    "rc": 2,
    "servo": None,
    "pwm_min_us": 1000,
    "pwm_trim_us": 1500,
    "pwm_max_us": 2000,
}


@pytest.mark.parametrize(
    ("f_hz", "codes"), [("5", ["E-SWEEP-NYQUIST"]), ("4", ["W-SWEEP-SAMPLES"])]
)
def test_sweep_reaching_nyquist_is_an_error(f_hz: str, codes: list[str], tmp_path: Path) -> None:
    path = tmp_path / "m.yaml"
    path.write_text(MISSION.format(f=f_hz), encoding="utf-8")
    found = [f for f in validate_file(path, "m.yaml").findings if f.code.startswith(("E-", "W-SW"))]
    assert [f.code for f in found] == codes
    if codes == ["E-SWEEP-NYQUIST"]:
        assert "at the Nyquist limit 5 Hz" in found[0].message


def _sweep(f_start: float, f_stop: float, duration_s: float = 4.0) -> StateSpec:
    params: dict[str, Any] = {
        "channel": CHANNEL,
        "amplitude_us": 200,
        "f_start_hz": f_start,
        "f_stop_hz": f_stop,
        "duration_s": duration_s,
    }
    return StateSpec(
        name="sweep",
        path="sweep",
        kind="primitive",
        primitive="sine_sweep",
        params=params,
        block=None,
        initial=None,
        parallel=False,
        finish="all",
        final=False,
        timeout_s=None,
        transitions=(),
        source="",
        states=(),
    )


def test_flat_output_keeps_none_of_the_waveform() -> None:
    state = _sweep(5, 5)
    flat = expected_signal(state, 10)
    assert set(flat) == {1500}  # the sampled "waveform" is flat
    share, _ = sweep_fidelity(state, 10, flat)
    assert share < 0.01


@pytest.mark.parametrize(("f_start", "f_stop"), [(0.2, 2.0), (1.0, 1.0), (0.5, 3.3)])
def test_well_sampled_sweep_keeps_its_waveform(f_start: float, f_stop: float) -> None:
    state = _sweep(f_start, f_stop, 10.0)
    share, _ = sweep_fidelity(state, 10, expected_signal(state, 10))
    assert share > 0.8


def _run(state: StateSpec, signal: list[int]) -> str:
    rec = Recording(end_s=10.0)
    rec.states["cub"] = [
        StateEntry(0.0, "start", ("sweep",), ("sweep",)),
        StateEntry(len(signal) / 10, "done", (), ()),
    ]
    rec.signals[("cub", "rc2")] = [(k / 10, pwm) for k, pwm in enumerate(signal)]
    config = cast(AgentConfig, SimpleNamespace(machine=state, loop_hz=10.0))
    check = {"name": "sweep", "signal": {"agent": "cub", "state": "sweep"}}
    (result,) = evaluate([check], rec, {"cub": config}, Origin(30.0, -96.0))
    return ("pass " if result.passed else "FAIL ") + result.observed


def test_signal_check_fails_a_flat_sweep() -> None:
    state = _sweep(5, 5)
    verdict = _run(state, expected_signal(state, 10))
    assert verdict.startswith("FAIL"), verdict
    assert "largest error 0 us" in verdict and "0% of the intended waveform" in verdict


def test_signal_check_passes_a_good_sweep() -> None:
    state = _sweep(0.2, 2.0)
    verdict = _run(state, expected_signal(state, 10))
    assert verdict.startswith("pass"), verdict
