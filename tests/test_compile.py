"""The compiler: self-contained, schema-valid, deterministic configs; atomic writes."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from clark_engine.cli import main
from clark_engine.mission.compiler import agent_config, compile_mission
from clark_engine.mission.geo import LocalPoint, Origin, to_global, to_local
from clark_engine.mission.schemas import validator
from clark_engine.mission.validate import validate_path

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = sorted((ROOT / "missions").glob("*.yaml"))


def load(path: Path):  # type: ignore[no-untyped-def]
    result = validate_path(path, path.name)
    assert result.mission is not None, [f.format_text() for f in result.findings]
    return result.mission


@pytest.mark.parametrize("path", MISSIONS, ids=lambda p: p.name)
def test_every_config_is_valid_and_deterministic(path: Path) -> None:
    first = compile_mission(load(path))
    second = compile_mission(load(path))
    assert first == second
    for name, text in first.items():
        config = json.loads(text)
        validator("agent-config").validate(config)
        assert config["mission"]["agent"] == name
        assert config["source"]["sha256"] == load(path).source_sha256


def test_compile_cli_is_byte_identical_twice(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    mission = str(ROOT / "missions" / "cooperative_follow.yaml")
    assert main(["compile", mission, "-o", str(tmp_path / "a")]) == 0
    assert main(["compile", mission, "-o", str(tmp_path / "b")]) == 0
    files_a = sorted((tmp_path / "a" / "cooperative-follow").iterdir())
    files_b = sorted((tmp_path / "b" / "cooperative-follow").iterdir())
    assert [f.name for f in files_a] == ["mcs.json", "slash_a.json", "slash_b.json"]
    for fa, fb in zip(files_a, files_b, strict=True):
        assert fa.read_bytes() == fb.read_bytes()
    assert "wrote" in capsys.readouterr().out


def test_agent_option_writes_one(tmp_path: Path) -> None:
    mission = str(ROOT / "missions" / "cooperative_follow.yaml")
    assert main(["compile", mission, "-o", str(tmp_path), "--agent", "slash_b"]) == 0
    assert [p.name for p in (tmp_path / "cooperative-follow").iterdir()] == ["slash_b.json"]
    assert main(["compile", mission, "-o", str(tmp_path), "--agent", "nobody"]) == 2


def test_invalid_mission_writes_nothing(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text(
        (ROOT / "missions" / "cooperative_follow.yaml")
        .read_text(encoding="utf-8")
        .replace("agent_status: 2,", "agent_status: 40,"),
        encoding="utf-8",
    )
    out = tmp_path / "out"
    assert main(["compile", str(bad), "-o", str(out)]) == 1
    assert not out.exists()
    assert "E-RATE" in capsys.readouterr().err


def test_config_has_the_thesis_three_sections_and_the_rest() -> None:
    mission = load(ROOT / "missions" / "cooperative_follow.yaml")
    config = agent_config(mission, mission.agents["slash_b"])
    assert config["mission"]["loop_hz"] == 10
    assert config["clark"]["enable"] == {
        "radio": True,
        "autopilot": True,
        "payload": False,
        "gui": False,
    }
    assert config["agent"]["hardware"]["radio"]["address"] == "0013A20040A1B203"
    assert config["agent"]["hardware"]["autopilot"]["modes"]["GUIDED"] == 15  # ArduRover
    assert {p["name"] for p in config["peers"]} == {"mcs", "slash_a"}
    slash_a = next(p for p in config["peers"] if p["name"] == "slash_a")
    assert slash_a["sends"] == {"agent_status": 2, "heartbeat": 1}
    assert [t["every_ticks"] for t in config["telemetry"]] == [10, 5, 20]  # health every 2 s
    chase = next(s for s in config["machine"]["states"] if s["name"] == "chase")
    assert chase["params"]["target"] == {"name": "slash_a", "id": 2}
    assert chase["transitions"][0] == {
        "event": "done",
        "target": "parked",
        "when": None,
        "source": chase["transitions"][0]["source"],
    }
    station = agent_config(mission, mission.agents["mcs"])
    assert station["clark"]["enable"]["gui"] is True
    assert station["agent"]["hardware"]["autopilot"] is None


def test_one_block_resolves_through_each_airframe() -> None:
    """aileron_doublet on the Super Cub and on the Anaconda: same block, each one's channels."""
    cub = load(ROOT / "missions" / "supercub_sysid.yaml")
    anaconda = load(ROOT / "missions" / "anaconda_survey.yaml")
    cub_state = cub.agents["cub"].behavior.find(("excite", "aileron"))  # type: ignore[union-attr]
    ana_state = anaconda.agents["anaconda"].behavior.find(("doublet",))  # type: ignore[union-attr]
    assert cub_state is not None and ana_state is not None
    assert cub_state.block == ana_state.block == "aileron_doublet"
    cub_cfg = agent_config(cub, cub.agents["cub"])
    ana_cfg = agent_config(anaconda, anaconda.agents["anaconda"])
    cub_channel = cub_cfg["machine"]["states"][1]["states"][0]["params"]["channel"]
    ana_channel = next(s for s in ana_cfg["machine"]["states"] if s["name"] == "doublet")["params"][
        "channel"
    ]
    assert cub_channel["name"] == ana_channel["name"] == "aileron"
    assert cub_channel["rc"] == ana_channel["rc"] == 1
    assert ana_state.params["amplitude_us"] == 120  # the mission's value
    assert cub_state.params["amplitude_us"] == 150  # the block's default, via the sequence


def test_waypoints_compile_to_both_frames() -> None:
    mission = load(ROOT / "missions" / "single_vehicle_mode_change.yaml")
    config = agent_config(mission, mission.agents["slash"])
    drive = next(s for s in config["machine"]["states"] if s["name"] == "drive")
    to = drive["params"]["to"]
    assert (to["north_m"], to["east_m"]) == (30, 20)
    back = to_local(to["lat"], to["lon"], to["alt_m"], mission.origin)
    assert abs(back.north_m - 30) < 0.02 and abs(back.east_m - 20) < 0.02


def test_local_frame_round_trip() -> None:
    origin = Origin(30.6372, -96.4787, 90)
    for point in (LocalPoint(0, 0), LocalPoint(1500, -800, 60), LocalPoint(-3, 4, 0)):
        lat, lon, alt = to_global(point, origin)
        back = to_local(lat, lon, alt, origin)
        assert abs(back.north_m - point.north_m) < 1e-6
        assert abs(back.east_m - point.east_m) < 1e-6
