"""A simulated ArduPilot: a MAVLink endpoint in front of a :class:`VehicleModel`.

:class:`SimAutopilot` speaks MAVLink 2 as ArduPilot does, so that the engine's
real :class:`~clark_engine.io.autopilot.AutopilotAdapter` (and pymavlink,
MAVProxy, MAVSDK or a ground station, in real-time mode) can fly a simulated
vehicle without knowing it is one. It wraps a
:class:`~clark_engine.sim.ardupilot.vehicle_model.VehicleModel` (the physics and flight modes) and
adds what ArduPilot's own logic does around them: it boots, gets ready, checks
before it arms, refuses what ArduPilot refuses with ArduPilot's words, keeps home,
disarms a landed copter, streams at requested intervals and answers commands.

It is never kinder than ArduPilot where the engine or a ground station can tell.
The facts it follows are per firmware in :mod:`clark_engine.sim.ardupilot.firmware`, each
measured on ArduPilot SITL; ``tests/conformance`` runs the same scenarios against
this class and against SITL, and docs/autopilot-fidelity.md tables the result.

It is pure and deterministic: no clock, no socket, no randomness. The simulator
hands it incoming bytes with :meth:`SimAutopilot.receive` and collects what it
emits with :meth:`SimAutopilot.advance`; both take the virtual time. Replies to
requests are queued by ``receive`` and leave with the next ``advance``.

What it does, in ArduPilot's order:

- **Boot** (:class:`~clark_engine.sim.ardupilot.firmware.BootTimes`, counted from ``boot_s``):
  HEARTBEAT from power-on (INITIALISING for a second where the firmware has it),
  its boot STATUSTEXTs, then the streams from "ArduPilot Ready"; a stream request
  that arrives before the first HEARTBEAT is acknowledged and lost, as ArduPilot's
  is (one after it is kept, and starts with the streams). No position (0, 0) and
  GPS fix 0 until the fix; SYSTEM_TIME's Unix time 0 until then; home set when the
  firmware sets it (HOME_POSITION sent then); the EKF's flags step from
  uninitialised to attitude to an absolute position; SYS_STATUS's sensor bits as
  ArduPilot sets them (:mod:`clark_engine.sim.ardupilot.sys_status`), its pre-arm check bit
  set once arming would pass in the current mode.
- **Arming** (MAV_CMD_COMPONENT_ARM_DISARM): refused with CRITICAL ``Arm: ...``
  texts and FAILED while a check fails (the boot phase, a mode that is not armable,
  a mode that needs a position before the EKF has one); while checks fail a
  ``PreArm: ...`` text every 30 s; the throttle must be at zero. Forced arming
  skips the checks. Home moves where each firmware moves it (ArduCopter at arming,
  ArduRover at disarming, ArduPlane with its GPS while disarmed) unless a ground
  station set it. Disarming in the air is refused (FAILED, no text) unless forced.
  ArduCopter disarms by itself DISARM_DELAY after arming if it has not taken off,
  and 2 s after touching down in LAND, RTL or AUTO. Arming a plane in TAKEOFF (or
  AUTO with a takeoff first) launches it. Two internal errors SITL showed block
  arming until a reboot: ArduRover's RTL before its EKF origin and ArduCopter's
  second SMART_RTL entry while disarmed.
- **Modes** (MAV_CMD_DO_SET_MODE acknowledged; the SET_MODE message is not, as in
  ArduPilot 4.7): an unknown number is FAILED with "No such mode N"; every
  refusal of every mode of the profiles, disarmed and armed, before and after the
  vehicle is ready, is ArduPilot's, with its texts (the firmware's facts, measured
  mode by mode); ArduPlane's AUTO without a mission becomes RTL at once;
  ArduCopter's LAND on the ground disarms it.
- **Missions** (:class:`~clark_engine.sim.ardupilot.mission_protocol.MissionProtocol`):
  upload, download, clear, partial update and the current item of the mission,
  fence and rally lists, as ArduPilot answers them; MISSION_CURRENT; AUTO entered
  as each firmware allows it (ArduRover and ArduCopter armed on the ground need a
  mission, ArduCopter one that starts with a takeoff), MAV_CMD_MISSION_START and
  DO_SET_MISSION_CURRENT. AUTO flies the mission's navigation items one after the
  other (takeoff, waypoints and loiters as points, land, return to launch; any
  other item is passed), saying what ArduPilot says at each, and ends as each
  firmware ends it (ArduRover stops, "Mission Complete"; ArduCopter holds, or
  lands, disarms and starts the mission over; ArduPlane turns to RTL).
- **Commands**: DO_CHANGE_SPEED as each firmware accepts it; NAV_TAKEOFF
  (ArduCopter: guided, armed, landed; COMMAND_INT in the relative-altitude frame);
  NAV_LAND; NAV_RETURN_TO_LAUNCH; NAV_LOITER_UNLIM; DO_SET_HOME; GET_HOME_POSITION;
  DO_REPOSITION (COMMAND_INT); DO_SET_SERVO; SET_MESSAGE_INTERVAL,
  GET_MESSAGE_INTERVAL, REQUEST_MESSAGE, REQUEST_AUTOPILOT_CAPABILITIES; anything
  else UNSUPPORTED. SET_POSITION_TARGET_GLOBAL_INT in guided (position, or position
  and velocity, which ArduCopter extrapolates; ArduPlane takes only the altitude);
  RC_CHANNELS_OVERRIDE from MAV_GCS_SYSID, lapsing after RC_OVERRIDE_TIME; the
  guided-mode MISSION_ITEM(_INT) of MAVProxy's ``guided``; PARAM_* as ArduPilot 4.7
  answers them, over its whole list (:mod:`clark_engine.sim.ardupilot.params`: SITL's names,
  types, values and order; a list paced at PARAM_LIST_RATE_HZ; a PARAM_VALUE
  answering a read by name or a set carries index 65535;
  a set is echoed with the stored value in the parameter's own type, integers
  truncated and clamped to their C type, never clamped to the documented range;
  unknown names, NaN and infinities get no answer);
  FILE_TRANSFER_PROTOCOL (a NAK, so stations fall back to parameters); TIMESYNC.
- **Streams**: HEARTBEAT at 1 Hz; SYS_STATUS, GPS_RAW_INT, GLOBAL_POSITION_INT,
  ATTITUDE (with body rates), VFR_HUD, SYSTEM_TIME, RC_CHANNELS, SERVO_OUTPUT_RAW,
  EKF_STATUS_REPORT, EXTENDED_SYS_STATE (ArduCopter, ArduPlane), MISSION_CURRENT,
  BATTERY_STATUS, NAV_CONTROLLER_OUTPUT and POSITION_TARGET_GLOBAL_INT (while the
  mode flies to a target) at rates from the MAV1_* stream parameters (ArduCopter
  streams nothing until asked), overridden per message by
  MAV_CMD_SET_MESSAGE_INTERVAL (-1 stops, 0 restores the default) or per group by
  REQUEST_DATA_STREAM. STATUSTEXT whenever ArduPilot would speak.

- **The fence** (:mod:`clark_engine.sim.ardupilot.fence`): FENCE_* and the uploaded fence list,
  checked at each firmware's rate against the position the autopilot believes (its
  altitude above home as it reports it), breach texts and FENCE_ACTION, manual
  recovery, pre-arm refusals, guided destinations refused (ArduCopter, ArduPlane),
  ArduRover's avoidance stopping short, SYS_STATUS's geofence bit, FENCE_STATUS,
  MAV_CMD_DO_FENCE_ENABLE.
- **The ground-station failsafe** (:mod:`clark_engine.sim.ardupilot.gcs_failsafe`): the silence of
  MAV_GCS_SYSID's heartbeats (and RC overrides, MANUAL_CONTROL), each firmware's
  timeouts, actions and texts.
- **Altitudes** as each firmware fills GLOBAL_POSITION_INT while it boots: ArduCopter
  all zero before its fix; ArduRover and ArduPlane their barometer's height until their
  estimate has one above sea level (ArduRover's home set at that height). Positions
  before the fix are 0, 0, but ArduPlane's, which drift away from there as its DCM
  dead-reckons (SITL: 35 m in 6 s) while GPS_RAW_INT says no fix.

Not simulated (docs/autopilot-fidelity.md): flying by rally points (they are kept,
never used), mission DO items other than DO_CHANGE_SPEED, DO_SET_SERVO and
DO_SET_HOME, signing, terrain, failsafes other than the ground station's and the fence
(radio, battery; of the EKF's, only ArduRover's refusal of modes that need a position),
AUTOLAND, and more than one MAVLink channel (all peers share one byte stream, as behind
a router).

Its concepts are helper objects it owns, in modules of their own, each in an attribute
(named in brackets) and acting, through the autopilot, on the state it shares with the
others: :class:`~clark_engine.sim.ardupilot.telemetry.Telemetry` (``telemetry``) builds
every message it sends, :class:`~clark_engine.sim.ardupilot.commands.Commands`
(``commands``) carries out the commands and guided targets it is sent,
:class:`~clark_engine.sim.ardupilot.mission_executor.MissionExecutor` (``auto``) flies
AUTO's mission, :class:`~clark_engine.sim.ardupilot.readiness.Readiness` (``readiness``) is
its boot, home and its EKF's heights, :class:`~clark_engine.sim.ardupilot.arming.Arming`
(``arming``) its pre-arm checks, arming and disarming,
:class:`~clark_engine.sim.ardupilot.modes.ModeChanges` (``mode_changes``) its mode changes,
:class:`~clark_engine.sim.ardupilot.parameters.Parameters` (``parameters``) the PARAM_*
protocol and what setting a parameter does,
:class:`~clark_engine.sim.ardupilot.streams.Streams` (``streams``) the stream requests and
schedule, :class:`~clark_engine.sim.ardupilot.rc_overrides.RcOverrides` (``rc_overrides``)
the RC overrides, :class:`~clark_engine.sim.ardupilot.fence_checks.FenceChecks`
(``fence_checks``) the fence's checks,
:class:`~clark_engine.sim.ardupilot.avoidance.Avoidance` (``avoidance``) ArduRover's
avoidance, and :class:`~clark_engine.sim.ardupilot.safety_hooks.SafetyHooks` is what the
fence and the failsafe see of it.

Over 800 lines because this docstring is the simulated ArduPilot's whole description (about
130 lines; the code is about 750), and what is left is the state the helpers share, read and
changed by several of them at every step, and the two places that drive them in ArduPilot's
order: the message dispatch (``receive``) and the step (``advance`` and its supervision of
boot texts, home, pre-arm reports, arrivals, the fence and the failsafe).
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot import sys_status as ap_sys_status
from clark_engine.sim.ardupilot.arming import Arming
from clark_engine.sim.ardupilot.avoidance import Avoidance
from clark_engine.sim.ardupilot.commands import Commands
from clark_engine.sim.ardupilot.fence import (
    ArduFence,
    Point2,
)
from clark_engine.sim.ardupilot.fence_checks import FenceChecks
from clark_engine.sim.ardupilot.firmware import (
    COMMON_PARAMS,
    FIRMWARES,
    BootTimes,
    Firmware,
)
from clark_engine.sim.ardupilot.gcs_failsafe import GcsFailsafe
from clark_engine.sim.ardupilot.mission_executor import (
    MissionExecutor,
)
from clark_engine.sim.ardupilot.mission_protocol import MissionProtocol
from clark_engine.sim.ardupilot.modes import ModeChanges
from clark_engine.sim.ardupilot.parameters import Parameters
from clark_engine.sim.ardupilot.params import INT16, Param, ParamStore, sitl_table
from clark_engine.sim.ardupilot.rc_overrides import RcOverrides
from clark_engine.sim.ardupilot.readiness import Readiness
from clark_engine.sim.ardupilot.safety_hooks import SafetyHooks
from clark_engine.sim.ardupilot.streams import NOT_STREAMED, STREAM_RATES, Streams
from clark_engine.sim.ardupilot.telemetry import (
    FIRMWARE_TYPES,
    M_PER_DEG_LAT,
    STREAM_GROUPS,
    Telemetry,
)
from clark_engine.sim.ardupilot.vehicle_model import Truth, VehicleModel
from clark_engine.sim.ardupilot.vehicle_safety import ModeReason

MISSION_POLL_S: Final = 0.1
"""How often an upload's resends and timeout are looked at (their times are whole seconds)."""
ROVER_STOPPED_M_S: Final = 0.1
"""ArduRover says "Reached destination" in RTL once stopped there (ATC_STOP_SPEED; SITL
said it 0.4 m from home, at 0.38 m/s after overshooting, 17.5 s into a 25 m return)."""
STATUSTEXT_CHUNK: Final = 50
"""Characters per STATUSTEXT; ArduPilot sends a longer text as several with one id."""
PREARM_REPORT_PERIOD_S: Final = 30.0
"""ArduPilot prints failing pre-arm checks this often (AP_Arming's PREARM_DISPLAY_PERIOD)."""
PLANE_HOME_PERIOD_S: Final = 6.0
"""ArduPlane re-sends HOME_POSITION this often while disarmed (measured)."""
FENCE_UPDATE_S: Final = 0.1
"""ArduPilot looks at FENCE_ENABLE and FENCE_AUTOENABLE at 10 Hz (AC_Fence::update)."""
ROVER_HOME_CHECK_PERIOD_S: Final = 1.0
"""ArduRover looks at moving home once a second while disarmed (Rover::one_second_loop)."""
ROVER_HOME_MIN_CHANGE_M: Final = 0.5
"""ArduRover's DISTANCE_HOME_MINCHANGE: home moves once the rover is this far from it."""

_FTP_OP_NAK: Final = 129
_FTP_ERR_UNKNOWN_COMMAND: Final = 7
_FTP_HEADER: Final = struct.Struct("<HBBBBBBI")
_FTP_PAYLOAD_BYTES: Final = 251

_INFO, _NOTICE, _WARNING, _CRITICAL = (
    mavlink2.MAV_SEVERITY_INFO,
    mavlink2.MAV_SEVERITY_NOTICE,
    mavlink2.MAV_SEVERITY_WARNING,
    mavlink2.MAV_SEVERITY_CRITICAL,
)


_MAV_OPTION_GCS_ONLY: Final = 1
"""MAV_OPTIONS bit 0: accept MAVLink only from MAV_GCS_SYSID (and our own system)."""


_PREARM_BIT: Final = ap_sys_status.PREARM


@dataclass(frozen=True, slots=True)
class _Asker:
    """Who sent the message being answered."""

    system_id: int
    component_id: int


class _Outbox:
    def __init__(self) -> None:
        self.data = bytearray()

    def write(self, data: bytes) -> None:
        self.data += data


_ACCEPTED, _DENIED, _FAILED, _UNSUPPORTED = (
    int(mavlink2.MAV_RESULT_ACCEPTED),
    int(mavlink2.MAV_RESULT_DENIED),
    int(mavlink2.MAV_RESULT_FAILED),
    int(mavlink2.MAV_RESULT_UNSUPPORTED),
)


class SimAutopilot:
    """One simulated ArduPilot autopilot; see the module docstring for what it does.

    Args:
        model: The vehicle it flies.
        firmware: ``arduplane``, ``arducopter`` or ``ardurover``.
        system_id: Its MAVLink system id (MAV_SYSID).
        component_id: Its component id (1).
        modes: Mode name -> custom_mode number; the model's by default.
        guided_mode: The mode in which position targets are flown.
        origin_lat_deg: Latitude of the mission origin (the model's local frame).
        origin_lon_deg: Longitude of the mission origin.
        origin_alt_amsl_m: Altitude of the origin above mean sea level; the model's
            heights are above it.
        start_time_unix_us: Unix time at the simulator's time 0, as its GPS would know
            it; None for a GPS without time (SYSTEM_TIME then carries 0).
        boot_s: The simulator time at which it powers on. An autopilot that powered
            on long before the run starts (a vehicle the pilot flew up) is ready from
            the run's first instant.
        boot: Its boot timeline; the firmware's (measured on SITL) by default.
        params: Parameter values to start from instead of the defaults (names must
            exist in its table).
        throttle: The throttle's RC input channel and its zero (the pulse width of no
            throttle: the minimum, or the trim of a centred rover throttle), for the
            arming check that the throttle is at zero; None: no such check.
        unix_clock_us: The wall clock in Unix microseconds, for SYSTEM_TIME in real
            time; None: the simulated clock from ``start_time_unix_us``.

    Raises:
        ValueError: Unknown firmware or parameter name.
    """

    def __init__(
        self,
        model: VehicleModel,
        *,
        firmware: str,
        system_id: int = 1,
        component_id: int = 1,
        modes: Mapping[str, int] | None = None,
        guided_mode: str = "GUIDED",
        origin_lat_deg: float,
        origin_lon_deg: float,
        origin_alt_amsl_m: float = 0.0,
        start_time_unix_us: int | None = None,
        boot_s: float = 0.0,
        boot: BootTimes | None = None,
        params: Mapping[str, float] | None = None,
        unix_clock_us: Callable[[], int] | None = None,
        throttle: tuple[int, int] | None = None,
    ) -> None:
        if firmware not in FIRMWARE_TYPES:
            raise ValueError(f"unknown firmware {firmware!r}; use one of {sorted(FIRMWARE_TYPES)}")
        self.model = model
        self.firmware = firmware
        self.fw: Firmware = FIRMWARES[firmware]
        self.boot_times = boot if boot is not None else self.fw.boot
        self._sysid = system_id
        self._compid = component_id
        self.modes: Mapping[str, int] = dict(modes if modes is not None else model.modes)
        self._mode_names = {number: name for name, number in reversed(self.modes.items())}
        self.guided_mode = guided_mode
        self.origin_lat_deg = origin_lat_deg
        self.origin_lon_deg = origin_lon_deg
        self.origin_alt_amsl_m = origin_alt_amsl_m
        self.start_time_unix_us = start_time_unix_us
        self.boot_s = boot_s
        self._unix_clock_us = unix_clock_us
        self._throttle = throttle

        self._outbox = _Outbox()
        self._mav = mavlink2.MAVLink(self._outbox, srcSystem=system_id, srcComponent=component_id)
        self._parser = mavlink2.MAVLink(None, system_id, component_id)
        self._parser.robust_parsing = True
        self.missions = MissionProtocol(
            self._mav,
            lambda: self._home,
            self._text,
            firmware=firmware,
            in_auto=lambda: self.model.mode == "AUTO",
        )
        """The mission, fence and rally lists and their protocol; AUTO flies the mission."""
        self._mission_poll_s = 0.0
        # AUTO's executor: the mission item it flies (seq), and how far it got with it.
        self._auto_seq: int | None = None
        self.auto = MissionExecutor(self)
        """AUTO: the executor that flies the mission, item by item."""
        self.commands = Commands(self)
        """The commands it answers (COMMAND_LONG/INT, guided targets, DO items)."""
        self.streams = Streams(self)
        """Stream requests (REQUEST_DATA_STREAM, message intervals) and the streams' schedule."""
        self.arming = Arming(self)
        """Pre-arm checks, arming and disarming, and ArduCopter's disarms by itself."""
        self.mode_changes = ModeChanges(self)
        """Mode changes as ArduPilot's set_mode makes or refuses them."""
        self.readiness = Readiness(self)
        """Boot and readiness: the boot timeline, home, the EKF's altitudes and check."""
        self._auto_go = False  # ArduCopter on the ground: MISSION_START came
        self._auto_landing = False  # the item flown is a landing (ArduCopter disarms after)
        self._throttle_up_s: float | None = None  # last seen off zero (holds the idle disarm)

        self._interval_us: dict[str, int | None] = {}  # per-message overrides; None: stopped
        self._due_us: dict[str, int] = {}
        self._next_due_us = 0  # earliest due time over every stream (0: look again)
        # Every stream's interval, in emission order, for advance() to go through whenever
        # something is due; None: to be worked out again (a parameter or an interval changed).
        self._schedule: tuple[tuple[str, int | None], ...] | None = None
        self._absent = NOT_STREAMED.get(firmware, frozenset())
        # What it streams and answers with: every message it builds (see telemetry.py).
        self.telemetry = Telemetry(self)
        # Message name -> the method that builds it, looked up once rather than per message.
        self._builders: dict[str, Callable[[float], Any]] = self.telemetry.builders(
            (*STREAM_GROUPS, "HOME_POSITION", "AUTOPILOT_VERSION")
        )
        # The truth every message built by one advance() call reports (see _truth).
        self._advancing = False
        self._advance_truth: Truth | None = None
        self._deferred: list[str] = []  # messages asked for, sent after the acknowledgement
        self._heartbeat_sent = False  # stream requests before the first one are lost
        # The source line of an internal error that blocks arming until a reboot (None:
        # none), and whether ArduCopter entered SMART_RTL disarmed since it last armed.
        self._internal_error: int | None = None
        self._smart_rtl_entered = False
        self._guided_arrival_due = False  # MISSION_ITEM_REACHED due at the guided target
        self._home_locked = False  # set by a ground station: ArduPilot moves it no more
        self._rtl_arrival_due = False  # ArduRover's "Reached destination" still to say
        self._takeoff_starts_s = -math.inf  # ArduPlane's takeoff proper starts then
        self._guided_wp_active = False  # ArduCopter flies guided position targets now
        self._text_id = 0  # id of the last STATUSTEXT sent in chunks
        # The parameters the simulation acts on (read on hot paths by name), and the whole
        # list ArduPilot's firmware reports, over them (ap_params: the firmware's values
        # win over SITL's default-parameter file; a profile's over both).
        self._params: dict[str, Param] = {"MAV_SYSID": Param(system_id, INT16)}
        for name, (value, kind) in {**COMMON_PARAMS, **self.fw.params}.items():
            if name in STREAM_RATES:
                value = self.fw.default_stream_hz if value else 0.0
            self._params[name] = Param(float(value), kind)
        self.params = ParamStore(firmware, self._params)
        """Every parameter a ground station can read and set, in ArduPilot's order."""
        self.parameters = Parameters(self)
        """PARAM_* answered, and what setting a parameter does."""
        for name, value in (params or {}).items():
            if name not in self.params:
                raise ValueError(f"no parameter {name!r} in the simulated {firmware}")
            self.parameters.set(name, value)
        self._logging_until_s = -math.inf  # AP_Logger logs on this long after a disarm
        self.model.configure(self.param_values())

        self._mode_reason: ModeReason = "autopilot"  # why the current mode was entered
        self.fence_checks = FenceChecks(self)
        """When and against what the fence is checked, and what it asks of the autopilot."""
        self.fence = ArduFence(
            firmware, self._param_value, self._text, self.fence_checks.status_due
        )
        """ArduPilot's geofence (FENCE_* and the uploaded fence list)."""
        self._fence_list_changes = -1  # MissionProtocol.changed when the zones were built
        # The fence was idle at its last check and nothing it reads changed since (a
        # parameter, the fence list, DO_FENCE_ENABLE, arming): checks are skipped.
        self._fence_quiet = False
        self._next_fence_check_s = 0.0
        self._next_fence_update_s = 0.0
        self.gcs_failsafe = GcsFailsafe(firmware, boot_s)
        """ArduPilot's ground-station failsafe (MAV_GCS_SYSID's heartbeats)."""
        self._hooks = SafetyHooks(self)
        self._plane_climbing = False  # ArduPlane in its TAKEOFF climb at the last look
        # ArduRover's simple avoidance: the point the model drives to instead of the
        # target, when the straight line to the target would cross the fence margin.
        self._avoid_cut = False
        self.avoidance = Avoidance(self)
        """ArduRover's simple avoidance (AC_Avoid), stopping guided targets short of the fence."""

        self.rc_overrides = RcOverrides(self)
        """RC_CHANNELS_OVERRIDE from the ground station, and their lapsing."""
        self._target: tuple[float, float, float] | None = None  # guided lat, lon, rel alt
        # A velocity target (ArduCopter extrapolates it): position, velocity n/e, set at.
        self._velocity_target: tuple[float, float, float, float, float, float] | None = None
        self._peers: dict[tuple[int, int], float] = {}
        # Readiness and arming.
        self._home: tuple[float, float, float] | None = None  # lat, lon, alt AMSL
        self._home_sent_s = -math.inf
        self._next_home_check_s = 0.0
        self._next_ekf_check_s = 0.0
        self._ekf_fail_count = 0  # ArduRover's EKF check (Readiness.rover_ekf_check)
        self._ekf_failsafe = False
        self._armed_s: float | None = self.readiness.boot_armed()
        self._ground_since_s: float | None = None  # armed and on the ground since
        self._was_flying = self.model.airborne
        self._touchdown_s: float | None = None
        self._texts_due = self.readiness.boot_text_schedule()
        self._next_prearm_report_s = boot_s + PREARM_REPORT_PERIOD_S
        self._last_mode = self.model.mode
        if boot_s + self.boot_times.home_s <= 0.0:
            self.readiness.home_here(0.0)  # powered on long enough before time 0 to have a home

        self.bad_frames = 0
        """Garbage and corrupted frames received."""

    @classmethod
    def from_profile(
        cls,
        model: VehicleModel,
        autopilot: Mapping[str, Any],
        *,
        origin_lat_deg: float,
        origin_lon_deg: float,
        origin_alt_amsl_m: float = 0.0,
        start_time_unix_us: int | None = None,
        boot_s: float = 0.0,
        boot: BootTimes | None = None,
        unix_clock_us: Callable[[], int] | None = None,
    ) -> SimAutopilot:
        """The autopilot a resolved profile (``agent.hardware.autopilot``) describes.

        Firmware, ids, modes, guided mode and parameters come from the profile, so the
        engine's adapter, built from the same profile, finds it where it expects it.
        Profile parameters ArduPilot's list has are stored (a ground station reads them
        back) even where the simulation does not act on them; names the firmware does not
        have are left out.
        """
        mav = autopilot.get("mavlink") or {}
        firmware = str(autopilot["firmware"])
        channel = (autopilot.get("channels") or {}).get("throttle") or {}
        throttle = None
        if channel.get("rc") is not None:
            zero = channel.get("pwm_trim_us" if firmware == "ardurover" else "pwm_min_us")
            throttle = (int(channel["rc"]), int(zero if zero is not None else 1100))
        known = {"MAV_SYSID", *COMMON_PARAMS, *FIRMWARES[firmware].params}
        listed = sitl_table(firmware).types
        params = {
            str(name): float(value)
            for name, value in (autopilot.get("parameters") or {}).items()
            if name in known or name in listed
        }
        return cls(
            model,
            firmware=firmware,
            system_id=int(mav.get("system_id", 1)),
            component_id=int(mav.get("component_id", 1)),
            modes=dict(autopilot.get("modes") or model.modes),
            guided_mode=str(autopilot.get("guided_mode", "GUIDED")),
            origin_lat_deg=origin_lat_deg,
            origin_lon_deg=origin_lon_deg,
            origin_alt_amsl_m=origin_alt_amsl_m,
            start_time_unix_us=start_time_unix_us,
            boot_s=boot_s,
            boot=boot,
            params=params,
            unix_clock_us=unix_clock_us,
            throttle=throttle,
        )

    # -- public -----------------------------------------------------------------------------

    @property
    def sysid(self) -> int:
        """Its MAVLink system id."""
        return self._sysid

    @property
    def gcs_peers(self) -> Mapping[tuple[int, int], float]:
        """Ground stations heard: (system id, component id) -> time of their last heartbeat."""
        return dict(self._peers)

    @property
    def home(self) -> tuple[float, float, float] | None:
        """Home (latitude, longitude, altitude above mean sea level), None until set."""
        return self._home

    def param(self, name: str) -> float | None:
        """A parameter's value, None if it has no such parameter."""
        found = self.params.get(name)
        return None if found is None else found[0]

    def _param_value(self, name: str) -> float:
        return self._params[name].value

    def param_values(self) -> dict[str, float]:
        """Every parameter's value by name (what the vehicle model is configured from)."""
        return {name: entry.value for name, entry in self._params.items()}

    def set_home(self, lat_deg: float, lon_deg: float, alt_m: float, now_s: float) -> None:
        """Set home (as DO_SET_HOME does), e.g. where a pilot took off before the run."""
        self._home = (lat_deg, lon_deg, alt_m)
        north = (lat_deg - self.origin_lat_deg) * M_PER_DEG_LAT
        east = (
            (lon_deg - self.origin_lon_deg)
            * M_PER_DEG_LAT
            * math.cos(math.radians(self.origin_lat_deg))
        )
        self.model.set_home(north, east, alt_m - self.origin_alt_amsl_m)
        self.missions.write_home()
        if "HOME_POSITION" not in self._deferred:
            self._deferred.append("HOME_POSITION")
        self._next_due_us = 0

    def receive(self, data: bytes, now_s: float) -> None:
        """Take bytes from the ground station side and act on every complete message.

        Garbage and corrupted frames are counted and skipped. Answers leave with the
        next :meth:`advance`.
        """
        for msg in self._parser.parse_buffer(data) or []:
            if msg.get_type() == "BAD_DATA":
                self.bad_frames += 1
                continue
            self._handle(msg, now_s)

    def advance(self, now_s: float) -> bytes:
        """Everything due by ``now_s``: ArduPilot's own doings, queued answers, the streams due.

        Each stream is due on its own grid of intervals from its first emission
        (integer microseconds, so a virtual clock keeps exact rates); a message is
        sent at most once per call, so call at least as often as the fastest rate.
        RC overrides older than RC_OVERRIDE_TIME are released first.
        """
        if self.rc_overrides.channels:  # (usually there are none: a call saved at every step)
            self.rc_overrides.expire(now_s)
        if now_s >= self._mission_poll_s:  # resends and timeouts of an upload
            self._mission_poll_s = now_s + MISSION_POLL_S
            self.missions.poll(now_s)
        self._supervise(now_s)
        if self._deferred:
            self._send_deferred(now_s)
        if self.parameters.list_from_s is not None:
            self.parameters.send_list(now_s)
        now_us = round(now_s * 1e6)
        if now_us < self._next_due_us and not self._outbox.data:
            return b""  # nothing due and no answer queued: the common case, kept cheap
        due_us, send, builders = self._due_us, self._mav.send, self._builders
        self._advancing = True
        streaming = now_s - self.boot_s >= self.boot_times.streams_s
        for name, interval in self.streams.schedule():
            if interval is None or (not streaming and name != "HEARTBEAT"):
                due_us.pop(name, None)
                continue
            due = due_us.setdefault(name, now_us)
            if now_us < due:
                continue
            message = builders[name](now_s)
            if message is not None:
                send(message)
            due += interval
            due_us[name] = due if due > now_us else now_us + interval
        self._advancing = False
        self._advance_truth = None
        self._next_due_us = min(due_us.values(), default=now_us)
        if not streaming:
            self._next_due_us = min(
                self._next_due_us, round((self.boot_s + self.boot_times.streams_s) * 1e6)
            )
        data, self._outbox.data = bytes(self._outbox.data), bytearray()
        return data

    # -- ArduPilot's own doings ---------------------------------------------------------------

    def _supervise(self, now_s: float) -> None:
        """What ArduPilot does by itself: boot texts, home, pre-arm reports, auto-disarm.

        Also its fence and its ground-station failsafe, each at its firmware's rate.
        """
        self._hooks.now_s = now_s
        if self._texts_due and self._texts_due[0][0] <= now_s:
            while self._texts_due and self._texts_due[0][0] <= now_s:
                _at, severity, text = self._texts_due.pop(0)
                self._text(severity, text)
        if self._home is None and self.readiness.age_s(now_s) >= self.boot_times.home_s:
            self.readiness.home_here(now_s)
        elif (
            self.fw.home_at == "while_disarmed"
            and self._home is not None
            and not self.model.armed
            and now_s - self._home_sent_s >= PLANE_HOME_PERIOD_S
            and "HOME_POSITION" not in self._deferred
        ):
            # ArduPlane's home follows its GPS until it arms (and is sent again, unmoved,
            # once a ground station has set it).
            if self._home_locked:
                self.set_home(*self._home, now_s)
            else:
                self.readiness.home_here(now_s)
        elif (
            self.fw.home_at == "disarming"
            and self._home is not None
            and not self._home_locked
            and not self.model.armed
            and now_s >= self._next_home_check_s
        ):
            # ArduRover's one-second loop: while disarmed, home follows the vehicle once
            # it is DISTANCE_HOME_MINCHANGE away (a rover still rolling after its disarm).
            self._next_home_check_s = now_s + ROVER_HOME_CHECK_PERIOD_S
            if self.readiness.distance_from_home_m() >= ROVER_HOME_MIN_CHANGE_M:
                self.readiness.home_here(now_s)
        if self.firmware == "ardurover" and now_s >= self._next_ekf_check_s:
            self.readiness.rover_ekf_check(now_s)
        if now_s >= self._next_prearm_report_s:
            self._next_prearm_report_s = now_s + PREARM_REPORT_PERIOD_S
            if not self.model.armed:
                for reason in self.arming.refusals(now_s, self.model.mode):
                    self._text(_CRITICAL, "Pre" + reason)
        if self._velocity_target is not None:
            self.commands.fly_velocity_target(now_s)
        if self.model.mode == "AUTO":
            self.auto.fly(now_s)
        if (
            self._guided_arrival_due
            and self.model.target_reached
            and self._in_guided()
            and not self._avoid_cut
        ):
            self._guided_arrival_due = False
            self._mav.send(self._mav.mission_item_reached_encode(0))
        if (
            self._rtl_arrival_due
            and self.model.armed
            and self.model.target_reached
            and self.model.truth().ground_speed_m_s < ROVER_STOPPED_M_S
        ):
            self._rtl_arrival_due = False  # ArduRover's RTL and SMART_RTL stop there
            self._text(_INFO, "Reached destination")
        if now_s >= self._next_fence_update_s:
            # AC_Fence::update at 10 Hz: a FENCE_ENABLE changed and changed back between
            # two of them goes unnoticed, as on ArduPilot (measured).
            self._next_fence_update_s = max(self._next_fence_update_s + FENCE_UPDATE_S, now_s)
            if not self._fence_quiet:
                self.fence.update()
        if now_s >= self._next_fence_check_s:
            self.fence_checks.check(now_s)
        if now_s >= self.gcs_failsafe.next_check_s:
            self.gcs_failsafe.check(self._hooks, now_s)
        if self._plane_climbing or (self.firmware == "arduplane" and self.model.mode == "TAKEOFF"):
            climbing = self._hooks.initial_climb
            if self._plane_climbing and not climbing and self.model.mode == "TAKEOFF":
                self.gcs_failsafe.takeoff_climb_over(self._hooks)
            self._plane_climbing = climbing
        self.arming.landing_and_disarm(now_s)

    # -- the fence ----------------------------------------------------------------------

    def _to_local(self, lat_deg: float, lon_deg: float) -> Point2:
        """(north_m, east_m) from the mission origin (the model's frame)."""
        north = (lat_deg - self.origin_lat_deg) * M_PER_DEG_LAT
        east = (
            (lon_deg - self.origin_lon_deg)
            * M_PER_DEG_LAT
            * math.cos(math.radians(self.origin_lat_deg))
        )
        return north, east

    def _from_local(self, north_m: float, east_m: float) -> tuple[float, float]:
        lat = self.origin_lat_deg + north_m / M_PER_DEG_LAT
        lon = self.origin_lon_deg + east_m / (
            M_PER_DEG_LAT * math.cos(math.radians(self.origin_lat_deg))
        )
        return lat, lon

    # -- ArduRover's simple avoidance ----------------------------------------------------------

    def _text(self, severity: int, text: str) -> None:
        """A STATUSTEXT, as ArduPilot's gcs().send_text.

        A text longer than 50 characters goes in 50-character chunks that share an id
        (1-255, counting up), each with its chunk_seq; a short one has id 0.
        """
        data = text.encode("ascii", "replace")
        if len(data) <= STATUSTEXT_CHUNK:
            self._mav.send(self._mav.statustext_encode(severity, data))
            return
        self._text_id = self._text_id % 255 + 1
        for seq, start in enumerate(range(0, len(data), STATUSTEXT_CHUNK)):
            chunk = data[start : start + STATUSTEXT_CHUNK]
            self._mav.send(self._mav.statustext_encode(severity, chunk, self._text_id, seq))

    def _say_at(self, at_s: float, severity: int, text: str) -> None:
        """A STATUSTEXT to send at ``at_s`` (with the boot texts' schedule)."""
        self._texts_due.append((at_s, severity, text))
        self._texts_due.sort(key=lambda due: due[0])

    # -- modes -------------------------------------------------------------------------------

    def _in_guided(self) -> bool:
        return self.model.mode == self.guided_mode

    # -- handling ---------------------------------------------------------------------------

    def _handle(self, msg: Any, now_s: float) -> None:
        self._hooks.now_s = now_s
        source = (msg.get_srcSystem(), msg.get_srcComponent())
        if source == (self._sysid, self._compid):
            return  # our own frames echoed back by a shared link
        target_system = getattr(msg, "target_system", 0)
        target_component = getattr(msg, "target_component", 0)
        if target_system not in (0, self._sysid) or target_component not in (0, self._compid):
            return  # addressed to another vehicle or component
        asker = _Asker(*source)
        kind = msg.get_type()
        if not self._accepts(msg):
            return
        if kind == "HEARTBEAT":
            if msg.type == mavlink2.MAV_TYPE_GCS or msg.autopilot == mavlink2.MAV_AUTOPILOT_INVALID:
                self._peers[source] = now_s
            if source[0] == self._gcs_sysid():  # any type, any component
                self.gcs_failsafe.seen(now_s)
        elif kind == "MANUAL_CONTROL":
            # Not flown here, but ArduPilot counts it as its ground station's heartbeat.
            if source[0] == self._gcs_sysid() and msg.target == self._sysid:
                self.gcs_failsafe.seen(now_s)
        elif kind == "COMMAND_LONG":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6)
            result = self.commands.command(msg.command, params, msg.param7, None, now_s)
            self._ack(msg.command, result, asker)
            self._send_deferred(now_s)
        elif kind == "COMMAND_INT":
            params = (msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y)
            result = self.commands.command(msg.command, params, msg.z, msg.frame, now_s)
            self._ack(msg.command, result, asker)
            self._send_deferred(now_s)
        elif kind == "SET_MODE":
            self.mode_changes.set_mode(
                msg.base_mode, msg.custom_mode, now_s
            )  # ArduPilot 4.7: no ack
        elif kind == "SET_POSITION_TARGET_GLOBAL_INT":
            self.commands.position_target(msg, now_s)
        elif kind == "RC_CHANNELS_OVERRIDE":
            self.rc_overrides.receive(msg, now_s)
        elif kind == "PARAM_REQUEST_LIST":  # (a second one starts the list again)
            self.parameters.list_from_s, self.parameters.list_sent = now_s, 0
        elif kind == "PARAM_REQUEST_READ":
            self.parameters.handle_read(msg)
        elif kind == "PARAM_SET":
            self.parameters.handle_set(msg)
        elif kind == "REQUEST_DATA_STREAM":
            self.streams.request_data_stream(msg)
        elif kind.startswith("MISSION_") and self.missions.handle(msg, now_s):
            pass  # the mission protocol answered (the executor sees what changed)
        elif kind in ("MISSION_ITEM_INT", "MISSION_ITEM"):
            # A guided-mode waypoint (current 2) or altitude change (current 3).
            result = self.commands.mission_item(msg, now_s, integer=kind == "MISSION_ITEM_INT")
            self._mav.send(
                self._mav.mission_ack_encode(
                    asker.system_id, asker.component_id, result, msg.mission_type
                )
            )
        elif kind == "FILE_TRANSFER_PROTOCOL":
            self._ftp_nak(msg, asker)
        elif kind == "TIMESYNC" and msg.tc1 == 0:
            self._mav.send(self._mav.timesync_encode(round((now_s - self.boot_s) * 1e9), msg.ts1))

    def _accepts(self, msg: Any) -> bool:
        """Whether ArduPilot takes this message (GCS_MAVLINK::accept_packet).

        With MAV_OPTIONS bit 0 only our own system, MAV_GCS_SYSID, and radio status
        messages are taken; otherwise everyone.
        """
        if not int(self._params["MAV_OPTIONS"].value) & _MAV_OPTION_GCS_ONLY:
            return True
        sysid = msg.get_srcSystem()
        return sysid in (self._sysid, self._gcs_sysid()) or msg.get_type() in (
            "RADIO",
            "RADIO_STATUS",
        )

    def _gcs_sysid(self) -> int:
        """MAV_GCS_SYSID: the system whose heartbeats and RC overrides are the GCS's."""
        return int(self._params["MAV_GCS_SYSID"].value)

    def _ack(self, command: int, result: int, asker: _Asker) -> None:
        self._mav.send(
            self._mav.command_ack_encode(command, result, 0, 0, asker.system_id, asker.component_id)
        )

    def _send_deferred(self, now_s: float) -> None:
        for name in self._deferred:
            message = self._build(name, now_s)
            if message is not None:
                self._mav.send(message)
        self._deferred.clear()

    def _goto(self, lat_deg: float, lon_deg: float, alt_m: float) -> bool:
        self._target = (lat_deg, lon_deg, alt_m)
        self._guided_arrival_due = self.fw.guided_reached_text
        taken = self.avoidance.drive_to(lat_deg, lon_deg, alt_m)
        self._guided_wp_active = taken and self.model.airborne
        return taken

    def _relative_alt_m(self, alt: float, frame: int) -> float | None:
        """A target's height above the origin (the model's frame) from its frame's altitude."""
        home_alt = self._home[2] if self._home is not None else self.origin_alt_amsl_m
        if frame in (
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
            mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT,
            mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT_INT,  # flat terrain at home's altitude
            mavlink2.MAV_FRAME_GLOBAL_TERRAIN_ALT,
        ):
            return float(alt) + home_alt - self.origin_alt_amsl_m
        if frame in (mavlink2.MAV_FRAME_GLOBAL_INT, mavlink2.MAV_FRAME_GLOBAL):
            return float(alt) - self.origin_alt_amsl_m
        return None

    # -- message requests ---------------------------------------------------------------------

    def _ftp_nak(self, msg: Any, asker: _Asker) -> None:
        seq, session, opcode = struct.unpack_from("<HBB", bytes(msg.payload[:4]))
        header = _FTP_HEADER.pack((seq + 1) & 0xFFFF, session, _FTP_OP_NAK, 1, opcode, 0, 0, 0)
        payload = [*header, _FTP_ERR_UNKNOWN_COMMAND]
        payload += [0] * (_FTP_PAYLOAD_BYTES - len(payload))
        self._mav.send(
            self._mav.file_transfer_protocol_encode(
                msg.target_network, asker.system_id, asker.component_id, payload
            )
        )

    # -- streams -----------------------------------------------------------------------------

    def _build(self, name: str, now_s: float) -> Any:
        return self._builders[name](now_s)

    def _truth(self) -> Truth:
        """The model's true state, for the message builders.

        Within one :meth:`advance` call the model does not move, and up to five of the
        messages it sends report its state: it is read once per call. Outside one
        (answers to requests, which follow commands that may change the model) it is
        read afresh.
        """
        truth = self._advance_truth
        if truth is None:
            truth = self.model.truth()
            if self._advancing:
                self._advance_truth = truth
        return truth

    def _home_alt_m(self) -> float:
        return self._home[2] if self._home is not None else self.origin_alt_amsl_m

    # GLOBAL_POSITION_INT, ATTITUDE and VFR_HUD go out at the telemetry rate: each is one
    # pymavlink message object (built in __init__) whose fields are set before every send,
    # which packs it anew, rather than a new object each time.
