"""ClarkLink messages <-> Protocol Buffers: round trips, quantisation, ranges, rejection."""

from __future__ import annotations

import math
import struct

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from clark_engine.link.errors import MalformedPacket
from clark_engine.link.messages import (
    ActivateController,
    AgentAttitude,
    AgentStatus,
    AgentType,
    BehaviorState,
    Condition,
    Heartbeat,
    Message,
    ModeChangeRequest,
    PictureData,
    PrearmState,
    Terminate,
    VehicleHealth,
)
from clark_engine.link.wire import (
    MESSAGE_ORDER,
    bundle_bytes,
    canonical_order,
    encode_entry,
    encoded_size,
    parse_bundle,
)

GPS_MS = 1_400_000_000_000

#: One message of every type from agent 2 of mission 7, with values exact on the wire.
SAMPLES: tuple[Message, ...] = (
    Heartbeat(2, GPS_MS, 7, AgentType.VEHICLE, Condition.DEGRADED, payload_count=1),
    AgentStatus(2, GPS_MS, 30.6319, -96.4826, 121.5, 17.25, -1.5, 271.3, 10),
    PictureData(2, GPS_MS, 30.63191, -96.48262, 80.0, 42),
    ModeChangeRequest(2, GPS_MS, target_id=3, mode=4),
    ActivateController(2, GPS_MS, target_id=0, active=True, start_time_ms=GPS_MS + 5000, option=-3),
    AgentAttitude(2, GPS_MS, -12.5, 3.25, 271.3),
    Terminate(2, GPS_MS, target_id=0, reason="operator: weather"),
    BehaviorState(2, GPS_MS, ("survey.leg_2", "photos"), "done"),
    VehicleHealth(2, GPS_MS, True, 12.6, 87, 6, 10, PrearmState.PASSING, 4, "GPS Glitch", ""),
)


def status(**changes: object) -> AgentStatus:
    fields: dict[str, object] = {
        "agent_id": 2,
        "gps_time_ms": GPS_MS,
        "lat_deg": 30.6319,
        "lon_deg": -96.4826,
        "alt_m": 10.0,
        "ground_speed_m_s": 1.0,
        "climb_rate_m_s": 0.0,
        "heading_deg": 90.0,
        "mode": 4,
    }
    fields.update(changes)
    return AgentStatus(**fields)  # type: ignore[arg-type]


# ---------------------------------------------------------------- hand-made protobuf bytes


def varint(value: int) -> bytes:
    out = bytearray()
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


def vfield(number: int, value: int) -> bytes:
    return varint(number << 3) + varint(value)


def lfield(number: int, payload: bytes) -> bytes:
    return varint((number << 3) | 2) + varint(len(payload)) + payload


def f32field(number: int, value: int) -> bytes:
    return varint((number << 3) | 5) + struct.pack("<i", value)


def zigzag(value: int) -> int:
    return (value << 1) ^ (value >> 63)


GOOD_STATUS_BODY = vfield(1, 2) + vfield(2, GPS_MS) + f32field(3, 306_319_000)


# ---------------------------------------------------------------- round trips


@pytest.mark.parametrize("message", SAMPLES, ids=lambda m: type(m).__name__)
def test_every_message_type_round_trips_exactly(message: Message) -> None:
    assert parse_bundle(bundle_bytes([message])) == (message,)


def test_every_message_type_has_a_sample() -> None:
    assert {type(m) for m in SAMPLES} == set(MESSAGE_ORDER)


def test_a_bundle_of_every_type_round_trips_in_type_order() -> None:
    shuffled = [*reversed(SAMPLES), SAMPLES[1]]
    decoded = parse_bundle(bundle_bytes(shuffled))
    assert decoded == tuple(canonical_order(shuffled))
    assert [type(m) for m in decoded] == [*MESSAGE_ORDER[:2], AgentStatus, *MESSAGE_ORDER[2:]]


def test_within_a_type_messages_keep_the_order_they_were_sent() -> None:
    first, second = status(mode=1), status(mode=2)
    beat = SAMPLES[0]
    assert parse_bundle(bundle_bytes([second, beat, first])) == (beat, second, first)


def test_interleaved_fields_on_the_wire_decode_in_the_same_deterministic_order() -> None:
    # Another encoder may interleave repeated fields; the order we return does not depend on it.
    hb, st1, st2 = SAMPLES[0], status(mode=1), status(mode=2)
    interleaved = encode_entry(st1) + encode_entry(hb) + encode_entry(st2)
    assert parse_bundle(interleaved) == (hb, st1, st2)


def test_bundle_is_the_concatenation_of_its_entries() -> None:
    assert bundle_bytes(SAMPLES) == b"".join(encode_entry(m) for m in SAMPLES)


@pytest.mark.parametrize("message", SAMPLES, ids=lambda m: type(m).__name__)
def test_encoded_size_is_what_the_message_adds_to_a_bundle(message: Message) -> None:
    others = [m for m in SAMPLES if m is not message]
    assert encoded_size(message) == len(encode_entry(message))
    assert len(bundle_bytes([*others, message])) - len(bundle_bytes(others)) == encoded_size(
        message
    )


def test_an_all_default_message_still_takes_two_bytes() -> None:
    # agent_id and gps_time_ms are never zero in practice, but sizes stay additive if they are.
    assert encoded_size(Terminate(agent_id=1, gps_time_ms=0)) == 4


def test_agent_status_is_compact() -> None:
    # 1 tag + 1 length + agent id 2 + gps time 7 + lat 5 + lon 5 + alt 4 + speed 3 + climb 3
    # + heading 4 + mode 2: the thesis-era budget of about 40 bytes per status holds.
    assert encoded_size(SAMPLES[1]) == 37


# ---------------------------------------------------------------- quantisation


@settings(max_examples=60, derandomize=True, deadline=None, database=None)
@given(
    lat=st.floats(-90, 90),
    lon=st.floats(-180, 180),
    alt=st.floats(-2_000_000, 2_000_000),
    speed=st.floats(0, 20_000_000),
    climb=st.floats(-20_000_000, 20_000_000),
    heading=st.floats(0, 360, exclude_max=True),
)
def test_agent_status_decodes_within_half_a_unit(
    lat: float, lon: float, alt: float, speed: float, climb: float, heading: float
) -> None:
    sent = status(
        lat_deg=lat,
        lon_deg=lon,
        alt_m=alt,
        ground_speed_m_s=speed,
        climb_rate_m_s=climb,
        heading_deg=heading,
    )
    data = bundle_bytes([sent])
    (got,) = parse_bundle(data)
    assert isinstance(got, AgentStatus)
    assert abs(got.lat_deg - lat) <= 0.5e-7 + 1e-12
    assert abs(got.lon_deg - lon) <= 0.5e-7 + 1e-12
    assert abs(got.alt_m - alt) <= 0.5e-3 + 1e-9
    assert abs(got.ground_speed_m_s - speed) <= 0.005 + 1e-6
    assert abs(got.climb_rate_m_s - climb) <= 0.005 + 1e-6
    # Heading is on a circle: 359.996 comes back as 0.
    turn = abs(got.heading_deg - heading) % 360
    assert min(turn, 360 - turn) <= 0.005 + 1e-9
    assert bundle_bytes([got]) == data  # quantising again changes nothing


@settings(max_examples=40, derandomize=True, deadline=None, database=None)
@given(angles=st.tuples(*[st.floats(-360, 360)] * 3))
def test_attitude_decodes_within_half_a_centidegree(angles: tuple[float, float, float]) -> None:
    sent = AgentAttitude(2, GPS_MS, *angles)
    (got,) = parse_bundle(bundle_bytes([sent]))
    assert isinstance(got, AgentAttitude)
    for before, after in zip(angles, (got.roll_deg, got.pitch_deg, got.yaw_deg), strict=True):
        assert abs(after - before) <= 0.005 + 1e-9


def test_rounding_is_to_nearest() -> None:
    (got,) = parse_bundle(bundle_bytes([status(lat_deg=1.00000006, alt_m=0.0016)]))
    assert isinstance(got, AgentStatus)
    assert got.lat_deg == 1.0000001
    assert got.alt_m == 0.002


def test_heading_just_under_360_wraps_to_north() -> None:
    (got,) = parse_bundle(bundle_bytes([status(heading_deg=359.996)]))
    assert isinstance(got, AgentStatus)
    assert got.heading_deg == 0.0


def test_the_extremes_of_every_range_are_accepted() -> None:
    for lat, lon in ((90.0, 180.0), (-90.0, -180.0), (90.00000004, -180.00000004)):
        sent = status(lat_deg=lat, lon_deg=lon)
        (got,) = parse_bundle(bundle_bytes([sent]))
        assert isinstance(got, AgentStatus)
        assert abs(got.lat_deg) == 90.0
        assert abs(got.lon_deg) == 180.0
    assert parse_bundle(bundle_bytes([status(heading_deg=359.99)]))[0] == status(heading_deg=359.99)
    extreme = AgentAttitude(2, (1 << 64) - 1, 360.0, -360.0, 0.0)
    assert parse_bundle(bundle_bytes([extreme])) == (extreme,)
    command = ActivateController(65535, 0, 65535, False, (1 << 64) - 1, -(1 << 31))
    assert parse_bundle(bundle_bytes([command])) == (command,)


@pytest.mark.parametrize(
    ("message", "field"),
    [
        (status(lat_deg=90.00000006), "lat_deg"),
        (status(lat_deg=-91.0), "lat_deg"),
        (status(lon_deg=180.1), "lon_deg"),
        (status(lat_deg=math.nan), "lat_deg"),
        (status(lon_deg=math.inf), "lon_deg"),
        (status(alt_m=2_147_484.0), "alt_m"),
        (status(ground_speed_m_s=-0.01), "ground_speed_m_s"),
        (status(climb_rate_m_s=-21_474_837.0), "climb_rate_m_s"),
        (status(heading_deg=360.0), "heading_deg"),
        (status(heading_deg=-0.001), "heading_deg"),
        (status(heading_deg=math.nan), "heading_deg"),
        (status(mode=-1), "mode"),
        (status(mode=1 << 32), "mode"),
        (status(agent_id=0), "agent_id"),
        (status(agent_id=65536), "agent_id"),
        (status(gps_time_ms=-1), "gps_time_ms"),
        (status(gps_time_ms=1 << 64), "gps_time_ms"),
        (ModeChangeRequest(2, GPS_MS, target_id=65536, mode=1), "target_id"),
        (ActivateController(2, GPS_MS, 1, True, option=1 << 31), "option"),
        (ActivateController(2, GPS_MS, 1, True, start_time_ms=-5), "start_time_ms"),
        (AgentAttitude(2, GPS_MS, 0.0, 360.01, 0.0), "pitch_deg"),
        (Heartbeat(2, GPS_MS, 1 << 32, AgentType.MCS), "mission_id"),
        (Heartbeat(2, GPS_MS, 7, AgentType.MCS, payload_count=-1), "payload_count"),
    ],
)
def test_out_of_range_values_are_refused_at_encode_never_clamped(
    message: Message, field: str
) -> None:
    with pytest.raises(ValueError, match=field):
        bundle_bytes([message])
    with pytest.raises(ValueError, match=field):
        encoded_size(message)


def test_bad_enum_values_are_refused_at_encode() -> None:
    with pytest.raises(ValueError):
        bundle_bytes([Heartbeat(2, GPS_MS, 7, 9)])  # type: ignore[arg-type]
    with pytest.raises(ValueError):
        bundle_bytes([Heartbeat(2, GPS_MS, 7, AgentType.MCS, 0)])  # type: ignore[arg-type]


def test_wrong_types_are_refused_at_encode() -> None:
    with pytest.raises(TypeError):
        bundle_bytes([status(mode=4.0)])
    with pytest.raises(TypeError):
        bundle_bytes(["heartbeat"])  # type: ignore[list-item]
    with pytest.raises(TypeError):
        encoded_size(object())  # type: ignore[arg-type]


def test_an_empty_sequence_bundles_to_nothing() -> None:
    assert bundle_bytes([]) == b""


# ---------------------------------------------------------------- rejection on decode


@pytest.mark.parametrize(
    ("data", "why"),
    [
        (b"", "empty"),
        (b"\xff", "does not parse"),
        (lfield(2, GOOD_STATUS_BODY)[:-1], "does not parse"),
        (lfield(7, vfield(1, 2) + lfield(4, b"\xff\xfe")), "UTF-8"),
        (lfield(10, b""), "fields this ClarkLink version does not define"),
        (lfield(2, GOOD_STATUS_BODY) + vfield(15, 1), "fields this ClarkLink version"),
        (lfield(2, GOOD_STATUS_BODY + vfield(15, 1)), "agent_status has fields"),
        (lfield(2, vfield(1, 2) + f32field(3, 900_000_001)), "lat_e7"),
        (lfield(2, vfield(1, 2) + f32field(3, -900_000_001)), "lat_e7"),
        (lfield(3, vfield(1, 2) + f32field(4, 1_800_000_001)), "lon_e7"),
        (lfield(3, vfield(1, 2) + f32field(4, -(1 << 31))), "lon_e7"),
        (lfield(2, vfield(1, 2) + vfield(8, 36_000)), "heading_cdeg"),
        (lfield(1, vfield(1, 2) + vfield(5, 1)), "agent_type"),  # UNSPECIFIED agent type
        (lfield(1, vfield(1, 2) + vfield(4, 9) + vfield(5, 1)), "agent_type"),
        (lfield(1, vfield(1, 2) + vfield(4, 1) + vfield(5, 5)), "condition"),
        (lfield(1, vfield(1, 2) + vfield(4, 1) + vfield(5, (1 << 64) - 1)), "condition"),
        (lfield(4, vfield(1, 0)), "agent_id"),
        (lfield(4, vfield(1, 65_536)), "agent_id"),
        (lfield(4, vfield(1, 2) + vfield(3, 65_536)), "target_id"),
        (lfield(6, vfield(1, 2) + vfield(5, zigzag(-36_001))), "yaw_cdeg"),
        (lfield(6, vfield(1, 2) + vfield(3, zigzag(36_001))), "roll_cdeg"),
        (vfield(2, 5), "does not define"),  # a varint where a message belongs: unknown
    ],
)
def test_unparseable_or_out_of_range_bundles_are_malformed(data: bytes, why: str) -> None:
    with pytest.raises(MalformedPacket, match=why) as caught:
        parse_bundle(data)
    assert caught.value.sender_id is None


def test_hand_made_bytes_decode_like_the_encoder_s() -> None:
    data = lfield(2, GOOD_STATUS_BODY)
    (got,) = parse_bundle(data)
    assert got == AgentStatus(2, GPS_MS, 30.6319, 0.0, 0.0, 0.0, 0.0, 0.0, 0)
    assert bundle_bytes([got]) == data
