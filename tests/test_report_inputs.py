"""inputs.png names each channel by its function in the vehicle's profile, not rc1/rc2."""

from __future__ import annotations

import io
from pathlib import Path

from clark_engine.dryrun.command import run_dry_run
from clark_engine.dryrun.report_plots import channel_function, inputs_figure

ROOT = Path(__file__).resolve().parent.parent
SYSID = ROOT / "missions" / "supercub_sysid.yaml"


def test_inputs_are_labelled_by_channel_function() -> None:
    outcome = run_dry_run(
        SYSID, seed=None, until_s=40.0, report=None, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.result is not None
    recording, configs = outcome.result.recording, outcome.result.configs
    assert {key for key in recording.signals} == {("cub", "rc1"), ("cub", "rc2"), ("cub", "rc4")}
    figure = inputs_figure(recording, configs)
    assert figure is not None
    labels = [ax.get_ylabel() for ax in figure.axes]
    # The Super Cub's channels come from pixhawk_arduplane's map: RC1 aileron, RC2
    # elevator, RC4 rudder (hardware_profiles/autopilots/pixhawk_arduplane.yaml).
    assert labels == [
        "cub aileron\n(rc1, us)",
        "cub elevator\n(rc2, us)",
        "cub rudder\n(rc4, us)",
    ]


def test_channel_function_reads_the_compiled_channel_map() -> None:
    outcome = run_dry_run(
        SYSID, seed=None, until_s=1.0, report=None, speed=None,
        out=io.StringIO(), err=io.StringIO(),
    )  # fmt: skip
    assert outcome.result is not None
    cub = outcome.result.configs["cub"]
    assert channel_function(cub, "rc3") == "throttle"
    assert channel_function(cub, "servo2") == "elevator"
    assert channel_function(cub, "rc7") == "failsafe_mux"  # the platform's own channel
    assert channel_function(cub, "rc12") is None
    assert channel_function(None, "rc1") is None
