"""The safety pilot of a dry run: arms a vehicle the mission says the pilot arms.

In the thesis's flights a safety pilot armed every vehicle with the transmitter
and, for an aircraft, took off; the mission computer took over after that. A
mission says so with ``launch: {armed_by: pilot}`` (the default), and the runtime
then waits for an armed vehicle before its behaviour starts. In a dry run nobody
holds a transmitter, so :class:`SimPilot` does the pilot's part, through the
same autopilot the engine talks to and by MAVLink, as a pilot's handheld ground
station would (a stick-arming pilot goes through the same arming checks):

- It watches the autopilot's own messages and arms the vehicle, in the mode it is
  in, once the autopilot reports itself ready as a pilot sees it: the ready light
  (:attr:`SimPilot.sees_ready`) is its pre-arm checks passed (SYS_STATUS), its
  EKF's absolute position (EKF_STATUS_REPORT) and its home (HOME_POSITION). A
  position in GLOBAL_POSITION_INT is not enough: ArduCopter's pre-arm checks pass
  and it streams a GPS position about 18 s before its EKF has an absolute one (24 s
  against 42 s after power-on), and a copter armed then is disarmed by ArduCopter
  10 s later, before the engine may start its behaviour. It asks again every
  :data:`ARM_RETRY_S` until the vehicle is armed, and never again after that: a
  vehicle disarmed later (its pilot's business, a copter's auto-disarm after
  landing) stays disarmed.
- Its sticks rest where a pilot leaves them. The throttle is at the bottom on the
  ground and while disarmed (ArduPilot refuses to arm otherwise: "Throttle too
  high", "Throttle (RC3) is not neutral"; and ArduCopter's idle disarm waits for it).
  A multirotor's pilot centres it once the copter flies, as a safety pilot does
  before an automatic or altitude-holding mode: ArduCopter's LOITER and ALT_HOLD
  climb or sink with that stick (at its bottom LOITER sinks at 2.5 m/s and lands),
  and lowers it again once the copter is down or disarmed. The pilot reacts to what
  it sees, the vehicle itself (the backend's true height and the motors armed; the
  autopilot's land detector too, as a fallback), after :data:`REACTION_S`, not only
  to a once-a-second status message: a pilot who centred
  the stick only when EXTENDED_SYS_STATE said IN_AIR left it low through the first
  second or two of a mission's hold, and the three-vehicle example's F450 hovered at
  14 m simulated and 12 m on SITL instead of at its 15 m takeoff height.

The pilot sends from system 255, component 25 (MAV_COMP_ID_USER1), so neither the
engine's adapter (component 191) nor a ground station (usually 190) takes the
autopilot's answers to the pilot for its own. It speaks through the vehicle
backend directly: a fault that cuts the mission computer's cable to the autopilot
does not cut the pilot's radio. Vehicles the pilot hands over in flight
(``launch.airborne``) start in the air in the simulation; real SITL vehicles are
flown up before the run starts (see :mod:`clark_engine.dryrun.sitl_backend`).
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.backend import VehicleBackend

ARM_RETRY_S: Final = 2.0
"""Time between two arm commands while the vehicle stays disarmed."""

REACTION_S: Final = 0.5
"""How long the pilot takes to move a stick after seeing the vehicle leave the ground
or come down: a choice reaction to a visual cue (a simple one is 0.2-0.3 s)."""
SEES_FLYING_M: Final = 1.0
"""The pilot sees an armed copter flying once it is this high above where it stood."""
SEES_DOWN_M: Final = 0.2
"""... and down again once it is this close to it (or disarmed)."""

PILOT_SYSTEM_ID: Final = 255
PILOT_COMPONENT_ID: Final = 25
"""The pilot's MAVLink ids: the ground-station system, a component of its own (USER1)."""

_PREARM_BIT: Final = mavlink2.MAV_SYS_STATUS_PREARM_CHECK
_POSITION_FLAGS: Final = mavlink2.EKF_POS_HORIZ_ABS
_FLYING_STATES: Final = frozenset(
    {
        mavlink2.MAV_LANDED_STATE_IN_AIR,
        mavlink2.MAV_LANDED_STATE_TAKEOFF,
        mavlink2.MAV_LANDED_STATE_LANDING,
    }
)
"""What the autopilot's land detector says of a copter off the ground."""
_CONST_POS_FLAG: Final = mavlink2.EKF_CONST_POS_MODE
"""An EKF in constant-position mode has no position source: not ready, whatever else it sets."""


class SimPilot:
    """One vehicle's simulated safety pilot.

    Args:
        backend: The vehicle: the pilot reads what its autopilot sends and sends to it.
        system_id: The autopilot's system id.
        component_id: The autopilot's component id.
        arms: The mission says the pilot arms this vehicle.
        throttle_rc: A multirotor's throttle RC input channel, centred once it flies and
            lowered once it is down; None for other vehicles.
        throttle_mid_us: The throttle stick's middle, in microseconds.
        reaction_s: Seconds the pilot takes to arm after the ready light first shows
            (``sim.jitter.pilot_s``); 0 arms at once.
        throttle_bottom_us: The throttle stick's bottom (its minimum), in microseconds.
    """

    def __init__(
        self,
        backend: VehicleBackend,
        *,
        system_id: int,
        component_id: int = 1,
        arms: bool,
        throttle_rc: int | None = None,
        throttle_mid_us: int = 1500,
        reaction_s: float = 0.0,
        throttle_bottom_us: int = 1100,
    ) -> None:
        self.backend = backend
        self._target = (system_id, component_id)
        self.arms = arms
        self._throttle = (
            (throttle_rc, throttle_mid_us, throttle_bottom_us) if throttle_rc is not None else None
        )
        self._out = bytearray()
        self._mav = mavlink2.MAVLink(
            self, srcSystem=PILOT_SYSTEM_ID, srcComponent=PILOT_COMPONENT_ID
        )
        self._parser = mavlink2.MAVLink(None, PILOT_SYSTEM_ID, PILOT_COMPONENT_ID)
        self._parser.robust_parsing = True
        self._armed = False
        self._ever_armed = False
        self._prearm_ok = False
        self._position_ok = False
        self._home = False
        self._stick_centred: bool | None = None  # where the throttle is; None: not yet seen
        self._ground_m: float | None = None  # the height the copter stood at
        self._moving: tuple[bool, float] | None = None  # (to centre, since when it saw why)
        self._landed_state = mavlink2.MAV_LANDED_STATE_UNDEFINED  # the autopilot's, last heard
        self._next_arm_s = 0.0
        self.armed_at_s: float | None = None
        """When the pilot saw the vehicle armed the first time (for the report)."""
        # The reaction hook (sim.jitter.pilot_s): when the ready light first showed.
        self.reaction_s = reaction_s
        self._ready_since_s: float | None = None

    @property
    def done(self) -> bool:
        """The pilot has nothing left to do (the engine stops feeding it).

        It watches the ready light and the arming until the vehicle is armed (whoever
        arms it: the bench's announcements say when), and a multirotor's pilot never is
        done: it keeps watching to move the throttle stick.
        """
        return self._ever_armed and self._throttle is None

    @property
    def sees_ready(self) -> bool:
        """The ready light: pre-arm checks passed, an EKF absolute position, and home.

        What the engine's own launch gate waits for too (``AutopilotStatus.ready``), as
        the autopilot reports it; a pilot arms only then.
        """
        return self._prearm_ok and self._position_ok and self._home

    def write(self, data: bytes) -> None:
        """Where pymavlink puts the pilot's encoded frames."""
        self._out += data

    def hear(self, data: bytes, now_s: float) -> None:
        """What the autopilot sent; then act on it.

        The messages are read until the vehicle is first armed (the ready light, the
        arming), and for a copter all along: the sticks follow what the pilot sees of
        the vehicle (the backend's true height), and what the autopilot's land detector
        says (EXTENDED_SYS_STATE) where the eye cannot tell (ArduPilot SITL's true
        height can stall).
        """
        if not self._ever_armed or self._throttle is not None:
            self.hear_messages(self._parser.parse_buffer(data) or [], now_s)
        else:
            self._act(now_s)

    def hear_messages(self, messages: Iterable[Any], now_s: float) -> None:
        """As :meth:`hear`, from messages parsed already (SITL's backend parses its link)."""
        if not self._ever_armed or self._throttle is not None:
            for msg in messages:
                self._note(msg, now_s)
        self._act(now_s)

    def _note(self, msg: Any, now_s: float) -> None:
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self._target:
            return
        kind = msg.get_type()
        if kind == "HEARTBEAT":
            self._armed = bool(msg.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
            if self._armed and not self._ever_armed:
                self._ever_armed = True
                self.armed_at_s = now_s
        elif kind == "SYS_STATUS":
            self._prearm_ok = bool(msg.onboard_control_sensors_health & _PREARM_BIT)
        elif kind == "EKF_STATUS_REPORT":
            flags = int(msg.flags)
            self._position_ok = bool(flags & _POSITION_FLAGS) and not flags & _CONST_POS_FLAG
        elif kind == "HOME_POSITION":
            self._home = True
        elif kind == "EXTENDED_SYS_STATE":
            self._landed_state = int(msg.landed_state)

    def _act(self, now_s: float) -> None:
        if self._ready_since_s is None and self.sees_ready:  # the reaction hook
            self._ready_since_s = now_s
            self._next_arm_s = max(self._next_arm_s, now_s + self.reaction_s)
        if self._throttle is not None:
            self._move_throttle(now_s)
        if (
            self.arms
            and not self._ever_armed
            and self.sees_ready
            and now_s >= self._next_arm_s
            and not self._stick_centred  # a pilot arms with the throttle at the bottom
        ):
            self._next_arm_s = now_s + ARM_RETRY_S
            system, component = self._target
            self._mav.command_long_send(
                system, component, mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, 1, 0, 0, 0, 0, 0, 0
            )
            data, self._out = bytes(self._out), bytearray()
            self.backend.send(data, now_s)

    def _move_throttle(self, now_s: float) -> None:
        """Centre a copter's throttle once it flies; lower it once it is down or disarmed."""
        assert self._throttle is not None
        channel, mid_us, bottom_us = self._throttle
        armed = self.backend.flight_status()[0]
        up_m = self.backend.truth().up_m
        if self._stick_centred is None:
            # Where the pilot found it: an aircraft handed over in flight is being flown
            # (its stick at hover), one on the ground rests at the bottom.
            flying = armed and up_m > SEES_FLYING_M
            self._stick_centred = flying
            self._ground_m = None if flying else up_m
        if self._ground_m is None:
            self._ground_m = 0.0
        said = self._landed_state
        said_flying = said in _FLYING_STATES
        if not armed or (up_m <= self._ground_m + SEES_DOWN_M and not said_flying):
            want = False
            if not armed and up_m <= self._ground_m + SEES_DOWN_M:
                self._ground_m = up_m  # where it stands now (the next takeoff's ground)
        elif up_m > self._ground_m + SEES_FLYING_M or said_flying:
            want = True
        else:
            want = self._stick_centred
        if want == self._stick_centred:
            self._moving = None
            return
        if self._moving is None or self._moving[0] != want:
            self._moving = (want, now_s)  # seen now; the hand follows after the reaction
            return
        if now_s - self._moving[1] >= REACTION_S:
            self._moving = None
            self._stick_centred = want
            self.backend.set_pilot({channel: mid_us if want else bottom_us})
