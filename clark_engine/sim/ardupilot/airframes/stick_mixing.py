"""ArduPlane's stick mixing in its automatic modes, and SITL's plane's answer to it.

Apart from the fixed-wing model because it is one measured concept: the sticks read through
their dead zones and mixed into the navigation's demand (ArduPlane's code), and the fitted
filters through which SITL's plane answers the pitch that asks for (a band-pass) and swings
its bank with it (a coupling). Their long provenance (SITL runs, fits, residuals) lives
beside them, not among the plane's other constants.
"""

from __future__ import annotations

import math
from collections import deque
from typing import Final

from clark_engine.sim.ardupilot.airframes.control import TAU

PLANE_RC_DEAD_ZONE_US: Final = 30
"""ArduPlane's RCn_DZ for its roll, pitch and rudder sticks (Plane::init_rc_in; SITL
reports 30): what a model never configured from a parameter table reads them with."""
PLANE_STICK_PITCH_GAIN: Final = 2.055
"""Gain of the stick-mixed pitch's band-pass (below) in the automatic modes. A fit, not
ArduPlane's code: ArduPlane adds the elevator stick to TECS's pitch demand
(Plane::stabilize_stick_mixing_fbw), its pitch controller (PTCH2SRV_TCONST 0.25) flies it on
SITL's airframe, and TECS (TECS_TIME_CONST 5, TECS_PTCH_DAMP 0.3) answers the climb and sink
it causes: the pitch answers a sine of elevator as a band-pass, washed out below a few
tenths of a hertz, resonant near 0.8 Hz, cut above 1.2 Hz. Fitted (with the model's own
0.3 s pitch lag) to SITL's pitch in LOITER at 18 m/s, 150 m AMSL, under 100 us elevator
sines (0.19 of the stick, 4.25 degrees of demand; 8 s bursts, runs probe2 and probe3 of
2026-11-28, which two runs reproduced to 0.05 degrees): pitch amplitude 3.06, 3.89, 5.66,
12.91, 10.05, 7.08, 5.91, 2.46 and 1.04 degrees at 0.3, 0.45, 0.6, 0.75, 0.85, 0.95, 1.0,
1.2 and 1.5 Hz; the fit gives 2.91, 4.35, 6.49, 10.68, 10.92, 6.90, 5.39, 2.44 and 1.08
(phases within 16 degrees). Before it, the stick's pitch was a 0.3 s lag: 5.2 degrees at
0.3 Hz falling to 1.9 at 1.5 Hz (2.7 at 1 Hz). SITL's airframe, not the Super Cub's."""
PLANE_STICK_PITCH_WASHOUT_1_S: Final = 5.32
"""The band-pass's wash-out corner, rad/s (the fit above: TECS holding its height)."""
PLANE_STICK_PITCH_MODE_HZ: Final = 0.826
"""Its resonance (the fit above): the pitch loop with TECS on SITL's airframe."""
PLANE_STICK_PITCH_DAMPING: Final = 0.143
"""Its damping ratio (the fit above)."""
PLANE_STICK_PITCH_DELAY_S: Final = 0.12
"""Its delay, s (the fit above; taken in whole physics steps)."""
PLANE_ROLL_COUPLING_S: Final = 0.2
"""Roll per unit of ``sin(bank)`` times the pitch rate (s) that SITL's plane departs from its
roll demand by in the automatic modes: a pull in a bank rolls it further in. A fit, not
ArduPlane's code (what the airframe's roll due to the yaw rate of the tighter turn, against
ArduPlane's roll loop, would give). In LOITER at 18 m/s, bank 32.5 degrees, under the 100 us
elevator sines of :data:`PLANE_STICK_PITCH_GAIN` (probes of 2026-11-28), SITL's bank swung
with its pitch, 0.42-0.56 of the pitch's amplitude at 0.3-1.0 Hz (1.8, 7.05, 5.63, 3.87 and
0.91 degrees at 0.45, 0.75, 0.85, 0.95 and 1.2 Hz), more than its roll demand
(NAV_CONTROLLER_OUTPUT's nav_roll) explains. What is left after the demand's lag is a
second-order, delayed answer to the pitch rate: the mode, damping and delay below, and 0.115
s here, fitted open-loop to SITL's own nav_roll at 0.3-1.5 Hz; in the simulation's closed
loop (its L1 loiter answering its own track) the gain that gives SITL's bank is this one:
1.8-2.2, 5.1, 5.9, 4.8 and 1.8 degrees at those frequencies (0.75 Hz low with the pitch
there, 8.6 degrees against 12.9). With the pull's turn (:meth:`FixedWing._fly`) it is what
tightens SITL's circle at its pitch resonance. SITL's airframe, measured there only."""
PLANE_ROLL_COUPLING_MODE_HZ: Final = 1.09
"""The roll coupling's second-order mode (the fit above)."""
PLANE_ROLL_COUPLING_DAMPING: Final = 0.35
"""Its damping ratio (the fit above)."""
PLANE_ROLL_COUPLING_DELAY_S: Final = 0.14
"""Its delay, s (the fit above; taken in whole physics steps)."""


def stick_mix(value: float) -> float:
    """ArduPlane's FBW stick mixing curve: linear to half stick, then 3x - 1 (to 2 at full).

    Plane::stabilize_stick_mixing_fbw, so that a pilot can turn an automatic mode's
    aircraft any way they want; the demand is clamped to the limit afterwards.
    """
    if value > 0.5:
        return 3.0 * value - 1.0
    if value < -0.5:
        return 3.0 * value + 1.0
    return value


class StickPitchBandPass:
    """The pitch SITL's plane answers a stick-mixed pitch demand with (a fitted band-pass).

    A helper object :class:`~clark_engine.sim.ardupilot.airframes.fixed_wing.FixedWing` owns
    (one per aircraft, its state the filter's), so that the fit and its state sit beside
    the measurements they stand for, not among the plane's flying.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Empty the stick-mixed pitch's band-pass (at the start, and once it has settled)."""
        self.washout = self.pitch = self.rate = 0.0
        self.delayed: deque[float] = deque()

    def step(self, h: float, pitch_rad: float) -> float:
        """The pitch the automatic modes add for a stick-mixed pitch demand (band-pass).

        ``pitch_rad`` is ArduPlane's stick-mixing share of nav_pitch; the answer is what
        SITL's plane pitches for it, in the fit of :data:`PLANE_STICK_PITCH_GAIN`: a wash-out
        (``s / (s + a)``), a lightly damped second-order mode and a delay. With the stick
        centred and nothing left ringing, it is exactly 0 (no draw, no change to a flight
        without sticks).
        """
        if pitch_rad == 0.0 and not self.delayed and self.pitch == 0.0:
            return 0.0
        a = PLANE_STICK_PITCH_WASHOUT_1_S
        decay = math.exp(-a * h)
        self.washout = decay * self.washout + (1.0 - decay) / a * pitch_rad
        washed = pitch_rad - a * self.washout
        omega = TAU * PLANE_STICK_PITCH_MODE_HZ
        self.rate += h * (
            omega * omega * (washed - self.pitch)
            - 2.0 * PLANE_STICK_PITCH_DAMPING * omega * self.rate
        )
        self.pitch += h * self.rate
        delayed = self.delayed
        delayed.append(self.pitch)
        steps = max(round(PLANE_STICK_PITCH_DELAY_S / h), 1)
        out = delayed.popleft() if len(delayed) > steps else 0.0
        settled = (
            pitch_rad == 0.0
            and max(abs(self.pitch), abs(self.rate), abs(self.washout), *map(abs, delayed)) < 1e-9
        )
        if settled:
            self.reset()  # back to exactly 0
        return PLANE_STICK_PITCH_GAIN * out


class RollCoupling:
    """How far SITL's plane's bank departs from its demand for a pull in a bank (a fit).

    A helper object :class:`~clark_engine.sim.ardupilot.airframes.fixed_wing.FixedWing` owns,
    as :class:`StickPitchBandPass`; it also keeps the roll's lagged demand while a coupling
    is under way (``roll_lagged``), which the aircraft's roll follows then.
    """

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        """Empty the roll coupling's filter (at the start, on the ground, once settled)."""
        self.bank = self.bank_rate = 0.0
        self.roll_lagged = 0.0  # the roll's lagged demand while a coupling is under way
        self.delayed: deque[float] = deque()

    def step(self, h: float, drive_rad_s: float) -> float:
        """The roll (rad) SITL's plane departs from its demand by for a pull in a bank.

        ``drive_rad_s`` is ``sin(bank)`` times the pitch rate; the answer is the
        second-order, delayed fit of :data:`PLANE_ROLL_COUPLING_S`. Exactly 0 with no pull
        and nothing left ringing (a level, steady flight is unchanged).
        """
        if drive_rad_s == 0.0 and not self.delayed and self.bank == 0.0:
            return 0.0
        delayed = self.delayed
        delayed.append(drive_rad_s)
        steps = max(round(PLANE_ROLL_COUPLING_DELAY_S / h), 1)
        drive = delayed.popleft() if len(delayed) > steps else 0.0
        omega = TAU * PLANE_ROLL_COUPLING_MODE_HZ
        self.bank_rate += h * (
            omega * omega * (PLANE_ROLL_COUPLING_S * drive - self.bank)
            - 2.0 * PLANE_ROLL_COUPLING_DAMPING * omega * self.bank_rate
        )
        self.bank += h * self.bank_rate
        if (
            max(abs(self.bank), abs(self.bank_rate), *map(abs, delayed)) < 1e-9
            and drive_rad_s == 0.0
        ):
            self.reset()  # back to exactly 0
        return self.bank
