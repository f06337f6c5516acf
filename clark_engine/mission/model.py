"""The resolved mission: what a mission file means once every name is looked up.

These types are what checks, the compiler and (later) the runtime work with.
Every part keeps the :class:`Location` it was written at, so any finding about
it can point at the exact place to change.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

from clark_engine.mission.findings import Location
from clark_engine.mission.geo import LocalPoint, Origin

if TYPE_CHECKING:
    from clark_engine.behaviors.declaration import Traits
    from clark_engine.mission.envelope import Envelope, EnvelopeDecl

#: Messages an agent may send periodically (its telemetry schedule).
TELEMETRY_MESSAGES = (
    "heartbeat",
    "agent_status",
    "agent_attitude",
    "behavior_state",
    "vehicle_health",
)

#: The phases of one tick, in the order the compiler writes them (thesis 7.3.3-7.3.4).
#: A compiled config lists each exactly once: a config without ``timeouts`` would switch
#: off every timeout and failsafe, so loading refuses one.
TICK_PHASES = ("timeouts", "machine", "commands", "telemetry", "log")

PARTS = ("airframe", "autopilot", "radio", "computer")

#: What the autopilot itself does when the mission computer falls silent
#: (``failsafe.computer_lost``): ArduPilot's GCS failsafe, set up by the engine.
COMPUTER_LOST_ACTIONS = ("rtl", "land", "hold")
#: Default seconds from the mission computer's last heartbeat to the autopilot's reaction.
DEFAULT_COMPUTER_LOST_S = 5.0
#: The range ArduPilot gives that time (ArduCopter's and ArduRover's FS_GCS_TIMEOUT).
COMPUTER_LOST_RANGE_S = (2.0, 120.0)


@dataclass(frozen=True, slots=True)
class Channel:
    """A named control channel of one vehicle, resolved through its profile.

    Attributes:
        name: The name behaviours use (``aileron``, ``rudder``, ``steering``...).
        rc: RC input number for RC_CHANNELS_OVERRIDE, if the channel is an RC input.
        servo: SERVOn output number for DO_SET_SERVO, if the channel drives an output.
        pwm_min_us: Lowest pulse width the channel accepts.
        pwm_trim_us: Neutral pulse width (surfaces centred, throttle idle).
        pwm_max_us: Highest pulse width the channel accepts.
    """

    name: str
    rc: int | None
    servo: int | None
    pwm_min_us: int
    pwm_trim_us: int
    pwm_max_us: int


@dataclass(slots=True)
class Hardware:
    """An agent's hardware: its platform profile with every part resolved and merged.

    Attributes:
        platform: Name of the platform profile the agent named.
        role: ``vehicle`` or ``mcs``.
        parts: Part kind (airframe, autopilot, radio, computer) -> merged profile data.
        part_profiles: Part kind -> name of the profile it came from.
        payloads: Payload name -> merged payload profile data.
        payload_profiles: Payload name -> name of the profile it came from.
        channels: Control channel name -> channel.
        gui: The station's GUI settings (mcs only).
    """

    platform: str
    role: str
    parts: dict[str, dict[str, Any]] = field(default_factory=dict)
    part_profiles: dict[str, str] = field(default_factory=dict)
    payloads: dict[str, dict[str, Any]] = field(default_factory=dict)
    payload_profiles: dict[str, str] = field(default_factory=dict)
    channels: dict[str, Channel] = field(default_factory=dict)
    gui: dict[str, Any] | None = None

    def part(self, kind: str) -> dict[str, Any] | None:
        """One part's merged data, or None when the platform has none."""
        return self.parts.get(kind)

    @property
    def modes(self) -> dict[str, int]:
        """Autopilot flight modes (name -> custom_mode number); empty without an autopilot."""
        autopilot = self.parts.get("autopilot") or {}
        modes: dict[str, int] = autopilot.get("modes", {})
        return modes

    @property
    def max_loop_hz(self) -> float | None:
        """The mission computer's measured maximum loop rate."""
        computer = self.parts.get("computer") or {}
        value = computer.get("max_loop_hz")
        return float(value) if value is not None else None

    @property
    def radio_range_m(self) -> float | None:
        """The radio's required range; None for links without one (UDP)."""
        radio = self.parts.get("radio") or {}
        value = radio.get("range_m")
        return float(value) if value is not None else None


@dataclass(frozen=True, slots=True)
class Telemetry:
    """One periodic message an agent sends.

    Attributes:
        message: One of :data:`TELEMETRY_MESSAGES`.
        rate_hz: How often it is sent.
        to: Agent names it goes to; empty means broadcast to every agent.
        location: Where the rate was written.
    """

    message: str
    rate_hz: float
    to: tuple[str, ...]
    location: Location

    def reaches(self, agent: str) -> bool:
        """True when ``agent`` receives this message."""
        return not self.to or agent in self.to


@dataclass(slots=True)
class Transition:
    """A move from one state to another on an event.

    Attributes:
        event: The event name as written (``done``, ``rc:8:high``, ``lost:slash_a``).
        target: Path of the target state from the machine's root.
        condition: Structured condition that must hold, or None.
        location: Where the transition was written.
        condition_locations: Path inside ``condition`` -> where that part was written.
    """

    event: str
    target: tuple[str, ...]
    condition: dict[str, Any] | None
    location: Location
    condition_locations: dict[tuple[str | int, ...], Location] = field(default_factory=dict)

    def condition_location(self, path: tuple[str | int, ...]) -> Location:
        """Where a part of the condition was written (its nearest written ancestor)."""
        probe = path
        while probe:
            if probe in self.condition_locations:
                return self.condition_locations[probe]
            probe = probe[:-1]
        return self.condition_locations.get((), self.location)


@dataclass(slots=True)
class State:
    """One state of an agent's behaviour, after blocks are expanded.

    A state is one of: a primitive (``primitive`` set), a machine of child
    states (``children`` with an ``initial``), parallel regions (``parallel``),
    or an empty final state.

    Attributes:
        name: The state's name ("" for the root of an agent's behaviour).
        path: Names from the root down to this state.
        location: Where the state was written (in the mission or a block file).
        primitive: Name of the primitive it runs, if any.
        params: The primitive's parameters, defaults applied.
        param_locations: Where each parameter's value was written.
        children: Child states, in the order written.
        initial: Name of the first child entered (machines only).
        parallel: Children run side by side as regions.
        finish: For parallel states, ``all`` regions or ``any`` region finishing finishes it.
        final: Reaching this state finishes its parent (raises ``done`` on it).
        timeout_s: Time after entry at which ``timeout`` is raised.
        timeout_location: Where ``timeout_s`` was written.
        transitions: Outgoing transitions, in the order written.
        block: Name of the behaviour block the state's body came from.
        use_location: Where the ``use:`` naming the primitive or block was written.
        mission_use: For states expanded from blocks, the ``use:`` in the mission file
            that brought them in (what a user changes when a block does not fit).
        description: The author's note about the state.
        unresolved: An error (already reported) left the state's body unknown: an
            unknown ``use:``, a block whose parameters failed, a primitive whose
            parameters failed. Checks that judge the body (can it finish? does it run a
            doublet?) skip it rather than guess.
    """

    name: str
    path: tuple[str, ...]
    location: Location
    primitive: str | None = None
    params: dict[str, Any] = field(default_factory=dict)
    param_locations: dict[str, Location] = field(default_factory=dict)
    children: dict[str, State] = field(default_factory=dict)
    initial: str | None = None
    parallel: bool = False
    finish: str = "all"
    final: bool = False
    timeout_s: float | None = None
    timeout_location: Location | None = None
    transitions: list[Transition] = field(default_factory=list)
    block: str | None = None
    use_location: Location | None = None
    mission_use: Location | None = None
    description: str | None = None
    unresolved: bool = False

    @property
    def kind(self) -> str:
        """``primitive``, ``parallel``, ``machine``, ``final`` or ``empty``."""
        if self.primitive is not None:
            return "primitive"
        if self.children:
            return "parallel" if self.parallel else "machine"
        return "final" if self.final else "empty"

    @property
    def traits(self) -> Traits:
        """What the behaviour it runs is (guided, takes off, lands...); none without one.

        The one way the checks ask what a behaviour does: never by its name.
        """
        from clark_engine.behaviors import traits_of  # the behaviours import this module

        return traits_of(self.primitive)

    @property
    def dotted(self) -> str:
        """The state's path as users write it (``excite.aileron``); ``(root)`` at the root."""
        return ".".join(self.path) or "(root)"

    def walk(self) -> list[State]:
        """This state and every descendant, parents before children."""
        out = [self]
        for child in self.children.values():
            out.extend(child.walk())
        return out

    def find(self, path: tuple[str, ...]) -> State | None:
        """The descendant at ``path`` (relative to this state), or None."""
        node: State | None = self
        for name in path:
            if node is None:
                return None
            node = node.children.get(name)
        return node


#: The dry run's length when the mission's ``sim.duration_s`` does not say.
DEFAULT_SIM_DURATION_S = 300.0

#: Who may arm a vehicle (``launch.armed_by``); the first is the default.
ARMED_BY = ("pilot", "engine")


@dataclass(frozen=True, slots=True)
class Launch:
    """How a vehicle gets going before its behaviour runs (the mission's ``launch``).

    Real ArduPilot vehicles start disarmed on the ground: someone arms them and an
    aircraft must take off before it goes anywhere. The mission says who does what,
    so that checks can tell a vehicle that will never leave the ground from one the
    pilot hands over in flight, and the runtime knows when the behaviour may start.

    Attributes:
        armed_by: ``pilot`` (the safety pilot arms; the engine never does) or
            ``engine`` (the engine arms when the behaviour first needs it).
        airborne: The pilot has armed the aircraft and taken off before the behaviour
            starts.
        location: Where ``launch`` was written; the agent's own place when it was not.
        key_locations: Where ``armed_by`` and ``airborne`` were written, when they were.
    """

    armed_by: str
    airborne: bool
    location: Location
    key_locations: tuple[tuple[str, Location], ...] = ()

    @property
    def engine_arms(self) -> bool:
        """True when the engine may arm the vehicle."""
        return self.armed_by == "engine"

    def locate(self, key: str) -> Location:
        """Where ``key`` of ``launch`` was written, else where ``launch`` itself was."""
        return dict(self.key_locations).get(key, self.location)


@dataclass(slots=True)
class Agent:
    """One agent of the mission: a vehicle or a mission control station.

    Attributes:
        name: The agent's key under ``agents:``.
        id: ClarkLink agent id, unique in the mission.
        role: ``vehicle`` or ``mcs``.
        profile: Name of its platform profile.
        hardware: The resolved hardware.
        telemetry: Message name -> schedule.
        behavior: Root state of its behaviour, or None.
        failsafe: Situation -> action: ``mcs_lost`` (``hold``, ``rtl``, ``land``,
            ``continue``: the runtime's, on the station's silence) and, for vehicles,
            ``computer_lost`` (``rtl``, ``land``, ``hold``: the autopilot's own, on the
            mission computer's silence).
        terminal_mode: Mode the vehicle is put in when the mission terminates.
        position: Where the agent is in the local frame (stations; vehicles start here).
        launch: How a vehicle gets going (defaults when not written); None for stations,
            and for a vehicle whose ``launch`` or ``position`` the schema rejected (that
            error says why, and the launch checks wait until it is fixed).
        radio_address: Its radio's network address, if given.
        location: Where the agent was declared.
        raw: The agent's mapping as written (for the compiler's pass-through fields).
        locations: Where some of its settings were written (id, telemetry, failsafe,
            terminal_mode, radio_address), for findings about them.
        envelope: A vehicle's resolved safety envelope (the mission's, narrowed by its
            own); None for stations, and for a vehicle whose envelope the schema rejected.
        envelope_decl: The vehicle's own ``envelope:`` as written, when it wrote one.
        computer_lost_s: How long after the mission computer's last heartbeat the
            autopilot applies ``failsafe.computer_lost`` (``failsafe.computer_lost_s``).
    """

    name: str
    id: int
    role: str
    profile: str
    hardware: Hardware
    telemetry: dict[str, Telemetry]
    behavior: State | None
    failsafe: dict[str, str]
    terminal_mode: str | None
    position: LocalPoint
    radio_address: str | None
    location: Location
    launch: Launch | None = None
    raw: dict[str, Any] = field(default_factory=dict)
    locations: dict[str, Location] = field(default_factory=dict)
    envelope: Envelope | None = None
    envelope_decl: EnvelopeDecl | None = None
    computer_lost_s: float = DEFAULT_COMPUTER_LOST_S

    @property
    def is_vehicle(self) -> bool:
        """True for vehicles, False for mission control stations."""
        return self.role == "vehicle"

    @property
    def airframe_class(self) -> str | None:
        """``fixed_wing``, ``multirotor`` or ``rover``; None for stations."""
        airframe = self.hardware.part("airframe") or {}
        value = airframe.get("class")
        return str(value) if value is not None else None


@dataclass(slots=True)
class Mission:
    """A whole resolved mission.

    Attributes:
        file: The mission file as the user named it.
        id: Mission id; agents ignore peers with another one.
        name: Short name, used for output folders.
        loop_hz: Rate of every agent's loop.
        heartbeat_timeout_s: Silence after which a peer counts as lost.
        origin: Reference point of the local frame (its altitude above mean sea level is
            the mission's one AMSL figure).
        log_level: Level of the mission and interface logs.
        agents: Agent name -> agent, in the order written.
        checks: The dry-run expectations as written (evaluated by ``clark dry-run``).
        description: The author's note about the mission.
        source_sha256: Hash of the mission file's bytes, recorded in compiled configs.
        key_file: The ClarkLink key file as written (relative to the mission file), if any.
        operator: What the station operator and pilots do in a dry run, as written.
        operator_locations: Where each operator action was written.
        faults: Faults a dry run injects, as written.
        fault_locations: Where each fault was written.
        sim: Dry-run settings (duration, seed, radio loss and latency, GPS noise).
        sim_locations: Where each dry-run setting was written (``duration_s`` -> location).
        locations: Where each mission setting was written (``loop_hz`` -> location).
        check_locations: Where each dry-run check was written, in order.
        unresolved: Agents declared but too broken to resolve; references to them are
            not reported again.
        envelope: The mission's ``envelope:`` as written (every vehicle's resolved
            envelope is on the vehicle); None when the schema rejected it.
        campaign: How ``clark campaign`` flies it (``runs``, ``seed``, ``min_pass_rate``,
            ``min_pass_rates``), as written; empty when absent or rejected.
        campaign_locations: Where each campaign setting was written.
    """

    file: str
    id: int
    name: str
    loop_hz: float
    heartbeat_timeout_s: float
    origin: Origin
    log_level: str
    agents: dict[str, Agent]
    checks: list[dict[str, Any]] = field(default_factory=list)
    description: str | None = None
    source_sha256: str = ""
    key_file: str | None = None
    operator: list[dict[str, Any]] = field(default_factory=list)
    operator_locations: list[Location] = field(default_factory=list)
    faults: list[dict[str, Any]] = field(default_factory=list)
    fault_locations: list[Location] = field(default_factory=list)
    sim: dict[str, Any] = field(default_factory=dict)
    sim_locations: dict[str, Location] = field(default_factory=dict)
    locations: dict[str, Location] = field(default_factory=dict)
    check_locations: list[Location] = field(default_factory=list)
    unresolved: set[str] = field(default_factory=set)
    envelope: EnvelopeDecl | None = None
    campaign: dict[str, Any] = field(default_factory=dict)
    campaign_locations: dict[str, Location] = field(default_factory=dict)

    @property
    def sim_duration_s(self) -> float:
        """How long a dry run of the mission lasts: ``sim.duration_s``, else the default."""
        return float(self.sim.get("duration_s", DEFAULT_SIM_DURATION_S))

    @property
    def stations(self) -> list[Agent]:
        """The mission control station agents."""
        return [a for a in self.agents.values() if a.role == "mcs"]
