"""Hardware profiles: composition, overrides, every shipped profile resolves."""

from __future__ import annotations

from pathlib import Path

import pytest

from clark_engine.data import data_dir
from clark_engine.mission.findings import Location
from clark_engine.mission.profiles import HardwareResolver, ProfileLibrary, deep_merge
from clark_engine.mission.validate import validate_path
from clark_engine.mission.yaml_loader import load_yaml

ROOT = Path(__file__).resolve().parent.parent


@pytest.fixture
def library() -> ProfileLibrary:
    return ProfileLibrary([(data_dir("hardware_profiles"), "hardware_profiles")])


def test_deep_merge_rules() -> None:
    base = {"a": {"x": 1, "y": 2}, "l": [1, 2], "s": 1}
    assert deep_merge(base, {"a": {"y": 3}, "l": [9], "s": 2}) == {
        "a": {"x": 1, "y": 3},
        "l": [9],
        "s": 2,
    }
    serial = {"connection": {"kind": "serial", "device": "/dev/ttyACM0", "baud_bps": 115200}}
    udp = deep_merge(serial, {"connection": {"kind": "udp", "address": "127.0.0.1:14550"}})
    assert udp == {"connection": {"kind": "udp", "address": "127.0.0.1:14550"}}
    assert base["a"] == {"x": 1, "y": 2}  # inputs untouched


def test_every_shipped_profile_loads_and_composes(library: ProfileLibrary) -> None:
    names = library.names()
    assert (
        len(names) == 18
    )  # 4 airframes, 4 autopilots, 2 radios, 2 computers, 1 payload, 5 platforms
    for name in names:
        assert library.compose(name) is not None, name
    assert library.findings == []


@pytest.mark.parametrize(
    "platform", ["anaconda", "super_cub", "dji_f450", "traxxas_slash", "mcs_laptop"]
)
def test_every_platform_resolves(library: ProfileLibrary, platform: str) -> None:
    doc = load_yaml("{}", "m.yaml")
    result = HardwareResolver(library).resolve(
        "a", platform, Location("m.yaml", 1, 1), {}, doc, ("hardware",)
    )
    assert result.findings == []
    assert result.hardware is not None
    hw = result.hardware
    if platform == "mcs_laptop":
        assert hw.role == "mcs" and hw.part("autopilot") is None and hw.gui
    else:
        assert hw.role == "vehicle"
        assert hw.modes and hw.channels and hw.max_loop_hz == 13


def test_thesis_figures(library: ProfileLibrary) -> None:
    doc = load_yaml("{}", "m.yaml")
    resolver = HardwareResolver(library)
    cub = resolver.resolve("c", "super_cub", Location("m.yaml"), {}, doc, ()).hardware
    mcs = resolver.resolve("m", "mcs_laptop", Location("m.yaml"), {}, doc, ()).hardware
    assert cub is not None and mcs is not None
    radio = cub.part("radio")
    assert radio is not None
    assert radio["throughput_bps"] == 33000
    assert radio["max_packet_bytes"] == 256
    assert radio["connection"]["baud_bps"] == 115200
    assert cub.radio_range_m == pytest.approx(1609.344)
    assert cub.max_loop_hz == 13 and mcs.max_loop_hz == 98
    assert cub.modes["GUIDED"] == 15 and cub.modes["MANUAL"] == 0  # ArduPlane numbers


def test_agent_override_and_part_swap(library: ProfileLibrary) -> None:
    text = (
        "hardware:\n"
        "  radio: {profile: udp_lan, address: '127.0.0.1:14601'}\n"
        "  autopilot: {connection: {device: /dev/ttyACM1}}\n"
        "  channels: {aileron: {pwm_max_us: 1800}}\n"
    )
    doc = load_yaml(text, "m.yaml")
    result = HardwareResolver(library).resolve(
        "cub", "super_cub", Location("m.yaml", 1, 1), doc.data["hardware"], doc, ("hardware",)
    )
    assert result.findings == [], [f.format_text() for f in result.findings]
    hw = result.hardware
    assert hw is not None
    assert hw.part_profiles["radio"] == "udp_lan"
    assert hw.part("radio")["address"] == "127.0.0.1:14601"  # type: ignore[index]
    assert hw.part("autopilot")["connection"]["device"] == "/dev/ttyACM1"  # type: ignore[index]
    assert hw.part("autopilot")["connection"]["baud_bps"] == 115200  # type: ignore[index]
    assert hw.channels["aileron"].pwm_max_us == 1800
    # the origin of a merged value is where it was written
    origin = result.origins["autopilot"].locate(("connection", "device"), Location("x"))
    assert (origin.file, origin.line) == ("m.yaml", 3)
    base = result.origins["autopilot"].locate(("connection", "baud_bps"), Location("x"))
    assert base.file.endswith("pixhawk.yaml")


def test_broken_override_points_at_the_mission(tmp_path: Path) -> None:
    mission = (ROOT / "missions" / "cooperative_follow.yaml").read_text(encoding="utf-8")
    mission = mission.replace(
        'radio: {address: "0013A20040A1B202"}',
        'radio: {address: "0013A20040A1B202", throughput_bps: -5}',
    )
    path = tmp_path / "m.yaml"
    path.write_text(mission, encoding="utf-8")
    result = validate_path(path, "m.yaml")
    (finding,) = [f for f in result.findings if f.is_error]
    assert finding.location.file == "m.yaml"
    assert finding.code == "E-RANGE"


def test_profile_files_validate_on_their_own() -> None:
    for file in sorted((ROOT / "hardware_profiles").rglob("*.yaml")):
        result = validate_path(file, file.name)
        assert result.kind == "profile" and result.ok, [f.format_text() for f in result.findings]


def test_block_files_validate_on_their_own() -> None:
    for file in sorted((ROOT / "behaviors").glob("*.yaml")):
        result = validate_path(file, file.name)
        assert result.kind == "block"
        assert result.ok, [f.format_text() for f in result.findings]


def test_a_block_machine_is_checked_on_its_own(tmp_path: Path) -> None:
    block = tmp_path / "broken_block.yaml"
    block.write_text(
        "block: broken_block\n"
        "description: names a state that does not exist\n"
        "parameters:\n"
        "  type: object\n"
        "  required: [target]\n"
        "  properties:\n"
        "    target: {type: string, description: who, examples: [leader]}\n"
        "machine:\n"
        "  initial: go\n"
        "  states:\n"
        "    go: {use: follow_agent, with: {target: $target}, transitions: {done: stpo}}\n"
        "    stop: {use: hold, final: true}\n",
        encoding="utf-8",
    )
    result = validate_path(block, "broken_block.yaml")
    (finding,) = result.findings
    assert (finding.code, finding.location.line) == ("E-STATE-UNKNOWN", 11)
    assert "did you mean 'stop'" in finding.message
    # without examples the machine cannot be checked alone, and the tool says so
    block.write_text(block.read_text().replace(", examples: [leader]", ""), encoding="utf-8")
    result = validate_path(block, "broken_block.yaml")
    assert [f.code for f in result.findings] == ["W-BLOCK-UNCHECKED"]
    assert result.ok
