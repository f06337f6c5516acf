"""The pilot's part before a SITL run: an aircraft handed over in flight, flown up.

A vehicle the mission hands over in flight (``launch.airborne``) is flown up by the
backend before the run, as its pilot would: ready, armed, taken off (ArduCopter's guided
takeoff, ArduPlane's TAKEOFF mode), put where the simulation starts it and left in its
hold mode; a plane that misses its position goes round its approach again.

A mixin of :class:`~clark_engine.dryrun.sitl_backend.SitlBackend`, not a helper object
it owns: the pre-flight drives the backend's own link exactly as the run does (its reads
and duties, the latest message of each kind, the parameters due, the streams wanted,
SITL's clock and truth), and a helper would need a dozen of those private fields made
public for code that runs only before time 0. It is kept apart because it is a mode of
its own (the engine's link is not parsed meanwhile) with its own geometry and constants.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.mission.geo import EARTH_RADIUS_M

if TYPE_CHECKING:
    from clark_engine.mission.geo import Origin
    from clark_engine.sim.ardupilot.vehicle_model import Truth
    from clark_engine.sitl.launcher import SitlProcess

COPTER_HANDOVER_M: Final = 1.0
"""A copter is handed over within this of its position (metres, horizontally and in
height), :data:`COPTER_STILL_M_S` at most: where the simulation starts it, hovering."""
COPTER_STILL_M_S: Final = 0.5
"""A copter's speed at most when it is handed over (m/s)."""
PLANE_APPROACH_M: Final = 500.0
"""A plane's approach line: its waypoints this far before and after its position."""
PLANE_LEAD_IN_M: Final = 800.0
"""...and a lead-in leg of this length before the approach, on the same line."""
PLANE_LINE_M: Final = 5.0
"""A plane is handed over when it crosses its position at most this far off the line."""
PLANE_ALIGNED: Final = 0.95
"""...flying along the line: its speed along the heading at least this share of its
ground speed (within 18 degrees)."""
PLANE_HANDOVER_M: Final = 5.0
"""The last plane handed over must be this close to its position at the run's time 0
(metres); one further off (the machine held the engine back while SITL flew on) goes
round its approach again, :data:`PLANE_HANDOVER_TRIES` times at most."""
PLANE_HANDOVER_TRIES: Final = 3
PLANE_AGAIN_S: Final = 300.0
"""SITL seconds a plane may take to go round its approach again (the lead-in and the
approach are 1.8 km: about 100 s at 18 m/s, and the turn onto it)."""
PLANE_LEAD_S: Final = 0.05
"""LOITER is asked for this long before the plane reaches its position: SIM_STATE's
interval (its position is up to that old) against the command's way to SITL."""


_M_PER_DEG_LAT: Final = math.radians(1.0) * EARTH_RADIUS_M


class SitlPreflight:
    """Flies a SITL vehicle up to where the run starts it (a mixin of ``SitlBackend``)."""

    if TYPE_CHECKING:
        # What the pre-flight uses of the backend it is mixed into.
        process: SitlProcess
        firmware: str
        origin: Origin
        _live: bool
        _streams_wanted: dict[str, int]
        _params_due: dict[str, float]
        _latest: dict[str, Any]
        _mav: Any
        _target: tuple[int, int]
        _truth: Truth
        _clock_s: float | None
        _handover: tuple[float, float, float, float, Mapping[str, int], str] | None

        def _flush(self) -> None: ...
        def _duties(self) -> None: ...
        def _read(self, timeout_s: float) -> bool: ...
        def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
            """As :meth:`SitlBackend.set_pilot`."""

        def start_run_here(self) -> None:
            """As :meth:`SitlBackend.start_run_here`."""

    def fly_up(
        self,
        *,
        up_m: float,
        north_m: float,
        east_m: float,
        modes: Mapping[str, int],
        hold_mode: str,
        throttle: tuple[int, int] | None = None,
        heading_deg: float = 0.0,
        within_s: float = 600.0,
        meanwhile: Callable[[], None] | None = None,
    ) -> None:
        """Fly the vehicle up to its start point, as its pilot does before the run.

        Waits until the autopilot is ready (pre-arm checks, an EKF position); arms;
        takes off to ``up_m`` (ArduCopter: guided and NAV_TAKEOFF; ArduPlane: TKOFF_ALT
        and its TAKEOFF mode); then puts the vehicle where the simulation starts it
        (:data:`COPTER_HANDOVER_M`, :meth:`_plane_over`) and leaves it in ``hold_mode``,
        a copter's throttle stick (``throttle``: its RC channel and middle width)
        centred. Then the run's time 0 is now.

        Args:
            up_m: Height above home to hand over at.
            north_m: Where to hand over, metres north of the origin.
            east_m: Metres east of the origin.
            modes: The autopilot's mode numbers by name.
            hold_mode: The mode to hand over in (LOITER).
            throttle: A copter's throttle RC channel and mid-stick width.
            heading_deg: A plane's heading as it passes over its position (its
                ``sim.heading_deg``, as the simulation starts it).
            within_s: SITL seconds the whole pre-flight may take.
            meanwhile: Called as it waits (the vehicles flown up before it drained).

        Raises:
            SitlError: SITL exited, stalled, or did not get there in time.
        """
        self._live = False  # what the engine's link carries meanwhile is dropped unparsed
        for name in ("SYS_STATUS", "EKF_STATUS_REPORT", "EXTENDED_SYS_STATE"):
            self._streams_wanted[name] = 500_000
        self._streams_wanted["GLOBAL_POSITION_INT"] = 200_000
        self._streams_wanted["HEARTBEAT"] = 1_000_000
        wait = self._waiter(within_s, meanwhile)

        def prearm_ok() -> bool:
            status, ekf = self._latest.get("SYS_STATUS"), self._latest.get("EKF_STATUS_REPORT")
            bit = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
            return (
                status is not None
                and bool(status.onboard_control_sensors_health & bit)
                and ekf is not None
                and bool(ekf.flags & mavlink2.EKF_POS_HORIZ_ABS)
            )

        def armed() -> bool:
            beat = self._latest.get("HEARTBEAT")
            return beat is not None and bool(beat.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)

        def in_mode(name: str) -> Any:
            def check() -> bool:
                beat = self._latest.get("HEARTBEAT")
                return beat is not None and beat.custom_mode == modes[name]

            return check

        def height_m() -> float:
            position = self._latest.get("GLOBAL_POSITION_INT")
            return float(position.relative_alt) / 1000.0 if position is not None else 0.0

        def command(cmd: int, *params: float) -> None:
            values = (*params, *(0.0,) * (7 - len(params)))
            self._mav.command_long_send(*self._target, cmd, 0, *values)

        def set_mode(name: str) -> None:
            command(
                mavlink2.MAV_CMD_DO_SET_MODE,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                modes[name],
            )

        wait("get ready", prearm_ok)
        if self.firmware == "arduplane":
            self._params_due["TKOFF_ALT"] = round(up_m)
            wait("set TKOFF_ALT", lambda: "TKOFF_ALT" not in self._params_due)
            wait("enter TAKEOFF", in_mode("TAKEOFF"), lambda: set_mode("TAKEOFF"))
            wait("arm", armed, lambda: command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1))
            wait("climb", lambda: height_m() >= up_m - 3.0)
        else:
            wait("enter GUIDED", in_mode("GUIDED"), lambda: set_mode("GUIDED"))
            wait("arm", armed, lambda: command(mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1))
            wait(
                "climb",
                lambda: height_m() >= up_m - 0.5,
                lambda: command(mavlink2.MAV_CMD_NAV_TAKEOFF, 0, 0, 0, math.nan, 0, 0, up_m),
                every_s=5.0,
            )
        if self.firmware == "arduplane":
            self._handover = (north_m, east_m, up_m, heading_deg, modes, hold_mode)
            self._plane_over(*self._handover, wait)
        else:
            self._copter_over(north_m, east_m, up_m, hold_mode, throttle, wait, in_mode, set_mode)
        for name in ("SYS_STATUS", "EKF_STATUS_REPORT", "EXTENDED_SYS_STATE", "HEARTBEAT"):
            self._streams_wanted.pop(name, None)
        self._streams_wanted.pop("GLOBAL_POSITION_INT", None)
        self.start_run_here()

    def _waiter(self, within_s: float, meanwhile: Callable[[], None] | None) -> Any:
        """A pre-flight's ``wait(what, done, act=None, every_s=2.0)``.

        It waits until ``done()``, doing ``act()`` every ``every_s`` SITL seconds and
        ``meanwhile()`` as it waits, all of it within ``within_s`` SITL seconds.
        """
        deadline_s = (self._clock_s or 0.0) + within_s

        def wait(what: str, done: Any, act: Any = None, every_s: float = 2.0) -> None:
            next_act = -math.inf
            while not done():
                now = self._clock_s or 0.0
                if now > deadline_s:
                    raise self.process.failure(f"pre-flight: did not {what} in time")
                if act is not None and now >= next_act:
                    next_act = now + every_s
                    act()
                    self._flush()
                self._duties()
                self._read(0.05)
                if meanwhile is not None:
                    meanwhile()

        return wait

    def handover_miss_m(self) -> float | None:
        """How far a plane handed over in flight is from its position now (metres).

        Horizontally; None for any other vehicle.

        Read at the run's time 0: the plane was put in LOITER as it crossed its position,
        but it flies on at 18 m/s through whatever wall time passes before the run
        starts, ten times that at a speed-up of 10: a test process not scheduled for
        0.3 s put the Super Cub 57 m on.
        """
        if self._handover is None:
            return None
        north_m, east_m = self._handover[0], self._handover[1]
        return math.hypot(self._truth.north_m - north_m, self._truth.east_m - east_m)

    def hand_over_again(self, meanwhile: Callable[[], None] | None = None) -> None:
        """Fly a plane that missed its position round its approach again; hand it over.

        As :meth:`_plane_over`; then the run's time 0 is now.
        """
        assert self._handover is not None, "only a plane handed over in flight goes round"
        self._live = False
        self._plane_over(*self._handover, self._waiter(PLANE_AGAIN_S, meanwhile))
        self.start_run_here()

    def _copter_over(
        self,
        north_m: float,
        east_m: float,
        up_m: float,
        hold_mode: str,
        throttle: tuple[int, int] | None,
        wait: Any,
        in_mode: Any,
        set_mode: Any,
    ) -> None:
        """A copter to its position in guided, stopped there, then in ``hold_mode``."""
        wait("enter GUIDED", in_mode("GUIDED"), lambda: set_mode("GUIDED"))
        lat, lon = self._global(north_m, east_m)

        def go() -> None:
            self._mav.set_position_target_global_int_send(
                0, *self._target, mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT, 0x0DF8,
                round(lat * 1e7), round(lon * 1e7), up_m, 0, 0, 0, 0, 0, 0, 0, 0,
            )  # fmt: skip

        def there() -> bool:
            truth = self._truth
            return (
                math.hypot(truth.north_m - north_m, truth.east_m - east_m) <= COPTER_HANDOVER_M
                and abs(truth.up_m - up_m) <= COPTER_HANDOVER_M
                and math.hypot(truth.ground_speed_m_s, truth.climb_rate_m_s) <= COPTER_STILL_M_S
            )

        wait("reach its start point", there, go, every_s=5.0)
        if throttle is not None:
            channel, mid_us = throttle
            self.set_pilot({channel: mid_us})
        wait(f"enter {hold_mode}", in_mode(hold_mode), lambda: set_mode(hold_mode))

    def _plane_over(
        self,
        north_m: float,
        east_m: float,
        up_m: float,
        heading_deg: float,
        modes: Mapping[str, int],
        hold_mode: str,
        wait: Any,
    ) -> None:
        """A plane over its position on its heading, then in ``hold_mode`` (LOITER).

        As the simulation starts it: at the position, at its height, flying its
        heading, circling the position (ArduPlane's LOITER circles where it was
        entered). A plane cannot stop there, so it flies a line through the position:
        an AUTO mission of waypoints on the heading, :data:`PLANE_LEAD_IN_M` and
        :data:`PLANE_APPROACH_M` before it (a plane turned round at a waypoint came out
        of the turn 94 m off the next line and was still 57 m off it 500 m on: the
        lead-in leg takes that turn, and the approach starts on the line) and
        :data:`PLANE_APPROACH_M` after it; LOITER is entered as it crosses the position
        (a plane that missed it goes round again, from the first waypoint).
        """
        heading = math.radians(heading_deg)
        unit_n, unit_e = math.cos(heading), math.sin(heading)

        def on_line(along_m: float) -> tuple[float, float]:
            return self._global(north_m + unit_n * along_m, east_m + unit_e * along_m)

        relative = mavlink2.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT
        waypoint = mavlink2.MAV_CMD_NAV_WAYPOINT
        items = [
            (mavlink2.MAV_FRAME_GLOBAL, waypoint, on_line(0.0), 0.0),  # home (ignored)
            (relative, waypoint, on_line(-PLANE_LEAD_IN_M - PLANE_APPROACH_M), up_m),
            (relative, waypoint, on_line(-PLANE_APPROACH_M), up_m),
            (relative, waypoint, on_line(PLANE_APPROACH_M), up_m),
            (relative, mavlink2.MAV_CMD_NAV_LOITER_UNLIM, on_line(PLANE_APPROACH_M), up_m),
        ]
        self._upload(items, wait)
        wait(
            "enter AUTO",
            lambda: self._mode_is(modes["AUTO"]),
            lambda: self._set_mode(modes["AUTO"]),
        )

        def along_m() -> tuple[float, float, float]:
            """(past the position along the heading, off the line, speed along it)."""
            truth = self._truth
            dn, de = truth.north_m - north_m, truth.east_m - east_m
            speed = truth.velocity_north_m_s * unit_n + truth.velocity_east_m_s * unit_e
            return dn * unit_n + de * unit_e, -dn * unit_e + de * unit_n, speed

        def crossing() -> bool:
            past, off, speed = along_m()
            aligned = speed > PLANE_ALIGNED * max(self._truth.ground_speed_m_s, 1.0)
            return aligned and abs(off) <= PLANE_LINE_M and past >= -speed * PLANE_LEAD_S

        def round_again() -> None:
            past, _, speed = along_m()
            if speed > 0.0 and past > PLANE_LINE_M:  # missed: back to the first waypoint
                self._command(mavlink2.MAV_CMD_DO_SET_MISSION_CURRENT, 1)

        wait("line up on its position", crossing, round_again, every_s=5.0)
        # Confirmed by its COMMAND_ACK, at once: a HEARTBEAT may come a second (18 m) later.
        ack_before = self._latest.get("COMMAND_ACK")

        def accepted() -> bool:
            ack = self._latest.get("COMMAND_ACK")
            return (
                ack is not None
                and ack is not ack_before
                and int(ack.command) == mavlink2.MAV_CMD_DO_SET_MODE
                and int(ack.result) == mavlink2.MAV_RESULT_ACCEPTED
            ) or self._mode_is(modes[hold_mode])

        wait(f"enter {hold_mode}", accepted, lambda: self._set_mode(modes[hold_mode]))

    def _upload(self, items: list[tuple[int, int, tuple[float, float], float]], wait: Any) -> None:
        """Upload a mission (frame, command, (lat, lon), altitude) by MAVLink's protocol."""
        answered: dict[str, Any] = {}

        def done() -> bool:
            for kind in ("MISSION_REQUEST_INT", "MISSION_REQUEST"):
                request = self._latest.get(kind)
                if request is not None and answered.get(kind) is not request:
                    answered[kind] = request
                    seq = int(request.seq)
                    if 0 <= seq < len(items):
                        frame, command, (lat, lon), alt_m = items[seq]
                        self._mav.mission_item_int_send(
                            *self._target, seq, frame, command, 0, 1, 0, 0, 0, 0,
                            round(lat * 1e7), round(lon * 1e7), alt_m,
                        )  # fmt: skip
                        self._flush()
            ack = self._latest.get("MISSION_ACK")
            return ack is not None and ack is not answered.get("ack_before") and ack.type == 0

        answered["ack_before"] = self._latest.get("MISSION_ACK")
        wait(
            "take its approach",
            done,
            lambda: self._mav.mission_count_send(*self._target, len(items)),
        )

    def _global(self, north_m: float, east_m: float) -> tuple[float, float]:
        """A local point's latitude and longitude (flat earth around the origin)."""
        lat = self.origin.lat_deg + north_m / _M_PER_DEG_LAT
        lon = self.origin.lon_deg + east_m / (
            _M_PER_DEG_LAT * math.cos(math.radians(self.origin.lat_deg))
        )
        return lat, lon

    def _mode_is(self, number: int) -> bool:
        beat = self._latest.get("HEARTBEAT")
        return beat is not None and int(beat.custom_mode) == number

    def _set_mode(self, number: int) -> None:
        self._command(
            mavlink2.MAV_CMD_DO_SET_MODE, mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, number
        )

    def _command(self, cmd: int, *params: float) -> None:
        values = (*params, *(0.0,) * (7 - len(params)))
        self._mav.command_long_send(*self._target, cmd, 0, *values)
