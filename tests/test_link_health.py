"""Vehicle Health on the wire: golden bytes, unknowns kept apart from zeros, bounded texts."""

from __future__ import annotations

import pytest
from test_link_wire import GPS_MS, lfield, vfield

from clark_engine.link import Codec, MalformedPacket
from clark_engine.link.messages import (
    MAX_FAILSAFE_TEXT_BYTES,
    MAX_HEALTH_TEXT_BYTES,
    PrearmState,
    VehicleHealth,
    fit_text,
)
from clark_engine.link.wire import bundle_bytes, encoded_size, parse_bundle

HEALTH = VehicleHealth(
    agent_id=2,
    gps_time_ms=GPS_MS,
    armed=True,
    battery_v=12.6,
    battery_pct=87,
    gps_fix_type=6,
    satellites=10,
    prearm=PrearmState.PASSING,
    text_severity=2,
    text="PreArm: Need Position Estimate",
    failsafe="hold: mcs_lost",
    text_age_s=12,
)

# Bundle field 9 (vehicle_health), 74 bytes: agent 2, gps time, armed, 12600 mV, 87 %,
# fix 6 (RTK fixed), 10 satellites, PASSING, severity 2, the text (30 bytes), the failsafe,
# the text's age (12 s).
GOLDEN_HEALTH = (
    "4a4a"
    "0802"  # agent_id 2
    "1080e082b4df28"  # gps_time_ms 1400000000000
    "1801"  # armed
    "20b862"  # battery_mv 12600
    "2857"  # battery_remaining_pct 87
    "3006"  # gps_fix_type 6
    "380a"  # satellites 10
    "4002"  # prearm PASSING
    "4802"  # text_severity 2 (CRITICAL)
    "521e" + b"PreArm: Need Position Estimate".hex() + "5a0e" + b"hold: mcs_lost".hex() + "680c"
)


def test_golden_bytes() -> None:
    assert bundle_bytes([HEALTH]).hex() == GOLDEN_HEALTH
    assert parse_bundle(bytes.fromhex(GOLDEN_HEALTH)) == (HEALTH,)
    assert encoded_size(HEALTH) == 76


def test_a_health_of_nothing_known_is_six_bytes_and_says_unknown() -> None:
    # Before its autopilot speaks a vehicle knows nothing: every optional figure absent.
    empty = VehicleHealth(2, 1)
    data = bundle_bytes([empty])
    assert data.hex() == "4a06" + "0802" + "1001" + "4001"  # agent, time, prearm UNKNOWN
    (got,) = parse_bundle(data)
    assert isinstance(got, VehicleHealth)
    assert (got.battery_v, got.battery_pct, got.satellites) == (None, None, None)
    assert got.prearm is PrearmState.UNKNOWN


def test_zero_is_a_figure_not_an_unknown() -> None:
    # A flat battery and no satellite in view are facts an operator must see as such.
    flat = VehicleHealth(2, GPS_MS, battery_v=0.0, battery_pct=0, satellites=0)
    (got,) = parse_bundle(bundle_bytes([flat]))
    assert isinstance(got, VehicleHealth)
    assert (got.battery_v, got.battery_pct, got.satellites) == (0.0, 0, 0)
    assert encoded_size(flat) > encoded_size(VehicleHealth(2, GPS_MS))


def test_voltage_is_quantised_to_the_millivolt() -> None:
    (got,) = parse_bundle(bundle_bytes([VehicleHealth(2, GPS_MS, battery_v=11.9034)]))
    assert isinstance(got, VehicleHealth)
    assert got.battery_v == 11.903


@pytest.mark.parametrize(
    ("message", "field"),
    [
        (VehicleHealth(2, GPS_MS, battery_v=-0.001), "battery_v"),
        (VehicleHealth(2, GPS_MS, battery_v=65.535), "battery_v"),
        (VehicleHealth(2, GPS_MS, battery_pct=101), "battery_pct"),
        (VehicleHealth(2, GPS_MS, battery_pct=-1), "battery_pct"),
        (VehicleHealth(2, GPS_MS, gps_fix_type=9), "gps_fix_type"),
        (VehicleHealth(2, GPS_MS, satellites=255), "satellites"),
        (VehicleHealth(2, GPS_MS, text_severity=5, text="note"), "text_severity"),
        (VehicleHealth(2, GPS_MS, text_severity=3), "text_severity"),
        (VehicleHealth(2, GPS_MS, text="x" * (MAX_HEALTH_TEXT_BYTES + 1)), "text"),
        (VehicleHealth(2, GPS_MS, text="é" * 26), "text"),  # 52 bytes in 26 characters
        (VehicleHealth(2, GPS_MS, failsafe="y" * (MAX_FAILSAFE_TEXT_BYTES + 1)), "failsafe"),
    ],
)
def test_out_of_range_figures_and_long_texts_are_refused_at_encode(
    message: VehicleHealth, field: str
) -> None:
    with pytest.raises(ValueError, match=field):
        bundle_bytes([message])


def test_the_bounds_themselves_are_accepted() -> None:
    edge = VehicleHealth(
        65535,
        (1 << 64) - 1,
        battery_v=65.534,
        battery_pct=100,
        gps_fix_type=8,
        satellites=254,
        prearm=PrearmState.FAILING,
        text_severity=0,
        text="E" * MAX_HEALTH_TEXT_BYTES,
        failsafe="F" * MAX_FAILSAFE_TEXT_BYTES,
        autopilot_lost=True,
        text_age_s=(1 << 32) - 1,
    )
    assert parse_bundle(bundle_bytes([edge])) == (edge,)


def _health(*fields: bytes) -> bytes:
    return lfield(9, vfield(1, 2) + vfield(8, 2) + b"".join(fields))


@pytest.mark.parametrize(
    ("data", "why"),
    [
        (lfield(9, vfield(1, 2)), "prearm"),  # UNSPECIFIED is never sent
        (_health(vfield(8, 4)), "prearm"),
        (_health(lfield(10, b"x" * (MAX_HEALTH_TEXT_BYTES + 1))), "text is 51 bytes"),
        (_health(lfield(11, b"y" * (MAX_FAILSAFE_TEXT_BYTES + 1))), "failsafe is 33 bytes"),
        (_health(vfield(9, 5), lfield(10, b"note")), "text_severity"),
        (_health(vfield(9, 2)), "text_severity"),  # a severity without its text
        (_health(vfield(6, 9)), "gps_fix_type"),
        (_health(vfield(4, 65_535)), "battery_mv"),
        (_health(vfield(5, 101)), "battery_remaining_pct"),
        (_health(vfield(7, 255)), "satellites"),
        (_health(lfield(10, b"\xc3")), "UTF-8"),
        (_health(vfield(14, 1)), "vehicle_health has fields"),
        (lfield(9, vfield(1, 0) + vfield(8, 2)), "agent_id"),
    ],
)
def test_hostile_health_bytes_are_malformed(data: bytes, why: str) -> None:
    with pytest.raises(MalformedPacket, match=why):
        parse_bundle(data)


def test_a_health_from_another_agent_than_the_sender_is_malformed() -> None:
    (packet,) = Codec(7, 3).encode([VehicleHealth(3, GPS_MS)], destination=0)
    forged = packet[:7] + b"\x02" + packet[8:]  # the header now claims agent 2
    with pytest.raises(MalformedPacket, match="agent"):
        Codec(7, 1).decode(forged)


@pytest.mark.parametrize(
    ("text", "limit", "expected"),
    [
        ("PreArm: Throttle below Failsafe", 50, "PreArm: Throttle below Failsafe"),
        ("x" * 60, 50, "x" * 50),
        ("é" * 30, 50, "é" * 25),  # never half a character
        ("ab\U0001f680", 5, "ab"),  # a 4-byte character that does not fit is left out whole
        ("a\ud800b", 50, "a?b"),  # a lone surrogate cannot be UTF-8
        ("line\nbreak\x1b[2J", 50, "line\nbreak\x1b[2J"),  # escaping is the viewer's job
    ],
)
def test_fit_text_cuts_at_a_character_boundary(text: str, limit: int, expected: str) -> None:
    got = fit_text(text, limit)
    assert got == expected
    assert len(got.encode("utf-8")) <= limit
