"""The dry run's wind: one air mass for the whole fleet, the same as ArduPilot SITL's.

A mission declares ``sim.wind`` (docs/dry-run.md, "Wind"); :class:`WindConfig` reads
it and :meth:`WindConfig.sitl_params` gives ArduPilot SITL the same wind as its own
``SIM_WIND_*`` parameters, so that ``--autopilot sitl`` and the simulated vehicles fly
in the same air. The model follows SITL's (``SITL_State::_simulator_servos`` and
``Aircraft::update_wind`` in ArduPilot's libraries):

- A mean wind of ``speed_mps`` blowing *from* ``from_deg`` (true; SIM_WIND_SPD,
  SIM_WIND_DIR): the air mass moves toward ``from_deg + 180``.
- An altitude profile (SIM_WIND_T, SIM_WIND_T_ALT, SIM_WIND_T_COEF): ``sqrt`` scales
  the mean by ``sqrt(height / full_alt_m)`` below ``full_alt_m`` (SITL's default, 60 m:
  no wind on the ground); ``linear`` adds ``(height - full_alt_m) * linear_mps_per_m``;
  ``none`` is the same at every height. Never below 0, as SITL's.
- Turbulence (SIM_WIND_TURB): SITL adds to the wind, in flight only, a random
  horizontal vector whose speed has a standard deviation of ``turbulence_mps`` and is
  low-pass filtered over 50 of its physics frames (about 0.04 s), its direction new
  every frame, and likewise a vertical part. The simulation draws the horizontal part
  as a first-order Gauss-Markov process of the same strength and correlation time on
  the grid :data:`WIND_STEP_S`; the vertical part is not simulated (the models have
  no vertical air motion).
- Gusts (not SITL's, not given to SITL: SITL has no gust model): gusts along the mean
  wind arriving at random (exponential intervals of mean ``gusts.every_s``), each a
  one-minus-cosine rise and fall of ``gusts.speed_mps`` over ``gusts.duration_s``,
  scaled by the altitude profile like the mean.

Every draw comes from one ``random.Random(f"{seed}:wind")`` advanced on a fixed time
grid, so the wind at a time is the same whichever vehicle asks, in whatever order:
one air mass. The air is uniform over the mission
area (no spatial variation); SITL's wind is uniform too.
"""

from __future__ import annotations

import math
import random
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

#: Time grid of the turbulence and gust process (the dry run's physics step).
WIND_STEP_S: Final = 0.02
#: SITL's turbulence filter: an IIR coefficient of 0.98 per physics frame at SITL's
#: 1200 Hz frame rate, a correlation time of 1 / (1 - 0.98) frames.
SITL_TURBULENCE_TC_S: Final = 50.0 / 1200.0
#: SIM_WIND_T values by profile name (ArduPilot's SITL::WindType).
PROFILE_TYPES: Final[Mapping[str, int]] = {"sqrt": 0, "none": 1, "linear": 2}
#: The SIM_WIND_* parameters :meth:`WindConfig.sitl_params` sets.
SITL_WIND_PARAMS: Final = (
    "SIM_WIND_SPD",
    "SIM_WIND_DIR",
    "SIM_WIND_TURB",
    "SIM_WIND_T",
    "SIM_WIND_T_ALT",
    "SIM_WIND_T_COEF",
    "SIM_WIND_DIR_Z",
)


@dataclass(frozen=True, slots=True)
class WindConfig:
    """A declared wind, in the mission's terms (the resolved ``sim.wind``).

    Attributes:
        speed_mps: Mean wind speed at and above ``full_alt_m`` (SIM_WIND_SPD).
        from_deg: True direction the wind blows from (SIM_WIND_DIR).
        turbulence_mps: Standard deviation of the random variation (SIM_WIND_TURB).
        profile: ``sqrt``, ``none`` or ``linear`` (SIM_WIND_T).
        full_alt_m: Height above home where the profile's wind is the mean (SIM_WIND_T_ALT).
        linear_mps_per_m: The linear profile's change per metre of height (SIM_WIND_T_COEF).
        gust_mps: A gust's peak, added to the mean along its direction (0: no gusts).
        gust_every_s: Mean time between gusts.
        gust_duration_s: How long a gust lasts, rise and fall.
    """

    speed_mps: float = 0.0
    from_deg: float = 180.0
    turbulence_mps: float = 0.0
    profile: str = "sqrt"
    full_alt_m: float = 60.0
    linear_mps_per_m: float = 0.01
    gust_mps: float = 0.0
    gust_every_s: float = 60.0
    gust_duration_s: float = 4.0

    @classmethod
    def from_sim(cls, sim: Mapping[str, Any]) -> WindConfig | None:
        """The resolved mission's ``sim.wind`` (plain numbers); None when not declared."""
        wind = sim.get("wind")
        if not isinstance(wind, Mapping):
            return None
        profile = wind.get("profile") or {}
        gusts = wind.get("gusts") or {}
        return cls(
            speed_mps=float(wind.get("speed_mps", 0.0)),
            from_deg=float(wind.get("from_deg", 180.0)),
            turbulence_mps=float(wind.get("turbulence_mps", 0.0)),
            profile=str(profile.get("type", "sqrt")),
            full_alt_m=float(profile.get("full_alt_m", 60.0)),
            linear_mps_per_m=float(profile.get("linear_mps_per_m", 0.01)),
            gust_mps=float(gusts.get("speed_mps", 0.0)),
            gust_every_s=float(gusts.get("every_s", 60.0)),
            gust_duration_s=float(gusts.get("duration_s", 4.0)),
        )

    @classmethod
    def from_sitl_params(cls, params: Mapping[str, float]) -> WindConfig:
        """The wind ArduPilot SITL flies for these SIM_WIND_* values (SITL's defaults else).

        The inverse of :meth:`sitl_params`, for a conformance scenario that sets SITL's
        parameters and must give the simulated vehicle the same air.
        """
        kind = int(params.get("SIM_WIND_T", 0))
        names = {v: k for k, v in PROFILE_TYPES.items()}
        return cls(
            speed_mps=float(params.get("SIM_WIND_SPD", 0.0)),
            from_deg=float(params.get("SIM_WIND_DIR", 180.0)),
            turbulence_mps=float(params.get("SIM_WIND_TURB", 0.0)),
            profile=names.get(kind, "none"),
            full_alt_m=float(params.get("SIM_WIND_T_ALT", 60.0)),
            linear_mps_per_m=float(params.get("SIM_WIND_T_COEF", 0.01)),
        )

    def sitl_params(self) -> dict[str, float]:
        """ArduPilot SITL's parameters for this wind (gusts have none: SITL has no gusts)."""
        return {
            "SIM_WIND_SPD": self.speed_mps,
            "SIM_WIND_DIR": self.from_deg,
            "SIM_WIND_TURB": self.turbulence_mps,
            "SIM_WIND_T": float(PROFILE_TYPES.get(self.profile, 0)),
            "SIM_WIND_T_ALT": self.full_alt_m,
            "SIM_WIND_T_COEF": self.linear_mps_per_m,
            "SIM_WIND_DIR_Z": 0.0,
        }

    def profile_factor(self, height_m: float) -> float:
        """The share of the mean that blows at ``height_m`` above home (sqrt profile), or 1."""
        if self.profile == "sqrt" and height_m < self.full_alt_m:
            if self.full_alt_m <= 0.0:
                return 1.0
            return math.sqrt(max(height_m, 0.0) / self.full_alt_m)
        return 1.0

    def speed_at(self, height_m: float, base_mps: float) -> float:
        """The profile applied to a mean (plus gust) speed at ``height_m``, as SITL does."""
        if self.profile == "linear":
            return max(base_mps + (height_m - self.full_alt_m) * self.linear_mps_per_m, 0.0)
        return max(base_mps * self.profile_factor(height_m), 0.0)


class WindField:
    """The air mass's velocity over time and height, reproducible from the run's seed.

    Build one per vehicle (or share one): two fields of the same config and seed give the
    same wind at the same time, whatever was asked of them before.

    Args:
        config: The declared wind.
        seed: The run's seed; the draws come from ``random.Random(f"{seed}:wind")``.
    """

    def __init__(self, config: WindConfig, seed: int | str) -> None:
        self.config = config
        self._rng = random.Random(f"{seed}:wind")
        direction = math.radians(config.from_deg)
        # Unit vector the air moves toward (north, east): opposite to where it comes from.
        self._to_n = -math.cos(direction)
        self._to_e = -math.sin(direction)
        self._step_index = -1
        self._turb_n = self._turb_e = 0.0
        self._turb_sigma = config.turbulence_mps / math.sqrt(2.0)  # per horizontal axis
        self._turb_a = math.exp(-WIND_STEP_S / SITL_TURBULENCE_TC_S)
        self._turb_b = math.sqrt(1.0 - self._turb_a * self._turb_a) * self._turb_sigma
        self._gusty = config.gust_mps > 0.0 and config.gust_every_s > 0.0
        self._gust_start_s = math.inf
        self._gust_next_s = math.inf
        if self._gusty:
            self._gust_next_s = self._rng.expovariate(1.0 / config.gust_every_s)
        self._gust_now = 0.0
        self._advance_to(0)

    def _advance_to(self, index: int) -> None:
        """Step the random processes on the grid up to grid point ``index`` (never back)."""
        config = self.config
        rng = self._rng
        while self._step_index < index:
            self._step_index += 1
            t_s = self._step_index * WIND_STEP_S
            if self._turb_sigma > 0.0:
                a, b = self._turb_a, self._turb_b
                self._turb_n = a * self._turb_n + b * rng.gauss(0.0, 1.0)
                self._turb_e = a * self._turb_e + b * rng.gauss(0.0, 1.0)
            if self._gusty:
                while t_s >= self._gust_next_s:
                    self._gust_start_s = self._gust_next_s
                    self._gust_next_s += config.gust_duration_s + rng.expovariate(
                        1.0 / config.gust_every_s
                    )
                into = t_s - self._gust_start_s
                if 0.0 <= into < config.gust_duration_s:
                    phase = _TAU * into / config.gust_duration_s
                    self._gust_now = 0.5 * config.gust_mps * (1.0 - math.cos(phase))
                else:
                    self._gust_now = 0.0

    def gust_mps(self, t_s: float) -> float:
        """The gust blowing at ``t_s`` (0 between gusts), before the altitude profile."""
        self._advance_to(max(int(t_s / WIND_STEP_S + 1e-9), 0))
        return self._gust_now

    def air_velocity(self, t_s: float, height_m: float, airborne: bool) -> tuple[float, float]:
        """The air mass's (north, east) velocity in m/s at ``t_s`` and ``height_m`` above home.

        ``airborne`` False leaves out the turbulence (SITL adds it only off the ground).
        """
        self._advance_to(max(int(t_s / WIND_STEP_S + 1e-9), 0))
        speed = self.config.speed_at(height_m, self.config.speed_mps + self._gust_now)
        north = speed * self._to_n
        east = speed * self._to_e
        if airborne:
            north += self._turb_n
            east += self._turb_e
        return north, east


_TAU: Final = 2.0 * math.pi


def wind_field(sim: Mapping[str, Any], seed: int | str) -> WindField | None:
    """The run's wind from the resolved ``sim`` settings; None when none is declared."""
    config = WindConfig.from_sim(sim)
    return None if config is None else WindField(config, seed)


def sitl_wind_params(sim: Mapping[str, Any]) -> dict[str, float]:
    """SIM_WIND_* for ArduPilot SITL from the resolved ``sim``; empty when no wind is declared.

    Without a declared wind SITL keeps its own defaults (SIM_WIND_SPD 0: calm).
    """
    config = WindConfig.from_sim(sim)
    return {} if config is None else config.sitl_params()
