"""Translate ClarkLink messages between dataclasses and Protocol Buffers bytes.

This is the only module that imports the generated ``_pb2`` code; everything
else in the engine sees the dataclasses of :mod:`clark_engine.link.messages`
(MAVSDK-Python's ``translate_from_rpc`` pattern). It knows nothing of packets,
headers or keys: :mod:`clark_engine.link.codec` frames what this module encodes.

Decisions, each pinned by tests:

* **Quantisation rounds to nearest** (Python's :func:`round`, ties to even):
  latitude and longitude to 1e-7 degrees, altitude to millimetres, speeds to
  cm/s, angles to centidegrees. A decoded value is within half a unit of the sent
  one, and encoding a decoded message again gives the same bytes.
* **Out-of-range values raise ValueError at encode; nothing is clamped.** A
  latitude of 91 degrees or a negative ground speed is a bug in the sender;
  clamping would put a wrong position on the air looking like a right one. The
  one exception is heading, which is an angle on a circle: 359.996 degrees
  rounds to 36000 centidegrees and is sent as 0, the same direction.
* **The same ranges are enforced on decode**, raising
  :class:`~clark_engine.link.errors.MalformedPacket`: latitude within +-90,
  longitude within +-180, heading 0..35999 centidegrees, roll, pitch and yaw
  within +-360 degrees (either convention for yaw, +-180 or 0..360, fits), agent
  and target ids within 16 bits (the header's width), enum values this engine
  knows (proto3 keeps unknown enum numbers as plain ints; the zero
  ``UNSPECIFIED`` value is never sent, so it is rejected too), and Vehicle Health's
  texts within their bounds (:data:`~clark_engine.link.messages.MAX_HEALTH_TEXT_BYTES`,
  :data:`~clark_engine.link.messages.MAX_FAILSAFE_TEXT_BYTES` of UTF-8), its
  battery, fix type, satellites and severity within MAVLink's ranges.
* **Unknown fields are rejected** on decode, in the bundle and in every message:
  the header's protocol version fixes the message set, so a field this engine
  does not know means a peer speaking another version or damaged bytes, and half
  understanding either is worse than a counted rejection.
* **An empty bundle is malformed.** No sender makes one (a codec with nothing to
  send sends nothing), and accepting it would let a packet with no content move
  a replay window.
* **Bundle order:** messages are bundled, and decoded, by type in the order of
  :data:`MESSAGE_ORDER` (the ``Bundle`` field numbers), then in the order they
  were given. Protocol Buffers writes fields in number order anyway; sorting
  before encoding makes a split bundle's packets follow that same order.
"""

from __future__ import annotations

import functools
import math
import operator
from collections.abc import Callable, Iterable, Sequence
from typing import Any, cast

from google.protobuf.message import DecodeError
from google.protobuf.message import Message as PbMessage
from google.protobuf.unknown_fields import UnknownFieldSet

from clark_engine.link._generated import clarklink_pb2 as pb
from clark_engine.link.errors import MalformedPacket
from clark_engine.link.messages import (
    MAX_FAILSAFE_TEXT_BYTES,
    MAX_HEALTH_TEXT_BYTES,
    MAX_SEVERITY_SENT,
    MESSAGE_NAMES,
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

#: Message types in bundle order; index + 1 is the ``Bundle`` field number.
MESSAGE_ORDER: tuple[type[Message], ...] = (
    Heartbeat,
    AgentStatus,
    PictureData,
    ModeChangeRequest,
    ActivateController,
    AgentAttitude,
    Terminate,
    BehaviorState,
    VehicleHealth,
)
_RANK: dict[type, int] = {cls: i for i, cls in enumerate(MESSAGE_ORDER)}
# Field key of each Bundle field: (field number << 3) | wire type 2 (length-delimited).
_FIELD_KEY: dict[type, bytes] = {
    cls: bytes([((i + 1) << 3) | 2]) for i, cls in enumerate(MESSAGE_ORDER)
}

AGENT_ID_MAX = 0xFFFF  # the packet header holds sender and destination in 16 bits
_U32 = (1 << 32) - 1
_U64 = (1 << 64) - 1
_S32_MIN, _S32_MAX = -(1 << 31), (1 << 31) - 1

LAT_E7_MAX = 900_000_000
LON_E7_MAX = 1_800_000_000
HEADING_CDEG_MAX = 35_999
ATTITUDE_CDEG_MAX = 36_000
BATTERY_MV_MAX = 65_534  # SYS_STATUS.voltage_battery is a uint16; 65535 means "not measured"
GPS_FIX_TYPE_MAX = 8  # MAVLink GPS_FIX_TYPE_PPP
SATELLITES_MAX = 254  # GPS_RAW_INT.satellites_visible is a uint8; 255 means "unknown"


# --------------------------------------------------------------------------- encode helpers


def _uint(value: int, high: int, name: str, low: int = 0) -> int:
    """Check an integer field; floats are refused (TypeError), not truncated."""
    number = operator.index(value)
    if not low <= number <= high:
        raise ValueError(f"{name}={number} is outside {low}..{high}")
    return number


def _scaled(value: float, scale: int, low: int, high: int, name: str) -> int:
    """Quantise ``value * scale`` to the nearest integer, refusing what does not fit."""
    if not math.isfinite(value):
        raise ValueError(f"{name}={value!r} is not a finite number")
    quantised = round(value * scale)
    if not low <= quantised <= high:
        raise ValueError(f"{name}={value!r} is outside {low / scale:g}..{high / scale:g}")
    return quantised


def _ids(message: Message) -> tuple[int, int]:
    return (
        _uint(message.agent_id, AGENT_ID_MAX, "agent_id", low=1),
        _uint(message.gps_time_ms, _U64, "gps_time_ms"),
    )


def _position(message: AgentStatus | PictureData) -> tuple[int, int, int]:
    return (
        _scaled(message.lat_deg, 10_000_000, -LAT_E7_MAX, LAT_E7_MAX, "lat_deg"),
        _scaled(message.lon_deg, 10_000_000, -LON_E7_MAX, LON_E7_MAX, "lon_deg"),
        _scaled(message.alt_m, 1000, _S32_MIN, _S32_MAX, "alt_m"),
    )


def _heading_cdeg(heading_deg: float) -> int:
    if not math.isfinite(heading_deg) or not 0.0 <= heading_deg < 360.0:
        raise ValueError(f"heading_deg={heading_deg!r} is outside 0 <= heading < 360")
    return round(heading_deg * 100) % 36_000  # 359.996 is 0.00: the same direction


def _attitude_cdeg(angle_deg: float, name: str) -> int:
    return _scaled(angle_deg, 100, -ATTITUDE_CDEG_MAX, ATTITUDE_CDEG_MAX, name)


def _text(value: str, limit: int, name: str) -> str:
    """A bounded text field: refused (ValueError) beyond ``limit`` bytes of UTF-8."""
    if not isinstance(value, str):
        raise TypeError(f"{name} must be a str, not {type(value).__name__}")
    size = len(value.encode("utf-8"))
    if size > limit:
        raise ValueError(f"{name} is {size} bytes of UTF-8, over {limit}; cut it with fit_text")
    return value


def _heartbeat_to_pb(m: Heartbeat) -> pb.Heartbeat:
    agent_id, gps_time_ms = _ids(m)
    return pb.Heartbeat(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        mission_id=_uint(m.mission_id, _U32, "mission_id"),
        agent_type=cast(pb.AgentType, AgentType(m.agent_type).value),
        condition=cast(pb.Condition, Condition(m.condition).value),
        payload_count=_uint(m.payload_count, _U32, "payload_count"),
        clarklink_version=_uint(m.clarklink_version, _U32, "clarklink_version"),
    )


def _agent_status_to_pb(m: AgentStatus) -> pb.AgentStatus:
    agent_id, gps_time_ms = _ids(m)
    lat_e7, lon_e7, alt_mm = _position(m)
    return pb.AgentStatus(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        lat_e7=lat_e7,
        lon_e7=lon_e7,
        alt_mm=alt_mm,
        ground_speed_cm_s=_scaled(m.ground_speed_m_s, 100, 0, _U32, "ground_speed_m_s"),
        climb_rate_cm_s=_scaled(m.climb_rate_m_s, 100, _S32_MIN, _S32_MAX, "climb_rate_m_s"),
        heading_cdeg=_heading_cdeg(m.heading_deg),
        mode=_uint(m.mode, _U32, "mode"),
    )


def _picture_data_to_pb(m: PictureData) -> pb.PictureData:
    agent_id, gps_time_ms = _ids(m)
    lat_e7, lon_e7, alt_mm = _position(m)
    return pb.PictureData(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        lat_e7=lat_e7,
        lon_e7=lon_e7,
        alt_mm=alt_mm,
        image_index=_uint(m.image_index, _U32, "image_index"),
    )


def _mode_change_request_to_pb(m: ModeChangeRequest) -> pb.ModeChangeRequest:
    agent_id, gps_time_ms = _ids(m)
    return pb.ModeChangeRequest(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        target_id=_uint(m.target_id, AGENT_ID_MAX, "target_id"),
        mode=_uint(m.mode, _U32, "mode"),
    )


def _activate_controller_to_pb(m: ActivateController) -> pb.ActivateController:
    agent_id, gps_time_ms = _ids(m)
    return pb.ActivateController(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        target_id=_uint(m.target_id, AGENT_ID_MAX, "target_id"),
        active=bool(m.active),
        start_time_ms=_uint(m.start_time_ms, _U64, "start_time_ms"),
        option=_uint(m.option, _S32_MAX, "option", low=_S32_MIN),
    )


def _agent_attitude_to_pb(m: AgentAttitude) -> pb.AgentAttitude:
    agent_id, gps_time_ms = _ids(m)
    return pb.AgentAttitude(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        roll_cdeg=_attitude_cdeg(m.roll_deg, "roll_deg"),
        pitch_cdeg=_attitude_cdeg(m.pitch_deg, "pitch_deg"),
        yaw_cdeg=_attitude_cdeg(m.yaw_deg, "yaw_deg"),
    )


def _terminate_to_pb(m: Terminate) -> pb.Terminate:
    agent_id, gps_time_ms = _ids(m)
    return pb.Terminate(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        target_id=_uint(m.target_id, AGENT_ID_MAX, "target_id"),
        reason=m.reason,
    )


def _behavior_state_to_pb(m: BehaviorState) -> pb.BehaviorState:
    agent_id, gps_time_ms = _ids(m)
    return pb.BehaviorState(
        agent_id=agent_id,
        gps_time_ms=gps_time_ms,
        active_states=list(m.active_states),
        last_event=m.last_event,
    )


def _vehicle_health_to_pb(m: VehicleHealth) -> pb.VehicleHealth:
    agent_id, gps_time_ms = _ids(m)
    severity = _uint(m.text_severity, MAX_SEVERITY_SENT, "text_severity")
    text = _text(m.text, MAX_HEALTH_TEXT_BYTES, "text")
    if severity and not text:
        raise ValueError(f"text_severity={severity} without a text")
    fields: dict[str, Any] = {
        "agent_id": agent_id,
        "gps_time_ms": gps_time_ms,
        "armed": bool(m.armed),
        "gps_fix_type": _uint(m.gps_fix_type, GPS_FIX_TYPE_MAX, "gps_fix_type"),
        "prearm": cast(pb.PrearmState, PrearmState(m.prearm).value),
        "text_severity": severity,
        "text": text,
        "failsafe": _text(m.failsafe, MAX_FAILSAFE_TEXT_BYTES, "failsafe"),
        "autopilot_lost": bool(m.autopilot_lost),
        "text_age_s": _uint(m.text_age_s, _U32, "text_age_s"),
    }
    # Absent, not zero, when unknown: proto3's optional fields keep the difference.
    if m.battery_v is not None:
        fields["battery_mv"] = _scaled(m.battery_v, 1000, 0, BATTERY_MV_MAX, "battery_v")
    if m.battery_pct is not None:
        fields["battery_remaining_pct"] = _uint(m.battery_pct, 100, "battery_pct")
    if m.satellites is not None:
        fields["satellites"] = _uint(m.satellites, SATELLITES_MAX, "satellites")
    return pb.VehicleHealth(**fields)


_TO_PB: dict[type, Callable[[Any], PbMessage]] = {
    Heartbeat: _heartbeat_to_pb,
    AgentStatus: _agent_status_to_pb,
    PictureData: _picture_data_to_pb,
    ModeChangeRequest: _mode_change_request_to_pb,
    ActivateController: _activate_controller_to_pb,
    AgentAttitude: _agent_attitude_to_pb,
    Terminate: _terminate_to_pb,
    BehaviorState: _behavior_state_to_pb,
    VehicleHealth: _vehicle_health_to_pb,
}


def _to_pb(message: Message) -> PbMessage:
    try:
        convert = _TO_PB[type(message)]
    except KeyError:
        raise TypeError(f"not a ClarkLink message: {type(message).__name__}") from None
    return convert(message)


def _varint(value: int) -> bytes:
    out = bytearray()
    while value > 0x7F:
        out.append((value & 0x7F) | 0x80)
        value >>= 7
    out.append(value)
    return bytes(out)


# --------------------------------------------------------------------------- encode API


def canonical_order(messages: Iterable[Message]) -> list[Message]:
    """The messages in bundle order: by type as in :data:`MESSAGE_ORDER`, then as given.

    Raises:
        TypeError: An item is not a ClarkLink message.
    """
    items = list(messages)
    for message in items:
        if type(message) not in _RANK:
            raise TypeError(f"not a ClarkLink message: {type(message).__name__}")
    return sorted(items, key=lambda message: _RANK[type(message)])  # sorted() is stable


def encode_entry(message: Message) -> bytes:
    """The bytes one message adds to a bundle: its field key, length and body.

    Bundles are the concatenation of entries in :func:`canonical_order`, which is
    what lets :class:`~clark_engine.link.codec.Codec` split a bundle at message
    boundaries without encoding anything twice.

    Raises:
        ValueError: A field is out of its range (a bug in the sender).
        TypeError: Not a ClarkLink message, or a field of the wrong type.
    """
    body = _to_pb(message).SerializeToString()
    return _FIELD_KEY[type(message)] + _varint(len(body)) + body


def encoded_size(message: Message) -> int:
    """Bytes ``message`` adds to a bundle (field key, length prefix and body), for the link budget.

    A bundle's size is the sum of its messages' sizes; a packet adds
    :data:`~clark_engine.link.packet.HEADER_BYTES`, and
    :data:`~clark_engine.link.packet.TAG_BYTES` when authenticated. Sizes depend
    on values (varints, zigzag), so budget with realistic ones.

    Raises:
        ValueError: A field is out of its range.
    """
    size = _to_pb(message).ByteSize()
    return 1 + len(_varint(size)) + size


def bundle_bytes(messages: Sequence[Message]) -> bytes:
    """Serialise messages into one ``Bundle``, in :func:`canonical_order`.

    An empty sequence gives ``b""``, which :func:`parse_bundle` rejects: send
    nothing rather than an empty bundle.

    Raises:
        ValueError: A field is out of its range (a bug in the sender).
        TypeError: Not a ClarkLink message, or a field of the wrong type.
    """
    return b"".join(encode_entry(message) for message in canonical_order(messages))


# --------------------------------------------------------------------------- decode


def _check(condition: bool, what: str) -> None:
    if not condition:
        raise MalformedPacket(what)


def _check_ids(p: Any, name: str) -> None:
    _check(1 <= p.agent_id <= AGENT_ID_MAX, f"{name}.agent_id {p.agent_id} is outside 1..65535")


def _check_target(p: Any, name: str) -> None:
    _check(p.target_id <= AGENT_ID_MAX, f"{name}.target_id {p.target_id} is above 65535")


def _check_position(p: Any, name: str) -> None:
    _check(-LAT_E7_MAX <= p.lat_e7 <= LAT_E7_MAX, f"{name}.lat_e7 {p.lat_e7} is beyond 90 deg")
    _check(-LON_E7_MAX <= p.lon_e7 <= LON_E7_MAX, f"{name}.lon_e7 {p.lon_e7} is beyond 180 deg")


def _heartbeat_from_pb(p: pb.Heartbeat) -> Heartbeat:
    _check_ids(p, "heartbeat")
    try:
        agent_type = AgentType(p.agent_type)
        condition = Condition(p.condition)
    except ValueError:
        raise MalformedPacket(
            f"heartbeat has an unknown agent_type {p.agent_type} or condition {p.condition}"
        ) from None
    return Heartbeat(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        mission_id=p.mission_id,
        agent_type=agent_type,
        condition=condition,
        payload_count=p.payload_count,
        clarklink_version=p.clarklink_version,
    )


def _agent_status_from_pb(p: pb.AgentStatus) -> AgentStatus:
    _check_ids(p, "agent_status")
    _check_position(p, "agent_status")
    _check(
        p.heading_cdeg <= HEADING_CDEG_MAX, f"agent_status.heading_cdeg {p.heading_cdeg} >= 360 deg"
    )
    return AgentStatus(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        lat_deg=p.lat_e7 / 1e7,
        lon_deg=p.lon_e7 / 1e7,
        alt_m=p.alt_mm / 1000,
        ground_speed_m_s=p.ground_speed_cm_s / 100,
        climb_rate_m_s=p.climb_rate_cm_s / 100,
        heading_deg=p.heading_cdeg / 100,
        mode=p.mode,
    )


def _picture_data_from_pb(p: pb.PictureData) -> PictureData:
    _check_ids(p, "picture_data")
    _check_position(p, "picture_data")
    return PictureData(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        lat_deg=p.lat_e7 / 1e7,
        lon_deg=p.lon_e7 / 1e7,
        alt_m=p.alt_mm / 1000,
        image_index=p.image_index,
    )


def _mode_change_request_from_pb(p: pb.ModeChangeRequest) -> ModeChangeRequest:
    _check_ids(p, "mode_change_request")
    _check_target(p, "mode_change_request")
    return ModeChangeRequest(
        agent_id=p.agent_id, gps_time_ms=p.gps_time_ms, target_id=p.target_id, mode=p.mode
    )


def _activate_controller_from_pb(p: pb.ActivateController) -> ActivateController:
    _check_ids(p, "activate_controller")
    _check_target(p, "activate_controller")
    return ActivateController(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        target_id=p.target_id,
        active=p.active,
        start_time_ms=p.start_time_ms,
        option=p.option,
    )


def _agent_attitude_from_pb(p: pb.AgentAttitude) -> AgentAttitude:
    _check_ids(p, "agent_attitude")
    for name in ("roll_cdeg", "pitch_cdeg", "yaw_cdeg"):
        value = getattr(p, name)
        _check(abs(value) <= ATTITUDE_CDEG_MAX, f"agent_attitude.{name} {value} is beyond 360 deg")
    return AgentAttitude(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        roll_deg=p.roll_cdeg / 100,
        pitch_deg=p.pitch_cdeg / 100,
        yaw_deg=p.yaw_cdeg / 100,
    )


def _terminate_from_pb(p: pb.Terminate) -> Terminate:
    _check_ids(p, "terminate")
    _check_target(p, "terminate")
    return Terminate(
        agent_id=p.agent_id, gps_time_ms=p.gps_time_ms, target_id=p.target_id, reason=p.reason
    )


def _behavior_state_from_pb(p: pb.BehaviorState) -> BehaviorState:
    _check_ids(p, "behavior_state")
    return BehaviorState(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        active_states=tuple(p.active_states),
        last_event=p.last_event,
    )


def _vehicle_health_from_pb(p: pb.VehicleHealth) -> VehicleHealth:
    _check_ids(p, "vehicle_health")
    try:
        prearm = PrearmState(p.prearm)
    except ValueError:
        raise MalformedPacket(f"vehicle_health has an unknown prearm {p.prearm}") from None
    for name, value, limit in (
        ("text", p.text, MAX_HEALTH_TEXT_BYTES),
        ("failsafe", p.failsafe, MAX_FAILSAFE_TEXT_BYTES),
    ):
        size = len(value.encode("utf-8"))
        _check(size <= limit, f"vehicle_health.{name} is {size} bytes, over {limit}")
    _check(
        p.text_severity <= MAX_SEVERITY_SENT and (bool(p.text) or not p.text_severity),
        f"vehicle_health.text_severity {p.text_severity} is not a warning of its text",
    )
    _check(
        p.gps_fix_type <= GPS_FIX_TYPE_MAX,
        f"vehicle_health.gps_fix_type {p.gps_fix_type} is above {GPS_FIX_TYPE_MAX}",
    )
    battery_mv = p.battery_mv if p.HasField("battery_mv") else None
    pct = p.battery_remaining_pct if p.HasField("battery_remaining_pct") else None
    satellites = p.satellites if p.HasField("satellites") else None
    _check(battery_mv is None or battery_mv <= BATTERY_MV_MAX, "vehicle_health.battery_mv")
    _check(pct is None or pct <= 100, f"vehicle_health.battery_remaining_pct {pct} is over 100")
    _check(
        satellites is None or satellites <= SATELLITES_MAX,
        f"vehicle_health.satellites {satellites} is over {SATELLITES_MAX}",
    )
    return VehicleHealth(
        agent_id=p.agent_id,
        gps_time_ms=p.gps_time_ms,
        armed=p.armed,
        battery_v=battery_mv / 1000 if battery_mv is not None else None,
        battery_pct=pct,
        gps_fix_type=p.gps_fix_type,
        satellites=satellites,
        prearm=prearm,
        text_severity=p.text_severity,
        text=p.text,
        failsafe=p.failsafe,
        autopilot_lost=p.autopilot_lost,
        text_age_s=p.text_age_s,
    )


# Bundle field name -> converter; the names are MESSAGE_NAMES (and the .proto's field names).
_FROM_PB: dict[str, Callable[[Any], Message]] = {
    MESSAGE_NAMES[Heartbeat]: _heartbeat_from_pb,
    MESSAGE_NAMES[AgentStatus]: _agent_status_from_pb,
    MESSAGE_NAMES[PictureData]: _picture_data_from_pb,
    MESSAGE_NAMES[ModeChangeRequest]: _mode_change_request_from_pb,
    MESSAGE_NAMES[ActivateController]: _activate_controller_from_pb,
    MESSAGE_NAMES[AgentAttitude]: _agent_attitude_from_pb,
    MESSAGE_NAMES[Terminate]: _terminate_from_pb,
    MESSAGE_NAMES[BehaviorState]: _behavior_state_from_pb,
    MESSAGE_NAMES[VehicleHealth]: _vehicle_health_from_pb,
}


def parse_bundle(data: bytes) -> tuple[Message, ...]:
    """Decode a ``Bundle`` into messages, by type in :data:`MESSAGE_ORDER`, then as sent.

    Recent results are remembered by their bytes: a broadcast reaches every agent of a
    simulated fleet with the same bundle, and decoding is a pure function whose result
    (frozen dataclasses) cannot be changed by whoever receives it. Each receiver's codec
    still checks the header, the tag and its own replay window before this is called.

    Raises:
        MalformedPacket: For anything that is not a bundle this engine would send:
            bytes Protocol Buffers cannot parse (including invalid UTF-8 in a
            string), an empty bundle, unknown fields, unknown enum values, or a
            value outside its range (see the module docstring). Its
            ``sender_id`` and ``mission_id`` are unset: the codec fills them in.
    """
    return _parse_bundle_cached(bytes(data))


@functools.lru_cache(maxsize=512)
def _parse_bundle_cached(data: bytes) -> tuple[Message, ...]:
    try:
        bundle = pb.Bundle.FromString(data)
    except DecodeError as exc:
        raise MalformedPacket(f"bundle does not parse: {exc}") from None
    except Exception as exc:
        # Protocol Buffers documents only DecodeError; whatever else its parser
        # raises on foreign bytes is still a malformed packet, never a crash of
        # the receive loop.
        raise MalformedPacket(f"bundle does not parse: {type(exc).__name__}") from None
    if len(UnknownFieldSet(bundle)):
        raise MalformedPacket("bundle has fields this ClarkLink version does not define")
    messages: list[Message] = []
    for field, values in bundle.ListFields():  # in field-number order
        convert = _FROM_PB[field.name]
        for value in values:
            if len(UnknownFieldSet(value)):
                raise MalformedPacket(
                    f"{field.name} has fields this ClarkLink version does not define"
                )
            messages.append(convert(value))
    if not messages:
        raise MalformedPacket("bundle is empty")
    return tuple(messages)
