"""Behaviour plugins: an installed package adds behaviours through an entry point.

Issue 20 item 2. Each test runs clark in a fresh interpreter whose path holds the
example plugin (examples/clark-behavior-zigzag) and a throw-away ``.dist-info``
declaring its entry point, which is what ``pip install`` leaves behind as far as
``importlib.metadata`` (and so the engine) can tell. No network, no installation.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "clark-behavior-zigzag"
MISSION = """\
clark: 1
mission:
  id: 7
  name: zigzag-sweep
  loop_hz: 5
  heartbeat_timeout_s: 5
  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}
agents:
  mcs:
    id: 1
    profile: mcs_laptop
    hardware:
      radio: {address: "0013A20040A1B201"}
    telemetry: {heartbeat: 1}
  slash:
    id: 2
    profile: traxxas_slash
    hardware:
      radio: {address: "0013A20040A1B202"}
    telemetry: {heartbeat: 1, agent_status: 1}
    behavior:
      initial: sweep
      states:
        sweep:
          use: zigzag
          with: {start: [0, 0], heading_deg: 0, advance_m: 10, width_m: 20, legs: 4}
          transitions: {done: stopped}
        stopped: {use: hold}
"""


def _site(tmp_path: Path, dist: str, entry: str) -> Path:
    """A folder holding one distribution's metadata with one behaviours entry point."""
    site = tmp_path / f"site-{dist}"
    info = site / f"{dist.replace('-', '_')}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1.0\n", encoding="utf-8"
    )
    (info / "entry_points.txt").write_text(f"[clark_engine.behaviors]\n{entry}\n", encoding="utf-8")
    return site


def _python(code: str, *path: Path) -> subprocess.CompletedProcess[str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(ROOT), *map(str, path)])
    return subprocess.run(
        [sys.executable, "-c", code],
        cwd=ROOT,
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
    )


def test_the_example_plugin_is_listed_described_validated_compiled_and_loaded(
    tmp_path: Path,
) -> None:
    site = _site(tmp_path, "clark-behavior-zigzag", "zigzag = clark_behavior_zigzag:BEHAVIOR")
    mission = tmp_path / "zigzag.yaml"
    mission.write_text(MISSION, encoding="utf-8")
    out = tmp_path / "build"
    code = f"""
import contextlib, io, json, pathlib
from clark_engine.cli import main
from clark_engine.runtime.config import load_config

def run(*args):
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        rc = main(list(args))
    return rc, text.getvalue()

results = {{}}
results["behaviors"] = run("behaviors")
results["behaviours"] = run("behaviours", "--json")
results["schema"] = run("schema", "mission")
results["config_schema"] = run("schema", "agent-config")
results["validate"] = run("validate", {str(mission)!r})[0]
results["compile"] = run("compile", {str(mission)!r}, "-o", {str(out)!r})[0]
config = load_config(pathlib.Path({str(out / "zigzag-sweep" / "slash.json")!r}))
results["loaded"] = [s.primitive for s in config.machine.walk()]
print(json.dumps(results))
"""
    proc = _python(code, EXAMPLE, site)
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout.splitlines()[-1])
    rc, listing = results["behaviors"]
    assert rc == 0
    line = next(x for x in listing.splitlines() if x.startswith("zigzag "))
    assert "clark-behavior-zigzag" in line and "zig-zag" in line
    assert next(x for x in listing.splitlines() if x.startswith("hold ")).split()[1] == "built-in"
    rc, listed = results["behaviours"]
    assert rc == 0
    assert {"name": "zigzag", "origin": "clark-behavior-zigzag"}.items() <= next(
        row for row in json.loads(listed) if row["name"] == "zigzag"
    ).items()
    rc, schema = results["schema"]
    assert rc == 0
    defs = json.loads(schema)["$defs"]
    assert "params_zigzag" in defs
    assert "heading_deg" in defs["params_zigzag"]["properties"]
    config_schema = json.loads(results["config_schema"][1])
    assert "zigzag" in config_schema["$defs"]["state"]["properties"]["primitive"]["enum"]
    assert results["validate"] == 0
    assert results["compile"] == 0
    assert "zigzag" in results["loaded"]


def test_the_shipped_schemas_do_not_depend_on_what_is_installed(tmp_path: Path) -> None:
    site = _site(tmp_path, "clark-behavior-zigzag", "zigzag = clark_behavior_zigzag:BEHAVIOR")
    code = (
        "from clark_engine.mission.schema_source.render import render\n"
        "print('params_zigzag' in render('mission.schema.json'))\n"
    )
    proc = _python(code, EXAMPLE, site)
    assert proc.returncode == 0, proc.stderr
    assert proc.stdout.strip() == "False"


def _clark(site: Path, *args: str) -> subprocess.CompletedProcess[str]:
    code = f"import sys\nfrom clark_engine.cli import main\nsys.exit(main({list(args)!r}))\n"
    return _python(code, site)


def test_a_plugin_that_fails_to_import_is_named_without_a_traceback(tmp_path: Path) -> None:
    site = _site(tmp_path, "clark-behavior-broken", "broken = clark_behavior_missing:BEHAVIOR")
    proc = _clark(site, "behaviors")
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "behaviour plugin 'clark-behavior-broken'" in proc.stderr
    assert "failed to load: ModuleNotFoundError" in proc.stderr
    assert "pip uninstall clark-behavior-broken" in proc.stderr


def test_a_plugin_that_takes_a_built_in_name_is_refused(tmp_path: Path) -> None:
    site = _site(tmp_path, "clark-behavior-hold", "hold = clark_engine.behaviors.hold:BEHAVIOR")
    proc = _clark(site, "validate", str(ROOT / "missions" / "single_vehicle_mode_change.yaml"))
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    assert "declares behaviour 'hold', which a built-in behaviour already declares" in (proc.stderr)


def test_a_plugin_that_gives_no_behavior_is_refused(tmp_path: Path) -> None:
    site = _site(tmp_path, "clark-behavior-odd", "odd = json:dumps")
    proc = _clark(site, "behaviors")
    assert proc.returncode == 2
    assert "gives function, not a clark_engine.behaviors.Behavior" in proc.stderr
