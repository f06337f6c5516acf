"""What several behaviours' runtime classes share: targets, distances, guided legs, channels.

A waypoint, a tour and a follower all send guided targets and judge arrival the
same way; a doublet and a sweep drive a control channel and hand it back the
same way. Those rules live here once, so the behaviours cannot drift apart.

The runtime's command, config and launch modules are imported where they are
used, never when this module is: the behaviour modules import it, and
``clark validate`` imports them (it must stay fast and free of flight code).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, ClassVar, NamedTuple

from clark_engine.behaviors.base import BehaviorRuntime, ChannelMap, Point

if TYPE_CHECKING:
    from clark_engine.runtime.commands import Command, SetMode
    from clark_engine.runtime.context import PrimitiveContext

#: Slack when comparing runtime-clock times: ``k / loop_hz`` summed or divided in
#: floating point may land a hair before a deadline it reaches exactly.
TIME_EPSILON_S = 1e-9


class Schedule:
    """Deadlines every ``period_s`` on the runtime clock, counted from a first time.

    Deadline n is ``first_s + n * period_s``, computed afresh each time rather than
    by adding periods up, so a long run does not drift; when a tick comes later
    than one or more deadlines, it counts as one (no burst to catch up).

    Args:
        period_s: Time between deadlines.
    """

    def __init__(self, period_s: float) -> None:
        self.period_s = period_s
        self._first_s: float | None = None
        self._count = 0

    @property
    def started(self) -> bool:
        """True once :meth:`begin` has run."""
        return self._first_s is not None

    def begin(self, now_s: float) -> None:
        """Count deadlines from now; the first falls one period later."""
        self._first_s = now_s
        self._count = 1

    def due(self, now_s: float) -> bool:
        """True when a deadline has come since the last one that was due."""
        if self._first_s is None:
            return False
        elapsed = now_s - self._first_s + TIME_EPSILON_S
        if elapsed < self._count * self.period_s:
            return False
        self._count = math.floor(elapsed / self.period_s) + 1
        return True


class Target(NamedTuple):
    """A position to go to.

    Attributes:
        lat_deg: Latitude.
        lon_deg: Longitude.
        alt_m: Altitude above the mission origin, as Goto and VehicleState use it.
    """

    lat_deg: float
    lon_deg: float
    alt_m: float

    @classmethod
    def from_point(cls, point: Point) -> Target:
        """A target from a compiled point."""
        return cls(point.lat, point.lon, point.alt_m)


def distance_m(ctx: PrimitiveContext, target: Target, *, three_d: bool) -> float | None:
    """Distance from the vehicle to a target, None before the first vehicle state.

    Args:
        ctx: The agent's context (its vehicle state).
        target: Where to measure to.
        three_d: Include the altitude difference (air vehicles); ground distance
            only when False (rovers, whose altitude is whatever the terrain is).
    """
    ground_m = ctx.distance_to_m(target.lat_deg, target.lon_deg)
    if ground_m is None or ctx.vehicle is None or not three_d:
        return ground_m
    return math.hypot(ground_m, ctx.vehicle.alt_m - target.alt_m)


def is_airborne(ctx: PrimitiveContext) -> bool:
    """True when the vehicle flies (:func:`clark_engine.runtime.launch.is_airborne`)."""
    from clark_engine.runtime.launch import is_airborne as airborne

    return airborne(ctx.autopilot, ctx.vehicle)


def mode_command(ctx: PrimitiveContext, mode: str) -> SetMode:
    """A SetMode carrying both the mode's name and its number in this firmware."""
    from clark_engine.runtime.commands import SetMode

    return SetMode(mode, ctx.mode_number(mode))


def reported_mode(ctx: PrimitiveContext) -> str | None:
    """The mode the autopilot last reported, None before any vehicle state."""
    return ctx.vehicle.mode if ctx.vehicle is not None else None


#: Time between two SetMode commands while the autopilot has refused the mode and
#: nobody has changed it since (as :mod:`.set_mode` re-asks).
MODE_RETRY_S = 1.0


class ModeRequest:
    """Asks for a flight mode, again while the autopilot has not granted it.

    :meth:`begin` sends SetMode always (a stale report proves nothing, and a change
    to the current mode is a no-op for ArduPilot). ArduPilot refuses a mode for
    reasons that pass: ArduRover refuses position modes for about a second after
    its EKF has a position when it was armed before that (its EKF failsafe), and
    a mode may need a home or an origin a moment away. So :meth:`update` sends
    SetMode again every :data:`MODE_RETRY_S` while the vehicle still reports the
    mode it was in when the request began. Once it reports the requested mode,
    or any third mode (the pilot or the station chose one), the request is over
    and never repeated: a pilot who takes over is not fought.
    """

    def __init__(self) -> None:
        self.mode: str | None = None
        self._from: str | None = None
        self._sent_s = 0.0
        self._over = True

    def begin(self, ctx: PrimitiveContext, mode: str) -> None:
        """Ask for ``mode`` now."""
        self.mode = mode
        self._from = reported_mode(ctx)
        self._over = self._from == mode
        self._send(ctx)

    def update(self, ctx: PrimitiveContext) -> None:
        """Ask again when due and the mode is neither granted nor changed by someone else."""
        if self._over or self.mode is None:
            return
        now = reported_mode(ctx)
        if now == self.mode or (now is not None and self._from is not None and now != self._from):
            self._over = True
            return
        self._from = self._from if self._from is not None else now
        if ctx.now_s - self._sent_s + TIME_EPSILON_S >= MODE_RETRY_S:
            self._send(ctx)

    def _send(self, ctx: PrimitiveContext) -> None:
        assert self.mode is not None
        self._sent_s = ctx.now_s
        ctx.command(mode_command(ctx, self.mode))


class ProfileModeBehavior(BehaviorRuntime):
    """A primitive flown in a mode its autopilot profile names (hold, land, RTL).

    ``start`` asks for the mode the profile's ``mode_key`` names, through a
    :class:`ModeRequest` (asked again while refused, a pilot's change never fought);
    :meth:`keep_mode` keeps that request going from ``update``. A profile that
    names no such mode makes the primitive FAILED (the mission layer refuses such a
    mission; this is the runtime's own guard for a hand-made config).

    Attributes:
        mode_key: The name of the runtime config's field holding the mode.
    """

    mode_key: ClassVar[str] = ""

    def __init__(self, params: Any) -> None:
        super().__init__(params)
        self._mode = ModeRequest()
        self._failed = False

    def start(self, ctx: PrimitiveContext) -> None:
        """Switch to the profile's mode."""
        mode: str | None = getattr(ctx.config, self.mode_key)
        self._failed = mode is None
        if mode is None:
            from clark_engine.runtime.log_events import LogEvent

            ctx.log.error(
                "%s: the autopilot profile names no %s",
                ctx.config.agent,
                self.mode_key,
                extra=LogEvent.BEHAVIOR_ERROR.extra,
            )
            return
        self._mode.begin(ctx, mode)

    def keep_mode(self, ctx: PrimitiveContext) -> bool:
        """Ask for the mode again if due; False when the profile names none (FAILED)."""
        if self._failed:
            return False
        self._mode.update(ctx)
        return True


#: Time between two Arm commands while the vehicle stays disarmed (ArduPilot explains a
#: refusal in a STATUSTEXT, logged; its pre-arm checks may pass a moment later).
ARM_RETRY_S = 5.0


class EngineArming:
    """Arms the vehicle for a state that needs it, when the mission lets the engine arm.

    With ``launch.armed_by: engine``, :meth:`begin` sends Arm when the vehicle is
    not armed, and :meth:`update` sends it again every :data:`ARM_RETRY_S` while it
    stays disarmed (a refusal's reason is in the mission log). Once the vehicle
    has been seen armed in the state, the engine never arms it again there: a
    vehicle disarmed after that was disarmed by its pilot, its failsafe or
    ArduCopter's auto-disarm, and a pilot's disarm is never fought. With
    ``armed_by: pilot`` it commands nothing.
    """

    def __init__(self) -> None:
        self._sent_s: float | None = None
        self.was_armed = False
        """The vehicle has been seen armed since :meth:`begin`."""

    def begin(self, ctx: PrimitiveContext) -> None:
        """Arm now when the engine may and the vehicle is not armed."""
        self._sent_s = None
        self.was_armed = ctx.vehicle is not None and ctx.vehicle.armed
        if ctx.config.launch.engine_arms and not self.was_armed:
            self._arm(ctx)

    def update(self, ctx: PrimitiveContext) -> None:
        """Note arming; send Arm again when it is due."""
        if ctx.vehicle is not None and ctx.vehicle.armed:
            self.was_armed = True
            return
        if self.was_armed or self._sent_s is None:
            return
        if ctx.now_s - self._sent_s + TIME_EPSILON_S >= ARM_RETRY_S:
            self._arm(ctx)

    def _arm(self, ctx: PrimitiveContext) -> None:
        from clark_engine.runtime.commands import Arm

        self._sent_s = ctx.now_s
        ctx.command(Arm())


class GuidedLeg:
    """Guided navigation towards one target at a time (thesis 5.2.1).

    Rules, shared by waypoint, waypoint_tour and follow_agent:

    - :meth:`begin` always sends SetMode(guided). It is sent even when the vehicle
      already reports guided, because that report may be a tick old and the
      previous state may just have asked for another mode; ArduPilot treats a
      change to the mode it is already in as a no-op, so the extra command costs
      nothing and can never leave the vehicle in the wrong mode. A refused
      request is repeated as :class:`ModeRequest` says. When the engine arms the
      vehicle (``launch.armed_by: engine``) and it is disarmed, Arm follows
      (:class:`EngineArming`).
    - :meth:`go` sends a Goto. Once the vehicle has been in guided mode, or another
      mode was chosen, the leg never sends SetMode again: if the pilot or the
      station moves the vehicle out of guided mode, the engine does not fight
      them, and the autopilot ignores guided targets outside guided mode.
    - :meth:`track` re-sends the current Goto when the vehicle is seen *entering*
      guided mode (reported guided now, another mode or no state at the previous
      look), when it is seen *armed* after being disarmed, and when it is seen
      *flying* after being on the ground. ArduPilot resets its guided target to
      where the vehicle stands on entering GUIDED (Copter and Rover stop, Plane
      loiters), and ArduCopter ignores targets while it is on the ground, so
      without this a vehicle switched back to guided by the station, armed late
      by its pilot or lifted off by a takeoff would sit still forever.

    Args:
        speed_m_s: Ground speed to request, None for the autopilot's own.
        loiter_radius_m: ArduPlane's loiter radius round each target (orbit), None for
            WP_LOITER_RAD (:class:`~clark_engine.runtime.commands.Goto`).
        loiter_ccw: Circle the targets counter-clockwise (ArduPlane).
    """

    def __init__(
        self,
        speed_m_s: float | None,
        loiter_radius_m: float | None = None,
        loiter_ccw: bool = False,
    ) -> None:
        self.speed_m_s = speed_m_s
        self.loiter_radius_m = loiter_radius_m
        self.loiter_ccw = loiter_ccw
        self.target: Target | None = None
        self._velocity: tuple[float, float] | None = None
        self.failed = False
        self._guided_mode: str | None = None
        self._seen: tuple[str | None, bool, bool] = (None, False, False)
        self._arming = EngineArming()
        self._mode = ModeRequest()

    def begin(self, ctx: PrimitiveContext) -> None:
        """Enter guided mode (and arm, when the engine does); failed without a guided mode."""
        self.target = None
        self._guided_mode = ctx.config.guided_mode
        self._seen = self._look(ctx)
        self.failed = self._guided_mode is None
        if self._guided_mode is None:
            from clark_engine.runtime.log_events import LogEvent

            ctx.log.error(
                "%s: the autopilot profile names no guided_mode; cannot navigate",
                ctx.config.agent,
                extra=LogEvent.BEHAVIOR_ERROR.extra,
            )
            return
        self._mode.begin(ctx, self._guided_mode)
        self._arming.begin(ctx)

    def go(
        self,
        ctx: PrimitiveContext,
        target: Target,
        velocity_m_s: tuple[float, float] | None = None,
    ) -> None:
        """Send a guided target now; with ``velocity_m_s`` (north, east), a moving one."""
        self.target = target
        self._velocity = velocity_m_s
        self._seen = self._look(ctx)
        from clark_engine.runtime.commands import Goto

        north, east = velocity_m_s if velocity_m_s is not None else (None, None)
        ctx.command(
            Goto(
                target.lat_deg,
                target.lon_deg,
                target.alt_m,
                self.speed_m_s,
                north,
                east,
                self.loiter_radius_m,
                self.loiter_ccw,
            )
        )

    def track(self, ctx: PrimitiveContext) -> None:
        """Re-send the target when the vehicle enters guided, is armed or lifts off."""
        self._mode.update(ctx)
        self._arming.update(ctx)
        mode, armed, flying = seen = self._look(ctx)
        was_mode, was_armed, was_flying = self._seen
        self._seen = seen
        entered = mode is not None and mode == self._guided_mode and was_mode != mode
        if self.target is not None and (
            entered or (armed and not was_armed) or (flying and not was_flying)
        ):
            self.go(ctx, self.target, self._velocity)

    @staticmethod
    def _look(ctx: PrimitiveContext) -> tuple[str | None, bool, bool]:
        """(mode, armed, flying) as last reported."""
        vehicle = ctx.vehicle
        return (
            reported_mode(ctx),
            vehicle is not None and vehicle.armed,
            ctx.config.is_aircraft and is_airborne(ctx),
        )


class ChannelOutput(NamedTuple):
    """One control channel as a doublet or sweep drives it.

    Attributes:
        name: The channel's name (``aileron``).
        via: ``rc_override`` (RC_CHANNELS_OVERRIDE) or ``servo`` (DO_SET_SERVO).
        number: The RC input (rc_override) or servo output (servo) it drives.
        pwm_min_us: Lowest pulse width the channel accepts.
        pwm_trim_us: Its trim (neutral) pulse width.
        pwm_max_us: Highest pulse width the channel accepts.
    """

    name: str
    via: str
    number: int
    pwm_min_us: int
    pwm_trim_us: int
    pwm_max_us: int

    @classmethod
    def of(cls, channel: ChannelMap, via: str) -> ChannelOutput:
        """The output of a doublet's or sweep's compiled ``channel`` and ``via``.

        Raises:
            ConfigError: The channel has no output for ``via`` (the mission layer
                reports this as E-CHANNEL-VIA, so only a hand-edited config gets here,
                and it fails when the behaviour is built, not in flight).
        """
        number = channel.servo if via == "servo" else channel.rc
        if number is None:
            from clark_engine.runtime.config import ConfigError

            output = "servo output" if via == "servo" else "RC input"
            raise ConfigError(
                f"channel {channel.name!r} has no {output} for via {via}; "
                "compile the mission again with clark compile"
            )
        return cls(
            name=channel.name,
            via=via,
            number=number,
            pwm_min_us=channel.pwm_min_us,
            pwm_trim_us=channel.pwm_trim_us,
            pwm_max_us=channel.pwm_max_us,
        )

    def clamp(self, pwm_us: float) -> int:
        """A pulse width rounded to whole microseconds and kept inside the channel's limits."""
        return min(max(round(pwm_us), self.pwm_min_us), self.pwm_max_us)

    def drive(self, pwm_us: int) -> Command:
        """The command that puts ``pwm_us`` on the channel."""
        from clark_engine.runtime.commands import RcOverride, SetServo

        if self.via == "servo":
            return SetServo(self.number, pwm_us)
        return RcOverride({self.number: pwm_us})

    def finish(self) -> list[Command]:
        """Trim, then hand the channel back.

        For ``rc_override`` the trim is followed by an override of 0, which
        releases the channel so the pilot's stick drives it again; a servo driven
        by DO_SET_SERVO has no pilot input behind it, so it is left at trim.
        """
        from clark_engine.runtime.commands import RcOverride

        commands = [self.drive(self.pwm_trim_us)]
        if self.via != "servo":
            commands.append(RcOverride({self.number: 0}))
        return commands


class ChannelExcitation(BehaviorRuntime):
    """What a doublet and a sine sweep share: a channel driven while active, then let go.

    The subclass sets ``channel`` (:meth:`ChannelOutput.of`) and ``_active`` in its
    ``__init__`` and ``start``, and calls :meth:`_finish` when its signal is over.
    """

    channel: ChannelOutput
    _active: bool

    def stop(self, ctx: PrimitiveContext) -> None:
        """Return the channel to trim and release it if the excitation was cut short."""
        if self._active:
            self._finish(ctx)

    def _finish(self, ctx: PrimitiveContext) -> None:
        self._active = False
        for command in self.channel.finish():
            ctx.command(command)
