"""A behaviour is one module: one registry, typed parameters, traits instead of name switches.

Issue 20 item 1. The declarations are the single source of each behaviour's schema,
defaults, compiled form and runtime parameters; nothing outside a behaviour's own module
switches on its name; ``clark validate`` imports every declaration and no runtime code.
"""

from __future__ import annotations

import dataclasses
import re
import subprocess
import sys
from pathlib import Path

import pytest

from clark_engine.behaviors import behaviors, built_in, make_behavior
from clark_engine.behaviors.base import BehaviorRuntime, ChannelMap, Point
from clark_engine.behaviors.waypoint import WaypointParams
from clark_engine.runtime.config import ConfigError, StateSpec

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "clark_engine"
NAMES = list(built_in())

# A switch on a behaviour's name: `state.primitive == "x"`, `primitive in (...)`, a set of
# behaviour names. Allowed only in a behaviour's own module.
_SWITCH = re.compile(
    r"primitive\s*(==|!=|in|not in)\s*[\"'(\[{A-Z_]"
    r"|\{\s*\"(" + "|".join(NAMES) + r")\"\s*,"
)


def test_the_built_in_behaviors_in_reference_order() -> None:
    assert NAMES == [
        "waypoint",
        "waypoint_tour",
        "follow_agent",
        "orbit",
        "doublet",
        "sine_sweep",
        "photo_trigger",
        "survey",
        "hold",
        "set_mode",
        "wait",
        "terminate",
        "takeoff",
        "land",
        "return_home",
    ]
    for name, behavior in behaviors().items():
        assert behavior.name == name
        assert behavior.origin == "built-in"
        assert behavior.runtime.name == name


def test_no_module_outside_the_behaviors_switches_on_a_behavior_name() -> None:
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.parent.name == "behaviors" or "_generated" in path.parts:
            continue
        for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
            if _SWITCH.search(line):
                found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "ask the behaviour's traits or declaration instead:\n" + "\n".join(found)


def test_no_runtime_default_is_restated() -> None:
    # The runtime, the dry run and the station read typed fields, never a default again.
    pattern = re.compile(r"params\.get\(\s*\"\w+\"\s*,")
    found = []
    for folder in ("runtime", "sim", "gcs", "shells"):
        for path in sorted((PACKAGE / folder).rglob("*.py")):
            for number, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1):
                if pattern.search(line) and "SIM_" not in line and "RC{" not in line:
                    found.append(f"{path.relative_to(ROOT)}:{number}: {line.strip()}")
    assert not found, "\n".join(found)


def test_one_dataclass_gives_schema_defaults_and_the_typed_parameters() -> None:
    schema = WaypointParams.schema()
    assert list(schema["properties"]) == ["to", "tolerance_m", "speed_m_s"]
    assert schema["required"] == ["to"]
    tolerance = schema["properties"]["tolerance_m"]["default"]
    assert WaypointParams.with_defaults({"to": {"north_m": 1}}) == {
        "to": {"north_m": 1},
        "tolerance_m": tolerance,
    }
    config = WaypointParams.config_schema()["properties"]["to"]
    assert "lat" in config["properties"]  # the compiled form: both frames
    point = {"north_m": 1, "east_m": 2, "up_m": 3, "lat": 4, "lon": 5, "alt_m": 3}
    typed = WaypointParams.from_config({"to": point})
    assert typed.to == Point(1.0, 2.0, 3.0, 4.0, 5.0, 3.0)
    assert typed.tolerance_m == tolerance
    assert typed.speed_m_s is None
    with pytest.raises(dataclasses.FrozenInstanceError):
        typed.tolerance_m = 1.0  # type: ignore[misc]


def test_every_behavior_builds_its_runtime_class_from_typed_parameters() -> None:
    channel = {
        "name": "elevator",
        "rc": 2,
        "servo": None,
        "pwm_min_us": 1000,
        "pwm_trim_us": 1500,
        "pwm_max_us": 2000,
    }
    spec = StateSpec(
        name="s",
        path="s",
        kind="primitive",
        primitive="doublet",
        params={"channel": channel, "amplitude_us": 100, "width_s": 1},
        block=None,
        initial=None,
        parallel=False,
        finish="all",
        final=False,
        timeout_s=None,
        transitions=(),
        source="x.json",
        states=(),
    )
    built = make_behavior(spec)
    assert isinstance(built, BehaviorRuntime)
    assert built.params.channel == ChannelMap("elevator", 2, None, 1000, 1500, 2000)
    assert built.params.via == "rc_override"  # the declared default, typed
    unknown = dataclasses.replace(spec, primitive="spiral")
    with pytest.raises(ConfigError, match="does not have"):
        make_behavior(unknown)


def test_traits_replace_the_name_lists() -> None:
    traits = {name: b.traits for name, b in behaviors().items()}
    assert {n for n, t in traits.items() if t.guided} == {
        "waypoint",
        "waypoint_tour",
        "follow_agent",
        "survey",
        "orbit",
    }
    assert {n for n, t in traits.items() if t.floor_exempt} == {"takeoff", "land", "return_home"}
    assert {n for n, t in traits.items() if t.lands} == {"land", "return_home", "terminate"}
    assert {n for n, t in traits.items() if t.takes_off} == {"takeoff"}
    assert {n for n, t in traits.items() if t.takes_pictures} == {"photo_trigger", "survey"}
    assert {n for n, t in traits.items() if t.drives_channel} == {"doublet", "sine_sweep"}
    assert {n for n, t in traits.items() if t.flies} == {
        "waypoint",
        "waypoint_tour",
        "follow_agent",
        "survey",
        "orbit",
        "takeoff",
        "doublet",
        "sine_sweep",
    }


def test_validate_imports_every_declaration_and_no_runtime_code() -> None:
    example = ROOT / "missions" / "supercub_sysid.yaml"
    code = (
        "import sys\n"
        "from clark_engine.cli import main\n"
        f"rc = main(['validate', {str(example)!r}])\n"
        "runtime = sorted(m for m in sys.modules if m.startswith('clark_engine.runtime.')"
        " and m not in ('clark_engine.runtime.config',))\n"
        "declared = sorted(m for m in sys.modules if m.startswith('clark_engine.behaviors.'))\n"
        "print('RUNTIME', runtime)\n"
        "print('DECLARED', len(declared))\n"
        "sys.exit(rc)\n"
    )
    proc = subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "RUNTIME []" in proc.stdout, proc.stdout
    assert "DECLARED 0" not in proc.stdout
