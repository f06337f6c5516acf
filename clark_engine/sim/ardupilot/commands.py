"""The commands the simulated ArduPilot answers, as ArduPilot answers them.

:class:`Commands` carries out COMMAND_LONG and COMMAND_INT (modes, arming, DO_SET_SERVO,
DO_CHANGE_SPEED, NAV_TAKEOFF, NAV_LAND, NAV_RETURN_TO_LAUNCH, DO_SET_HOME, DO_REPOSITION,
DO_FENCE_ENABLE, MISSION_START, the message requests; anything else UNSUPPORTED), the
guided targets (SET_POSITION_TARGET_GLOBAL_INT, the guided MISSION_ITEM(_INT) of MAVProxy's
``guided``, ArduCopter's extrapolated velocity target), and the DO items AUTO carries out
the same way (DO_CHANGE_SPEED, DO_SET_SERVO, DO_SET_HOME), each with each firmware's
refusals and texts.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because what is
asked of it is one concept: a helper object the autopilot owns (``SimAutopilot.commands``),
handed each command by the autopilot's message handling. It keeps no state of its own: it
acts on the autopilot's (its model, modes, home, targets) through it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.fence import ALL_FENCES, ALT_MIN
from clark_engine.sim.ardupilot.mission_executor import SPOOLED_AFTER_S, TAKEOFF_DELAY_SPOOLING_S
from clark_engine.sim.ardupilot.telemetry import M_PER_DEG_LAT
from clark_engine.sim.ardupilot.vehicle_model import Truth

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_INFO = mavlink2.MAV_SEVERITY_INFO
_ACCEPTED, _DENIED, _FAILED, _UNSUPPORTED = (
    int(mavlink2.MAV_RESULT_ACCEPTED),
    int(mavlink2.MAV_RESULT_DENIED),
    int(mavlink2.MAV_RESULT_FAILED),
    int(mavlink2.MAV_RESULT_UNSUPPORTED),
)

TAKEOFF_DELAY_SPOOLED_S: Final = 1.5
"""From NAV_TAKEOFF to the climb when already spooled (measured 1.55 s)."""

GUIDED_TIMEOUT_S: Final = 3.0
"""ArduCopter's GUID_TIMEOUT: a velocity target lapses this long after the last one."""


def _msg_id(name: str) -> int:
    return int(getattr(mavlink2, f"MAVLINK_MSG_ID_{name}"))


class Commands:
    """The command handling of one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot whose commands it carries out.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap

    def command(
        self, command: int, params: tuple[float, ...], z: float, frame: int | None, now_s: float
    ) -> int:
        """Carry out one COMMAND_LONG (``frame`` None) or COMMAND_INT; returns MAV_RESULT."""
        p1, p2 = params[0], params[1]
        if command == mavlink2.MAV_CMD_DO_SET_MODE:
            return self._ap.mode_changes.set_mode(int(p1), int(p2), now_s)
        if command == mavlink2.MAV_CMD_COMPONENT_ARM_DISARM:
            return self._ap.arming.command(p1, p2, now_s)
        if command == mavlink2.MAV_CMD_DO_SET_SERVO:
            servo = int(p1)
            if not self.servo_free(servo):
                self._ap._text(_INFO, f"ServoRelayEvent: Channel {servo} is already in use")
                return _FAILED
            self._ap.model.set_servo(servo, int(p2))
            return _ACCEPTED
        if command == mavlink2.MAV_CMD_DO_CHANGE_SPEED:
            return self.change_speed(int(p1), p2)
        if command == mavlink2.MAV_CMD_NAV_TAKEOFF:
            return self._takeoff(z, frame, now_s)
        if command == mavlink2.MAV_CMD_NAV_LAND:
            if self._ap.firmware != "arducopter":
                return _UNSUPPORTED
            return self._ap.mode_changes.enter("LAND", now_s)
        if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self._ap.mode_changes.enter("RTL", now_s)
        if command == mavlink2.MAV_CMD_NAV_LOITER_UNLIM and self._ap.firmware == "arducopter":
            return self._ap.mode_changes.enter("LOITER", now_s)
        if command == mavlink2.MAV_CMD_DO_SET_HOME:
            return self.set_home_command(params, z, frame, now_s)
        if command == mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL:
            return self._ap.streams.message_interval(int(p1), int(p2), now_s)
        if command == mavlink2.MAV_CMD_GET_MESSAGE_INTERVAL:
            name = self._ap.streams.streamed_name(int(p1))
            if name is None:
                return _FAILED
            interval = self._ap.streams.interval_us(name)
            self._ap._mav.send(
                self._ap._mav.message_interval_encode(int(p1), -1 if interval is None else interval)
            )
            return _ACCEPTED
        if command == mavlink2.MAV_CMD_REQUEST_MESSAGE:
            return self._ap.streams.request_message(int(p1))
        if command == mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            if p1 != 1.0:
                return _DENIED
            return self._ap.streams.request_message(_msg_id("AUTOPILOT_VERSION"))
        if command == mavlink2.MAV_CMD_GET_HOME_POSITION:
            if self._ap._home is None:
                return _FAILED
            return self._ap.streams.request_message(_msg_id("HOME_POSITION"))
        if command == mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT:
            if not self._ap.missions.set_current(int(p1)):
                return _DENIED
            self._ap._deferred.append("MISSION_CURRENT")
            return _ACCEPTED
        if command == mavlink2.MAV_CMD_MISSION_START:
            return self._ap.auto.start(p1, p2, now_s)
        if command == mavlink2.MAV_CMD_DO_REPOSITION and frame is not None:
            return self._reposition(params, z, frame, now_s)
        if command == mavlink2.MAV_CMD_DO_FENCE_ENABLE:
            return self._fence_enable(int(p1), int(p2) & 0xFF)
        return _UNSUPPORTED

    def _fence_enable(self, action: int, fences: int) -> int:
        """MAV_CMD_DO_FENCE_ENABLE: 0 off, 1 on (FAILED if none of them exists), 2 floor off.

        The fences asked for (param2; 0: all) change, FENCE_ENABLE does not.
        """
        fences = fences or ALL_FENCES
        self._ap._fence_quiet = False
        self._ap.fence_checks.zones()
        if action == 0:
            self._ap.fence.enable(False, fences)
        elif action == 1:
            if not self._ap.fence.present() & fences:
                return _FAILED
            self._ap.fence.enable(True, fences)
        elif action == 2:
            self._ap.fence.enable(False, ALT_MIN)
        else:
            return _FAILED
        return _ACCEPTED

    def servo_free(self, servo: int) -> bool:
        """An output DO_SET_SERVO may drive: 1-16, with no function (ArduPilot's rule)."""
        in_use = getattr(self._ap.model, "servo_function", None)
        return 1 <= servo <= 16 and (in_use is None or in_use(servo) is None)

    def _takeoff(self, alt_m: float, frame: int | None, now_s: float) -> int:
        """MAV_CMD_NAV_TAKEOFF: ArduCopter's guided takeoff; ArduPlane's is quadplane-only."""
        if self._ap.firmware != "arducopter":
            if self._ap.firmware == "arduplane":
                return _DENIED if frame is not None else _FAILED
            return _UNSUPPORTED
        if frame is not None and frame != mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT:
            return _DENIED
        model = self._ap.model
        if not (alt_m > 0) or not model.armed or model.airborne or not self._ap._in_guided():
            return _FAILED
        armed_for_s = now_s - (self._ap._armed_s if self._ap._armed_s is not None else now_s)
        delay_s = (
            TAKEOFF_DELAY_SPOOLED_S
            if armed_for_s >= SPOOLED_AFTER_S
            else (TAKEOFF_DELAY_SPOOLING_S)
        )
        if not model.takeoff(float(alt_m), delay_s):
            return _FAILED
        self._ap._guided_wp_active = False
        self._ap._ground_since_s = None  # taking off: no auto-disarm
        return _ACCEPTED

    def set_home_command(
        self, params: tuple[float, ...], z: float, frame: int | None, now_s: float
    ) -> int:
        """MAV_CMD_DO_SET_HOME: here (param1 1), or a point.

        A home set so is locked: ArduPilot's own re-setting at arming or disarming
        leaves it alone.
        """
        if params[0] == 1.0:
            if not self._ap.readiness.gps_fix(now_s):
                return _FAILED
            truth = self._ap.model.truth()
            lat, lon, alt = truth.lat_deg, truth.lon_deg, self._ap.origin_alt_amsl_m + truth.up_m
        else:
            lat, lon, alt = params[4], params[5], z
            if frame is not None:  # COMMAND_INT: degrees * 1e7
                lat, lon = lat / 1e7, lon / 1e7
            if not (abs(lat) <= 90 and abs(lon) <= 180) or (lat == 0 and lon == 0):
                return _FAILED
        self._ap.set_home(float(lat), float(lon), float(alt), now_s)
        self._ap._home_locked = True
        if self._ap.fw.set_home_text:
            self._ap._text(_INFO, f"Set HOME to {lat:.5f} {lon:.5f} at {alt:.2f}m")
        return _ACCEPTED

    def change_speed(self, speed_type: int, speed_m_s: float) -> int:
        """MAV_CMD_DO_CHANGE_SPEED, accepted where each firmware accepts it (measured)."""
        mode, model = self._ap.model.mode, self._ap.model
        if self._ap.firmware == "arducopter":
            if speed_m_s <= 0:
                return _DENIED
            if mode not in (self._ap.guided_mode, "AUTO"):
                return _FAILED
            # ArduCopter takes an airspeed as a ground speed. In GUIDED the speed goes to
            # its waypoint controller, which a position target after a takeoff (or on
            # entering GUIDED) starts afresh at WPNAV_SPEED: until one has been flown, an
            # accepted change is lost (measured).
            if speed_type in (0, 1) and (mode == "AUTO" or self._ap._guided_wp_active):
                model.set_speed(float(speed_m_s))
            return _ACCEPTED
        if self._ap.firmware == "ardurover":
            if speed_type not in (0, 1):
                return _DENIED
            if speed_m_s <= 0.05:
                return _FAILED
            guided_leg = mode == self._ap.guided_mode and self._ap._target is not None
            if not (guided_leg or mode == "AUTO"):
                return _FAILED  # MANUAL, HOLD, and guided before its first target
            model.set_speed(float(speed_m_s))
            return _ACCEPTED
        # ArduPlane: guided and auto only; an airspeed within its limits.
        if mode not in (self._ap.guided_mode, "AUTO"):
            return _FAILED
        if speed_type == 1:
            if speed_m_s < 0:
                return _FAILED
            self._ap._text(_INFO, f"Set groundspeed {speed_m_s:g}")
            return _ACCEPTED
        low, high = self._ap._params["AIRSPEED_MIN"].value, self._ap._params["AIRSPEED_MAX"].value
        if not low <= speed_m_s <= high:
            return _FAILED
        model.set_speed(float(speed_m_s))
        self._ap._text(_INFO, f"Set airspeed {speed_m_s:g} m/s")
        return _ACCEPTED

    def _reposition(self, params: tuple[float, ...], z: float, frame: int, now_s: float) -> int:
        speed, flags, lat_e7, lon_e7 = params[0], int(params[1]), params[4], params[5]
        alt_m = self._ap._relative_alt_m(z, frame)
        if alt_m is None or not (abs(lat_e7) <= 90e7 and abs(lon_e7) <= 180e7):
            return _DENIED
        change_mode = bool(flags & mavlink2.MAV_DO_REPOSITION_FLAGS_CHANGE_MODE)
        if self._ap.firmware != "ardurover" and not self._ap.fence_checks.target_inside(
            lat_e7 / 1e7, lon_e7 / 1e7, alt_m
        ):
            # ArduPlane DENIED, ArduCopter FAILED (its guided destination check), before
            # any mode change; ArduRover does not check (measured).
            return _DENIED if self._ap.firmware == "arduplane" else _FAILED
        if change_mode and not self._ap._in_guided():
            self._ap.mode_changes.enter(self._ap.guided_mode, now_s)
        if not self._ap._in_guided():
            return _FAILED
        loiter = getattr(self._ap.model, "guided_loiter", None)  # ArduPlane's (FixedWing)
        if self._ap.firmware == "arduplane" and loiter is not None:
            radius_m, ccw = params[2], params[3]
            loiter(radius_m, math.isfinite(ccw) and ccw != 0.0)
        if not self._ap._goto(lat_e7 / 1e7, lon_e7 / 1e7, alt_m):
            return _FAILED
        if speed > 0:
            self._ap.model.set_speed(float(speed))
        return _ACCEPTED

    def mission_item(self, msg: Any, now_s: float, *, integer: bool) -> int:
        """A mission item outside an upload: ArduPilot's guided waypoint and altitude change.

        As ArduPilot's GCS_MAVLINK::handle_mission_item: ``current`` 2 is a guided-mode
        waypoint (accepted in the guided mode only; MAVProxy's ``guided LAT LON ALT``
        sends one), ``current`` 3 an altitude change (always accepted); any other item
        arrives outside an upload, which is an error. (Items of an upload, and of the
        fence and rally lists, are the mission protocol's, which sees them first.)
        """
        if msg.mission_type != mavlink2.MAV_MISSION_TYPE_MISSION:
            return int(mavlink2.MAV_MISSION_UNSUPPORTED)
        if msg.current not in (2, 3):
            return int(mavlink2.MAV_MISSION_ERROR)
        alt_m = self._ap._relative_alt_m(msg.z, msg.frame)
        lat_deg, lon_deg = (msg.x / 1e7, msg.y / 1e7) if integer else (msg.x, msg.y)
        if alt_m is None or not (abs(lat_deg) <= 90 and abs(lon_deg) <= 180):
            return int(mavlink2.MAV_MISSION_UNSUPPORTED_FRAME)
        if msg.current == 3:
            if self._ap._target is not None and self._ap._in_guided():
                if not self._copter_may_go(self._ap._target[0], self._ap._target[1], alt_m):
                    return int(mavlink2.MAV_MISSION_ERROR)
                self._ap._goto(self._ap._target[0], self._ap._target[1], alt_m)
            return int(mavlink2.MAV_MISSION_ACCEPTED)
        if not self._copter_may_go(lat_deg, lon_deg, alt_m):
            return int(mavlink2.MAV_MISSION_ERROR)
        if not self._ap._in_guided() or not self._ap._goto(lat_deg, lon_deg, alt_m):
            return int(mavlink2.MAV_MISSION_ERROR)
        return int(mavlink2.MAV_MISSION_ACCEPTED)

    def position_target(self, msg: Any, now_s: float) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT in guided: a position, or a position and a velocity."""
        if not self._ap._in_guided():
            return  # ArduPilot drops position targets outside guided
        alt_m = self._ap._relative_alt_m(msg.alt, msg.coordinate_frame)
        if alt_m is None:
            return
        mask = msg.type_mask
        position_ignored = mask & (
            mavlink2.POSITION_TARGET_TYPEMASK_X_IGNORE | mavlink2.POSITION_TARGET_TYPEMASK_Y_IGNORE
        )
        if self._ap.firmware == "arduplane":
            # ArduPlane takes only the altitude of this message (its GCS_Mavlink.cpp).
            if mask & mavlink2.POSITION_TARGET_TYPEMASK_Z_IGNORE:
                return
            if self._ap._target is not None:
                lat_deg, lon_deg, _ = self._ap._target
            else:
                truth: Truth = self._ap.model.truth()
                lat_deg, lon_deg = truth.lat_deg, truth.lon_deg
            self._ap._goto(lat_deg, lon_deg, alt_m)
            return
        if position_ignored:
            return  # velocity-only and acceleration targets are not simulated
        lat_deg, lon_deg = msg.lat_int / 1e7, msg.lon_int / 1e7
        velocity_ignored = mask & (
            mavlink2.POSITION_TARGET_TYPEMASK_VX_IGNORE
            | mavlink2.POSITION_TARGET_TYPEMASK_VY_IGNORE
        )
        if not self._copter_may_go(lat_deg, lon_deg, alt_m):
            return  # ArduCopter refuses a target outside its fence without a word (measured)
        self._ap._velocity_target = None
        if not velocity_ignored and self._ap.firmware == "arducopter":
            # ArduCopter's guided position and velocity target: the position moves on
            # with the velocity until the next one (or GUID_TIMEOUT).
            self._ap._velocity_target = (lat_deg, lon_deg, alt_m, msg.vx, msg.vy, now_s)
        self._ap._goto(lat_deg, lon_deg, alt_m)

    def _copter_may_go(self, lat_deg: float, lon_deg: float, alt_m: float) -> bool:
        """ArduCopter's guided destinations must be inside its fence (set_destination)."""
        return self._ap.firmware != "arducopter" or self._ap.fence_checks.target_inside(
            lat_deg, lon_deg, alt_m
        )

    def fly_velocity_target(self, now_s: float) -> None:
        """Fly on along the velocity target ArduCopter extrapolates, until it lapses."""
        assert self._ap._velocity_target is not None
        lat_deg, lon_deg, alt_m, vn, ve, at_s = self._ap._velocity_target
        elapsed_s = now_s - at_s
        if elapsed_s > GUIDED_TIMEOUT_S or not self._ap._in_guided():
            self._ap._velocity_target = None
            return
        lat = lat_deg + vn * elapsed_s / M_PER_DEG_LAT
        lon = lon_deg + ve * elapsed_s / (M_PER_DEG_LAT * math.cos(math.radians(lat_deg)))
        self._ap._target = (lat, lon, alt_m)
        self._ap.model.goto(lat, lon, alt_m, None)
