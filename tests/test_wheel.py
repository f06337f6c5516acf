"""The wheel ships the data folders and the station view's page: an install outside the
repo validates the examples and serves the page with its vendored map library."""

from __future__ import annotations

import subprocess
import sys
import sysconfig
import venv
import zipfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parent.parent

# One worker builds and installs the wheel once for both tests (a module fixture is per
# worker: spread over two, each built it, 15 s apiece).
pytestmark = [pytest.mark.slow, pytest.mark.xdist_group("wheel")]


def _run(*cmd: str | Path, cwd: Path) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [str(c) for c in cmd], cwd=cwd, capture_output=True, text=True, timeout=300, check=False
    )


@pytest.fixture(scope="module")
def installed(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """A fresh venv with only the built wheel of clark-engine installed into it."""
    work = tmp_path_factory.mktemp("wheel")
    dist = work / "dist"
    built = _run(
        sys.executable,
        "-m",
        "pip",
        "wheel",
        "--no-deps",
        "--no-build-isolation",
        "--wheel-dir",
        dist,
        ROOT,
        cwd=work,
    )
    assert built.returncode == 0, built.stderr
    (wheel,) = dist.glob("clark_engine-*.whl")
    shipped = set(zipfile.ZipFile(wheel).namelist())
    for page_file in (
        "clark_engine/station/static/index.html",
        "clark_engine/station/static/app.js",
        "clark_engine/station/static/style.css",
        "clark_engine/station/static/vendor/leaflet/leaflet.js",
        "clark_engine/station/static/vendor/leaflet/leaflet.css",
        "clark_engine/station/static/vendor/leaflet/LICENSE",
        "clark_engine/station/static/vendor/leaflet/images/marker-icon.png",
        # ArduPilot's parameter lists the simulated autopilot reports (sim/ardupilot/params.py).
        "clark_engine/sim/ardupilot/sitl_params/ardurover.csv.gz",
        "clark_engine/sim/ardupilot/sitl_params/arducopter.csv.gz",
        "clark_engine/sim/ardupilot/sitl_params/arduplane.csv.gz",
    ):
        assert page_file in shipped, f"{page_file} is not in the wheel"
    env_dir = work / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    python = env_dir / "bin" / "python"
    install = _run(python, "-m", "pip", "install", "--no-deps", "--no-index", wheel, cwd=work)
    assert install.returncode == 0, install.stderr
    # Dependencies come from the test environment, without its editable engine:
    # a path added by a .pth line is searched, but .pth files inside it are not run.
    site = _run(python, "-c", "import sysconfig; print(sysconfig.get_paths()['purelib'])", cwd=work)
    Path(site.stdout.strip(), "deps-from-test-env.pth").write_text(
        sysconfig.get_paths()["purelib"] + "\n", encoding="utf-8"
    )
    return env_dir


def test_installed_engine_uses_its_own_data(installed: Path, tmp_path: Path) -> None:
    probe = _run(
        installed / "bin" / "python",
        "-c",
        "import clark_engine, clark_engine.data as d; "
        "print(clark_engine.__file__); print(d.data_dir('missions'))",
        cwd=tmp_path,
    )
    assert probe.returncode == 0, probe.stderr
    module, missions = probe.stdout.split()
    assert module.startswith(str(installed)), module
    assert missions.startswith(str(installed)) and missions.endswith("_data/missions")


def test_clark_validate_runs_from_outside_the_repo(installed: Path, tmp_path: Path) -> None:
    missions = _run(
        installed / "bin" / "python",
        "-c",
        "from clark_engine.data import data_dir; print(data_dir('missions'))",
        cwd=tmp_path,
    ).stdout.strip()
    proc = _run(
        installed / "bin" / "clark",
        "validate",
        Path(missions) / "supercub_sysid.yaml",
        cwd=tmp_path,
    )
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "valid mission" in proc.stdout
    schema = _run(installed / "bin" / "clark", "schema", "mission", cwd=tmp_path)
    assert schema.returncode == 0 and '"title": "Clark Engine mission"' in schema.stdout
    compiled = _run(
        installed / "bin" / "clark",
        "compile",
        Path(missions) / "cooperative_follow.yaml",
        "-o",
        tmp_path / "out",
        cwd=tmp_path,
    )
    assert compiled.returncode == 0, compiled.stderr
    assert (tmp_path / "out" / "cooperative-follow" / "slash_b.json").is_file()
    # A pip user's way to the examples: a copy to edit, valid where it lands.
    examples = _run(installed / "bin" / "clark", "examples", "mine", cwd=tmp_path)
    assert examples.returncode == 0, examples.stderr
    mine = _run(
        installed / "bin" / "clark",
        "validate",
        tmp_path / "mine" / "missions" / "anaconda_survey.yaml",
        cwd=tmp_path,
    )
    assert mine.returncode == 0 and "valid mission" in mine.stdout, mine.stderr


def test_installed_engine_serves_the_station_view_page(installed: Path, tmp_path: Path) -> None:
    """The installed package finds its own page and Leaflet (no checkout, no internet)."""
    probe = _run(
        installed / "bin" / "python",
        "-c",
        "from clark_engine.station.server import STATIC_DIR; "
        "print(STATIC_DIR); "
        "print((STATIC_DIR / 'vendor/leaflet/leaflet.js').stat().st_size); "
        "print('data-testid=\"agents\"' in (STATIC_DIR / 'index.html').read_text())",
        cwd=tmp_path,
    )
    assert probe.returncode == 0, probe.stderr
    folder, size, has_table = probe.stdout.split()
    assert folder.startswith(str(installed)), folder
    assert int(size) > 100_000 and has_table == "True"
