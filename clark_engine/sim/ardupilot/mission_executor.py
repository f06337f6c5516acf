"""AUTO: the simulated ArduPilot's mission executor, flying the mission item by item.

:class:`MissionExecutor` flies the mission's navigation items one after the other
(takeoff, waypoints and loiters as points, land, return to launch; any other item is
passed), carries out its DO items, says what ArduPilot says at each, and ends the mission
as each firmware ends it (ArduRover stops, ArduCopter holds or lands and disarms,
ArduPlane turns to RTL); MAV_CMD_MISSION_START starts it. The lists and AP_Mission's cursor
it follows are :class:`~clark_engine.sim.ardupilot.mission_protocol.MissionProtocol`'s.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because AUTO is a
mode with a behaviour of its own: a helper object the autopilot owns (``SimAutopilot.auto``),
which it tells when AUTO is entered and left and asks to fly at each step. What the rest of
the autopilot also reads (the item flown, whether a copter may launch, whether it lands)
stays on the autopilot, which the executor reads and sets through it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.mission_items import MissionItem
from clark_engine.sim.ardupilot.mission_protocol import MissionState
from clark_engine.sim.ardupilot.telemetry import M_PER_DEG_LAT

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_INFO, _NOTICE = (mavlink2.MAV_SEVERITY_INFO, mavlink2.MAV_SEVERITY_NOTICE)
_ACCEPTED, _DENIED, _FAILED = (
    int(mavlink2.MAV_RESULT_ACCEPTED),
    int(mavlink2.MAV_RESULT_DENIED),
    int(mavlink2.MAV_RESULT_FAILED),
)

_AUTO_IDLE, _AUTO_WAITING, _AUTO_FLYING, _AUTO_HOLDING, _AUTO_DONE = range(5)
"""AUTO's executor: no item, item not begun (disarmed, or a copter on the ground before
MISSION_START), flying it, holding at it (its hold time), done (LOITER_UNLIM)."""

_TARGET_COMMANDS: Final = frozenset(
    {
        int(mavlink2.MAV_CMD_NAV_WAYPOINT),
        int(mavlink2.MAV_CMD_NAV_LOITER_UNLIM),
        int(mavlink2.MAV_CMD_NAV_LOITER_TIME),
        int(mavlink2.MAV_CMD_NAV_LOITER_TURNS),
        int(mavlink2.MAV_CMD_NAV_LOITER_TO_ALT),
        int(mavlink2.MAV_CMD_NAV_SPLINE_WAYPOINT),
        int(mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH),
    }
)
"""Mission items flown as a point to go to (loiters and splines as a plain waypoint)."""

_WAYPOINT: Final = int(mavlink2.MAV_CMD_NAV_WAYPOINT)

_HOLDING_COMMANDS: Final = frozenset(
    {int(mavlink2.MAV_CMD_NAV_WAYPOINT), int(mavlink2.MAV_CMD_NAV_LOITER_TIME)}
)
"""Items whose param1 is a time to stay at their point (seconds)."""

COPTER_AUTO_TAKEOFF_DELAY_S: Final = 0.5
"""From MISSION_START to the climb of a copter armed for several seconds (measured)."""

SPOOLED_AFTER_S: Final = 4.7
"""A copter armed this long ago has its motors spooled up for a takeoff (measured)."""

TAKEOFF_DELAY_SPOOLING_S: Final = 3.25
"""From NAV_TAKEOFF to the climb when the motors still spool up (measured 3.25-3.35 s)."""


class MissionExecutor:
    """The mission executor of one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot whose mission it flies.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap
        self._auto_phase = _AUTO_IDLE
        self._auto_until_s = 0.0
        self._auto_land_there = False  # a land item with a place: flying there first
        self._started_seen: tuple[MissionItem, ...] = ()  # DO items already carried out
        self._mission_changes = 0  # MissionProtocol.changed when last looked at

    def has_items(self) -> bool:
        """The mission has an item besides home."""
        return self._ap.missions.count > 1  # item 0 is home

    def first_nav(self) -> MissionItem | None:
        """The mission's first navigation item; None without one."""
        return next((item for item in self._ap.missions.items[1:] if item.is_nav), None)

    def current_nav_is(self, command: int) -> bool:
        """The current navigation item is a ``command``."""
        item = self._ap.missions.nav_item
        return item is not None and item.command == command

    def entered(self) -> None:
        """AUTO entered: the mission goes on where it stopped (ArduPilot's MIS_RESTART 0)."""
        self._ap._auto_seq = None
        self._auto_phase = _AUTO_IDLE
        self._ap._auto_go = self._ap.model.airborne  # a copter in the air needs no MISSION_START
        if self.has_items():
            self._ap.missions.resume()
        else:
            # Nothing to fly: the (empty) mission is complete at once, and stays complete
            # across a later upload until it is started again (measured).
            self._ap.missions.start()

    def left(self) -> None:
        """AUTO left: the mission stops where it is."""
        self._ap.missions.stop()
        self._ap._auto_seq = None
        self._auto_phase = _AUTO_IDLE
        self._ap._auto_go = self._ap._auto_landing = self._auto_land_there = False

    def start(self, first: float, last: float, now_s: float) -> int:
        """MAV_CMD_MISSION_START: into AUTO if not there; ArduCopter's launch from the ground.

        Measured: param1 other than 0 is DENIED (ArduCopter); from another mode it
        switches to AUTO (ArduCopter starting the mission again: "Mission: 1 Takeoff"
        twice), disarmed too; in AUTO, armed on the ground, ArduCopter climbs within a
        second; a rover's finished mission stays finished.
        """
        if first != 0 or last != 0:
            return _DENIED
        entered = self._ap.model.mode != "AUTO"
        if entered:
            result = self._ap.mode_changes.enter("AUTO", now_s)
            if result != _ACCEPTED or self._ap.model.mode != "AUTO":
                return _FAILED if result == _ACCEPTED else result
        if not self.has_items():
            return _FAILED
        if self._ap.firmware == "arducopter":
            if entered or self._ap.missions.state != MissionState.RUNNING:
                self._ap.missions.start()
                self._ap._auto_seq = None
            self._ap._auto_go = True
        return _ACCEPTED

    def _item_alt_m(self, item: MissionItem) -> float:
        """A mission item's altitude above the origin (the model's frame)."""
        alt = self._ap._relative_alt_m(item.z, item.frame)
        return self._ap._truth().up_m if alt is None else alt

    def _item_place(self, item: MissionItem) -> tuple[float, float]:
        """A mission item's (north, east) from the origin; here when it has no place."""
        if item.x == 0 and item.y == 0:
            truth = self._ap._truth()
            return truth.north_m, truth.east_m
        north = (item.x / 1e7 - self._ap.origin_lat_deg) * M_PER_DEG_LAT
        east = (
            (item.y / 1e7 - self._ap.origin_lon_deg)
            * M_PER_DEG_LAT
            * math.cos(math.radians(self._ap.origin_lat_deg))
        )
        return north, east

    def _do_items(self, now_s: float) -> None:
        """Carry out the DO items the mission just started (those this simulation has)."""
        for item in self._ap.missions.started:
            if item.is_nav:
                continue
            command = item.command
            if command == mavlink2.MAV_CMD_DO_CHANGE_SPEED:
                self._ap.commands.change_speed(int(item.param1), item.param2)
            elif command == mavlink2.MAV_CMD_DO_SET_SERVO:
                servo = int(item.param1)
                if self._ap.commands.servo_free(servo):
                    self._ap.model.set_servo(servo, int(item.param2))
            elif command == mavlink2.MAV_CMD_DO_SET_HOME:
                params = (item.param1, 0.0, 0.0, 0.0, float(item.x), float(item.y))
                self._ap.commands.set_home_command(params, item.z, item.frame, now_s)
        self._started_seen = self._ap.missions.started

    def fly(self, now_s: float) -> None:
        """AUTO: fly the mission's current navigation item; on to the next when it is done."""
        missions, model = self._ap.missions, self._ap.model
        if missions.changed != self._mission_changes:
            self._mission_changes = missions.changed
            if missions.started != self._started_seen:
                self._do_items(now_s)
        if missions.state != MissionState.RUNNING:
            self._ap._auto_seq = None
            return
        item = missions.nav_item
        if item is None:
            return
        if item.seq != self._ap._auto_seq:
            self._ap._auto_seq = item.seq
            self._auto_phase = _AUTO_WAITING
            self._ap._auto_landing = self._auto_land_there = False
        if self._auto_phase == _AUTO_WAITING:
            if not model.armed:
                return
            if self._ap.firmware == "arducopter" and not model.airborne and not self._ap._auto_go:
                return  # armed on the ground in AUTO: waits for MISSION_START (measured)
            self._begin_item(item, now_s)
        if self._auto_phase == _AUTO_FLYING and model.target_reached and not self._ap._avoid_cut:
            if self._ap._auto_landing and self._ap.firmware == "arducopter":
                return  # landed: its disarm ends the item, and starts the mission over
            if self._auto_land_there:  # over the land item's place: now land
                self._auto_land_there = False
                self._ap._auto_landing = True
                model.auto_land()
                return
            hold_s = item.param1 if item.command in _HOLDING_COMMANDS else 0.0
            if self._ap.firmware == "arduplane" and item.command == _WAYPOINT:
                hold_s = 0.0  # ArduPlane reads param1 as no hold time (it flies on)
            self._auto_phase = _AUTO_HOLDING
            self._auto_until_s = now_s + max(hold_s, 0.0)
            if item.command == mavlink2.MAV_CMD_NAV_LOITER_UNLIM:
                self._auto_phase = _AUTO_DONE  # loiters until told otherwise
        if self._auto_phase == _AUTO_HOLDING and now_s >= self._auto_until_s:
            self._item_done(item, now_s)

    def _begin_item(self, item: MissionItem, now_s: float) -> None:
        """Command the model to fly ``item``; an item it cannot fly is done at once."""
        model, command = self._ap.model, item.command
        self._auto_phase = _AUTO_FLYING
        if command == mavlink2.MAV_CMD_NAV_TAKEOFF:
            above_home_m = self._item_alt_m(item) - (
                self._ap._home_alt_m() - self._ap.origin_alt_amsl_m
            )
            if self._ap.firmware == "arducopter":
                armed_for_s = now_s - (
                    self._ap._armed_s if self._ap._armed_s is not None else now_s
                )
                delay_s = (
                    COPTER_AUTO_TAKEOFF_DELAY_S
                    if armed_for_s >= SPOOLED_AFTER_S
                    else TAKEOFF_DELAY_SPOOLING_S
                )
                taken = model.auto_takeoff(above_home_m, delay_s)  # type: ignore[call-arg]
                self._ap._ground_since_s = None
            else:
                taken = model.auto_takeoff(above_home_m)
            if not taken:
                self._auto_phase = _AUTO_HOLDING  # (a rover; or already there)
                self._auto_until_s = now_s
        elif command == mavlink2.MAV_CMD_NAV_LAND:
            north, east = self._item_place(item)
            truth = self._ap._truth()
            far = math.hypot(north - truth.north_m, east - truth.east_m) > 1.0
            if far and (item.x or item.y) and self._ap.firmware == "arducopter":
                self._auto_land_there = True
                model.auto_target(north, east, truth.up_m, None)
            else:
                self._ap._auto_landing = True
                model.auto_land()
        elif command in _TARGET_COMMANDS:
            if command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH and self._ap._home is not None:
                home = self._ap._home
                north = (home[0] - self._ap.origin_lat_deg) * M_PER_DEG_LAT
                east = (
                    (home[1] - self._ap.origin_lon_deg)
                    * M_PER_DEG_LAT
                    * math.cos(math.radians(self._ap.origin_lat_deg))
                )
                alt = self._ap._truth().up_m
            else:
                north, east = self._item_place(item)
                alt = self._item_alt_m(item)
            self._ap._avoid_cut = False
            if self._ap.firmware == "ardurover":
                short = self._ap.avoidance.avoided((north, east))
                if short is not None:  # ArduRover's avoidance: it stops short, item not done
                    self._ap._avoid_cut = True
                    north, east = short
            if command == mavlink2.MAV_CMD_NAV_WAYPOINT:
                model.auto_waypoint(north, east, alt, self._next_course(item, (north, east)))
            else:
                model.auto_target(north, east, alt, None)
        else:  # not simulated: done at once
            self._auto_phase = _AUTO_HOLDING
            self._auto_until_s = now_s

    def _next_course(self, item: MissionItem, place: tuple[float, float]) -> float | None:
        """The course from ``place`` (``item``'s) to the next navigation item's place.

        AP_Mission::get_next_ground_course_cd, which ArduPlane turns into the turn it
        anticipates at a waypoint; None without a next navigation item with a place.
        """
        after = (i for i in self._ap.missions.items[item.seq + 1 :] if i.is_nav)
        following = next(after, None)
        if following is None or (following.x == 0 and following.y == 0):
            return None
        if following.command == mavlink2.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return None
        north, east = self._item_place(following)
        if math.hypot(north - place[0], east - place[1]) < 0.01:
            return None
        return math.atan2(east - place[1], north - place[0])

    def _item_done(self, item: MissionItem, now_s: float) -> None:
        """The current item is done: say so as each firmware does, and go on."""
        command, seq = item.command, item.seq
        self._ap._mav.send(self._ap._mav.mission_item_reached_encode(seq))
        if self._ap.firmware == "ardurover" and command in _TARGET_COMMANDS:
            self._ap._text(_INFO, f"Reached waypoint #{seq}")
        elif self._ap.firmware == "arducopter" and command in _TARGET_COMMANDS:
            self._ap._text(_INFO, f"Reached command #{seq}")
        elif self._ap.firmware == "arduplane":
            if command == mavlink2.MAV_CMD_NAV_TAKEOFF:
                self._ap._text(_INFO, f"Takeoff complete at {self._ap._truth().up_m:.2f}m")
            elif command in _TARGET_COMMANDS:
                outcome = self._ap.model.waypoint_outcome() if command == _WAYPOINT else None
                passed, distance_m = outcome if outcome is not None else (False, 0.0)
                said = "Passed" if passed else "Reached"
                self._ap._text(_INFO, f"{said} waypoint #{seq} dist {int(distance_m)}m")
        self._auto_phase = _AUTO_IDLE
        if self._ap.missions.advance() is None and self._ap.missions.state == MissionState.COMPLETE:
            self._mission_complete(now_s)

    def _mission_complete(self, now_s: float) -> None:
        """The last item is done.

        ArduRover stops there ("Mission Complete", still in AUTO), ArduCopter holds (or
        has landed), ArduPlane turns to RTL.
        """
        self._ap._auto_seq = None
        if self._ap.firmware == "ardurover":
            self._ap._text(_NOTICE, "Mission Complete")
        elif self._ap.firmware == "arduplane":
            self._ap._text(_INFO, "Mission complete, changing mode to RTL")
            self._ap.mode_changes.enter("RTL", now_s, "autopilot")
