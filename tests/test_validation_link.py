"""The checks that need ClarkLink: key file, link budget, one mesh."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from clark_engine.cli import main
from clark_engine.link import wire
from clark_engine.link.budget import Flow, PacketCosts, mesh_budget, sender_load
from clark_engine.link.messages import AgentStatus, Heartbeat
from clark_engine.mission.validate import validate_path
from clark_engine.validation import mission_flows, validate_file, worst_messages

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "benchmarks"))
from fleet import HEAVY_TELEMETRY, fleet_mission  # noqa: E402

COOP = (ROOT / "missions" / "cooperative_follow.yaml").read_text(encoding="utf-8")


def write(tmp_path: Path, text: str, name: str = "m.yaml") -> Path:
    path = tmp_path / name
    path.write_text(text, encoding="utf-8")
    return path


def codes(path: Path) -> list[str]:
    return [f.code for f in validate_file(path, path.name).findings]


def test_budget_matches_a_hand_count() -> None:
    """Slash A: heartbeat 1 Hz + status 2 Hz at 10 Hz, broadcast, and its Vehicle Health
    every 2 s to the station alone; XBee framing, no key."""
    mission = validate_path(ROOT / "missions" / "cooperative_follow.yaml").mission
    assert mission is not None
    flows = mission_flows(mission)
    costs = PacketCosts(header_bytes=16, tag_bytes=0, frame_bytes=18, max_packet_bytes=256)
    load = sender_load("slash_a", flows, mission.loop_hz, costs)
    hb = next(f.size_bytes for f in flows if f.sender == "slash_a" and f.message == "heartbeat")
    st = next(f.size_bytes for f in flows if f.sender == "slash_a" and f.message == "agent_status")
    vh = next(
        f.size_bytes for f in flows if f.sender == "slash_a" and f.message == "vehicle_health"
    )
    # tick 0: heartbeat + status in one packet; tick 5: status alone; 2 packets a second;
    # and every other tick 0, the health in a packet of its own to mcs: half a packet more
    assert load.packets_per_s == 2.5
    assert load.bytes_per_s == pytest.approx((hb + st + 34) + (st + 34) + (vh + 34) / 2)
    assert sum(load.by_message.values()) == pytest.approx(load.bytes_per_s)


def test_sizes_come_from_the_real_encoder() -> None:
    mission = validate_path(ROOT / "missions" / "supercub_sysid.yaml").mission
    assert mission is not None
    worst = worst_messages(mission, mission.agents["cub"])
    for message in worst.values():
        assert wire.encoded_size(message) == len(wire.encode_entry(message))
    # the behaviour state carries the longest active path of the cub's machine
    assert "excite.settle_1" in worst["behavior_state"].active_states or any(
        len(p) >= len("excite.settle_1") for p in worst["behavior_state"].active_states
    )


def test_splitting_follows_the_codec() -> None:
    big = Flow("a", "behavior_state", 1, (), 215, order=7)
    small = Flow("a", "heartbeat", 1, (), 20, order=0)
    costs = PacketCosts(16, 12, 18, 256)  # room for 228 bundle bytes: 235 must split
    load = sender_load("a", [big, small], 10, costs)
    assert load.split_ticks == 1  # the one tick of the hyperperiod
    assert load.packets_per_s == 20
    assert load.bytes_per_s == pytest.approx(10 * (235 + 2 * (16 + 12 + 18)))
    too_big = Flow("a", "behavior_state", 1, (), 300, order=7)
    assert sender_load("a", [too_big], 10, costs).unsendable == (("behavior_state", 300),)


def test_unicast_costs_a_packet_per_destination() -> None:
    one = Flow("a", "agent_status", 10, ("b", "c"), 34, order=1)
    load = sender_load("a", [one], 10, PacketCosts(16, 0, 18, 256))
    assert load.packets_per_s == 2


def test_fleet_over_the_xbee_budget(tmp_path: Path) -> None:
    heavy = {"radio": "xbee", "telemetry": HEAVY_TELEMETRY}
    assert "W-LINK-BUDGET" in codes(write(tmp_path, fleet_mission(20, **heavy)))
    findings = validate_file(write(tmp_path, fleet_mission(50, **heavy)), "m.yaml").findings
    (over,) = [f for f in findings if f.code == "E-LINK-BUDGET"]
    assert "247%" in over.message or "% of its measured 33 kbps" in over.message
    assert "by message: agent_status" in over.message
    assert over.location.path[-2:] == ("telemetry", "agent_status")
    on_udp = codes(write(tmp_path, fleet_mission(50)))
    assert not [c for c in on_udp if "LINK" in c] and "W-NO-KEY" in on_udp  # on UDP it fits


def test_budget_mesh_totals() -> None:
    flows = [Flow(s, "agent_status", 1, (), 34, order=1) for s in ("a", "b")]
    budget = mesh_budget(flows, ["a", "b"], 1, PacketCosts(16, 0, 18, 256), 1000)
    assert budget.bits_per_s == pytest.approx(2 * 68 * 8)
    assert budget.utilisation == pytest.approx(1.088)


def test_mixed_radios_cannot_hear_each_other(tmp_path: Path) -> None:
    text = COOP.replace(
        'hardware:\n      radio: {address: "0013A20040A1B201"}',
        'hardware:\n      radio: {profile: udp_lan, address: "127.0.0.1:14601"}',
        1,
    )
    assert "E-LINK-MIXED" in codes(write(tmp_path, text))


def test_key_file_rules(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    keyed = COOP.replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: keys/coop.key\n", 1)
    mission = write(tmp_path, keyed)
    follow = "W-ENVELOPE-REACTIVE"  # Slash B's follow, which only the dry run can judge
    gps = "W-POSITION-ERROR"  # its world's GPS error, against no declared position error
    assert codes(mission) == ["E-KEY-FILE", follow, gps]  # missing
    (tmp_path / "keys").mkdir()
    assert main(["keygen", str(tmp_path / "keys" / "coop.key")]) == 0
    assert "wrote" in capsys.readouterr().out
    assert codes(mission) == [follow, gps]
    assert main(["keygen", str(tmp_path / "keys" / "coop.key")]) == 2  # never overwrites
    (tmp_path / "keys" / "coop.key").chmod(0o644)
    findings = validate_file(mission, "m.yaml").findings
    assert [f.code for f in findings] == ["E-KEY-FILE", follow, gps]
    assert "chmod 600" in findings[0].message
    key_text = (tmp_path / "keys" / "coop.key").read_text().strip()
    assert key_text not in findings[0].message


def test_a_key_is_never_in_the_compiled_config(tmp_path: Path) -> None:
    keyed = COOP.replace("  loop_hz: 10\n", "  loop_hz: 10\n  key_file: coop.key\n", 1)
    mission = write(tmp_path, keyed)
    assert main(["keygen", str(tmp_path / "coop.key")]) == 0
    out = tmp_path / "out"
    assert main(["compile", str(mission), "-o", str(out)]) == 0
    key_text = (tmp_path / "coop.key").read_text().strip()
    for config in (out / "cooperative-follow").iterdir():
        text = config.read_text()
        assert key_text not in text and key_text.upper() not in text
        assert '"authenticated": true' in text and '"key_file": "coop.key"' in text


def test_no_key_warning_names_the_station() -> None:
    findings = validate_file(ROOT / "missions" / "cooperative_follow.yaml").findings
    (warn,) = [f for f in findings if f.code == "W-NO-KEY"]
    assert warn.location.path == ("agents", "mcs")


def test_worst_status_encodes() -> None:
    status = AgentStatus(2, 2**42 - 1, -89.9999999, -179.9999999, -400.0, 30.0, -5.0, 359.99, 24)
    heartbeat = Heartbeat(2, 2**42 - 1, 4294967295, agent_type=1)  # type: ignore[arg-type]
    assert wire.encoded_size(status) > wire.encoded_size(heartbeat) > 0


def test_absurd_profile_values_do_not_break_the_budget(tmp_path: Path) -> None:
    """Found in review: a huge max_altitude_m overflowed the encoder (a traceback)."""
    text = COOP.replace(
        'radio: {address: "0013A20040A1B202"}',
        'radio: {address: "0013A20040A1B202"}\n      airframe: {max_altitude_m: 3000000, '
        "max_speed_m_s: 50000000}",
        1,
    )
    assert codes(write(tmp_path, text))  # findings, not a crash


def test_rover_status_worst_case_is_not_under_counted() -> None:
    import dataclasses

    mission = validate_path(ROOT / "missions" / "cooperative_follow.yaml").mission
    assert mission is not None
    worst = worst_messages(mission, mission.agents["slash_a"])["agent_status"]
    real = dataclasses.replace(worst, climb_rate_m_s=-1.5)
    assert wire.encoded_size(worst) >= wire.encoded_size(real)
