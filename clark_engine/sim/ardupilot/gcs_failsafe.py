"""ArduPilot's ground-station failsafe, per firmware, as the simulated autopilot runs it.

ArduPilot watches the last HEARTBEAT (or RC_CHANNELS_OVERRIDE, or MANUAL_CONTROL) from
exactly one system, MAV_GCS_SYSID; the type and component of the heartbeat do not
matter. When it falls silent for longer than a timeout the vehicle reacts, and when
it is heard again the failsafe ends without restoring the mode. The engine uses this
as its dead-mission-computer reaction: the mission computer is the "ground station".
Measured on SITL and read in its source (docs/sitl-measurements.md, section 4):

- **ArduCopter** (``Copter::failsafe_gcs_check``, 3 Hz): FS_GCS_ENABLE on; never
  before that system was heard once; FS_GCS_TIMEOUT (+ up to a check period).
  Disarmed: WARNING "GCS Failsafe" only. Armed on the ground: disarms, "GCS Failsafe
  - Disarming". Landing with FS_OPTIONS bit 3, AUTO with bit 1, a pilot-controlled
  mode with bit 4 (the default): it carries on ("GCS Failsafe - Continuing ...").
  Otherwise "GCS Failsafe" and FS_GCS_ENABLE's action (1, 2: RTL or LAND; 3:
  SMART_RTL, RTL or LAND; 4: SMART_RTL or LAND; 5: LAND; 6: RTL; 7: BRAKE or LAND). RC
  overrides are dropped. "GCS Failsafe Cleared" on the next heartbeat; arming is
  refused ("GCS failsafe on") while it lasts.
- **ArduRover** (``Rover::gcs_failsafe_check``, 10 Hz, and ``failsafe_trigger``):
  FS_GCS_ENABLE on; never before that system was heard once; the loss is noticed
  after FS_GCS_TIMEOUT and acted on FS_TIMEOUT later, even disarmed, but never in RTL,
  nor in HOLD unless FS_OPTIONS bit 0. The WARNING says "Radio Failsafe" (its radio
  check, at 50 Hz, always reaches the shared trigger first); FS_ACTION then acts (1:
  RTL or HOLD; 2: HOLD; 3: SMART_RTL, RTL or HOLD; 4: SMART_RTL or HOLD; 5: disarm;
  6: LOITER or HOLD), unless FS_GCS_ENABLE 2 in AUTO ("Failsafe - Continuing Auto
  Mode"). RC overrides are dropped. INFO "GCS Failsafe Cleared" on the next one.
- **ArduPlane** (``Plane::check_long_failsafe``, 3 Hz): FS_GCS_ENABL 1 or 2 (3: in
  AUTO only); its clock starts at boot, so it fires FS_LONG_TIMEOUT after boot on a
  plane that never heard its ground station. FS_LONG_ACTN by mode: in MANUAL,
  STABILIZE, ACRO, FBWA, FBWB, CRUISE, TRAINING, CIRCLE, LOITER, THERMAL, AUTOTUNE and
  TAKEOFF: 0 or 1 RTL, 2 FBWA, 4 AUTO, 5 AUTOLAND or RTL (deferred during a TAKEOFF's
  initial climb unless 2 or 3); in AUTO, GUIDED, AVOID_ADSB: 0 nothing, 1 RTL, 2 FBWA,
  4 AUTO, 5 AUTOLAND or RTL; in RTL: 4 AUTO, 5 AUTOLAND. Then WARNING "GCS Failsafe
  On: <mode>", even disarmed. It ends ("GCS Failsafe Off") once the ground station was
  heard within FS_SHORT_TIMEOUT (FS_LONG_TIMEOUT when FS_SHORT_ACTN is 3, disabled).

No firmware goes back to the mode it was in before the failsafe.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.vehicle_safety import ApVehicle, ModeReason

CHECK_PERIOD_S: Final = {"arducopter": 1 / 3, "ardurover": 0.1, "arduplane": 1 / 3}
"""How often each firmware looks at the ground station's silence (3, 10 and 3 Hz)."""
ROVER_TRIGGER_PERIOD_S: Final = 0.02
"""ArduRover's radio check (50 Hz) acts on a failsafe that has lasted FS_TIMEOUT; its GCS
check (10 Hz, CHECK_PERIOD_S) notices the silence."""
PLANE_SHORT_DISABLED: Final = 3
"""FS_SHORT_ACTN 3: the short failsafe is disabled (the long timeout then ends a GCS one)."""

_WARNING, _INFO = int(mavlink2.MAV_SEVERITY_WARNING), int(mavlink2.MAV_SEVERITY_INFO)

_COPTER_ACTIONS: Final[dict[int, tuple[str, ...]]] = {
    1: ("RTL", "LAND"),
    2: ("RTL", "LAND"),
    3: ("SMART_RTL", "RTL", "LAND"),
    4: ("SMART_RTL", "LAND"),
    5: ("LAND",),
    6: ("RTL", "LAND"),  # a mission's landing sequence first (none is flown here)
    7: ("BRAKE", "LAND"),
}
"""ArduCopter's FS_GCS_ENABLE actions: the modes tried in turn (an unknown value: RTL)."""
_COPTER_AUTOPILOT_MODES: Final = frozenset(
    {
        "AUTO",
        "AUTO_RTL",
        "CIRCLE",
        "GUIDED",
        "GUIDED_NOGPS",
        "LAND",
        "RTL",
        "SMART_RTL",
        "AVOID_ADSB",
        "FOLLOW",
        "ZIGZAG",
        "AUTOROTATE",
    }
)
"""ArduCopter's modes that fly themselves (Mode::is_autopilot): FS_OPTIONS bit 4 does not
keep them going."""
_COPTER_PILOT_DISARM_MODES: Final = frozenset({"STABILIZE", "ACRO"})
"""ArduCopter's modes that disarm on a failsafe with the throttle at zero, even flying."""

_ROVER_ACTIONS: Final[dict[int, tuple[str, ...]]] = {
    1: ("RTL", "HOLD"),
    2: ("HOLD",),
    3: ("SMART_RTL", "RTL", "HOLD"),
    4: ("SMART_RTL", "HOLD"),
    6: ("LOITER", "HOLD"),
}
"""ArduRover's FS_ACTION: the modes tried in turn; 5 disarms; 0 does nothing."""

_PLANE_PILOT_MODES: Final = frozenset(
    {
        "MANUAL",
        "STABILIZE",
        "ACRO",
        "FBWA",
        "AUTOTUNE",
        "FBWB",
        "CRUISE",
        "TRAINING",
        "CIRCLE",
        "LOITER",
        "THERMAL",
        "TAKEOFF",
    }
)
"""ArduPlane's modes where FS_LONG_ACTN 0 (continue) still means RTL."""
_PLANE_GUIDED_MODES: Final = frozenset({"AUTO", "GUIDED", "AVOID_ADSB"})


@dataclass
class GcsFailsafe:
    """One autopilot's ground-station failsafe (see the module docstring).

    Args:
        firmware: ``ardurover``, ``arducopter`` or ``arduplane``.
        boot_s: When the autopilot powered on: ArduPlane counts its ground station as
            heard then.
    """

    firmware: str
    boot_s: float
    last_seen_s: float | None = None
    """When MAV_GCS_SYSID was last heard; None: never (ArduPlane: boot)."""
    active: bool = False
    """The failsafe is on (the ground station is lost and the vehicle reacted)."""
    next_check_s: float = 0.0
    """When :meth:`check` looks next (earlier calls return at once)."""
    _next_gcs_check_s: float = 0.0  # ArduRover's 10 Hz look at the silence
    _rover_lost: bool = False  # ArduRover's failsafe.bits: the silence noticed
    _rover_since_s: float | None = None  # the GCS loss noticed (failsafe.bits) since
    _plane_pending: bool = False  # deferred until the TAKEOFF climb is over
    _plane_state: str = "none"  # "none", "gcs", "long" (ArduPlane's failsafe.state)

    def __post_init__(self) -> None:
        if self.firmware == "arduplane":
            self.last_seen_s = self.boot_s  # Plane::init_ardupilot: sysid_mygcs_seen(now)

    def seen(self, now_s: float) -> None:
        """A HEARTBEAT, RC_CHANNELS_OVERRIDE or MANUAL_CONTROL from MAV_GCS_SYSID arrived."""
        self.last_seen_s = now_s

    def check(self, vehicle: ApVehicle, now_s: float) -> None:
        """Look at the ground station's silence, at the firmware's rate, and react."""
        if now_s < self.next_check_s:
            return
        if self.firmware == "arducopter":
            self.next_check_s = now_s + CHECK_PERIOD_S["arducopter"]
            self._copter(vehicle, now_s)
        elif self.firmware == "ardurover":
            self._rover(vehicle, now_s)
            # The 50 Hz trigger matters only once the silence is noticed (at 10 Hz).
            lost = self._rover_lost and not self.active
            self.next_check_s = now_s + (
                ROVER_TRIGGER_PERIOD_S if lost else CHECK_PERIOD_S["ardurover"]
            )
        else:
            self.next_check_s = now_s + CHECK_PERIOD_S["arduplane"]
            self._plane(vehicle, now_s)

    def takeoff_climb_over(self, vehicle: ApVehicle) -> None:
        """ArduPlane's TAKEOFF climb is over: a failsafe deferred during it acts now.

        ArduPilot calls it again as an RC failsafe (ModeTakeoff::update), so it says
        "RC Long Failsafe On" and, its RC being fine, "RC Long Failsafe Cleared" at the
        next check, after which the silent ground station turns it on once more.
        """
        if self._plane_pending:
            self._plane_pending = False
            self._plane_on(vehicle, "long")

    def mode_changed(self) -> None:
        """A mode change drops ArduPlane's deferred failsafe (Mode::enter)."""
        self._plane_pending = False

    # -- ArduCopter --------------------------------------------------------------------

    def _silent_s(self, now_s: float) -> float | None:
        return None if self.last_seen_s is None else now_s - self.last_seen_s

    def _copter(self, vehicle: ApVehicle, now_s: float) -> None:
        enable = int(vehicle.param("FS_GCS_ENABLE"))
        silent_s = self._silent_s(now_s)
        if enable == 0 or silent_s is None:
            return
        timeout_s = max(vehicle.param("FS_GCS_TIMEOUT"), 0.0)
        if silent_s < timeout_s and self.active:
            self.active = False
            vehicle.text(_WARNING, "GCS Failsafe Cleared")
        elif silent_s > timeout_s and not self.active:
            self.active = True
            self._copter_on(vehicle, enable)

    def _copter_on(self, vehicle: ApVehicle, enable: int) -> None:
        vehicle.clear_overrides()
        options = int(vehicle.param("FS_OPTIONS"))
        modes = _COPTER_ACTIONS.get(enable, _COPTER_ACTIONS[1])
        if not vehicle.armed:
            vehicle.text(_WARNING, "GCS Failsafe")
            return
        if self._copter_should_disarm(vehicle):
            vehicle.disarm()
            vehicle.text(_WARNING, "GCS Failsafe - Disarming")
            return
        if vehicle.landing and options & 8:
            vehicle.text(_WARNING, "GCS Failsafe - Continuing Landing")
            modes = ("LAND",)
        elif vehicle.mode == "AUTO" and options & 2:
            vehicle.text(_WARNING, "GCS Failsafe - Continuing Auto Mode")
            return
        elif options & 16 and vehicle.mode not in _COPTER_AUTOPILOT_MODES:
            vehicle.text(_WARNING, "GCS Failsafe - Continuing Pilot Control")
            return
        else:
            vehicle.text(_WARNING, "GCS Failsafe")
        for mode in modes:
            if vehicle.try_mode(mode, "gcs_failsafe"):
                return

    @staticmethod
    def _copter_should_disarm(vehicle: ApVehicle) -> bool:
        """Copter::should_disarm_on_failsafe: on the ground (or STABILIZE/ACRO at zero throttle)."""
        if vehicle.mode in _COPTER_PILOT_DISARM_MODES:
            return vehicle.throttle_zero or vehicle.landed
        return vehicle.landed

    # -- ArduRover ---------------------------------------------------------------------

    def _rover(self, vehicle: ApVehicle, now_s: float) -> None:
        enable = int(vehicle.param("FS_GCS_ENABLE"))
        if now_s >= self._next_gcs_check_s:  # Rover::gcs_failsafe_check, 10 Hz
            self._next_gcs_check_s = now_s + CHECK_PERIOD_S["ardurover"]
            silent_s = self._silent_s(now_s)
            if enable != 0 and silent_s is not None:  # (otherwise it returns, changing nothing)
                self._rover_lost = silent_s >= max(vehicle.param("FS_GCS_TIMEOUT"), 0.0)
        lost = self._rover_lost
        if lost and self._rover_since_s is None:
            self._rover_since_s = now_s
        if not lost:
            if self._rover_since_s is not None and self.active:
                vehicle.text(_INFO, "GCS Failsafe Cleared")
            self._rover_since_s = None
            self.active = False
            return
        assert self._rover_since_s is not None
        in_hold_exempt = vehicle.mode == "HOLD" and not int(vehicle.param("FS_OPTIONS")) & 1
        if (
            self.active
            or now_s - self._rover_since_s <= vehicle.param("FS_TIMEOUT")
            or vehicle.mode == "RTL"
            or in_hold_exempt
        ):
            return
        self.active = True
        vehicle.text(_WARNING, "Radio Failsafe")  # (sic: the radio check speaks first)
        vehicle.clear_overrides()
        if vehicle.mode == "AUTO" and enable == 2:
            vehicle.text(_WARNING, "Failsafe - Continuing Auto Mode")
            return
        action = int(vehicle.param("FS_ACTION"))
        if action == 5:
            vehicle.disarm()
            return
        for mode in _ROVER_ACTIONS.get(action, ()):
            if vehicle.try_mode(mode, "gcs_failsafe"):
                return

    # -- ArduPlane ---------------------------------------------------------------------

    def _plane(self, vehicle: ApVehicle, now_s: float) -> None:
        silent_s = self._silent_s(now_s)
        assert silent_s is not None  # (ArduPlane counts from boot)
        enable = int(vehicle.param("FS_GCS_ENABL"))
        long_s = vehicle.param("FS_LONG_TIMEOUT")
        if self._plane_state == "none":
            watching = enable in (1, 2) or (enable == 3 and vehicle.mode == "AUTO")
            if watching and silent_s > long_s:
                self._plane_on(vehicle, "gcs")
            return
        timeout_s = long_s
        if int(vehicle.param("FS_SHORT_ACTN")) != PLANE_SHORT_DISABLED:
            timeout_s = vehicle.param("FS_SHORT_TIMEOUT")
        if self._plane_state == "gcs" and silent_s < timeout_s:
            self._plane_state = "none"
            self.active = False
            self._plane_pending = False
            vehicle.text(_WARNING, "GCS Failsafe Off")
        elif self._plane_state == "long":  # (the RC is never lost here)
            self._plane_state = "none"
            self.active = False
            self._plane_pending = False
            vehicle.text(_WARNING, "RC Long Failsafe Cleared")

    def _plane_on(self, vehicle: ApVehicle, state: str) -> None:
        """Plane::failsafe_long_on_event: the action by mode, then the text naming the mode."""
        vehicle.clear_overrides()
        self._plane_state = state
        self.active = True
        action = int(vehicle.param("FS_LONG_ACTN"))
        reason: ModeReason = "gcs_failsafe" if state == "gcs" else "takeoff_failsafe"
        mode = vehicle.mode
        if mode in _PLANE_PILOT_MODES:
            if vehicle.initial_climb and action not in (2, 3):
                self._plane_pending = True  # acted on once the climb is over
            elif action == 2:
                vehicle.try_mode("FBWA", reason)
            elif action == 4:
                vehicle.try_mode("AUTO", reason)
            elif action == 5:
                if not vehicle.try_mode("AUTOLAND", reason):
                    vehicle.try_mode("RTL", reason)
            elif action != 3:  # (3: parachute, not simulated)
                vehicle.try_mode("RTL", reason)
        elif mode in _PLANE_GUIDED_MODES:
            if action == 2:
                vehicle.try_mode("FBWA", reason)
            elif action == 4:
                vehicle.try_mode("AUTO", reason)
            elif action == 5:
                if not vehicle.try_mode("AUTOLAND", reason):
                    vehicle.try_mode("RTL", reason)
            elif action == 1:
                vehicle.try_mode("RTL", reason)
        elif mode == "RTL":
            if action == 4:
                vehicle.try_mode("AUTO", reason)
            elif action == 5:
                vehicle.try_mode("AUTOLAND", reason)
        source = "GCS" if state == "gcs" else "RC Long"
        vehicle.text(_WARNING, f"{source} Failsafe On: {vehicle.spell(vehicle.mode)}")
