"""Mission items as ArduPilot takes and stores them: what an item is and what becomes of it.

Apart from the protocol (:mod:`~clark_engine.sim.ardupilot.mission_protocol`) because it is
the items' semantics, not the transfer: :class:`MissionItem` from and to MISSION_ITEM(_INT),
the checks ArduPilot refuses an item with (:class:`MissionItemError` and its
MAV_MISSION_RESULT), how each command is stored, lossily (``_COMMANDS``, ArduPilot's C
conversions, measured on SITL; :func:`stored_mission_item`), and what the fence and rally
lists accept (:func:`fence_item`, :func:`fence_problem`, :func:`rally_item`). The mission
types, results and severities the protocol answers with are named here too, as the lowest
module of the three.
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

MISSION: Final = int(mavlink2.MAV_MISSION_TYPE_MISSION)
FENCE: Final = int(mavlink2.MAV_MISSION_TYPE_FENCE)
RALLY: Final = int(mavlink2.MAV_MISSION_TYPE_RALLY)

ACCEPTED: Final = int(mavlink2.MAV_MISSION_ACCEPTED)
ERROR: Final = int(mavlink2.MAV_MISSION_ERROR)
UNSUPPORTED_FRAME: Final = int(mavlink2.MAV_MISSION_UNSUPPORTED_FRAME)
UNSUPPORTED: Final = int(mavlink2.MAV_MISSION_UNSUPPORTED)
NO_SPACE: Final = int(mavlink2.MAV_MISSION_NO_SPACE)
INVALID: Final = int(mavlink2.MAV_MISSION_INVALID)
INVALID_PARAM1: Final = int(mavlink2.MAV_MISSION_INVALID_PARAM1)
INVALID_PARAM5_X: Final = int(mavlink2.MAV_MISSION_INVALID_PARAM5_X)
INVALID_PARAM6_Y: Final = int(mavlink2.MAV_MISSION_INVALID_PARAM6_Y)
INVALID_PARAM7: Final = int(mavlink2.MAV_MISSION_INVALID_PARAM7)
INVALID_SEQUENCE: Final = int(mavlink2.MAV_MISSION_INVALID_SEQUENCE)
DENIED: Final = int(mavlink2.MAV_MISSION_DENIED)
OPERATION_CANCELLED: Final = int(mavlink2.MAV_MISSION_OPERATION_CANCELLED)

LOCATION_ALT_MAX_M: Final = 83000.0
"""Mission altitudes must stay below this in magnitude (AP's 24-bit centimetres)."""

SEVERITY_INFO, SEVERITY_WARNING, SEVERITY_DEBUG = (
    int(mavlink2.MAV_SEVERITY_INFO),
    int(mavlink2.MAV_SEVERITY_WARNING),
    int(mavlink2.MAV_SEVERITY_DEBUG),
)
"""STATUSTEXT severities the protocol speaks with."""


# -- ArduPilot's C conversions ----------------------------------------------------------------

_FLOAT: Final = struct.Struct("<f")
_HALF: Final = struct.Struct("<e")
_INT_MIN: Final = -(2**31)
_FLT_EPSILON: Final = 1.1920928955078125e-07


def f32(value: float) -> float:
    """The float32 nearest ``value`` (a C ``float``); overflow becomes infinity."""
    try:
        return float(_FLOAT.unpack(_FLOAT.pack(value))[0])
    except OverflowError:
        return math.copysign(math.inf, value)


_E7: Final = f32(1.0e7)
_EM7: Final = f32(1.0e-7)
_HUNDRED: Final = 100.0
CENTI: Final = f32(0.01)


def _cint(value: float) -> int:
    """C's float-to-int conversion on x86-64 (cvttss2si): truncation; INT_MIN when out of range.

    Narrower integer fields keep the low bits of that, which is why 70000 stored in a
    uint16 reads back as 4464 and -1 as 65535 (both seen on SITL).
    """
    if not math.isfinite(value) or not -(2.0**31) < value < 2.0**31:
        return _INT_MIN
    return int(value)


def _u8(value: float) -> float:
    return float(_cint(value) & 0xFF)


def _i8(value: float) -> float:
    low = _cint(value) & 0xFF
    return float(low - 0x100 if low > 0x7F else low)


def _u16(value: float) -> float:
    return float(_cint(value) & 0xFFFF)


def _i16(value: float) -> float:
    low = _cint(value) & 0xFFFF
    return float(low - 0x10000 if low > 0x7FFF else low)


def _zero(value: float) -> float:
    return 0.0


def _u16_max255(value: float) -> float:
    """A uint16 then ``MIN(0xFF, v)`` (ArduPlane's waypoint radii)."""
    return float(min(_cint(value) & 0xFFFF, 0xFF))


def _half(value: float) -> float:
    """Through ArduPilot's Float16 (NAV_SCRIPT_TIME's arguments)."""
    try:
        return float(_HALF.unpack(_HALF.pack(value))[0])
    except OverflowError:
        return math.copysign(math.inf, value)


def _positive(value: float) -> float:
    """A bool of ``value > 0`` (loiter_xtrack, engine start flags)."""
    return 1.0 if value > 0 else 0.0


def _centi_u16(value: float) -> float:
    """Metres stored as uint16 centimetres, read back times 0.01f."""
    return f32((_cint(f32(f32(value) * _HUNDRED)) & 0xFFFF) * CENTI)


def _bit0(value: float) -> float:
    return float(_cint(value) & 1)


def _signed_u16(value: float) -> float:
    """A radius kept as uint16 magnitude plus a counter-clockwise flag (value < 0)."""
    magnitude = _u16(abs(value))
    return -magnitude if value < 0 else magnitude


def _ccw_sign(value: float) -> float:
    """Only the direction survives: -1 counter-clockwise (value < 0), else 1."""
    return -1.0 if value < 0 else 1.0


def _land_yaw(value: float) -> float:
    """NAV_LAND's param4: -1 when negative beyond FLT_EPSILON, else 1 (NaN included)."""
    return -1.0 if value <= -_FLT_EPSILON else 1.0


def _clamp_u16(value: float) -> float:
    if math.isnan(value):
        return 0.0
    return float(_cint(min(max(value, 0.0), 65535.0)))


def _within(limit_low: float, limit_high: float) -> Callable[[float], float]:
    def keep(value: float) -> float:
        return _i16(value) if limit_low <= value <= limit_high else 0.0

    return keep


_F = f32
_Z = _zero
Params = tuple[float, float, float, float]
Codec = Callable[[float], float]


def _each(p1: Codec, p2: Codec, p3: Codec, p4: Codec) -> Callable[[Params], Params]:
    def convert(params: Params) -> Params:
        return (p1(params[0]), p2(params[1]), p3(params[2]), p4(params[3]))

    return convert


def _loiter_turns(params: Params) -> Params:
    """NAV_LOITER_TURNS: turns and radius share one uint16; radii over 255 m lose a digit."""
    turns = _cint(min(255.0, params[0])) & 0xFFFF
    radius = abs(params[2])
    big = radius > 255
    radius_byte = _cint(min(255.0, radius * 0.1) if big else radius) & 0xFF
    packed = (turns | (radius_byte << 8)) & 0xFFFF
    radius_back = float((packed >> 8) & 0xFF)
    if params[2] < 0:
        radius_back = -radius_back
    if big:
        radius_back *= 10
    return (float(packed & 0xFF), 0.0, radius_back, _positive(params[3]))


@dataclass(frozen=True, slots=True)
class _Command:
    """How ArduPilot stores one MAV_CMD: what a download gives back for what was sent."""

    name: str
    """What "Mission: N <name>" prints when it starts."""
    params: Callable[[Params], Params]
    located: bool = False
    """Kept in AP's location (x, y, altitude in cm, frame flags)."""
    x: Callable[[int], int] | None = None
    """For other commands: what is kept of x (None: nothing)."""
    y: Callable[[int], int] | None = None
    z: Callable[[float], float] | None = None


def _x_u8(value: int) -> int:
    return value & 0xFF


def _x_i16(value: int) -> int:
    low = value & 0xFFFF
    return low - 0x10000 if low > 0x7FFF else low


def _z_u8(value: float) -> float:
    return float(_cint(value) & 0xFF)


def _z_mount(value: float) -> float:
    return 2.0  # MAV_MOUNT_MODE_MAVLINK_TARGETING, whatever was sent (measured)


_P1_U16: Final = _each(_u16, _Z, _Z, _Z)
_NONE: Final = _each(_Z, _Z, _Z, _Z)

_COMMANDS: Final[Mapping[int, _Command]] = {
    16: _Command("WP", _P1_U16, located=True),
    17: _Command("LoitUnlim", _each(_Z, _Z, _signed_u16, _Z), located=True),
    18: _Command("LoitTurns", _loiter_turns, located=True),
    19: _Command("LoitTime", _each(_u16, _Z, _ccw_sign, _positive), located=True),
    20: _Command("RTL", _NONE),
    21: _Command("Land", _each(_u16, _Z, _Z, _land_yaw), located=True),
    22: _Command("Takeoff", _P1_U16, located=True),
    30: _Command("ContinueAndChangeAlt", _P1_U16, located=True),
    31: _Command("LoitAltitude", _each(_Z, _signed_u16, _Z, _positive), located=True),
    82: _Command("SplineWP", _P1_U16, located=True),
    83: _Command("AltitudeWait", _each(_F, _F, _u8, _Z)),
    84: _Command("VTOLTakeoff", _NONE, located=True),
    85: _Command("VTOLLand", _P1_U16, located=True),
    92: _Command("GuidedEnable", _P1_U16, located=True),
    93: _Command("Delay", _each(_F, _i8, _i8, _i8)),
    94: _Command("PayloadPlace", _each(_centi_u16, _Z, _Z, _Z), located=True),
    112: _Command("CondDelay", _each(_F, _Z, _Z, _Z)),
    114: _Command("CondDist", _each(_F, _Z, _Z, _Z)),
    115: _Command("CondYaw", _each(_F, _F, _i8, _u8)),
    177: _Command("Jump", _each(_u16, _i16, _Z, _Z)),
    178: _Command("ChangeSpeed", _each(_u8, _F, _F, _Z)),
    179: _Command("SetHome", _P1_U16, located=True),
    181: _Command("SetRelay", _each(_u8, _u8, _Z, _Z)),
    182: _Command("RepeatRelay", _each(_u8, _i16, _F, _Z)),
    183: _Command("SetServo", _each(_u8, _u16, _Z, _Z)),
    184: _Command("RepeatServo", _each(_u8, _u16, _i16, _F)),
    188: _Command("ReturnPathStart", _NONE, located=True),
    189: _Command("LandStart", _NONE, located=True),
    191: _Command("Go Around", _NONE, located=True),
    193: _Command("PauseContinue", _P1_U16),
    194: _Command("SetReverse", _P1_U16),
    195: _Command("SetROILocation", _P1_U16, located=True),
    197: _Command("SetROINone", _P1_U16),
    201: _Command("SetROI", _P1_U16, located=True),
    202: _Command("DigiCamCfg", _each(_u8, _u16, _u8, _u16), x=_x_u8, y=_x_u8, z=f32),
    203: _Command("DigiCamCtrl", _each(_u8, _u8, _i8, _u8), x=_x_u8, y=_x_u8),
    205: _Command("MountControl", _each(_F, _F, _F, _Z), z=_z_mount),
    206: _Command("SetCamTrigDst", _each(_F, _Z, _u8, _Z)),
    207: _Command("FenceEnable", _P1_U16),
    208: _Command("Parachute", _P1_U16),
    210: _Command("InvertedFlight", _P1_U16),
    211: _Command("Gripper", _each(_u8, _u8, _Z, _Z)),
    212: _Command("AutoTuneEnable", _P1_U16),
    213: _Command("SetYawSpd", _each(_F, _F, _u8, _Z)),
    215: _Command("SetRepeatDist", _P1_U16),
    216: _Command("Sprayer", _P1_U16),
    217: _Command("Scripting", _each(_u16, _F, _F, _F)),
    218: _Command("AuxFunction", _each(_u16, _u8, _Z, _Z)),
    222: _Command("GuidedLimits", _each(_u16, _F, _F, _F)),
    223: _Command("EngineControl", _each(_positive, _positive, _centi_u16, _bit0)),
    531: _Command("SetCameraZoom", _each(_u8, _F, _Z, _Z)),
    532: _Command("SetCameraFocus", _each(_u8, _F, _Z, _Z)),
    534: _Command("SetCameraSource", _each(_u8, _u8, _u8, _Z)),
    600: _Command("Tag", _P1_U16),
    601: _Command("JumpTag", _each(_u16, _i16, _Z, _Z)),
    1000: _Command("GimbalPitchYaw", _each(_i8, _i8, _i8, _i8), x=_x_u8, z=_z_u8),
    2000: _Command("ImageStartCapture", _each(_u8, _F, _u16, _u16)),
    2001: _Command("ImageStopCapture", _P1_U16),
    2500: _Command("VideoStartCapture", _each(_u8, _Z, _Z, _Z)),
    2501: _Command("VideoStopCapture", _each(_u8, _Z, _Z, _Z)),
    3000: _Command("VTOLTransition", _each(_u8, _Z, _Z, _Z)),
    42600: _Command("Winch", _each(_u8, _u8, _F, _F)),
    42702: _Command("NavScriptTime", _each(_u8, _u8, _half, _half), x=_x_i16, y=_x_i16),
    42703: _Command(
        "NavAttitudeTime",
        _each(_clamp_u16, _within(-180, 180), _within(-90, 90), _within(-180, 360)),
        x=_x_i16,
    ),
}
"""Every command AP_Mission stores (ArduCopter, ArduRover), with what survives storage.

Measured: each MAV_CMD of the dialect uploaded with five sets of values and read back on
SITL; every command not here is refused with UNSUPPORTED. Names are what SITL printed
("Tag" is printed with a number this table does not reproduce).
"""

_PLANE_COMMANDS: Final[Mapping[int, _Command]] = {
    **{cmd: spec for cmd, spec in _COMMANDS.items() if cmd != 82},  # no spline waypoints
    16: _Command("WP", _each(_Z, _u16_max255, _u16_max255, _Z), located=True),
}
"""ArduPlane: waypoints keep the acceptance and pass-by radii (0-255 m), not a delay."""

_PARAM_MAY_BE_NAN: Final[Mapping[int, frozenset[int]]] = {
    16: frozenset({3}),
    21: frozenset({3}),
    22: frozenset({3}),
    84: frozenset({3}),
    85: frozenset({2, 3}),
}
"""AP_Mission::sanity_check_params: the parameters a command may leave NaN (0-based)."""

_LOCATION_FRAMES: Final[Mapping[int, int]] = {
    int(mavlink2.MAV_FRAME_GLOBAL): 0,
    int(mavlink2.MAV_FRAME_MISSION): 0,
    int(mavlink2.MAV_FRAME_GLOBAL_INT): 0,
    int(mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT): 3,
    int(mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT): 3,
    int(mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT): 10,
    int(mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT): 10,
}
"""Frames a located command accepts, and the frame a download gives back for each."""

_RAW_XY_COMMANDS: Final = frozenset({202, 203, 42703, 1000})
"""Commands whose x and y are not latitude and longitude (MISSION_ITEM passes them as is)."""

_NAV_LAST: Final = int(mavlink2.MAV_CMD_NAV_LAST)
DO_JUMP: Final = int(mavlink2.MAV_CMD_DO_JUMP)


def is_nav_command(command: int) -> bool:
    """Whether AP_Mission treats ``command`` as a navigation command (AP_Mission::is_nav_cmd)."""
    return command <= _NAV_LAST or command in (213, 42702, 42703)


def command_name(command: int) -> str:
    """The name ArduPilot prints for ``command`` in "Mission: N <name>" ("?" if it has none)."""
    spec = _COMMANDS.get(command)
    return "?" if spec is None else spec.name


def _check_lat_e7(value: int) -> bool:
    return abs(value) <= 900_000_000


def _check_lng_e7(value: int) -> bool:
    return abs(value) <= 1_800_000_000


# -- items ------------------------------------------------------------------------------------


class MissionItemError(ValueError):
    """ArduPilot refuses to convert an item; ``result`` is the MAV_MISSION_RESULT it answers."""

    def __init__(self, result: int, message: str) -> None:
        super().__init__(message)
        self.result = result


@dataclass(frozen=True, slots=True)
class MissionItem:
    """One item as MISSION_ITEM_INT carries it.

    ``x`` and ``y`` are degrees times 1e7 for located commands (and integers with other
    meanings for a few others); ``z`` is metres in ``frame``.
    """

    seq: int
    """Position in its list; 0 is home in a mission."""
    frame: int
    """MAV_FRAME of ``z`` (and of x and y); stored missions use 0, 3 or 10 only."""
    command: int
    """MAV_CMD."""
    current: int
    """1 on the item being flown in a download (as ArduPilot computes it); 2 and 3 in an
    uploaded item mean a guided-mode target and an altitude change."""
    autocontinue: int
    param1: float
    param2: float
    param3: float
    param4: float
    x: int
    """Latitude in degrees times 1e7 for located commands."""
    y: int
    """Longitude in degrees times 1e7 for located commands."""
    z: float
    """Altitude in metres, in ``frame``."""
    mission_type: int = MISSION
    """MAV_MISSION_TYPE: 0 mission, 1 fence, 2 rally points."""

    @classmethod
    def from_mission_item_int(cls, msg: Any) -> MissionItem:
        """The item a MISSION_ITEM_INT message carries, as sent."""
        return cls(
            seq=int(msg.seq),
            frame=int(msg.frame),
            command=int(msg.command),
            current=int(msg.current),
            autocontinue=int(msg.autocontinue),
            param1=float(msg.param1),
            param2=float(msg.param2),
            param3=float(msg.param3),
            param4=float(msg.param4),
            x=int(msg.x),
            y=int(msg.y),
            z=float(msg.z),
            mission_type=int(msg.mission_type),
        )

    @classmethod
    def from_mission_item(cls, msg: Any) -> MissionItem:
        """The item a legacy MISSION_ITEM message carries, converted as ArduPilot converts it.

        Latitude and longitude are checked as float32 degrees, then multiplied by 1e7 in
        float32 and truncated (30.6372123 becomes 306372128, as on SITL); the commands
        whose x and y are not a position keep them truncated to integers.

        Raises:
            MissionItemError: The latitude or longitude is out of range
                (INVALID_PARAM5_X, INVALID_PARAM6_Y).
        """
        command = int(msg.command)
        if command in _RAW_XY_COMMANDS:
            x, y = _cint(float(msg.x)), _cint(float(msg.y))
        else:
            lat, lon = f32(float(msg.x)), f32(float(msg.y))
            if not abs(lat) <= 90.0:
                raise MissionItemError(INVALID_PARAM5_X, f"latitude {lat} out of range")
            if not abs(lon) <= 180.0:
                raise MissionItemError(INVALID_PARAM6_Y, f"longitude {lon} out of range")
            x, y = _cint(f32(lat * _E7)), _cint(f32(lon * _E7))
        return cls(
            seq=int(msg.seq),
            frame=int(msg.frame),
            command=command,
            current=int(msg.current),
            autocontinue=int(msg.autocontinue),
            param1=float(msg.param1),
            param2=float(msg.param2),
            param3=float(msg.param3),
            param4=float(msg.param4),
            x=x,
            y=y,
            z=float(msg.z),
            mission_type=int(msg.mission_type),
        )

    @property
    def lat_deg(self) -> float:
        """Latitude in degrees (for located commands)."""
        return self.x / 1e7

    @property
    def lon_deg(self) -> float:
        """Longitude in degrees (for located commands)."""
        return self.y / 1e7

    @property
    def is_nav(self) -> bool:
        """Whether ArduPilot flies this item (a navigation command) rather than doing it."""
        return is_nav_command(self.command)

    def mission_item_int(self, mav: Any, target_system: int, target_component: int) -> Any:
        """This item as a MISSION_ITEM_INT message, encoded by ``mav``."""
        return mav.mission_item_int_encode(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            self.x,
            self.y,
            self.z,
            self.mission_type,
        )

    def mission_item(self, mav: Any, target_system: int, target_component: int) -> Any:
        """This item as a legacy MISSION_ITEM message (float32 degrees), as ArduPilot sends it.

        Raises:
            MissionItemError: The position does not convert back to valid degrees.
        """
        if self.command in _RAW_XY_COMMANDS:
            x, y = f32(float(self.x)), f32(float(self.y))
        else:
            x, y = f32(f32(float(self.x)) * _EM7), f32(f32(float(self.y)) * _EM7)
            if not abs(x) <= 90.0:
                raise MissionItemError(INVALID_PARAM5_X, f"latitude {x} out of range")
            if not abs(y) <= 180.0:
                raise MissionItemError(INVALID_PARAM6_Y, f"longitude {y} out of range")
        return mav.mission_item_encode(
            target_system,
            target_component,
            self.seq,
            self.frame,
            self.command,
            self.current,
            self.autocontinue,
            self.param1,
            self.param2,
            self.param3,
            self.param4,
            x,
            y,
            self.z,
            self.mission_type,
        )


def stored_mission_item(item: MissionItem, firmware: str = "arducopter") -> MissionItem:
    """``item`` as ``firmware``'s AP_Mission stores it, i.e. as a download gives it back.

    Raises:
        MissionItemError: ArduPilot refuses the item, with the MAV_MISSION_RESULT it
            answers (AP_Mission::mavlink_int_to_mission_cmd, in its order of checks).
    """
    params = (item.param1, item.param2, item.param3, item.param4)
    may_be_nan = _PARAM_MAY_BE_NAN.get(item.command, frozenset())
    for index, value in enumerate(params):
        if math.isinf(value) or (math.isnan(value) and index not in may_be_nan):
            raise MissionItemError(INVALID_PARAM1 + index, f"param{index + 1} is {value}")
    if item.command in (0, 1):
        raise MissionItemError(INVALID, f"command {item.command} is reserved")
    table = _PLANE_COMMANDS if firmware == "arduplane" else _COMMANDS
    spec = table.get(item.command)
    if spec is None:
        raise MissionItemError(UNSUPPORTED, f"command {item.command} is not supported")
    p1, p2, p3, p4 = spec.params(params)
    if spec.located:
        if not _check_lat_e7(item.x):
            raise MissionItemError(INVALID_PARAM5_X, f"latitude {item.x} out of range")
        if not _check_lng_e7(item.y):
            raise MissionItemError(INVALID_PARAM6_Y, f"longitude {item.y} out of range")
        if math.isnan(item.z) or abs(f32(item.z)) >= LOCATION_ALT_MAX_M:
            raise MissionItemError(INVALID_PARAM7, f"altitude {item.z} out of range")
        frame = _LOCATION_FRAMES.get(item.frame)
        if frame is None:
            raise MissionItemError(UNSUPPORTED_FRAME, f"frame {item.frame} is not supported")
        altitude_cm = _cint(f32(f32(item.z) * _HUNDRED))
        x, y, z = item.x, item.y, f32(altitude_cm * CENTI)
    else:
        frame = 0
        x = 0 if spec.x is None else spec.x(item.x)
        y = 0 if spec.y is None else spec.y(item.y)
        z = 0.0 if spec.z is None else spec.z(item.z)
    return MissionItem(
        seq=item.seq,
        frame=frame,
        command=item.command,
        current=0,
        autocontinue=1,
        param1=f32(p1),
        param2=f32(p2),
        param3=f32(p3),
        param4=f32(p4),
        x=x,
        y=y,
        z=z,
        mission_type=MISSION,
    )


# -- fence and rally items ------------------------------------------------------------------


class _FenceType(enum.IntEnum):
    """AC_PolyFenceType, numbered as ArduPilot prints them in its warnings."""

    POLYGON_INCLUSION = 98
    POLYGON_EXCLUSION = 97
    CIRCLE_EXCLUSION = 93
    RETURN_POINT = 95
    CIRCLE_INCLUSION = 92


_FENCE_COMMANDS: Final[Mapping[int, _FenceType]] = {
    int(mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION): _FenceType.POLYGON_INCLUSION,
    int(mavlink2.MAV_CMD_NAV_FENCE_POLYGON_VERTEX_EXCLUSION): _FenceType.POLYGON_EXCLUSION,
    int(mavlink2.MAV_CMD_NAV_FENCE_RETURN_POINT): _FenceType.RETURN_POINT,
    int(mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_INCLUSION): _FenceType.CIRCLE_INCLUSION,
    int(mavlink2.MAV_CMD_NAV_FENCE_CIRCLE_EXCLUSION): _FenceType.CIRCLE_EXCLUSION,
}
_FENCE_FRAMES: Final = frozenset({0, 3, 5, 6, 10, 11})
_RALLY_FRAMES: Final[Mapping[int, int]] = {0: 0, 5: 0, 3: 3, 6: 3, 10: 10, 11: 10}
_RALLY_POINT: Final = int(mavlink2.MAV_CMD_NAV_RALLY_POINT)


def fence_item(item: MissionItem) -> MissionItem:
    """A fence item as AC_PolyFence_loader stores it (frame 0, no altitude, autocontinue 0).

    Raises:
        MissionItemError: Unsupported frame or command, or a vertex count over 255.
    """
    if item.frame not in _FENCE_FRAMES:
        raise MissionItemError(UNSUPPORTED_FRAME, f"frame {item.frame} is not a fence frame")
    kind = _FENCE_COMMANDS.get(item.command)
    if kind is None:
        raise MissionItemError(UNSUPPORTED, f"command {item.command} is not a fence item")
    if kind in (_FenceType.POLYGON_INCLUSION, _FenceType.POLYGON_EXCLUSION):
        if item.param1 > 255:
            raise MissionItemError(INVALID_PARAM1, f"vertex count {item.param1}")
        param1 = _u8(item.param1)
    elif kind == _FenceType.RETURN_POINT:
        param1 = 0.0
    else:
        param1 = f32(item.param1)
    return MissionItem(
        seq=item.seq,
        frame=0,
        command=item.command,
        current=0,
        autocontinue=0,
        param1=param1,
        param2=0.0,
        param3=0.0,
        param4=0.0,
        x=item.x,
        y=item.y,
        z=0.0,
        mission_type=FENCE,
    )


def fence_problem(items: Sequence[MissionItem]) -> str | None:
    """AC_PolyFence_loader::validate_fence: the WARNING it prints, None for a valid fence."""
    expecting: _FenceType | None = None
    expected_left = 0
    vertex_count = 0
    seen_return_point = False
    for item in items:
        kind = _FENCE_COMMANDS[item.command]
        if kind in (_FenceType.POLYGON_INCLUSION, _FenceType.POLYGON_EXCLUSION):
            count = int(item.param1)
            if count < 3:
                return f"Invalid vertex count ({count})"
            if expected_left == 0:
                expected_left = vertex_count = count
                expecting = kind
            elif kind != expecting:
                assert expecting is not None
                return f"Received incorrect vertex type (want={expecting.value} got={kind.value})"
            elif count != vertex_count:
                return f"Unexpected vertex count want={vertex_count} got={count}\n"
            expected_left -= 1
        elif expected_left:
            assert expecting is not None
            return f"Received incorrect type (want={expecting.value} got={kind.value})"
        elif kind == _FenceType.RETURN_POINT:
            if seen_return_point:
                return "Multiple return points"
            seen_return_point = True
        elif not item.param1 >= _FLT_EPSILON:  # AP's is_positive()
            return "Non-positive circle radius"
        if not (_check_lat_e7(item.x) and _check_lng_e7(item.y)):
            return "Bad lat or lon"
    if expected_left:
        return "Incorrect item count"  # (INFO, the others are WARNINGs)
    return None


def rally_item(item: MissionItem) -> MissionItem:
    """A rally point as AP_Rally stores it: position, whole metres (int16), frame folded.

    Raises:
        MissionItemError: Not a rally point, unsupported frame, position or altitude out
            of range.
    """
    if item.command != _RALLY_POINT:
        raise MissionItemError(UNSUPPORTED, f"command {item.command} is not a rally point")
    frame = _RALLY_FRAMES.get(item.frame)
    if frame is None:
        raise MissionItemError(UNSUPPORTED_FRAME, f"frame {item.frame} is not a rally frame")
    if not _check_lat_e7(item.x):
        raise MissionItemError(INVALID_PARAM5_X, f"latitude {item.x} out of range")
    if not _check_lng_e7(item.y):
        raise MissionItemError(INVALID_PARAM6_Y, f"longitude {item.y} out of range")
    altitude = f32(item.z)
    if altitude < -32768.0 or altitude > 32767.0:  # (NaN passes, as in ArduPilot)
        raise MissionItemError(INVALID_PARAM7, f"altitude {item.z} out of range")
    return MissionItem(
        seq=item.seq,
        frame=frame,
        command=_RALLY_POINT,
        current=0,
        autocontinue=0,
        param1=0.0,
        param2=0.0,
        param3=0.0,
        param4=0.0,
        x=item.x,
        y=item.y,
        z=_i16(altitude),
        mission_type=RALLY,
    )
