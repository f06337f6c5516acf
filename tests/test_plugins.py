"""Plugins: an installed package adds behaviours, blocks and hardware profiles.

Issue 20 item 2. Each test runs clark in a fresh interpreter whose path holds the
example plugin (examples/clark-behavior-zigzag) and a throw-away ``.dist-info``
declaring its entry points, which is what ``pip install`` leaves behind as far as
``importlib.metadata`` (and so the engine) can tell. No network, no installation.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

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


def _site(tmp_path: Path, dist: str, entry: str, group: str = "clark_engine.behaviors") -> Path:
    """A folder holding one distribution's metadata and its entry points.

    ``entry`` is one entry point in ``group``, or a whole ``entry_points.txt`` when it
    starts with a ``[group]`` line.
    """
    site = tmp_path / f"site-{dist}"
    info = site / f"{dist.replace('-', '_')}-0.1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(
        f"Metadata-Version: 2.1\nName: {dist}\nVersion: 0.1.0\n", encoding="utf-8"
    )
    text = entry if entry.startswith("[") else f"[{group}]\n{entry}"
    (info / "entry_points.txt").write_text(f"{text}\n", encoding="utf-8")
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


# Blocks and hardware profiles: the entry-point groups clark_engine.blocks and
# clark_engine.hardware_profiles, each naming a package whose folder holds YAML files.

ZIGZAG_ENTRY_POINTS = """\
[clark_engine.behaviors]
zigzag = clark_behavior_zigzag:BEHAVIOR
[clark_engine.blocks]
zigzag = clark_behavior_zigzag.blocks
[clark_engine.hardware_profiles]
zigzag = clark_behavior_zigzag.hardware_profiles"""

SEARCH = MISSION.replace(
    '      radio: {address: "0013A20040A1B202"}\n    telemetry: {heartbeat: 1, agent_status: 1}',
    '      radio: {address: "0013A20040A1B202"}\n'
    "      payloads:\n"
    "        camera: {profile: zigzag_dashcam}\n"
    "    telemetry: {heartbeat: 1, agent_status: 1}",
).replace(
    "          use: zigzag\n",
    "          use: zigzag_search\n",
)
STABLE = "clark-behavior-zigzag/clark_behavior_zigzag/blocks/zigzag_search.yaml"


def _package(site: Path, name: str, files: dict[str, str]) -> None:
    """A package ``name`` in ``site`` holding ``files`` (relative path -> text)."""
    for rel, text in {"__init__.py": "", **files}.items():
        path = site / name.replace(".", "/") / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text, encoding="utf-8")


def _no_traceback(proc: subprocess.CompletedProcess[str]) -> None:
    assert "Traceback" not in proc.stderr + proc.stdout


def test_a_plugin_block_and_profile_are_found_and_used(tmp_path: Path) -> None:
    site = _site(tmp_path, "clark-behavior-zigzag", ZIGZAG_ENTRY_POINTS)
    assert "use: zigzag_search" in SEARCH and "zigzag_dashcam" in SEARCH
    mission = tmp_path / "search.yaml"
    mission.write_text(SEARCH, encoding="utf-8")
    out = tmp_path / "build"
    code = f"""
import contextlib, io, json
from clark_engine.cli import main

def run(*args):
    text = io.StringIO()
    with contextlib.redirect_stdout(text):
        rc = main(list(args))
    return rc, text.getvalue()

results = {{}}
results["blocks"] = run("behaviors", "--blocks", "--json")
results["profiles"] = run("profiles", "--json")
results["validate"] = run("validate", {str(mission)!r})[0]
results["explain"] = run("explain", {str(mission)!r})
results["compile"] = run("compile", {str(mission)!r}, "-o", {str(out)!r})[0]
print(json.dumps(results))
"""
    proc = _python(code, EXAMPLE, site)
    assert proc.returncode == 0, proc.stderr
    results = json.loads(proc.stdout.splitlines()[-1])
    rc, listed = results["blocks"]
    blocks = {row["name"]: row for row in json.loads(listed)}
    assert rc == 0
    assert blocks["zigzag_search"]["origin"] == "clark-behavior-zigzag"
    assert blocks["zigzag_search"]["file"] == STABLE
    assert blocks["rudder_doublet"]["origin"] == "shipped"
    rc, listed = results["profiles"]
    profiles = {row["name"]: row for row in json.loads(listed)}
    assert rc == 0
    assert profiles["zigzag_dashcam"]["origin"] == "clark-behavior-zigzag"
    assert profiles["zigzag_dashcam"]["kind"] == "payload"
    assert profiles["super_cub"]["origin"] == "shipped"
    assert results["validate"] == 0
    rc, explained = results["explain"]
    assert rc == 0 and "zigzag_search" in explained
    assert results["compile"] == 0
    config = json.loads((out / "zigzag-sweep" / "slash.json").read_text(encoding="utf-8"))
    assert config["agent"]["hardware"]["payloads"]["camera"]["profile"] == "zigzag_dashcam"
    sources = [s["source"] for s in config["machine"]["states"][0]["states"]]
    # Reproducible: the plugin's file by its distribution and package path, never its
    # install path (here the example's folder).
    assert all(s.startswith(STABLE + ":") for s in sources), sources
    compiled = (out / "zigzag-sweep" / "slash.json").read_text(encoding="utf-8")
    assert str(EXAMPLE) not in compiled and str(site) not in compiled


def test_a_plugin_profile_file_and_block_file_validate_as_shipped_ones(tmp_path: Path) -> None:
    site = _site(tmp_path, "clark-behavior-zigzag", ZIGZAG_ENTRY_POINTS)
    package = EXAMPLE / "clark_behavior_zigzag"
    proc = _python(
        "import sys\nfrom clark_engine.cli import main\nsys.exit(main(['validate', "
        f"{str(package / 'blocks' / 'zigzag_search.yaml')!r}, "
        f"{str(package / 'hardware_profiles' / 'payloads' / 'zigzag_dashcam.yaml')!r}]))\n",
        EXAMPLE,
        site,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "valid block" in proc.stdout and "valid profile" in proc.stdout


def test_a_plugin_profile_named_as_a_shipped_one_is_a_finding_naming_both(
    tmp_path: Path,
) -> None:
    site = _site(
        tmp_path, "clark-profiles-clash", "cub = clash_profiles", "clark_engine.hardware_profiles"
    )
    _package(
        site,
        "clash_profiles",
        {"platforms/super_cub.yaml": "profile: super_cub\nkind: platform\ndescription: mine\n"},
    )
    proc = _clark(site, "validate", str(ROOT / "missions" / "single_vehicle_mode_change.yaml"))
    _no_traceback(proc)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    line = next(x for x in proc.stdout.splitlines() if "[E-PROFILE-DUPLICATE]" in x)
    assert line.startswith("clark-profiles-clash/clash_profiles/platforms/super_cub.yaml:1:1:")
    assert (
        "hardware profile plugin 'clark-profiles-clash' (entry point cub = clash_profiles)" in line
    )
    assert "which hardware_profiles/platforms/super_cub.yaml already declares" in line
    proc = _clark(site, "profiles")
    _no_traceback(proc)
    assert proc.returncode == 1
    assert "[E-PROFILE-DUPLICATE]" in proc.stderr


def test_two_plugins_declaring_one_block_name_are_a_finding_naming_both(tmp_path: Path) -> None:
    block = (
        "block: sweep_twice\ndescription: two holds\n"
        "machine: {initial: a, states: {a: {use: hold}}}\n"
    )
    sites = []
    for dist, package in (("clark-blocks-a", "blocks_a"), ("clark-blocks-b", "blocks_b")):
        site = _site(tmp_path, dist, f"mine = {package}", "clark_engine.blocks")
        _package(site, package, {"sweep_twice.yaml": block})
        sites.append(site)
    proc = _clark_on(sites, "validate", str(ROOT / "missions" / "single_vehicle_mode_change.yaml"))
    _no_traceback(proc)
    assert proc.returncode == 1, proc.stdout + proc.stderr
    line = next(x for x in proc.stdout.splitlines() if "[E-BLOCK-DUPLICATE]" in x)
    assert line.startswith("clark-blocks-b/blocks_b/sweep_twice.yaml:1:1:")
    assert "block plugin 'clark-blocks-b' (entry point mine = blocks_b)" in line
    assert (
        "which block plugin 'clark-blocks-a' (entry point mine = blocks_a), "
        "file clark-blocks-a/blocks_a/sweep_twice.yaml already declares"
    ) in line


def _clark_on(sites: list[Path], *args: str) -> subprocess.CompletedProcess[str]:
    code = f"import sys\nfrom clark_engine.cli import main\nsys.exit(main({list(args)!r}))\n"
    return _python(code, *sites)


@pytest.mark.parametrize(
    ("group", "entry", "files", "said"),
    [
        (
            "clark_engine.blocks",
            "mine = clark_blocks_missing",
            None,
            "block plugin 'clark-data-broken' (entry point mine = clark_blocks_missing) failed "
            "to load: ModuleNotFoundError: No module named 'clark_blocks_missing'; fix it, or "
            "uninstall it (pip uninstall clark-data-broken)",
        ),
        (
            "clark_engine.hardware_profiles",
            "mine = clark_engine.errors",
            None,
            "hardware profile plugin 'clark-data-broken' (entry point mine = "
            "clark_engine.errors) names module clark_engine.errors, not a package with a folder",
        ),
        (
            "clark_engine.blocks",
            "mine = json:dumps",
            None,
            "block plugin 'clark-data-broken' (entry point mine = json:dumps) gives function, "
            "not a package",
        ),
        (
            "clark_engine.hardware_profiles",
            "mine = gone_profiles",
            {"__init__.py": "__path__ = ['/nonexistent/gone_profiles']\n"},
            "hardware profile plugin 'clark-data-broken' (entry point mine = gone_profiles): the "
            "folder of package gone_profiles is missing",
        ),
    ],
    ids=["import-error", "a-module", "an-object", "folder-missing"],
)
def test_a_broken_block_or_profile_entry_point_is_named_without_a_traceback(
    tmp_path: Path, group: str, entry: str, files: dict[str, str] | None, said: str
) -> None:
    site = _site(tmp_path, "clark-data-broken", entry, group)
    if files is not None:
        _package(site, entry.split(" = ")[1], files)
    for args in (
        ("validate", str(ROOT / "missions" / "single_vehicle_mode_change.yaml")),
        ("profiles",) if "profile" in group else ("behaviors", "--blocks"),
    ):
        proc = _clark(site, *args)
        _no_traceback(proc)
        assert proc.returncode == 2, (args, proc.stdout, proc.stderr)
        assert said in proc.stderr, proc.stderr


def test_without_plugins_the_listings_show_the_shipped_files_only() -> None:
    proc = _python(
        "from clark_engine.cli import main\nimport sys\n"
        "sys.exit(main(['profiles']) or main(['behaviors', '--blocks']))\n"
    )
    assert proc.returncode == 0, proc.stderr
    assert len(proc.stdout.splitlines()) > 20
    assert all("  shipped  " in line for line in proc.stdout.splitlines()), proc.stdout


def test_the_profile_kinds_clark_profiles_offers_are_the_engines() -> None:
    from clark_engine.cli import build_parser
    from clark_engine.mission.profiles import PROFILE_KINDS

    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    kind = next(a for a in sub.choices["profiles"]._actions if a.dest == "kind")  # type: ignore[union-attr]
    assert tuple(kind.choices) == PROFILE_KINDS


def test_the_example_plugin_passes_its_own_tests_from_its_own_folder() -> None:
    """What its README tells a plugin writer to run: ``python -m pytest`` in its folder."""
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTEST_ADDOPTS")}
    proc = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-p", "no:xdist"],
        cwd=EXAMPLE,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-3000:]
    assert " passed" in proc.stdout and "failed" not in proc.stdout
