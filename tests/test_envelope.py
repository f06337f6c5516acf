"""The safety envelope as declared and resolved: defaults, narrowing, the compiled form."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from clark_engine.mission.compiler import compile_mission
from clark_engine.mission.envelope import DEFAULT_FENCE_RADIUS_M
from clark_engine.runtime.config import config_from_dict
from clark_engine.validation import validate_file

HEAD = """\
clark: 1
mission: {id: 1, name: demo, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
"""

AGENTS = """\
agents:
  mcs: {id: 1, profile: mcs_laptop, telemetry: {heartbeat: 1}}
  slash: {id: 2, profile: traxxas_slash, position: [10, 20], telemetry: {heartbeat: 1}}
  f450: {id: 3, profile: dji_f450, position: [-20, 0], telemetry: {heartbeat: 1}%s}
  cub: {id: 4, profile: super_cub, position: [-40, 0], telemetry: {heartbeat: 1}}
"""


def mission(tmp_path: Path, envelope: str = "", f450: str = "") -> Path:
    path = tmp_path / "mission.yaml"
    path.write_text(HEAD + envelope + AGENTS % f450, encoding="utf-8")
    return path


def resolved(path: Path) -> dict[str, object]:
    result = validate_file(path)
    assert result.ok, [f.message for f in result.errors]
    assert result.mission is not None
    return {n: a.envelope for n, a in result.mission.agents.items()}


def test_defaults_are_safe(tmp_path: Path) -> None:
    envelopes = resolved(mission(tmp_path))
    assert envelopes["mcs"] is None
    slash, f450 = envelopes["slash"], envelopes["f450"]
    assert slash is not None and f450 is not None
    # The legal 120 m; the F450's airframe allows 300 m, so the law is the lower.
    assert (f450.ceiling_m, f450.ceiling_by, f450.floor_m) == (120.0, "legal", 0.0)
    # A geofence by default: a circle around home as wide as the XBee's mile.
    assert slash.default_radius_m == pytest.approx(1609.344)
    assert (slash.home.north_m, slash.home.east_m) == (10.0, 20.0)
    assert slash.fence().contains(10 + 1600, 20) and not slash.fence().contains(10 + 1700, 20)
    assert (slash.on_breach, f450.on_breach) == ("hold", "rtl")
    assert (f450.on_near_miss, f450.outside, f450.min_separation_m) == ("hold", "clamp", 5.0)
    assert f450.endurance_s == 600.0  # the airframe's


def test_a_udp_radio_gets_the_default_radius(tmp_path: Path) -> None:
    path = tmp_path / "udp.yaml"
    path.write_text(
        HEAD
        + "agents:\n"
        + "  mcs: {id: 1, profile: mcs_laptop, hardware: {radio: {profile: udp_lan, "
        + 'address: "127.0.0.1:14601"}}, telemetry: {heartbeat: 1}}\n'
        + "  f450: {id: 3, profile: dji_f450, hardware: {radio: {profile: udp_lan, "
        + 'address: "127.0.0.1:14603"}}, telemetry: {heartbeat: 1}}\n',
        encoding="utf-8",
    )
    f450 = resolved(path)["f450"]
    assert f450 is not None
    assert f450.default_radius_m == DEFAULT_FENCE_RADIUS_M


def test_the_airframe_caps_the_ceiling(tmp_path: Path) -> None:
    envelope = "envelope: {legal_ceiling_m: 400, ceiling_m: 400}\n"
    f450 = resolved(mission(tmp_path, envelope))["f450"]
    assert f450 is not None
    assert (f450.ceiling_m, f450.ceiling_by) == (300.0, "airframe")


def test_a_vehicle_narrows_the_mission(tmp_path: Path) -> None:
    envelope = """\
envelope:
  ceiling_m: 100
  floor_m: 5
  min_separation_m: 8
  separation: [{between: [slash, f450], min_m: 3}]
  geofence:
    include: [{polygon: [[-100, -100], [300, -100], [300, 300], [-100, 300]]}]
"""
    f450_own = (
        ", envelope: {ceiling_m: 50, floor_m: 10, on_breach: land, outside: refuse, "
        "endurance_s: 300, geofence: {exclude: [{circle: {center: [50, 50], radius_m: 10}}]}}"
    )
    envelopes = resolved(mission(tmp_path, envelope, f450_own))
    f450, cub, slash = envelopes["f450"], envelopes["cub"], envelopes["slash"]
    assert f450 is not None and cub is not None and slash is not None
    assert (f450.ceiling_m, f450.floor_m, f450.ceiling_by) == (50.0, 10.0, "agent")
    assert (cub.ceiling_m, cub.floor_m) == (100.0, 5.0)
    assert (f450.on_breach, f450.outside, f450.endurance_s) == ("land", "refuse", 300.0)
    assert f450.default_radius_m is None
    fence = f450.fence()
    assert fence.contains(0, 0) and not fence.contains(50, 50) and not fence.contains(400, 0)
    assert cub.fence().contains(50, 50)  # the exclusion zone is the F450's own
    assert f450.separation_from_m("slash") == 3.0 and f450.separation_from_m("cub") == 8.0
    assert slash.separation_from_m("f450") == 3.0


def test_the_compiled_config_carries_every_envelope(tmp_path: Path) -> None:
    envelope = "envelope:\n  geofence: {exclude: [{circle: {center: [50, 50], radius_m: 10}}]}\n"
    result = validate_file(mission(tmp_path, envelope))
    assert result.mission is not None
    files = compile_mission(result.mission)
    f450 = json.loads(files["f450"])
    assert f450["mission"]["origin"] == {"lat": 30.6372, "lon": -96.4787, "alt_amsl_m": 90.0}
    assert "ceiling_m" not in f450["mission"]
    assert f450["envelope"]["ceiling_m"] == 120.0
    assert f450["envelope"]["geofence"]["exclude"][0]["kind"] == "circle"
    station = json.loads(files["mcs"])
    assert station["envelope"] is None
    peers = {p["name"]: p for p in station["peers"]}
    assert peers["slash"]["envelope"]["on_breach"] == "hold"
    config = config_from_dict(f450)
    assert config.envelope is not None and config.origin_alt_amsl_m == 90.0
    fence = config.envelope.fence
    assert fence.contains(0, 0) and not fence.contains(50, 50)
    assert not fence.contains(2000, 0)  # the default circle around home
    assert all(p.envelope is None for p in config.peers)  # a vehicle keeps its own only
    slash = config_from_dict(station).peer("slash")
    assert slash is not None and slash.envelope is not None
    assert (slash.envelope.home_north_m, slash.envelope.home_east_m) == (10.0, 20.0)
