"""The dry run's world, built per agent before the run: its vehicles and its radio mesh.

What :class:`~clark_engine.dryrun.engine.DryRun` sets up once, apart from the loop that
runs it: each agent's pieces in the simulation (:class:`SimAgent`), the radio mesh, each
vehicle's simulated autopilot and physics or its ArduPilot SITL process with its safety
pilot, and the seeded draws each agent gets (its tick phase, its pilot's reaction). Kept
apart from the engine because the bench's stand-in (``clark autopilot-sim``) and the tests
build vehicles the same way without running a dry run.
"""

from __future__ import annotations

import random
import time
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

from clark_engine.dryrun.backend import SimulatedBackend, VehicleBackend
from clark_engine.dryrun.pilot import SimPilot
from clark_engine.dryrun.sitl_backend import LaterReport, SitlBackend
from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.mission.geo import parse_point
from clark_engine.mission.model import Agent, Mission
from clark_engine.runtime.config import AgentConfig, ChannelSpec
from clark_engine.runtime.context import offset_position
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.sim.ardupilot.airframes.factory import make_vehicle
from clark_engine.sim.ardupilot.autopilot import SimAutopilot
from clark_engine.sim.ardupilot.firmware import FIRMWARES
from clark_engine.sim.ardupilot.vehicle_model import VehicleModel
from clark_engine.sim.camera import SimCamera
from clark_engine.sim.gps_error import GpsError, GpsErrorSettings
from clark_engine.sim.radio import RadioMesh
from clark_engine.sim.radio_bursts import BurstSettings
from clark_engine.sim.wind import sitl_wind_params, wind_field
from clark_engine.sitl.launcher import Home, SitlInstall, SitlProcess, vehicle_for_firmware

#: The simulated GPS time at t = 0: 2026-01-01 00:00:00 UTC, fixed for reproducible logs.
START_UNIX_US = 1_767_225_600_000_000
#: The bottom of the throttle stick on ArduPilot SITL's RC input (its RC3_MIN).
SITL_THROTTLE_BOTTOM_US = 1000
#: How long before the run an aircraft the pilot hands over in flight was powered on,
#: beyond its autopilot's boot: it is ready, and its pilot took off, before time 0.
AIRBORNE_BOOTED_S = 60.0


@dataclass(slots=True)
class Window:
    """A time window [from_s, to_s)."""

    from_s: float
    to_s: float

    def covers(self, t_s: float) -> bool:
        """True when ``t_s`` is inside the window."""
        return self.from_s <= t_s < self.to_s


@dataclass(slots=True)
class SimAgent:
    """One agent's pieces in the simulation."""

    name: str
    config: AgentConfig
    runtime: AgentRuntime
    logbook: Logbook
    tick_offset_s: float
    backend: VehicleBackend | None = None
    adapter: AutopilotAdapter | None = None
    pilot: SimPilot | None = None
    cameras: dict[str, SimCamera] = field(default_factory=dict)
    alive: bool = True
    closed: bool = False
    ticks: int = 0
    autopilot_down: list[Window] = field(default_factory=list)
    signal_keys: list[tuple[str, str, int]] = field(default_factory=list)  # (label, via, number)
    signal_due_s: float | None = None  # the tick whose signals are recorded at the next
    # On SITL: (label, tick's time, its report to come), in tick order; and the last
    # DO_SET_SERVO pulse width asked for per output, what the autopilot should report.
    signal_later: list[tuple[str, float, LaterReport]] = field(default_factory=list)
    servo_asked_us: dict[int, int] = field(default_factory=dict)
    failsafe_seen: bool = False
    autopilot_lost_seen: bool = False

    def next_tick_s(self) -> float:
        """When this agent ticks next."""
        return self.tick_offset_s + self.ticks / self.config.loop_hz

    def link_up(self, t_s: float) -> bool:
        """True when its autopilot link is not disconnected by a fault."""
        return not any(w.covers(t_s) for w in self.autopilot_down)

    @property
    def model(self) -> VehicleModel | None:
        """The simulated vehicle's model (None for a station or a SITL vehicle)."""
        backend = self.backend
        return backend.model if isinstance(backend, SimulatedBackend) else None

    @property
    def autopilot(self) -> SimAutopilot | None:
        """The simulated autopilot (None for a station or a SITL vehicle)."""
        backend = self.backend
        return backend.autopilot if isinstance(backend, SimulatedBackend) else None


def tick_phase(seed: int, agent: str) -> float:
    """Where in its loop period (0..1) an agent's first tick falls.

    Seeded per agent: the thesis's agents were not synchronised, and a run must be
    reproducible.
    """
    return random.Random(f"{seed}:phase:{agent}").random()


def build_mesh(mission: Mission, seed: int) -> RadioMesh:
    """The mission's radio mesh: its ``sim`` settings and every agent's radio."""
    radio = RadioMesh(
        random.Random(f"{seed}:radio"),
        latency_s=float(mission.sim.get("radio_latency_s", 0.005)),
        loss_rate=float(mission.sim.get("radio_loss", 0.0)),
        bursts=BurstSettings.from_sim(mission.sim),
        burst_seed=seed,
    )
    for name, agent in mission.agents.items():
        profile = agent.hardware.part("radio")
        if profile is not None:
            radio.add_agent(name, agent.id, profile)
    return radio


def pilot_reaction_s(mission: Mission, agent: str, seed: int) -> float:
    """How long the agent's simulated pilot takes to arm once the vehicle shows ready.

    ``sim.jitter.pilot_s``: a uniform draw in [0, pilot_s] per vehicle, from its own
    generator; 0 when not declared (no draw).
    """
    pilot_s = float((mission.sim.get("jitter") or {}).get("pilot_s", 0.0))
    if pilot_s <= 0:
        return 0.0
    return random.Random(f"{seed}:jitter:pilot:{agent}").uniform(0.0, pilot_s)


def build_vehicle(
    mission: Mission, agent: Agent, config: AgentConfig, seed: int, *, wall_clock: bool = False
) -> tuple[SimulatedBackend, SimPilot]:
    """One vehicle of a dry run: its simulated autopilot and physics, and its safety pilot.

    A vehicle starts as the mission's ``launch`` says: on the ground, disarmed, in
    the mode its firmware boots in, its autopilot powered on at time 0 (so it needs
    ArduPilot's tens of seconds to get ready; ``sim.autopilot_ready_s`` changes
    that); or, when the pilot hands it over in flight, in the air at its
    ``position``, armed, in its hold mode, its autopilot long ready and home where
    it took off (the ground below its position).

    Args:
        mission: The resolved mission (origin, ``sim`` settings).
        agent: The vehicle.
        config: Its compiled config (its channels).
        seed: The run's seed (the vehicle's GPS noise is drawn from it).
        wall_clock: SYSTEM_TIME gives the wall clock's time (real-time runs).
    """
    sim = mission.sim
    raw = agent.raw
    start = parse_point(raw["position"], mission.origin) if "position" in raw else None
    north, east, up = (start.north_m, start.east_m, start.up_m) if start else (0.0, 0.0, 0.0)
    airframe, autopilot = agent.hardware.parts["airframe"], agent.hardware.parts["autopilot"]
    setup = raw.get("sim") or {}
    launch = agent.launch
    airborne = launch is not None and launch.airborne and airframe.get("class") != "rover"
    firmware = FIRMWARES[str(autopilot["firmware"])]
    ready_s = sim.get("autopilot_ready_s")
    boot = firmware.boot if ready_s is None else firmware.boot.scaled(float(ready_s))
    jitter = sim.get("jitter") or {}
    ready_jitter_s = float(jitter.get("ready_s", 0.0))
    if ready_jitter_s > 0 and not airborne:
        boot = boot.shifted(
            random.Random(f"{seed}:jitter:ready:{agent.name}").uniform(
                -ready_jitter_s, ready_jitter_s
            )
        )
    start_mode = setup.get("mode") or (
        autopilot.get("hold_mode") if airborne else firmware.boot_mode
    )
    gps_error_settings = GpsErrorSettings.from_sim(sim)
    gps_error = GpsError(gps_error_settings, seed, agent.name) if gps_error_settings else None
    # The model is the autopilot's estimate: it starts where the GPS says (the truth + error).
    error_n, error_e = gps_error.offset_m(0.0) if gps_error is not None else (0.0, 0.0)
    model = make_vehicle(
        airframe,
        autopilot,
        config.channels,
        mission.origin,
        (north + error_n, east + error_e, up if airborne else 0.0),
        random.Random(f"{seed}:vehicle:{agent.name}"),
        gps_noise_m=float(sim.get("gps_noise_m", 0.5)),
        heading_deg=float(setup.get("heading_deg", 0.0)),
        armed=airborne,
        mode=start_mode,
        rc_override_timeout_s=None,  # the simulated autopilot's RC_OVERRIDE_TIME applies
    )
    model.set_wind(wind_field(sim, seed))  # sim.wind: one air mass, the same in every copy
    # An aircraft the pilot flew up was powered on long before: ready, home set.
    boot_s = -(max(boot.position_s, boot.prearm_s) + AIRBORNE_BOOTED_S) if airborne else 0.0
    simulated = SimAutopilot.from_profile(
        model,
        autopilot,
        origin_lat_deg=mission.origin.lat_deg,
        origin_lon_deg=mission.origin.lon_deg,
        origin_alt_amsl_m=mission.origin.alt_amsl_m,
        start_time_unix_us=START_UNIX_US,
        boot_s=boot_s,
        boot=boot,
        unix_clock_us=(lambda: time.time_ns() // 1000) if wall_clock else None,
    )
    if airborne:
        takeoff_point = offset_position(mission.origin.lat_deg, mission.origin.lon_deg, north, east)
        simulated.set_home(*takeoff_point, mission.origin.alt_amsl_m, 0.0)
    backend = SimulatedBackend(model, simulated, gps_error, mission.origin.lat_deg)
    throttle = config.channels.get("throttle")
    copter_throttle = throttle if airframe.get("class") == "multirotor" else None
    pilot = SimPilot(
        backend,
        system_id=simulated.sysid,
        arms=not airborne and (launch is None or launch.armed_by == "pilot"),
        throttle_rc=copter_throttle.rc if copter_throttle is not None else None,
        throttle_mid_us=(copter_throttle.pwm_min_us + copter_throttle.pwm_max_us) // 2
        if copter_throttle is not None
        else 1500,
        reaction_s=pilot_reaction_s(mission, agent.name, seed),
        throttle_bottom_us=copter_throttle.pwm_min_us if copter_throttle is not None else 1100,
    )
    return backend, pilot


def rc_calibration_params(channels: Iterable[ChannelSpec]) -> dict[str, float]:
    """RCn_MIN, RCn_TRIM and RCn_MAX of a SITL autopilot, from the profile's channels.

    A vehicle's autopilot is calibrated to its receiver (the RC calibration a ground
    station does), and the simulated autopilot reads the sticks against the profile's
    ``pwm_min_us``/``pwm_trim_us``/``pwm_max_us``. SITL boots with its own calibration
    (1000/1500/2000 us), which reads the same pulse width as a smaller deflection: 150 us
    of aileron asked ArduPlane SITL for 0.255 of full stick (with its 30 us RCn_DZ) where
    the simulation, and the vehicle, read 0.324. A channel the profile maps twice keeps
    the first mapping.
    """
    params: dict[str, float] = {}
    for channel in channels:
        rc = channel.rc
        if rc is None or not 1 <= rc <= 16 or f"RC{rc}_MIN" in params:
            continue
        params[f"RC{rc}_MIN"] = float(channel.pwm_min_us)
        params[f"RC{rc}_TRIM"] = float(channel.pwm_trim_us)
        params[f"RC{rc}_MAX"] = float(channel.pwm_max_us)
    return params


def build_sitl_vehicle(
    mission: Mission,
    agent: Agent,
    config: AgentConfig,
    install: SitlInstall,
    speedup: float,
    seed: int = 0,
) -> tuple[SitlBackend, SimPilot, dict[str, Any] | None]:
    """One vehicle of a dry run on real ArduPilot SITL, started (listening, not connected).

    SITL boots at the ground point below the agent's ``position`` (its home), heading
    its ``sim.heading_deg``, with the firmware's flight parameters as the simulated
    autopilot has them (its defaults and the profile's ``parameters``).

    ``seed`` draws the vehicle's GPS error (``sim.gps_error``), the same error as the
    simulated run's, played through SITL's own GPS offset, and its pilot's reaction
    (``sim.jitter.pilot_s``).

    Returns:
        The backend, its pilot, and for a vehicle the pilot hands over in flight the
        arguments of :meth:`SitlBackend.fly_up` (None for one that starts on the ground).
    """
    raw = agent.raw
    start = parse_point(raw["position"], mission.origin) if "position" in raw else None
    north, east, up = (start.north_m, start.east_m, start.up_m) if start else (0.0, 0.0, 0.0)
    airframe, autopilot = agent.hardware.parts["airframe"], agent.hardware.parts["autopilot"]
    setup = raw.get("sim") or {}
    launch = agent.launch
    airborne = launch is not None and launch.airborne and airframe.get("class") != "rover"
    firmware = FIRMWARES[str(autopilot["firmware"])]
    lat, lon = offset_position(mission.origin.lat_deg, mission.origin.lon_deg, north, east)
    heading = float(setup.get("heading_deg", 0.0))
    process = SitlProcess(
        install,
        vehicle_for_firmware(firmware.name),
        Home(lat, lon, mission.origin.alt_amsl_m, heading),
        speedup=speedup,
    )
    params = {name: firmware.params[name][0] for name in firmware.flight_params}
    params.update(
        {
            str(name): float(value)
            for name, value in (autopilot.get("parameters") or {}).items()
            if name in firmware.flight_params
        }
    )
    params.update(sitl_wind_params(mission.sim))  # sim.wind as SITL's own SIM_WIND_*
    if firmware.name == "arduplane":
        # Where it was measured and needed: a plane mixing its sticks into its automatic
        # modes. Copters and rovers keep SITL's own calibration (measured against it).
        params.update(rc_calibration_params(config.channels.values()))
    mav = autopilot.get("mavlink") or {}
    process.start()
    backend = SitlBackend(
        process,
        origin=mission.origin,
        firmware=firmware.name,
        system_id=int(mav.get("system_id", 1)),
        component_id=int(mav.get("component_id", 1)),
        params=params,
        modes=dict(autopilot["modes"]),
        gps_error=GpsError(settings, seed, agent.name)
        if (settings := GpsErrorSettings.from_sim(mission.sim)) is not None
        else None,
    )
    throttle = config.channels.get("throttle")
    copter_throttle = throttle if airframe.get("class") == "multirotor" else None
    throttle_at = (
        (int(copter_throttle.rc), (copter_throttle.pwm_min_us + copter_throttle.pwm_max_us) // 2)
        if copter_throttle is not None and copter_throttle.rc is not None
        else None
    )
    pilot = SimPilot(
        backend,
        system_id=backend.system_id,
        arms=not airborne and (launch is None or launch.armed_by == "pilot"),
        throttle_rc=throttle_at[0] if throttle_at is not None else None,
        throttle_mid_us=throttle_at[1] if throttle_at is not None else 1500,
        reaction_s=pilot_reaction_s(mission, agent.name, seed),
        # SITL's RC input is calibrated 1000-2000 us (RC3_MIN 1000 in its copter.parm): the
        # profile's 1100 us minimum would read as throttle above zero there.
        throttle_bottom_us=SITL_THROTTLE_BOTTOM_US,
    )
    plan = (
        {
            "up_m": up,
            "north_m": north,
            "east_m": east,
            "modes": dict(autopilot["modes"]),
            "hold_mode": str(autopilot.get("hold_mode")),
            "throttle": throttle_at,
            "heading_deg": heading,
        }
        if airborne
        else None
    )
    return backend, pilot, plan
