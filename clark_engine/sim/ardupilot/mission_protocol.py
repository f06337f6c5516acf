"""ArduPilot's mission protocol, for the simulated autopilot to delegate to.

:class:`MissionProtocol` answers the MAVLink mission sub-protocol (upload, download,
partial update, clear, current item) for the three item lists ArduPilot keeps: the
mission, the fence and the rally points. It also keeps the mission's execution
cursor (AP_Mission's state and current navigation command), because what a ground
station reads back (MISSION_CURRENT, a download's ``current`` flag, what
MISSION_SET_CURRENT does) depends on it.

It is pure and deterministic: no clock, no socket. The autopilot hands it messages
with :meth:`MissionProtocol.handle` and calls :meth:`MissionProtocol.poll` as time
passes, both with the virtual time; replies are encoded with the autopilot's own
pymavlink ``MAVLink`` object (so they carry its ids and sequence numbers) and
STATUSTEXTs go through the autopilot's ``text`` callable, after the MAVLink replies
of the same step, in the order ArduPilot's queues deliver them.

What it follows was measured on ArduPilot SITL (4.7.0-dev, 90700977, the build in
``../shared/ardupilot-sitl``: copter, plane and rover), and read in ArduPilot's
MissionItemProtocol.cpp, MissionItemProtocol_{Waypoints,Fence,Rally}.cpp,
AP_Mission.cpp and AC_PolyFence_loader.cpp where SITL agreed:

- **Upload**: MISSION_COUNT is answered with MISSION_REQUEST (#40, never
  MISSION_REQUEST_INT), item by item, each request sent as the previous item is
  stored. The list is truncated to the new count as soon as MISSION_COUNT arrives
  (a failed upload leaves the old items beyond what was replaced). The end is
  MISSION_ACK ACCEPTED, then INFO "Flight plan received" (missions), DEBUG "Fence
  Indexed OK" (fences), nothing (rally points). MISSION_COUNT 0 is the same at once.
  An item whose seq is not the one requested: MISSION_ACK INVALID_SEQUENCE, the
  upload goes on. An item or MISSION_COUNT from another system or component during
  an upload: DENIED, the upload goes on; from the uploader, a new MISSION_COUNT
  restarts it. An item ArduPilot refuses (unsupported command or frame, NaN or
  infinite parameter, latitude, longitude or altitude out of range, a DO_JUMP to
  nowhere) ends the upload with that MAV_MISSION_RESULT. More items than storage:
  NO_SPACE and WARNING "Only N items are supported" (ending an upload under way;
  650 mission items on
  ArduCopter, 655 on ArduPlane and ArduRover; fences 70/84; rally points 46/50).
  A legacy MISSION_ITEM is taken (its float latitude and longitude multiplied in
  float32 as ArduPilot does) with WARNING "got MISSION_ITEM; GCS should send
  MISSION_ITEM_INT" once per upload (outside an upload too, with its ERROR).
- **Lost items**: the pending MISSION_REQUEST is sent again once more than 1 s
  passed since the last one; more than 8 s after the last item (or the
  MISSION_COUNT) the upload ends with MISSION_ACK OPERATION_CANCELLED to the
  uploader and WARNING "Mission upload timeout" ("Fence upload timeout", "Rally
  upload timeout"). Measured: requests at +0, 0.96, 2.0, 2.96, ... 6.96 s, the
  cancel at +8.0 s; an item at 7.5 s moves the deadline to 15.5 s.
- **Download**: MISSION_REQUEST_LIST gives MISSION_COUNT (missions: including
  home, 0 until home is set and after a clear). MISSION_REQUEST_INT gives
  MISSION_ITEM_INT; item 0 is always readable and is the current home (frame 0,
  z the home altitude above mean sea level; zeros before home is set). A seq out
  of range gives MISSION_COUNT (to tell the ground station the real size) and
  MISSION_ACK INVALID_SEQUENCE; the legacy MISSION_REQUEST gives MISSION_ITEM
  (float32 degrees), or only the ACK when out of range, with WARNING "got
  MISSION_REQUEST; use MISSION_REQUEST_INT!" once until the next upload. Requests
  during an upload: DENIED. Items come back as ArduPilot stores them, which is
  lossy: each command keeps only some parameters, as integers of a given width,
  altitudes in whole centimetres, frames folded to 0, 3 or 10, autocontinue 1
  (see ``_COMMANDS``, checked against a sweep of every MAV_CMD on SITL); and
  ``current`` is 1 on every item whose *command number* equals the current
  navigation index (ArduPilot compares the command id with the index).
- **Clear**: MISSION_CLEAR_ALL gives MISSION_ACK ACCEPTED and leaves 0 items
  (not 1: home comes back at the next home change). It stops a running mission.
  During an upload, from the uploader it cancels the upload and clears; from
  anyone else it is answered DENIED and then ERROR and the upload goes on.
- **Partial update** (MISSION_WRITE_PARTIAL_LIST): requests start..end; a range
  beyond the list is MISSION_ACK ERROR and WARNING "Flight plan update rejected".
- **Current item**: MISSION_SET_CURRENT is answered with MISSION_CURRENT at once
  (carrying the seq asked for; 0 becomes 1 in the state), nothing when out of
  range. Setting the current item follows AP_Mission::set_current_cmd: it lands on
  the first navigation command at or after the seq, and a stopped or complete
  mission becomes stopped there.
- **MISSION_CURRENT** (seq, total, mission_state, mission_mode): total counts items
  without home; no items: (0, 0, 1, m); otherwise state 2 stopped (also just after
  an upload, seq 0), 3 running, 5 complete, which stays after AUTO is left
  (ArduCopter (2, 2, 5, 0)) and after a new upload; mission_mode is 1 in AUTO.
- **Mission types**: fence (1) and rally (2) are kept apart and never touch the
  mission. A fence is validated when complete as AC_PolyFence_loader does (ERROR
  and its WARNINGs, "Fence validation failed"; the old fence stays). Any other
  type: MISSION_ACK UNSUPPORTED to lists, counts, clears and items, and silence to
  requests.
- **Execution** (AP_Mission): start, resume, stop, reset, advance and DO_JUMP
  counting, with INFO "Mission: N <name>" as each command starts.

Not simulated: MAVLink 1 links (fences and rally points need MAVLink 2; every peer
here speaks it), the request resend slowing down on a congested link, the fence
storage-size check, MAV_CMD_DO_SET_RESUME_REPEAT_DIST's rewinding, the
vehicle-specific start and verify of commands (the autopilot does those; DO
commands are taken to finish at once, so a CONDITION_* item only affects when its
"Mission:" text is printed).
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
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

UPLOAD_TIMEOUT_S: Final = 8.0
"""An upload ends this long after the last item (MissionItemProtocol's upload_timeout_ms)."""
REREQUEST_S: Final = 1.0
"""The pending MISSION_REQUEST is sent again once more than this passed since the last."""
LOCATION_ALT_MAX_M: Final = 83000.0
"""Mission altitudes must stay below this in magnitude (AP's 24-bit centimetres)."""

_INFO, _WARNING, _DEBUG = (
    int(mavlink2.MAV_SEVERITY_INFO),
    int(mavlink2.MAV_SEVERITY_WARNING),
    int(mavlink2.MAV_SEVERITY_DEBUG),
)


@dataclass(frozen=True, slots=True)
class ItemLimits:
    """How many items of each type a firmware's storage takes (measured on SITL)."""

    mission: int
    """Mission items, home included."""
    fence: int
    """Fence items."""
    rally: int
    """Rally points."""


ITEM_LIMITS: Final[Mapping[str, ItemLimits]] = {
    "arducopter": ItemLimits(mission=650, fence=70, rally=46),
    "arduplane": ItemLimits(mission=655, fence=84, rally=50),
    "ardurover": ItemLimits(mission=655, fence=84, rally=50),
}
"""Storage limits per firmware: what "Only N items are supported" says on SITL."""


class MissionState(enum.IntEnum):
    """AP_Mission's state, numbered as MISSION_CURRENT reports it (MISSION_STATE)."""

    STOPPED = int(mavlink2.MISSION_STATE_NOT_STARTED)
    RUNNING = int(mavlink2.MISSION_STATE_ACTIVE)
    COMPLETE = int(mavlink2.MISSION_STATE_COMPLETE)


# -- ArduPilot's C conversions ----------------------------------------------------------------

_FLOAT: Final = struct.Struct("<f")
_HALF: Final = struct.Struct("<e")
_INT_MIN: Final = -(2**31)
_FLT_EPSILON: Final = 1.1920928955078125e-07


def _f32(value: float) -> float:
    """The float32 nearest ``value`` (a C ``float``); overflow becomes infinity."""
    try:
        return float(_FLOAT.unpack(_FLOAT.pack(value))[0])
    except OverflowError:
        return math.copysign(math.inf, value)


_E7: Final = _f32(1.0e7)
_EM7: Final = _f32(1.0e-7)
_HUNDRED: Final = 100.0
_CENTI: Final = _f32(0.01)


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
    return _f32((_cint(_f32(_f32(value) * _HUNDRED)) & 0xFFFF) * _CENTI)


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


_F = _f32
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
    202: _Command("DigiCamCfg", _each(_u8, _u16, _u8, _u16), x=_x_u8, y=_x_u8, z=_f32),
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
_DO_JUMP: Final = int(mavlink2.MAV_CMD_DO_JUMP)
_JUMP_REPEAT_FOREVER: Final = -1
_JUMP_TIMES_MAX: Final = 32767
_MAX_JUMP_COMMANDS: Final = 100
"""AP_MISSION_MAX_NUM_DO_JUMP_COMMANDS on boards with SITL's memory class."""


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
            lat, lon = _f32(float(msg.x)), _f32(float(msg.y))
            if not abs(lat) <= 90.0:
                raise MissionItemError(INVALID_PARAM5_X, f"latitude {lat} out of range")
            if not abs(lon) <= 180.0:
                raise MissionItemError(INVALID_PARAM6_Y, f"longitude {lon} out of range")
            x, y = _cint(_f32(lat * _E7)), _cint(_f32(lon * _E7))
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
            x, y = _f32(float(self.x)), _f32(float(self.y))
        else:
            x, y = _f32(_f32(float(self.x)) * _EM7), _f32(_f32(float(self.y)) * _EM7)
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
        if math.isnan(item.z) or abs(_f32(item.z)) >= LOCATION_ALT_MAX_M:
            raise MissionItemError(INVALID_PARAM7, f"altitude {item.z} out of range")
        frame = _LOCATION_FRAMES.get(item.frame)
        if frame is None:
            raise MissionItemError(UNSUPPORTED_FRAME, f"frame {item.frame} is not supported")
        altitude_cm = _cint(_f32(_f32(item.z) * _HUNDRED))
        x, y, z = item.x, item.y, _f32(altitude_cm * _CENTI)
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
        param1=_f32(p1),
        param2=_f32(p2),
        param3=_f32(p3),
        param4=_f32(p4),
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


def _fence_item(item: MissionItem) -> MissionItem:
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
        param1 = _f32(item.param1)
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


def _fence_problem(items: Sequence[MissionItem]) -> str | None:
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


def _rally_item(item: MissionItem) -> MissionItem:
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
    altitude = _f32(item.z)
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


# -- the protocol ------------------------------------------------------------------------------


@dataclass(slots=True)
class _Upload:
    """One transfer from a ground station (MissionItemProtocol's receiving state)."""

    system_id: int
    component_id: int
    next_seq: int
    last_seq: int
    last_receive_s: float
    last_request_s: float


class _ItemList:
    """One of ArduPilot's MissionItemProtocol objects (mission, fence or rally points).

    The generic transfer logic lives here; the subclasses store items their own way.
    """

    mission_type: int
    timeout_text: str

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        self.owner = owner
        self.max_items = max_items
        self.upload: _Upload | None = None
        self.item_warning_sent = False
        self.request_warning_sent = False

    # storage, per type

    def count(self) -> int:
        raise NotImplementedError

    def begin(self, count: int) -> None:
        """Resources for a new upload of ``count`` items (allocate_receive_resources)."""

    def begin_update(self) -> None:
        """Resources for a partial update (allocate_update_resources)."""

    def end(self) -> None:
        """Free what begin() took (free_upload_resources)."""

    def truncate(self, count: int) -> None:
        raise NotImplementedError

    def store(self, item: MissionItem, append: bool) -> int:
        raise NotImplementedError

    def complete(self) -> int:
        raise NotImplementedError

    def clear_all(self) -> bool:
        raise NotImplementedError

    def get(self, seq: int) -> MissionItem | None:
        raise NotImplementedError

    # the protocol, as MissionItemProtocol.cpp

    @property
    def receiving(self) -> bool:
        return self.upload is not None

    def handle_count(self, msg: Any, count: int, now_s: float) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            if source != (self.upload.system_id, self.upload.component_id):
                self.owner._ack(source, DENIED, self.mission_type)
                return
            self.upload = None  # the uploader starts again (or gives up, if refused below)
            self.end()
        if count > self.max_items:
            self.owner._ack(source, NO_SPACE, self.mission_type)
            self.owner._say(_WARNING, f"Only {self.max_items} items are supported")
            return
        self.begin(count)
        self.truncate(count)
        if count == 0:
            self._transfer_complete(source)
            return
        self._start_requests(source, 0, count - 1, now_s)

    def handle_partial(self, msg: Any, start: int, end: int, now_s: float) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        count = self.count()
        start_u, end_u = start & 0xFFFF, end & 0xFFFF  # int16 compared as unsigned
        if start_u > count or end_u > count or end < start:
            self.owner._say(_WARNING, "Flight plan update rejected")
            self.owner._ack(source, ERROR, self.mission_type)
            return
        self.begin_update()
        self._start_requests(source, start, end, now_s)

    def handle_item(self, msg: Any, item: MissionItem, now_s: float) -> None:
        upload = self.upload
        assert upload is not None
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if item.seq != upload.next_seq:
            self.owner._ack(source, INVALID_SEQUENCE, self.mission_type)
            return
        if source != (upload.system_id, upload.component_id):
            self.owner._ack(source, DENIED, self.mission_type)
            return
        count = self.count()
        if item.seq < count:
            result = self.store(item, append=False)
        elif item.seq == count:
            result = self.store(item, append=True)
        else:
            result = ERROR
        if result != ACCEPTED:
            self.owner._ack(source, result, self.mission_type)
            self.upload = None
            self.end()
            return
        upload.last_receive_s = now_s
        upload.next_seq += 1
        if upload.next_seq > upload.last_seq:
            self._transfer_complete(source)
            return
        self._request(now_s)

    def handle_clear_all(self, msg: Any) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            if source != (self.upload.system_id, self.upload.component_id):
                self.owner._ack(source, DENIED, self.mission_type)
                self.owner._ack(source, ERROR, self.mission_type)
                return
            self.upload = None
            self.end()
        self.owner._ack(source, ACCEPTED if self.clear_all() else ERROR, self.mission_type)

    def handle_request_list(self, msg: Any) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            self.owner._ack(source, DENIED, self.mission_type)
            return
        self.owner._send(
            self.owner.mav.mission_count_encode(*source, self.count(), self.mission_type)
        )

    def handle_request(self, msg: Any, legacy: bool) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if self.upload is not None:
            self.owner._ack(source, DENIED, self.mission_type)
            return
        item = self.get(int(msg.seq))
        if item is None:
            if not legacy:  # the size, to set the ground station right (legacy: no)
                self.owner._send(
                    self.owner.mav.mission_count_encode(*source, self.count(), self.mission_type)
                )
            self.owner._ack(source, INVALID_SEQUENCE, self.mission_type)
            return
        item = replace(item, mission_type=int(msg.mission_type))
        if not legacy:
            self.owner._send(item.mission_item_int(self.owner.mav, *source))
            return
        try:
            reply = item.mission_item(self.owner.mav, *source)
        except MissionItemError as refused:
            self.owner._ack(source, refused.result, self.mission_type)
            return
        if not self.request_warning_sent:
            self.request_warning_sent = True
            self.owner._say(_WARNING, "got MISSION_REQUEST; use MISSION_REQUEST_INT!")
        self.owner._send(reply)

    def poll(self, now_s: float) -> None:
        upload = self.upload
        if upload is None:
            return
        if now_s - upload.last_receive_s > UPLOAD_TIMEOUT_S:
            self.upload = None
            self.owner._say(_WARNING, self.timeout_text)
            self.owner._ack(
                (upload.system_id, upload.component_id), OPERATION_CANCELLED, self.mission_type
            )
            self.end()
            return
        if now_s - upload.last_request_s > REREQUEST_S:
            self._request(now_s)

    def _start_requests(self, source: tuple[int, int], first: int, last: int, now_s: float) -> None:
        self.upload = _Upload(source[0], source[1], first, last, now_s, now_s)
        self.item_warning_sent = False
        self.request_warning_sent = False
        self._request(now_s)

    def _request(self, now_s: float) -> None:
        upload = self.upload
        assert upload is not None
        upload.last_request_s = now_s
        self.owner._send(
            self.owner.mav.mission_request_encode(
                upload.system_id, upload.component_id, upload.next_seq, self.mission_type
            )
        )

    def _transfer_complete(self, source: tuple[int, int]) -> None:
        result = self.complete()
        self.owner._ack(source, result, self.mission_type)
        self.end()
        self.upload = None


class _Waypoints(_ItemList):
    """The mission (MissionItemProtocol_Waypoints over AP_Mission)."""

    mission_type = MISSION
    timeout_text = "Mission upload timeout"

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        super().__init__(owner, max_items)
        self.stored: list[MissionItem] = []  # [0] is a placeholder: home is read live

    def count(self) -> int:
        return len(self.stored)

    def truncate(self, count: int) -> None:
        if len(self.stored) > count:
            del self.stored[count:]
            self.owner._touch()

    def store(self, item: MissionItem, append: bool) -> int:
        try:
            stored = stored_mission_item(item, self.owner.firmware)
        except MissionItemError as refused:
            return refused.result
        if stored.command == _DO_JUMP:
            target = int(stored.param1)
            upload = self.upload
            last_seq = upload.last_seq if upload is not None else 0
            if (target >= self.count() and target > last_seq) or target == 0:
                return ERROR
        if append:
            self.stored.append(stored)
        else:
            self.stored[item.seq] = stored
        self.owner._touch()
        return ACCEPTED

    def complete(self) -> int:
        self.owner._say(_INFO, "Flight plan received")
        return ACCEPTED

    def clear_all(self) -> bool:
        self.owner.clear()
        return True

    def get(self, seq: int) -> MissionItem | None:
        if seq != 0 and seq >= self.count():
            return None
        item = self.owner._read(seq)
        # ArduPilot marks "current" where the command number equals the current index.
        nav = self.owner._nav_index
        current = 1 if nav is not None and item.command == nav else 0
        return replace(item, current=current)


class _Fence(_ItemList):
    """The fence (MissionItemProtocol_Fence over AC_PolyFence_loader): staged, then validated."""

    mission_type = FENCE
    timeout_text = "Fence upload timeout"

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        super().__init__(owner, max_items)
        self.stored: list[MissionItem] = []
        self.staged: list[MissionItem | None] | None = None

    def count(self) -> int:
        if self.upload is not None and self.staged is not None:
            return len(self.staged)
        return len(self.stored)

    def begin(self, count: int) -> None:
        self.staged = [None] * count

    def begin_update(self) -> None:
        self.staged = list(self.stored)

    def end(self) -> None:
        self.staged = None

    def truncate(self, count: int) -> None:
        pass  # the fence is replaced whole when the upload completes

    def store(self, item: MissionItem, append: bool) -> int:
        if self.staged is None:
            return ERROR
        if item.seq >= len(self.staged):
            return INVALID_SEQUENCE
        try:
            self.staged[item.seq] = _fence_item(item)
        except MissionItemError as refused:
            return refused.result
        return ACCEPTED

    def complete(self) -> int:
        staged = self.staged if self.staged is not None else []
        items = [item for item in staged if item is not None]
        if len(items) != len(staged):
            return ERROR
        problem = _fence_problem(items)
        if problem is not None:
            severity = _INFO if problem == "Incorrect item count" else _WARNING
            self.owner._say(severity, problem)
            self.owner._say(_WARNING, "Fence validation failed")
            return ERROR
        self.stored = [replace(item, seq=seq) for seq, item in enumerate(items)]
        self.owner._say(_DEBUG, "Fence Indexed OK")
        self.owner._touch()
        return ACCEPTED

    def clear_all(self) -> bool:
        self.stored = []
        self.owner._say(_DEBUG, "Fence Indexed OK")
        self.owner._touch()
        return True

    def get(self, seq: int) -> MissionItem | None:
        return self.stored[seq] if 0 <= seq < len(self.stored) else None


class _Rally(_ItemList):
    """The rally points (MissionItemProtocol_Rally over AP_Rally)."""

    mission_type = RALLY
    timeout_text = "Rally upload timeout"

    def __init__(self, owner: MissionProtocol, max_items: int) -> None:
        super().__init__(owner, max_items)
        self.stored: list[MissionItem] = []

    def count(self) -> int:
        return len(self.stored)

    def truncate(self, count: int) -> None:
        if len(self.stored) > count:
            del self.stored[count:]
            self.owner._touch()

    def store(self, item: MissionItem, append: bool) -> int:
        try:
            stored = _rally_item(item)
        except MissionItemError as refused:
            return refused.result
        if append:
            if len(self.stored) >= self.max_items:
                return ERROR
            self.stored.append(stored)
        else:
            self.stored[item.seq] = stored
        self.owner._touch()
        return ACCEPTED

    def complete(self) -> int:
        return ACCEPTED  # (4.7 prints nothing)

    def clear_all(self) -> bool:
        self.truncate(0)
        return True

    def get(self, seq: int) -> MissionItem | None:
        return self.stored[seq] if 0 <= seq < len(self.stored) else None


class MissionProtocol:
    """ArduPilot's mission, fence and rally point lists and their MAVLink protocol.

    Args:
        mav: The autopilot's pymavlink ``MAVLink`` object; replies are encoded and sent
            with it (``mav.send``), so they carry the autopilot's ids.
        home: Home as (latitude deg, longitude deg, altitude above mean sea level m),
            None before it is set; read whenever item 0 is read, as ArduPilot reads it.
        text: Sends a STATUSTEXT (severity, text), as the autopilot's own texts go.
        firmware: ``arducopter``, ``arduplane`` or ``ardurover`` (storage limits, and
            how ArduPlane stores waypoints).
        in_auto: Whether the vehicle is in AUTO now; only for the MISSION_CURRENT sent at
            once after MISSION_SET_CURRENT (None: never in AUTO).
        limits: Storage limits instead of the firmware's.

    Raises:
        ValueError: Unknown firmware.
    """

    def __init__(
        self,
        mav: Any,
        home: Callable[[], tuple[float, float, float] | None],
        text: Callable[[int, str], None],
        *,
        firmware: str = "arducopter",
        in_auto: Callable[[], bool] | None = None,
        limits: ItemLimits | None = None,
    ) -> None:
        if firmware not in ITEM_LIMITS:
            raise ValueError(f"unknown firmware {firmware!r}; use one of {sorted(ITEM_LIMITS)}")
        self.mav = mav
        self.firmware = firmware
        self._home = home
        self._text = text
        self._in_auto = in_auto
        limits = limits if limits is not None else ITEM_LIMITS[firmware]
        self._waypoints = _Waypoints(self, limits.mission)
        self._fence = _Fence(self, limits.fence)
        self._rally = _Rally(self, limits.rally)
        self._lists: dict[int, _ItemList] = {
            MISSION: self._waypoints,
            FENCE: self._fence,
            RALLY: self._rally,
        }
        self._texts: list[tuple[int, str]] = []
        # AP_Mission's execution cursor.
        self._state = MissionState.STOPPED
        self._nav_index: int | None = None
        self._nav_loaded = False
        self._do_index: int | None = None
        self._do_loaded = False
        self._do_all_done = False
        self._jumps: dict[int, int] = {}  # DO_JUMP index -> times run
        self._started: list[MissionItem] = []

        self.changed = 0
        """Counts every change of the stored lists, the current item or the mission state;
        the autopilot compares it with the value it last saw to know when to look again."""

    # -- the stored lists -----------------------------------------------------------------------

    @property
    def items(self) -> tuple[MissionItem, ...]:
        """The mission as stored (what a download returns), item 0 the current home."""
        return tuple(self._read(seq) for seq in range(self._waypoints.count()))

    @property
    def count(self) -> int:
        """Mission items including home, as MISSION_COUNT reports them (0 when empty)."""
        return self._waypoints.count()

    @property
    def fence_items(self) -> tuple[MissionItem, ...]:
        """The fence as stored (never used for flying here)."""
        return tuple(self._fence.stored)

    @property
    def rally_items(self) -> tuple[MissionItem, ...]:
        """The rally points as stored (never used for flying here)."""
        return tuple(self._rally.stored)

    def receiving(self, mission_type: int = MISSION) -> bool:
        """Whether an upload of ``mission_type`` is under way."""
        items = self._lists.get(mission_type)
        return items is not None and items.receiving

    def write_home(self) -> None:
        """Home was set (AP_Mission::write_home_to_storage): an empty mission gets item 0.

        Call it wherever ArduPilot sets home (when it first gets one, DO_SET_HOME, a
        copter's arming, a rover's disarming): a mission cleared or emptied by
        MISSION_COUNT 0 counts 0 items until then, 1 after (measured).
        """
        if not self._waypoints.stored:
            self._waypoints.stored.append(self._home_item())
            self._touch()

    def clear(self) -> None:
        """Empty the mission as MISSION_CLEAR_ALL does: no items, stopped, no current item."""
        self._waypoints.stored.clear()
        self._state = MissionState.STOPPED
        self._nav_index = None
        self._do_index = None
        self._nav_loaded = self._do_loaded = False
        self._touch()

    # -- messages ----------------------------------------------------------------------------

    def handle(self, msg: Any, now_s: float) -> bool:
        """Act on a mission-protocol message and answer its sender; False if it is not one.

        A MISSION_ITEM(_INT) of the mission with ``current`` 2 or 3 (a guided-mode target
        or altitude change) is the autopilot's (False), during an upload too, as in
        ArduPilot. Call it with messages already addressed to this autopilot.
        """
        kind = msg.get_type()
        handler = self._handlers.get(kind)
        if handler is None:
            return False
        handled = handler(self, msg, now_s)
        self._flush()
        return handled

    def poll(self, now_s: float) -> None:
        """Re-request a missing item, or give an upload up, as time passes."""
        for items in self._lists.values():
            items.poll(now_s)
        self._flush()

    def _on_item(self, msg: Any, now_s: float) -> bool:
        legacy = msg.get_type() == "MISSION_ITEM"
        mission_type = int(msg.mission_type)
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        try:
            item = (
                MissionItem.from_mission_item(msg)
                if legacy
                else MissionItem.from_mission_item_int(msg)
            )
        except MissionItemError as refused:
            self._ack(source, refused.result, mission_type)
            return True
        if mission_type == MISSION and item.current in (2, 3):
            return False
        items = self._lists.get(mission_type)
        if items is None:
            self._ack(source, UNSUPPORTED, mission_type)
            return True
        if legacy and not items.item_warning_sent:  # (outside an upload too: measured)
            items.item_warning_sent = True
            self._say(_WARNING, "got MISSION_ITEM; GCS should send MISSION_ITEM_INT")
        if not items.receiving:
            self._ack(source, ERROR, mission_type)
        else:
            items.handle_item(msg, item, now_s)
        return True

    def _on_count(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_count(msg, int(msg.count), now_s)
        return True

    def _on_partial(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_partial(msg, int(msg.start_index), int(msg.end_index), now_s)
        return True

    def _on_clear_all(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_clear_all(msg)
        return True

    def _on_request_list(self, msg: Any, now_s: float) -> bool:
        items = self._supported_list(msg)
        if items is not None:
            items.handle_request_list(msg)
        return True

    def _supported_list(self, msg: Any) -> _ItemList | None:
        """The list ``msg``'s mission_type names; None (answered UNSUPPORTED) for another type."""
        items = self._lists.get(int(msg.mission_type))
        if items is None:
            self._unsupported(msg)
        return items

    def _on_request(self, msg: Any, now_s: float) -> bool:
        items = self._lists.get(int(msg.mission_type))
        if items is not None:  # other types: no answer at all (measured)
            items.handle_request(msg, legacy=msg.get_type() == "MISSION_REQUEST")
        return True

    def _on_set_current(self, msg: Any, now_s: float) -> bool:
        seq = int(msg.seq)
        self._started = []
        if self._set_current(seq):
            # No ack for this message: ArduPilot sends MISSION_CURRENT at once, with the
            # seq asked for (0 stays 0 there, though the mission goes to 1).
            in_auto = self._in_auto() if self._in_auto is not None else False
            _, total, state, mode = self.mission_current(in_auto)
            self._send(self.mav.mission_current_encode(seq, total, state, mode))
        return True

    def _on_ack(self, msg: Any, now_s: float) -> bool:
        return True  # a ground station's MISSION_ACK needs nothing from ArduPilot

    _handlers: Final[Mapping[str, Callable[[MissionProtocol, Any, float], bool]]] = {
        "MISSION_ITEM": _on_item,
        "MISSION_ITEM_INT": _on_item,
        "MISSION_COUNT": _on_count,
        "MISSION_WRITE_PARTIAL_LIST": _on_partial,
        "MISSION_CLEAR_ALL": _on_clear_all,
        "MISSION_REQUEST_LIST": _on_request_list,
        "MISSION_REQUEST_INT": _on_request,
        "MISSION_REQUEST": _on_request,
        "MISSION_SET_CURRENT": _on_set_current,
        "MISSION_ACK": _on_ack,
    }

    def _unsupported(self, msg: Any) -> None:
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        self._ack(source, UNSUPPORTED, int(msg.mission_type))

    # -- execution (AP_Mission) -----------------------------------------------------------------

    @property
    def state(self) -> MissionState:
        """AP_Mission's state: stopped, running or complete."""
        return self._state

    @property
    def current(self) -> int:
        """The current navigation command's seq as MISSION_CURRENT reports it (0: none)."""
        return 0 if self._nav_index is None else self._nav_index

    @property
    def nav_item(self) -> MissionItem | None:
        """The navigation command being flown (or to resume at), None if there is none."""
        if self._nav_index is None or self._nav_index >= self._waypoints.count():
            return None
        return self._read(self._nav_index)

    def mission_current(self, auto_active: bool) -> tuple[int, int, int, int]:
        """MISSION_CURRENT's (seq, total, mission_state, mission_mode), as ArduPilot fills it.

        ``total`` leaves home out; no items reports (0, 0, 1, mode); mission_mode is 1
        while the vehicle is in AUTO (``auto_active``), whatever the mission's state.
        Measured: (0, 0, 1, 0) empty, (0, N, 2, 0) just uploaded, (n, N, 3, 1) flying,
        (N, N, 5, 1) complete, which stays 5 out of AUTO and across a new upload.
        """
        total = max(self._waypoints.count() - 1, 0)
        state = int(mavlink2.MISSION_STATE_NO_MISSION) if total == 0 else int(self._state)
        return self.current, total, state, 1 if auto_active else 0

    def set_current(self, seq: int) -> bool:
        """Make ``seq`` the current item (AP_Mission::set_current_cmd); False if refused.

        Used for MISSION_SET_CURRENT and MAV_CMD_DO_SET_MISSION_CURRENT (the autopilot
        answers that one ACCEPTED or DENIED, then sends MISSION_CURRENT). Refused beyond
        the list or with home alone; 0 means 1; the index lands on the first navigation
        command at or after ``seq``. A running mission starts that command ("Mission: N
        ..." texts; :attr:`started` lists what started); a stopped or complete one
        becomes stopped there, to resume from it.
        """
        self._started = []
        done = self._set_current(seq)
        self._flush()
        return done

    def start(self) -> list[MissionItem]:
        """Start the mission from its first command (AP_Mission::start; AUTO with MIS_RESTART).

        Returns:
            The commands started, in order (a DO command before the first navigation
            command, that navigation command, the DO commands between), empty when the
            mission has nothing to fly: it is then complete.
        """
        self._started = []
        self._start()
        self._flush()
        return list(self._started)

    def resume(self) -> list[MissionItem]:
        """Go on from where the mission stopped (AP_Mission::resume; AUTO entered).

        A complete mission, or one with no current command or one beyond a shorter new
        mission, starts again from its first command; otherwise the current command
        starts again ("Mission: N WP" on re-entering AUTO, as measured).

        Returns:
            The commands started, as :meth:`start`.
        """
        self._started = []
        if self._state == MissionState.COMPLETE:
            self._start()
        else:
            self._state = MissionState.RUNNING
            nav = self._nav_index
            if nav is None or nav >= self.count:
                self._start()
            elif self._do_loaded and self._do_index is not None:
                self._set_current(self._do_index)
            elif self._nav_loaded:
                self._set_current(nav)
            self._touch()
        self._flush()
        return list(self._started)

    def stop(self) -> None:
        """Stop a running mission where it is (leaving AUTO); a complete one stays complete."""
        if self._state == MissionState.RUNNING:
            self._state = MissionState.STOPPED
            self._touch()

    def reset(self) -> None:
        """Forget the current command (AP_Mission::reset; ArduCopter does it at disarming)."""
        self._nav_index = None
        self._do_index = None
        self._nav_loaded = self._do_loaded = self._do_all_done = False
        self._jumps.clear()
        self._touch()

    def advance(self) -> MissionItem | None:
        """The current navigation command is done: start the next one (AP_Mission::update).

        DO_JUMP items are followed and counted as ArduPilot counts them.

        Returns:
            The navigation command now current, or None when the mission is complete
            (its state is then complete; the vehicle's own end-of-mission behaviour and
            texts are the autopilot's). :attr:`started` lists every command started.
        """
        self._started = []
        if self._state != MissionState.RUNNING:
            return None
        self._nav_loaded = False
        if self._advance_nav(0):
            self._run_do_commands()
        else:
            self._complete()
        self._flush()
        return self.nav_item if self._state == MissionState.RUNNING else None

    @property
    def started(self) -> tuple[MissionItem, ...]:
        """The commands the last start, resume, advance or set_current started, in order."""
        return tuple(self._started)

    def _set_current(self, seq: int) -> bool:
        total = self._waypoints.count()
        if seq < 0 or seq >= total or total == 1:
            return False
        self._do_index = None
        self._do_loaded = self._do_all_done = self._nav_loaded = False
        index = seq
        if index == 0 or self._state == MissionState.COMPLETE:
            self._jumps.clear()
            index = max(index, 1)
        self._touch()
        if self._state == MissionState.RUNNING:
            if self._advance_nav(index):
                self._run_do_commands()
                return True
            self._complete()
            return False
        # Stopped or complete: move the index only, to resume from there.
        while not self._nav_loaded:
            item = self._next_command(index, increment=True)
            if item is None:
                self._nav_index = None
                return False
            if item.is_nav:
                self._nav_index = item.seq
                self._nav_loaded = True
            elif not self._do_loaded:
                self._do_index = item.seq
                self._do_loaded = True
            index = item.seq + 1
        self._do_all_done = not self._do_loaded
        self._state = MissionState.STOPPED
        return True

    def _start(self) -> None:
        self._state = MissionState.RUNNING
        self._nav_index = None
        self._do_index = None
        self._nav_loaded = self._do_loaded = self._do_all_done = False
        self._jumps.clear()
        if not self._advance_nav(0):
            self._complete()
        else:
            self._run_do_commands()
        self._touch()

    def _complete(self) -> None:
        self._state = MissionState.COMPLETE
        self._touch()

    def _start_command(self, item: MissionItem) -> None:
        self._say(_INFO, f"Mission: {item.seq} {command_name(item.command)}")
        self._started.append(item)

    def _advance_nav(self, starting_index: int) -> bool:
        """AP_Mission::advance_current_nav_cmd: find, load and start the next nav command."""
        if self._state != MissionState.RUNNING or self._nav_loaded:
            return False
        self._do_index = None
        self._do_loaded = False
        self._do_all_done = False
        if starting_index > 0:
            index = starting_index
        elif self._nav_index is None:
            index = 1
        else:
            index = self._nav_index + 1
        loops_left = 255
        while not self._nav_loaded:
            item = self._next_command(index, increment=True)
            if item is None:
                return False
            if item.is_nav:
                self._nav_index = item.seq
                self._start_command(item)
                self._nav_loaded = True
            elif not self._do_loaded:
                self._do_index = item.seq
                self._do_loaded = True
                self._start_command(item)
            else:
                if loops_left == 0:
                    return False
                loops_left -= 1
            index = item.seq + 1
        if not self._do_loaded:
            self._do_all_done = True
        self._touch()
        return True

    def _run_do_commands(self) -> None:
        """The DO commands between the current one and the navigation command, each done at once."""
        while self._state == MissionState.RUNNING and not self._do_all_done:
            index = 1 if self._do_index is None else self._do_index + 1
            item = self._next_command(index, increment=False) if index < self.count else None
            if item is None or item.is_nav:
                self._do_all_done = True
                self._do_loaded = False
                return
            self._do_index = item.seq
            self._do_loaded = True
            self._start_command(item)

    def _next_command(self, start: int, increment: bool) -> MissionItem | None:
        """AP_Mission::get_next_cmd: the first non-jump command at or after ``start``."""
        index = start
        jump_index: int | None = None
        loops_left = 64
        total = self._waypoints.count()
        while index < total:
            item = self._read(index)
            if item.command != _DO_JUMP:
                return item
            if loops_left == 0:
                return None
            loops_left -= 1
            target, times = int(item.param1), int(item.param2)
            if target >= total or target == 0:
                return None
            if not increment and jump_index == index:
                return None
            if jump_index is None:
                jump_index = index
            if times == _JUMP_REPEAT_FOREVER:
                index = target
                continue
            run = self._jump_times_run(index)
            if run < times:
                if increment:
                    self._jumps[index] = run + 1
                    self._say(_INFO, f"Mission: {index} Jump {run + 1}/{times}")
                index = target
            else:
                index += 1
        return None

    def _jump_times_run(self, index: int) -> int:
        if index in self._jumps:
            return self._jumps[index]
        if len(self._jumps) >= _MAX_JUMP_COMMANDS:
            return _JUMP_TIMES_MAX
        self._jumps[index] = 0
        return 0

    # -- plumbing ---------------------------------------------------------------------------

    def _home_item(self) -> MissionItem:
        """Item 0 as AP_Mission reads it: the AHRS's home, frame 0, altitude in cm."""
        home = self._home()
        if home is None:
            x, y, z = 0, 0, 0.0
        else:
            lat_deg, lon_deg, alt_m = home
            x, y = round(lat_deg * 1e7), round(lon_deg * 1e7)
            z = _f32(round(alt_m * 100.0) * _CENTI)
        return MissionItem(0, 0, 16, 0, 1, 0.0, 0.0, 0.0, 0.0, x, y, z, MISSION)

    def _read(self, seq: int) -> MissionItem:
        if seq == 0:
            return self._home_item()
        return replace(self._waypoints.stored[seq], seq=seq)

    def _touch(self) -> None:
        self.changed += 1

    def _send(self, msg: Any) -> None:
        self.mav.send(msg)

    def _ack(self, target: tuple[int, int], result: int, mission_type: int) -> None:
        self._send(self.mav.mission_ack_encode(target[0], target[1], result, mission_type))

    def _say(self, severity: int, text: str) -> None:
        """A STATUSTEXT, sent after this step's MAVLink replies (ArduPilot queues its texts)."""
        self._texts.append((severity, text))

    def _flush(self) -> None:
        texts, self._texts = self._texts, []
        for severity, text in texts:
            self._text(severity, text)
