"""The runtime's flight commands in MAVLink: a Goto and its speed, a Takeoff, RC overrides.

What :meth:`~clark_engine.io.autopilot.AutopilotAdapter.command` sends for the commands
that move the vehicle: a Goto as a position target (SET_POSITION_TARGET_GLOBAL_INT, or
ArduPlane's DO_REPOSITION) on the mission origin's datum, its speed as DO_CHANGE_SPEED
(sent again after a refusal, and after a mode change); a Takeoff as NAV_TAKEOFF, its
height above home (ArduPlane's TKOFF_ALT); RC overrides, kept alive by the adapter's
``poll`` until released. Which MAVLink message and frame each firmware obeys is measured
on SITL (docs/flight.md).

Separate from the adapter because it is the one place that knows how ArduPilot is flown
in its guided mode; the adapter keeps the link, the requests waiting for answers and the
safety set-up. :class:`FlightCommands` is owned by the adapter and works through a
back-reference: the state it reads and writes (the overrides in force, the speed asked
for and accepted) is reset by the adapter when the autopilot reboots or is heard again.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_decode import RC_OVERRIDE_CHANNELS, UINT16_MAX
from clark_engine.io.autopilot_requests import Request, command_result_name
from clark_engine.runtime.commands import Goto, RcOverride, Takeoff
from clark_engine.runtime.log_events import LogEvent

if TYPE_CHECKING:
    from clark_engine.io.autopilot import AutopilotAdapter

SPEED_RETRY_S: Final = 1.0
"""A refused speed change is sent again this long after (ArduRover refuses one until its
guided mode has a target; it is never dropped)."""

_RC_IGNORE: Final = UINT16_MAX  # "no change" for every channel
_RC_RELEASE_LOW: Final = 0  # channels 1-8: give the channel back to the pilot
_RC_RELEASE_HIGH: Final = UINT16_MAX - 1  # channels 9-18: 0 means "ignore" there

POSITION_ONLY_TYPE_MASK: Final = (
    mavlink2.POSITION_TARGET_TYPEMASK_VX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_VZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
"""SET_POSITION_TARGET_GLOBAL_INT type_mask using lat, lon and alt only (0x0DF8)."""

POSITION_VELOCITY_TYPE_MASK: Final = (
    mavlink2.POSITION_TARGET_TYPEMASK_AX_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AY_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_AZ_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_IGNORE
    | mavlink2.POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE
)
"""The same with the target's velocity too (0x0DC0): ArduCopter moves the target on
with it between messages, so a moving target is followed without lag. ArduRover ignores
the velocity of a position target (measured), so it gets position only."""


class FlightCommands:
    """The adapter's flight commands out: targets, speeds, a take-off, RC overrides.

    Args:
        adapter: The adapter that owns it: its MAVLink encoder, requests and state.
    """

    def __init__(self, adapter: AutopilotAdapter) -> None:
        self._adapter = adapter
        self._settings = adapter.settings
        self._log = adapter._log

    def goto(self, cmd: Goto, now_s: float) -> None:
        """A Goto as the firmware's position target, on the origin's datum (then :meth:`speed`)."""
        s = self._settings
        lat_e7, lon_e7 = round(cmd.lat_deg * 1e7), round(cmd.lon_deg * 1e7)
        plane = s.firmware == "arduplane"
        self._adapter._speed_wanted = cmd.speed_m_s
        self._adapter._targeted = True
        where = f"Goto {cmd.lat_deg:.7f} {cmd.lon_deg:.7f} {cmd.alt_m:g} m above the origin"
        alt_amsl_m = float(cmd.alt_m) + s.origin_alt_amsl_m
        frame = mavlink2.MAV_FRAME_GLOBAL_INT
        if plane:
            self._adapter._tracker.track(
                Request(
                    "MAV_CMD_DO_REPOSITION",
                    mavlink2.MAV_CMD_DO_REPOSITION,
                    where,
                    lambda _attempt: self._adapter._mav.command_int_encode(
                        s.system_id,
                        s.component_id,
                        frame,
                        mavlink2.MAV_CMD_DO_REPOSITION,
                        0,
                        0,
                        -1,  # speed: default
                        0,  # flags: no mode change; the runtime owns the mode
                        cmd.loiter_radius_m or 0,  # loiter radius (> 0: ModeGuided's)
                        1.0 if cmd.loiter_ccw else math.nan,  # non-zero: counter-clockwise
                        lat_e7,
                        lon_e7,
                        alt_amsl_m,
                    ),
                ),
                now_s,
            )
            return
        time_boot_ms = round((now_s - (self._adapter._start_s or 0.0)) * 1000) & 0xFFFFFFFF
        moving = (
            s.firmware == "arducopter"
            and cmd.velocity_north_m_s is not None
            and cmd.velocity_east_m_s is not None
        )
        vn_m_s = float(cmd.velocity_north_m_s or 0.0) if moving else 0.0
        ve_m_s = float(cmd.velocity_east_m_s or 0.0) if moving else 0.0
        self._adapter._mav.send(
            self._adapter._mav.set_position_target_global_int_encode(
                time_boot_ms,
                s.system_id,
                s.component_id,
                frame,
                POSITION_VELOCITY_TYPE_MASK if moving else POSITION_ONLY_TYPE_MASK,
                lat_e7,
                lon_e7,
                alt_amsl_m,
                vn_m_s,
                ve_m_s,
                0,
                0,
                0,
                0,
                0,
                0,
            )
        )

    def takeoff(self, cmd: Takeoff, now_s: float) -> None:
        """ArduCopter: MAV_CMD_NAV_TAKEOFF. ArduPlane: TKOFF_ALT, then its TAKEOFF mode.

        ArduPlane's NAV_TAKEOFF is for quadplanes only (FAILED on a fixed wing); a
        fixed wing takes off in its TAKEOFF mode, armed, to TKOFF_ALT, so that
        parameter is set to the altitude asked for first (it is written to the
        autopilot's storage, as any PARAM_SET is). Both take their height above home,
        so the Takeoff's height above the origin is converted with home's altitude.
        """
        above_home_m = self.above_home_m(cmd.alt_m)
        if self._settings.firmware == "arduplane":
            number = self._settings.modes.get("TAKEOFF")
            if number is None:
                self._log.error(
                    "Takeoff: the autopilot profile has no TAKEOFF mode",
                    extra=LogEvent.AUTOPILOT_COMMAND.extra,
                )
                return
            self._adapter._param_set("TKOFF_ALT", round(above_home_m), now_s)
            self._adapter._tracker.command_long(
                mavlink2.MAV_CMD_DO_SET_MODE,
                f"SetMode TAKEOFF ({number}) to take off to {cmd.alt_m:g} m above the origin "
                f"({above_home_m:g} m above home)",
                now_s,
                mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
                int(number),
            )
            return
        self._adapter._tracker.command_long(
            mavlink2.MAV_CMD_NAV_TAKEOFF,
            f"takeoff to {cmd.alt_m:g} m above the origin ({above_home_m:g} m above home)",
            now_s,
            0,
            0,
            0,
            math.nan,  # yaw: unchanged
            0,
            0,
            above_home_m,
        )

    def above_home_m(self, alt_m: float) -> float:
        """A height above the origin as a height above home (HOME_POSITION's altitude).

        Before the autopilot reports home, home is taken to be at the origin's height
        (the engine's flat field).
        """
        home = self._adapter._status.home
        if home is None:
            return float(alt_m)
        return float(alt_m) - (home[2] - self._settings.origin_alt_amsl_m)

    def speed(self, now_s: float) -> None:
        """Send the speed the runtime wants, until the autopilot accepts it.

        After the position target, not before: ArduRover refuses a speed change in
        its guided mode until that mode has a target. A refusal or no answer is
        retried :data:`SPEED_RETRY_S` later (by :meth:`poll`); a mode change forgets
        the accepted speed, because ArduPilot starts every mode at its default speed.
        """
        wanted = self._adapter._speed_wanted
        if (
            wanted is None
            or wanted == self._adapter._speed_accepted
            or not self._adapter._targeted
            or now_s < self._adapter._speed_retry_s
        ):
            return
        self._adapter._speed_retry_s = math.inf  # until answered
        plane = self._settings.firmware == "arduplane"
        self._adapter._tracker.track(
            Request(
                "MAV_CMD_DO_CHANGE_SPEED",
                mavlink2.MAV_CMD_DO_CHANGE_SPEED,
                f"speed {wanted:g} m/s",
                self._adapter._tracker.long_builder(
                    mavlink2.MAV_CMD_DO_CHANGE_SPEED,
                    # SPEED_TYPE_AIRSPEED for ArduPlane (its ground-speed type sets only a
                    # minimum), SPEED_TYPE_GROUNDSPEED otherwise; throttle -1: no change.
                    (0 if plane else 1, wanted, -1),
                ),
                answered=lambda result, at_s: self._speed_answered(wanted, result, at_s),
            ),
            now_s,
        )

    def _speed_answered(self, speed_m_s: float, result: int | None, now_s: float) -> None:
        if result == mavlink2.MAV_RESULT_ACCEPTED:
            self._adapter._speed_accepted = speed_m_s
            self._adapter._speed_retry_s = -math.inf
            return
        why = "no answer" if result is None else command_result_name(result)
        if self._adapter._speed_retry_s != now_s + SPEED_RETRY_S:
            self._log.info(
                "autopilot did not take speed %g m/s (%s); sending it again in %g s",
                speed_m_s,
                why,
                SPEED_RETRY_S,
                extra=LogEvent.AUTOPILOT_COMMAND.extra,
            )
        self._adapter._speed_retry_s = now_s + SPEED_RETRY_S

    def rc_override(self, cmd: RcOverride, now_s: float) -> None:
        """Apply an RcOverride's channels (width 0 releases one) and send the overrides in force."""
        changes: dict[int, int] = {}
        for channel, pwm_us in cmd.pwm_us.items():
            if not 1 <= channel <= RC_OVERRIDE_CHANNELS or not 0 <= pwm_us < _RC_RELEASE_HIGH:
                self._log.error(
                    "RcOverride channel %d width %d us is outside MAVLink's range; ignored",
                    channel,
                    pwm_us,
                    extra=LogEvent.AUTOPILOT_COMMAND.extra,
                )
                continue
            changes[channel] = pwm_us
            if pwm_us == 0:
                self._adapter._overrides.pop(channel, None)
            else:
                self._adapter._overrides[channel] = pwm_us
        if changes:
            self.override_out({**self._adapter._overrides, **changes}, now_s)

    def override_out(self, channels: Mapping[int, int], now_s: float) -> None:
        """Send RC_CHANNELS_OVERRIDE: ``channels`` at their widths, 0 as the release value."""
        values = [_RC_IGNORE] * RC_OVERRIDE_CHANNELS
        for channel, pwm_us in channels.items():
            if pwm_us == 0:
                values[channel - 1] = _RC_RELEASE_LOW if channel <= 8 else _RC_RELEASE_HIGH
            else:
                values[channel - 1] = pwm_us
        s = self._settings
        self._adapter._mav.send(
            self._adapter._mav.rc_channels_override_encode(s.system_id, s.component_id, *values)
        )
        self._adapter._override_sent_s = now_s
