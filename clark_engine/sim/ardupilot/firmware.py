"""How each ArduPilot firmware behaves where a ground station or the engine can tell.

The simulated autopilot (:mod:`clark_engine.sim.ardupilot.autopilot`) is only worth its
name where it refuses what ArduPilot refuses, says what ArduPilot says and takes
as long as ArduPilot takes. Those facts differ between ArduRover, ArduCopter and
ArduPlane and are data, not logic, so they live here, one :class:`Firmware` per
firmware, with where each was measured: every number below was read off the
ArduPilot SITL builds in ``../shared/ardupilot-sitl`` (master of 2025-07-21),
booted fresh at the mission origin, unless it says "ArduPilot default" (the
firmware's parameter default, which SITL's own parameter files may change).

The conformance suite (``tests/conformance``) runs the same scenarios against
this simulation and against SITL, so a fact here that drifts from the real
firmware fails a test; docs/autopilot-fidelity.md tables what each does.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

_INT8, _INT16, _INT32, _REAL32 = (
    mavlink2.MAV_PARAM_TYPE_INT8,
    mavlink2.MAV_PARAM_TYPE_INT16,
    mavlink2.MAV_PARAM_TYPE_INT32,
    mavlink2.MAV_PARAM_TYPE_REAL32,
)

_INFO, _NOTICE, _WARNING = (
    int(mavlink2.MAV_SEVERITY_INFO),
    int(mavlink2.MAV_SEVERITY_NOTICE),
    int(mavlink2.MAV_SEVERITY_WARNING),
)

Texts = tuple[tuple[int, str], ...]
"""STATUSTEXTs as (MAV_SEVERITY, text), in the order ArduPilot sends them."""

FORCE_MAGIC: Final = frozenset({2989.0, 21196.0})
"""MAV_CMD_COMPONENT_ARM_DISARM param2 values that skip the checks (ArduPilot's)."""


@dataclass(frozen=True, slots=True)
class BootTimes:
    """When a freshly powered ArduPilot gets ready, in seconds after power-on.

    Attributes:
        streams_s: "ArduPilot Ready": messages other than HEARTBEAT start (a stream
            requested earlier, once the first HEARTBEAT was out, starts here too).
        attitude_s: The EKF has an attitude (EKF_STATUS_REPORT flags 0xA7).
        gps_fix_s: The GPS has a 3-D fix; positions are 0, 0 before it.
        origin_s: The EKF origin is set ("EKF3 IMU0 origin set").
        home_s: Home is set and HOME_POSITION first sent.
        prearm_s: The pre-arm checks pass in a mode that needs no position.
        position_s: The EKF uses the GPS: an absolute horizontal position
            (flags 0x33F); modes and arming that need a position are possible.
    """

    streams_s: float
    attitude_s: float
    gps_fix_s: float
    origin_s: float
    home_s: float
    prearm_s: float
    position_s: float

    def scaled(self, ready_s: float) -> BootTimes:
        """The same sequence, stretched or squeezed so that the last step comes at ``ready_s``.

        For a dry run that wants its vehicles ready sooner (or later) than SITL's
        (``sim.autopilot_ready_s``); the order of the steps is kept.
        """
        last = max(self.prearm_s, self.position_s)
        k = ready_s / last if last > 0 else 1.0
        return BootTimes(*(getattr(self, name) * k for name in self.__dataclass_fields__))

    def shifted(self, by_s: float) -> BootTimes:
        """The same sequence ``by_s`` seconds later (earlier when negative), never before 0.

        For ``sim.jitter.ready_s``: one autopilot boots a little sooner or later than
        another. A step an earlier shift would put before power-on happens at power-on;
        the order of the steps is kept.
        """
        return BootTimes(
            *(max(0.0, getattr(self, name) + by_s) for name in self.__dataclass_fields__)
        )


@dataclass(frozen=True, slots=True)
class Firmware:
    """One firmware's rules, texts, timings and parameter defaults.

    Attributes:
        name: ``ardurover``, ``arducopter`` or ``arduplane``.
        boot: Its boot timeline (SITL's).
        boot_mode: The mode it boots in (what its mode switch selects in SITL).
        initialising_mode: The mode number reported for the first second, or None.
        default_stream_hz: Rate of every telemetry stream before a ground station
            asks for one (ArduCopter streams nothing; ArduRover and ArduPlane 1 Hz).
        early_stream_requests_lost: SET_MESSAGE_INTERVAL requests that arrive before
            the autopilot's first HEARTBEAT are acknowledged (ACCEPTED) and then lost:
            GCS_MAVLINK sets every interval from the SRn_* rates at its first send,
            which also sends that HEARTBEAT. Measured on all three SITL builds (a
            request sent on connecting: ArduCopter never streamed it, ArduRover and
            ArduPlane at their 1 Hz default); a request sent after the first
            HEARTBEAT, even long before "ArduPilot Ready", is kept on all three.
        not_armable: Modes arming is refused in.
        arm_needs_position: Modes arming in needs an EKF position.
        absent_modes: Modes of the profile this build does not have: refused with
            WARNING "No such mode N" (compiled out, or another frame's).
        refused_modes: Modes always refused here, with the texts ArduPilot gives, in
            order (a mode whose init fails on these vehicles: no follow target, no
            optical flow, no landing sequence...). ``{mode}`` is the mode's name as the
            firmware spells it.
        set_needs_origin: Modes that cannot be entered before the EKF origin is set
            (disarmed; ArduRover), or before it has a position (ArduCopter).
        set_needs_position_armed: Modes that cannot be entered armed before the EKF
            has an absolute position; checked before anything else about the mode.
        position_refused_text: The WARNING of that refusal.
        refused_armed_on_ground: Modes refused when armed on the ground (texts).
        enter_texts: Texts sent on entering a mode.
        arm_texts: Texts sent after the armed text when arming in a mode.
        set_home_text: Whether DO_SET_HOME says "Set HOME to LAT LON at ALTm" (ArduRover).
        baro_alt_until: Until when GLOBAL_POSITION_INT.alt (and VFR_HUD.alt) is the
            barometer's height (about 0 m on any field) rather than above sea level:
            ``position`` (ArduRover: its AHRS stays on DCM until the EKF uses the GPS,
            about 42 s), ``home`` (ArduPlane: until home, 0.8 s after the fix), None
            (ArduCopter: the GPS's from the first fix). ArduRover also sets home at that
            barometer height while it lasts (0.19 m measured), so its relative_alt reads
            +90 m on a 90 m field. Measured on SITL (docs/sitl-measurements.md, section 1).
        zero_before_fix: GLOBAL_POSITION_INT is all zero before the GPS fix (ArduCopter
            sends its never-filled location); the others send the barometer's height.
        guided_reached_text: Whether arriving at a guided target sends
            MISSION_ITEM_REACHED (seq 0), as ArduRover does (measured).
        throttle_too_high_modes: Modes whose arming with the throttle off zero says
            "Arm: Throttle too high" (ArduCopter's pilot-throttle modes); elsewhere
            "Arm: Throttle (RC3) is not neutral" (measured on all three).
        home_at: When home moves to where the vehicle is: ``arming`` (ArduCopter),
            ``disarming`` (ArduRover), ``while_disarmed`` (ArduPlane follows its GPS
            until armed).
        mode_refused_text: The WARNING on a refused mode change; ``{mode}`` is the
            mode's name as ArduPilot spells it.
        not_armable_text: The CRITICAL text when the mode is not armable.
        no_position_text: The CRITICAL text when arming needs a position it lacks.
        armed_text: The INFO text of a successful arm.
        disarmed_text: The INFO text of a disarm.
        auto_disarm_s: Seconds on the ground after arming before it disarms by itself
            (ArduCopter's DISARM_DELAY); None: never.
        params: Parameter name -> (ArduPilot default, MAV_PARAM_TYPE) beyond the
            common ones.
        hidden_params: Parameters of ``params`` that ArduPilot hides from this
            vehicle's parameter list (``AP_GROUPINFO_FRAME`` for other frames) but still
            reads and sets by name (ArduRover's FENCE_ALT_MAX, measured).
        flight_params: The parameters that shape how the vehicle moves (speeds,
            accelerations, radii, heights): a SITL autopilot standing in for the
            simulated one (``clark dry-run --autopilot sitl``) is set to the same values,
            so that the two fly the same vehicle. The others (throttle tuning, stream
            rates) stay SITL's own, tuned for its vehicle model.
        spelled: Mode name -> how ArduPilot's texts spell it (SMART_RTL -> SMARTRTL).
    """

    name: str
    boot: BootTimes
    boot_mode: str
    initialising_mode: int | None
    default_stream_hz: float
    early_stream_requests_lost: bool
    not_armable: frozenset[str]
    arm_needs_position: frozenset[str]
    absent_modes: frozenset[str]
    refused_modes: Mapping[str, Texts]
    set_needs_origin: frozenset[str]
    set_needs_position_armed: frozenset[str]
    position_refused_text: str
    home_at: str
    mode_refused_text: str
    not_armable_text: str
    no_position_text: str
    armed_text: str
    disarmed_text: str
    auto_disarm_s: float | None
    params: Mapping[str, tuple[float, int]] = field(default_factory=dict)
    hidden_params: frozenset[str] = frozenset()
    flight_params: tuple[str, ...] = ()
    spelled: Mapping[str, str] = field(default_factory=dict)
    refused_armed_on_ground: Mapping[str, Texts] = field(default_factory=dict)
    enter_texts: Mapping[str, Texts] = field(default_factory=dict)
    arm_texts: Mapping[str, Texts] = field(default_factory=dict)
    throttle_too_high_modes: frozenset[str] = frozenset()
    guided_reached_text: bool = False
    set_home_text: bool = False
    baro_alt_until: str | None = None
    zero_before_fix: bool = False

    def spell(self, mode: str) -> str:
        """A mode's name as this firmware's texts spell it."""
        return self.spelled.get(mode, mode)


STREAM_RATE_PREFIX: Final = "MAV1_"
"""The stream-rate parameters of the first MAVLink channel (ArduPilot 4.7's MAV1_EXTRA1...;
4.5's SR0_EXTRA1... are gone)."""

COMMON_PARAMS: Final[Mapping[str, tuple[float, int]]] = {
    "MAV_GCS_SYSID": (255, _INT16),
    "MAV_OPTIONS": (0, _INT16),
    "RC_OVERRIDE_TIME": (3.0, _REAL32),
    "BATT_CAPACITY": (3300, _INT32),
    "MAV1_EXT_STAT": (1, _INT16),
    "MAV1_RC_CHAN": (1, _INT16),
    "MAV1_POSITION": (1, _INT16),
    "MAV1_EXTRA1": (1, _INT16),
    "MAV1_EXTRA2": (1, _INT16),
    "MAV1_EXTRA3": (1, _INT16),
    # The fence (AC_Fence), on every firmware; the per-firmware defaults are below.
    "FENCE_ENABLE": (0, _INT8),
    "FENCE_ACTION": (1, _INT8),
    "FENCE_RADIUS": (300.0, _REAL32),
    "FENCE_MARGIN": (2.0, _REAL32),
    "FENCE_TOTAL": (0, _INT8),
    "FENCE_OPTIONS": (0, _INT16),
    "FENCE_NTF_FREQ": (1.0, _REAL32),
    "FENCE_ALT_MAX": (100.0, _REAL32),
    "FENCE_ALT_MIN": (-10.0, _REAL32),
    "FENCE_AUTOENABLE": (0, _INT8),
}
"""Parameters every firmware has (after MAV_SYSID), with ArduPilot 4.7's names, types and
defaults as each SITL build reads them back (docs/sitl-measurements.md, sections 3-5).
MAV_GCS_SYSID is the one system whose HEARTBEAT, RC_CHANNELS_OVERRIDE and MANUAL_CONTROL
count as the ground station's (ArduPilot 4.5 called it SYSID_MYGCS, and MAV_SYSID
SYSID_THISMAV; those names are unknown here as in 4.7). MAV_OPTIONS bit 0 accepts MAVLink
only from MAV_GCS_SYSID. The MAV1_* stream rates of the groups it streams are the
firmware's own (Firmware.default_stream_hz) at start; the others (MAV1_RAW_SENS,
MAV1_RAW_CTRL, MAV1_PARAMS) it does not act on, and lists with SITL's values
(sim/ardupilot/params.py). FENCE_* are metres above home (ALT_MAX, ALT_MIN) and from home
(RADIUS); FENCE_TYPE is per firmware."""

RETURN_ALTITUDE_PARAMS: Final[Mapping[str, tuple[str, float]]] = {
    "arducopter": ("RTL_ALT", 0.01),
    "arduplane": ("RTL_ALTITUDE", 1.0),
}
"""Per firmware: the parameter of the height RTL returns at (above home), and the metres per
unit it is in (ArduCopter's RTL_ALT is in centimetres, ArduPlane's RTL_ALTITUDE in metres).
ArduRover drives home at its own height."""

GCS_FAILSAFE_PARAMS: Final[Mapping[str, tuple[str, ...]]] = {
    "arducopter": ("FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "FS_OPTIONS"),
    "ardurover": ("FS_GCS_ENABLE", "FS_GCS_TIMEOUT", "FS_ACTION", "FS_TIMEOUT", "FS_OPTIONS"),
    "arduplane": (
        "FS_GCS_ENABL",
        "FS_LONG_ACTN",
        "FS_LONG_TIMEOUT",
        "FS_SHORT_ACTN",
        "FS_SHORT_TIMEOUT",
    ),
}
"""Per firmware: the parameters of its ground-station (heartbeat) failsafe, in its names."""

FENCE_PARAMS: Final[Mapping[str, tuple[str, ...]]] = {
    "arducopter": (
        "FENCE_ENABLE",
        "FENCE_TYPE",
        "FENCE_ACTION",
        "FENCE_ALT_MAX",
        "FENCE_ALT_MIN",
        "FENCE_RADIUS",
        "FENCE_MARGIN",
        "FENCE_AUTOENABLE",
        "FENCE_OPTIONS",
    ),
    "ardurover": (
        "FENCE_ENABLE",
        "FENCE_TYPE",
        "FENCE_ACTION",
        "FENCE_RADIUS",
        "FENCE_MARGIN",
        "FENCE_OPTIONS",
        "AVOID_ENABLE",
    ),
    "arduplane": (
        "FENCE_ENABLE",
        "FENCE_TYPE",
        "FENCE_ACTION",
        "FENCE_ALT_MAX",
        "FENCE_ALT_MIN",
        "FENCE_RADIUS",
        "FENCE_MARGIN",
        "FENCE_AUTOENABLE",
        "FENCE_OPTIONS",
    ),
}
"""Per firmware: its fence's parameters as a ground station sees them in its list (ArduRover
also reads and sets FENCE_ALT_MAX, FENCE_ALT_MIN and FENCE_AUTOENABLE by name, and ignores
them: it has no altitude fence)."""

ROVER: Final = Firmware(
    name="ardurover",
    boot=BootTimes(
        streams_s=2.45,
        attitude_s=6.05,
        gps_fix_s=9.05,
        origin_s=19.85,
        home_s=10.05,
        prearm_s=24.0,
        position_s=41.85,
    ),
    boot_mode="MANUAL",
    initialising_mode=16,
    default_stream_hz=1.0,
    early_stream_requests_lost=True,
    not_armable=frozenset({"RTL", "SMART_RTL"}),
    arm_needs_position=frozenset(
        {"GUIDED", "LOITER", "CIRCLE", "SIMPLE", "STEERING", "ACRO", "AUTO", "RTL", "SMART_RTL"}
    ),
    absent_modes=frozenset(),
    refused_modes={
        "FOLLOW": ((_WARNING, "Flight mode change failed"),),  # no FOLL_ENABLE
        "DOCK": ((_NOTICE, "Dock: target not acquired"), (_WARNING, "Flight mode change failed")),
        "INITIALISING": ((_WARNING, "Flight mode change failed"),),
    },
    set_needs_origin=frozenset({"RTL", "SMART_RTL", "LOITER", "CIRCLE"}),
    set_needs_position_armed=frozenset(
        {"GUIDED", "RTL", "SMART_RTL", "AUTO", "LOITER", "CIRCLE", "SIMPLE", "DOCK"}
    ),
    position_refused_text="Flight mode change failed",
    home_at="disarming",
    mode_refused_text="Flight mode change failed",
    not_armable_text="Arm: Mode not armable",
    no_position_text="Arm: AHRS: not using configured AHRS type",
    armed_text="Throttle armed",
    disarmed_text="Throttle disarmed",
    auto_disarm_s=None,
    guided_reached_text=True,
    set_home_text=True,
    baro_alt_until="position",
    params={
        # ArduRover defaults (AR_WPNav, AR_AttitudeControl, Rover/Parameters.cpp).
        "CRUISE_SPEED": (2.0, _REAL32),
        "CRUISE_THROTTLE": (50, _INT8),
        "WP_SPEED": (2.0, _REAL32),
        "WP_RADIUS": (2.0, _REAL32),
        "WP_ACCEL": (0.0, _REAL32),
        "ATC_ACCEL_MAX": (1.0, _REAL32),
        "ATC_DECEL_MAX": (0.0, _REAL32),
        "ATC_TURN_MAX_G": (0.6, _REAL32),
        "TURN_RADIUS": (0.9, _REAL32),
        "RTL_SPEED": (0.0, _REAL32),
        # The fence (AC_Fence: circle and polygons only) and simple avoidance (AC_Avoid),
        # which stops the rover FENCE_MARGIN short of a circle fence.
        "FENCE_TYPE": (6, _INT8),
        "AVOID_ENABLE": (3, _INT8),
        "AVOID_MARGIN": (2.0, _REAL32),
        # The ground-station failsafe (Rover::gcs_failsafe_check, Rover::failsafe_trigger).
        "FS_GCS_ENABLE": (0, _INT8),
        "FS_GCS_TIMEOUT": (5.0, _REAL32),
        "FS_ACTION": (2, _INT8),
        "FS_TIMEOUT": (1.5, _REAL32),
        "FS_OPTIONS": (0, _INT32),
    },
    hidden_params=frozenset({"FENCE_ALT_MAX", "FENCE_ALT_MIN", "FENCE_AUTOENABLE"}),
    flight_params=(
        "WP_SPEED",
        "WP_RADIUS",
        "WP_ACCEL",
        "ATC_ACCEL_MAX",
        "ATC_DECEL_MAX",
        "RTL_SPEED",
    ),
)

COPTER: Final = Firmware(
    name="arducopter",
    boot=BootTimes(
        streams_s=2.45,
        attitude_s=6.0,
        gps_fix_s=10.0,
        origin_s=20.0,
        home_s=20.0,
        prearm_s=23.5,
        position_s=41.5,
    ),
    boot_mode="STABILIZE",
    initialising_mode=None,
    default_stream_hz=0.0,
    early_stream_requests_lost=True,
    not_armable=frozenset({"RTL", "CIRCLE", "LAND", "BRAKE", "SMART_RTL", "AUTO", "AVOID_ADSB"}),
    arm_needs_position=frozenset(
        {
            "GUIDED",
            "LOITER",
            "POSHOLD",
            "AUTO",
            "RTL",
            "CIRCLE",
            "BRAKE",
            "SMART_RTL",
            "DRIFT",
            "ZIGZAG",
            "THROW",
        }
    ),
    # Compiled out of the SITL build, as of the 4.5 release (SPORT), only for helicopters
    # (AUTOROTATE) or newer than 4.5 (RATE_ACRO).
    absent_modes=frozenset({"SPORT", "AUTOROTATE", "RATE_ACRO"}),
    refused_modes={
        "FLIP": ((_WARNING, "Mode change to FLIP failed: init failed"),),  # never on the ground
        "AUTOTUNE": ((_WARNING, "Mode change to AUTOTUNE failed: init failed"),),
        "FLOWHOLD": ((_WARNING, "Mode change to FLOWHOLD failed: init failed"),),  # no flow
        "TURTLE": ((_WARNING, "Mode change to TURTLE failed: init failed"),),
        "FOLLOW": (
            (_WARNING, "Set FOLL_ENABLE = 1"),
            (_WARNING, "Mode change to FOLLOW failed: init failed"),
        ),
        "SYSTEMID": (
            (_WARNING, "No axis selected, SID_AXIS = 0"),
            (_WARNING, "Mode change to SYSTEMID failed: init failed"),
        ),
        "AUTO_RTL": (
            (_WARNING, "Unable to start landing sequence"),
            (
                _WARNING,
                "Mode change to AUTO RTL failed: No return path or landing sequence found",
            ),
        ),
    },
    set_needs_origin=frozenset({"SMART_RTL"}),
    set_needs_position_armed=frozenset(
        {
            "RTL",
            "SMART_RTL",
            "AUTO",
            "GUIDED",
            "LOITER",
            "CIRCLE",
            "DRIFT",
            "POSHOLD",
            "BRAKE",
            "THROW",
            "AVOID_ADSB",
            "FOLLOW",
            "ZIGZAG",
        }
    ),
    position_refused_text="Mode change to {mode} failed: requires position",
    refused_armed_on_ground={"THROW": ((_WARNING, "Mode change to THROW failed: init failed"),)},
    arm_texts={"THROW": ((_INFO, "waiting for throw"),)},
    # Every mode but those that let a ground station arm with the throttle up
    # (Mode::allows_GCS_or_SCR_arming_with_throttle_high: GUIDED, GUIDED_NOGPS, AUTO).
    throttle_too_high_modes=frozenset(
        {
            "STABILIZE",
            "ACRO",
            "ALT_HOLD",
            "LOITER",
            "RTL",
            "CIRCLE",
            "LAND",
            "DRIFT",
            "SPORT",
            "FLIP",
            "AUTOTUNE",
            "POSHOLD",
            "BRAKE",
            "THROW",
            "AVOID_ADSB",
            "SMART_RTL",
            "FLOWHOLD",
            "FOLLOW",
            "ZIGZAG",
            "SYSTEMID",
            "AUTOROTATE",
            "AUTO_RTL",
            "TURTLE",
            "RATE_ACRO",
        }
    ),
    home_at="arming",
    zero_before_fix=True,
    mode_refused_text="Mode change to {mode} failed: init failed",
    not_armable_text="Arm: {mode} mode not armable",
    no_position_text="Arm: Need Position Estimate",
    armed_text="Arming motors",
    disarmed_text="Disarming motors",
    auto_disarm_s=10.0,
    params={
        # ArduCopter defaults (AC_WPNav, Copter Parameters.cpp), cm and cm/s as ArduPilot.
        "WPNAV_SPEED": (1000.0, _REAL32),
        "WPNAV_ACCEL": (250.0, _REAL32),
        "WPNAV_SPEED_UP": (250.0, _REAL32),
        "WPNAV_SPEED_DN": (150.0, _REAL32),
        "WPNAV_RADIUS": (200.0, _REAL32),
        "RTL_ALT": (1500, _INT32),
        "RTL_LOIT_TIME": (5000, _INT32),
        "LAND_SPEED": (50, _INT16),
        "LAND_ALT_LOW": (1000, _INT16),
        "PILOT_SPEED_UP": (250, _INT16),
        "DISARM_DELAY": (10, _INT8),
        "FRAME_CLASS": (1, _INT8),
        # The fence: every kind on by default (SITL's copter.parm sets FENCE_RADIUS 150; the
        # firmware's default, kept here, is 300 m).
        "FENCE_TYPE": (7, _INT8),
        "AVOID_ENABLE": (3, _INT8),
        "AVOID_MARGIN": (2.0, _REAL32),
        # The ground-station failsafe (Copter::failsafe_gcs_check).
        "FS_GCS_ENABLE": (0, _INT8),
        "FS_GCS_TIMEOUT": (5.0, _REAL32),
        "FS_OPTIONS": (16, _INT32),
    },
    flight_params=(
        "WPNAV_SPEED",
        "WPNAV_ACCEL",
        "WPNAV_SPEED_UP",
        "WPNAV_SPEED_DN",
        "WPNAV_RADIUS",
        "RTL_ALT",
        "RTL_LOIT_TIME",
        "LAND_SPEED",
        "LAND_ALT_LOW",
        "DISARM_DELAY",
    ),
    spelled={"SMART_RTL": "SMARTRTL", "AUTO_RTL": "AUTO RTL"},
)

PLANE: Final = Firmware(
    name="arduplane",
    boot=BootTimes(
        streams_s=1.75,
        attitude_s=12.2,
        gps_fix_s=9.3,
        origin_s=19.3,
        home_s=10.1,
        prearm_s=23.0,
        position_s=20.4,
    ),
    boot_mode="MANUAL",
    initialising_mode=16,
    default_stream_hz=1.0,
    early_stream_requests_lost=True,
    not_armable=frozenset({"RTL"}),
    arm_needs_position=frozenset(),
    absent_modes=frozenset(),
    refused_modes={
        "INITIALISING": ((_WARNING, "Flight mode change failed"),),
        "THERMAL": ((_WARNING, "Flight mode change failed"),),  # no soaring
        # The quadplane modes, on a plane without VTOL motors (Q_ENABLE 0).
        **{
            name: ((_INFO, "Q_ENABLE 0"),)
            for name in ("QSTABILIZE", "QHOVER", "QLOITER", "QLAND", "QRTL", "QAUTOTUNE", "QACRO")
        },
    },
    set_needs_origin=frozenset(),
    set_needs_position_armed=frozenset(),
    position_refused_text="Flight mode change failed",
    enter_texts={
        "AUTOTUNE": ((_INFO, "Started autotune"), (_INFO, "Autotuning roll pitch yaw")),
        # Entered, and flown as LOITER: its QLAND can never start (and says so, now and then).
        "LOITERALTQLAND": ((_INFO, "Q_ENABLE 0"),),
    },
    home_at="while_disarmed",
    baro_alt_until="home",
    mode_refused_text="Flight mode change failed",
    not_armable_text="Arm: {mode} mode not armable",
    no_position_text="Arm: Need Position Estimate",
    armed_text="Throttle armed",
    disarmed_text="Throttle disarmed",
    auto_disarm_s=None,
    params={
        # ArduPlane defaults (Plane Parameters.cpp): airspeeds in m/s.
        "AIRSPEED_CRUISE": (15.0, _REAL32),
        "AIRSPEED_MIN": (9, _INT16),
        "AIRSPEED_MAX": (22, _INT16),
        "TKOFF_ALT": (50, _INT16),
        "TKOFF_DIST": (200, _INT16),
        "WP_RADIUS": (90, _INT16),
        "WP_LOITER_RAD": (60, _INT16),
        "RTL_ALTITUDE": (100.0, _REAL32),
        # The L1 navigation and the bank limit the simulated plane turns by (SITL's
        # plane.parm: NAVL1_PERIOD 15, ROLL_LIMIT_DEG 65).
        "NAVL1_PERIOD": (17.0, _REAL32),
        "NAVL1_DAMPING": (0.75, _REAL32),
        "ROLL_LIMIT_DEG": (45.0, _REAL32),
        # The pitch limits the stick mixes to and the pilot's modes fly (SITL's plane.parm:
        # 25 and -20).
        "PTCH_LIM_MAX_DEG": (20.0, _REAL32),
        "PTCH_LIM_MIN_DEG": (-25.0, _REAL32),
        "LAND_DISARMDELAY": (20, _INT8),
        # The fence: uploaded polygons only by default, and no mode change while breached.
        "FENCE_TYPE": (4, _INT8),
        "FENCE_OPTIONS": (1, _INT16),
        "FENCE_RET_RALLY": (0, _INT8),
        "FENCE_RET_ALT": (0, _INT16),
        # The ground-station (long) failsafe; the short one is the RC's.
        "FS_GCS_ENABL": (0, _INT8),
        "FS_LONG_ACTN": (0, _INT8),
        "FS_LONG_TIMEOUT": (5.0, _REAL32),
        "FS_SHORT_ACTN": (0, _INT8),
        "FS_SHORT_TIMEOUT": (1.5, _REAL32),
    },
    flight_params=(
        "AIRSPEED_CRUISE",
        "AIRSPEED_MIN",
        "AIRSPEED_MAX",
        "TKOFF_ALT",
        "WP_RADIUS",
        "WP_LOITER_RAD",
        "RTL_ALTITUDE",
        "NAVL1_PERIOD",
        "NAVL1_DAMPING",
        "ROLL_LIMIT_DEG",
        "PTCH_LIM_MAX_DEG",
        "PTCH_LIM_MIN_DEG",
    ),
)

FIRMWARES: Final[Mapping[str, Firmware]] = {f.name: f for f in (ROVER, COPTER, PLANE)}
"""Every simulated firmware by name."""
