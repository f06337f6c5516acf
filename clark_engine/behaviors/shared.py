"""Parameter schemas and checks that several primitives share.

Points, control channels and PWM limits mean the same thing in a waypoint, a
tour, a doublet and a sweep; they are declared and checked once, here.
"""

from __future__ import annotations

import difflib
import math
from collections.abc import Iterable, Iterator, Mapping
from typing import Any

from clark_engine.behaviors.declaration import CompileContext, UseContext
from clark_engine.mission.envelope_checks import (
    check_height_margin as check_height_margin,  # for takeoff, beside the other checks
)
from clark_engine.mission.envelope_checks import check_leg, check_point
from clark_engine.mission.findings import Finding, Location, error, warning
from clark_engine.mission.geo import LocalPoint, Origin, parse_point, to_global
from clark_engine.mission.model import Agent, Channel
from clark_engine.mission.schema_source.common import (
    NAME_PATTERN,
    Schema,
    altitude_m,
    distance_m,
    integer,
    number,
    obj,
    position_m,
    resolved_point,
    speed_m_s,
    string,
)

POINT_SCHEMA: Schema = {
    "description": (
        "A position: [north_m, east_m] or [north_m, east_m, up_m] in metres from the "
        "mission origin, {north_m, east_m, up_m}, or {lat, lon, alt_m} in degrees and "
        "metres above the origin."
    ),
    "x-expected": (
        "a point: [north_m, east_m], [north_m, east_m, up_m], {north_m: .., east_m: .., up_m: ..} "
        "or {lat: .., lon: .., alt_m: ..}"
    ),
    "anyOf": [
        {
            "type": "array",
            "prefixItems": [
                position_m("Metres north of the origin."),
                position_m("Metres east of the origin."),
                altitude_m("Metres above the origin."),
            ],
            "items": False,
            "minItems": 2,
        },
        {
            "type": "object",
            "properties": {
                "north_m": position_m("Metres north of the origin."),
                "east_m": position_m("Metres east of the origin."),
                "up_m": altitude_m("Metres above the origin.", default=0),
            },
            "required": ["north_m", "east_m"],
            "additionalProperties": False,
        },
        {
            "type": "object",
            "properties": {
                "lat": number("Latitude.", unit="deg", minimum=-90, maximum=90),
                "lon": number("Longitude.", unit="deg", minimum=-180, maximum=180),
                "alt_m": altitude_m("Metres above the origin's altitude.", default=0),
            },
            "required": ["lat", "lon"],
            "additionalProperties": False,
        },
    ],
}

AGENT_NAME_SCHEMA: Schema = string("Name of an agent of this mission.", pattern=NAME_PATTERN)

CHANNEL_SCHEMA: Schema = string(
    "Name of a control channel (aileron, elevator, rudder, throttle, roll, pitch, yaw, "
    "steering, ...), resolved through the agent's hardware profile.",
    pattern=NAME_PATTERN,
)

# The compiled forms of the parameters the compiler resolves (PrimitiveSpec.compiled):
# what a compiled agent config holds in place of a point, a channel name or an agent name.

#: A point in both frames (the compiler's ``_point``).
RESOLVED_POINT_SCHEMA: Schema = resolved_point()


def resolved_channel_schema() -> Schema:
    """A channel as the compiler resolves it: its name and the profile's channel entry.

    The hardware-profile schema's own entry, every field present. A function: that
    schema's module takes a while to import, and only the schema generator needs this.
    """
    from clark_engine.mission.schema_source.hardware_parts import CHANNEL_SCHEMA

    return {
        **CHANNEL_SCHEMA,
        "description": "A control channel resolved through the agent's hardware profile.",
        "properties": {
            "name": string("The channel's name.", pattern=NAME_PATTERN),
            **CHANNEL_SCHEMA["properties"],
        },
        "required": ["name", *CHANNEL_SCHEMA["properties"]],
    }


#: Another agent of the mission, by name and by id (the peer table holds both).
RESOLVED_AGENT_SCHEMA: Schema = obj(
    "Another agent of the mission: its name and its id (one of the config's peers).",
    {
        "name": string("The agent's name.", pattern=NAME_PATTERN),
        "id": integer("The agent's id.", minimum=1, maximum=65535),
    },
    required=["name", "id"],
)

VIA_SCHEMA: Schema = string(
    "How the PWM reaches the surface: rc_override (RC_CHANNELS_OVERRIDE on the channel's RC "
    "input, for channels the autopilot maps to an RC input) or servo (DO_SET_SERVO on the "
    "channel's SERVOn output, for outputs with no function assigned).",
    enum=["rc_override", "servo"],
    default="rc_override",
)

TOLERANCE_SCHEMA: Schema = distance_m(
    "Distance from the target at which it counts as reached.",
    exclusive_minimum=0,
    maximum=1000,
    default=5,
)

SPEED_SCHEMA: Schema = speed_m_s(
    "Speed to fly at (ground speed; airspeed on ArduPlane), asked of the autopilot with "
    "each target; when omitted none is asked, and the autopilot flies its own "
    "(WP_SPEED, WPNAV_SPEED, AIRSPEED_CRUISE).",
    exclusive_minimum=0,
    maximum=100,
)


def compile_channel(params: dict[str, Any], ctx: CompileContext) -> dict[str, Any]:
    """A doublet's or sweep's ``channel``, resolved to its map in the agent's hardware profile."""
    channel = ctx.agent.hardware.channels[params["channel"]]
    params["channel"] = {
        "name": channel.name,
        "rc": channel.rc,
        "servo": channel.servo,
        "pwm_min_us": channel.pwm_min_us,
        "pwm_trim_us": channel.pwm_trim_us,
        "pwm_max_us": channel.pwm_max_us,
    }
    return params


def suggest(word: str, choices: Iterable[str]) -> str:
    """A "did you mean" clause for a misspelt name, or the list of choices."""
    options = sorted(choices)
    close = difflib.get_close_matches(word, options, n=1)
    if close:
        return f"did you mean {close[0]!r}?"
    if not options:
        return "there are none"
    return "choose one of " + ", ".join(options)


def resolve_channel(
    ctx: UseContext, param: str = "channel"
) -> tuple[Channel | None, list[Finding]]:
    """Look a channel name up in the agent's profile and check ``via`` can drive it."""
    name = str(ctx.params[param])
    channels = ctx.agent.hardware.channels
    channel = channels.get(name)
    if channel is None:
        return None, [
            error(
                "E-CHANNEL-UNKNOWN",
                ctx.locate(param),
                f"agent {ctx.agent.name!r} ({ctx.agent.profile}) has no control channel "
                f"{name!r}; {suggest(name, channels)} or map {name!r} in its profile's channels",
                ctx.use_location,
            )
        ]
    via = ctx.params.get("via", "rc_override")
    if via == "rc_override" and channel.rc is None:
        return channel, [
            error(
                "E-CHANNEL-VIA",
                ctx.locate("via"),
                f"channel {name!r} of {ctx.agent.name!r} has no RC input to override; "
                "write via: servo, or give the channel an rc number in the profile",
                ctx.use_location,
            )
        ]
    if via == "servo" and channel.servo is None:
        return channel, [
            error(
                "E-CHANNEL-VIA",
                ctx.locate("via"),
                f"channel {name!r} of {ctx.agent.name!r} has no servo output number; "
                "write via: rc_override, or give the channel a servo number in the profile",
                ctx.use_location,
            )
        ]
    return channel, []


def check_pwm_swing(ctx: UseContext, channel: Channel, amplitude_us: float) -> Iterator[Finding]:
    """Trim plus and minus the amplitude must stay inside the channel's PWM limits."""
    low = channel.pwm_trim_us - amplitude_us
    high = channel.pwm_trim_us + amplitude_us
    if low < channel.pwm_min_us or high > channel.pwm_max_us:
        room = min(
            channel.pwm_trim_us - channel.pwm_min_us, channel.pwm_max_us - channel.pwm_trim_us
        )
        yield error(
            "E-PWM-RANGE",
            ctx.locate("amplitude_us"),
            f"{amplitude_us:g} us around trim {channel.pwm_trim_us} us commands "
            f"{low:g}..{high:g} us, outside the limits of channel {channel.name!r}, "
            f"{channel.pwm_min_us}..{channel.pwm_max_us} us; use an amplitude of at most {room} us",
            ctx.use_location,
        )


def check_channel_swing(ctx: UseContext) -> Iterator[Finding]:
    """The named channel exists for ``via`` and trim +- amplitude_us fits its limits."""
    channel, findings = resolve_channel(ctx)
    yield from findings
    if channel is not None:
        yield from check_pwm_swing(ctx, channel, float(ctx.params["amplitude_us"]))


def check_points(
    ctx: UseContext, points: list[Any], param: str, *, indexed: bool
) -> Iterator[Finding]:
    """Every point stays inside the envelope and within radio range of the station(s).

    Inside the envelope: under the ceiling (:func:`check_ceiling`), over the floor,
    inside the geofence and far enough inside for the runtime to send it as written
    (a fixed-wing aircraft's circle round it included): :func:`check_point`.
    """
    mission = ctx.mission
    airframe = ctx.agent.hardware.part("airframe") or {}
    autopilot = ctx.agent.hardware.part("autopilot") or {}
    orbit_m = orbit_radius_m(airframe, autopilot, ctx.params.get("speed_m_s"))
    for index, raw in enumerate(points):
        point = parse_point(raw, mission.origin)
        where = ctx.locate(f"{param}[{index}]" if indexed else param)
        label = f"waypoint {index}" if indexed else "the waypoint"
        yield from check_ceiling(ctx, point.up_m, where, label)
        yield from check_point(ctx.agent, point, where, label, ctx.use_location, orbit_m=orbit_m)
        yield from _check_range(ctx, point, where, label)
        problem = off_the_globe(point, mission.origin)
        if problem:
            yield error("E-POSITION", where, f"{label} {problem}", ctx.use_location)


def check_tour_legs(ctx: UseContext) -> Iterator[Finding]:
    """Each leg of a tour, and a looping tour's closing leg, stays inside the geofence."""
    points = [parse_point(raw, ctx.mission.origin) for raw in ctx.params["waypoints"]]
    legs = [(i, i + 1) for i in range(len(points) - 1)]
    if ctx.params.get("loop") and len(points) > 2:
        legs.append((len(points) - 1, 0))  # with two points it is the first leg, reversed
    for i, j in legs:
        yield from check_leg(
            ctx.agent,
            points[i],
            points[j],
            ctx.locate(f"waypoints[{j}]"),
            f"the leg from waypoint {i} to waypoint {j}",
            ctx.locate(f"waypoints[{i}]"),
            ctx.use_location,
        )


def check_ceiling(ctx: UseContext, up_m: float, where: Location, label: str) -> Iterator[Finding]:
    """An aircraft's height must lie between the ground and its envelope's ceiling.

    Rovers are not checked: they drive on the ground whatever height a point gives.
    A vehicle without a resolved envelope (its envelope's own error is reported) is not
    checked either.

    Args:
        ctx: The use being checked.
        up_m: The height above the origin.
        where: Where the height was written.
        label: What the height belongs to, as the message names it ("waypoint 2").
    """
    envelope = ctx.agent.envelope
    if ctx.agent.airframe_class == "rover" or envelope is None:
        return
    if up_m > envelope.ceiling_m:
        yield error(
            "E-ALTITUDE-CEILING",
            where,
            f"{label} is {up_m:g} m above the origin, over {ctx.agent.name}'s ceiling of "
            f"{envelope.describe_ceiling()}; fly lower or raise the ceiling",
            ctx.use_location,
        )
    if up_m < 0:
        yield error(
            "E-ALTITUDE-CEILING",
            where,
            f"{label} is {-up_m:g} m below the origin; give a height above the origin",
            ctx.use_location,
        )


#: How a mission names each airframe class in a sentence.
AIRFRAME_NAMES = {
    "fixed_wing": "a fixed-wing aircraft",
    "multirotor": "a multirotor",
    "rover": "a rover",
}


def check_airframe(
    ctx: UseContext, primitive: str, refused: Mapping[str, str]
) -> Iterator[Finding]:
    """A primitive that only some airframes can fly must not be given to the others.

    Args:
        ctx: The use being checked.
        primitive: The primitive's name, for the message.
        refused: Airframe class -> why the primitive cannot run on it and what to use
            instead (the message's second half).
    """
    kind = ctx.agent.airframe_class
    if kind is None or kind not in refused:
        return
    yield error(
        "E-AIRFRAME-PRIMITIVE",
        ctx.use_location,
        f"{primitive} cannot run on {ctx.agent.name} ({ctx.agent.profile}), "
        f"{AIRFRAME_NAMES.get(kind, kind)}: {refused[kind]}",
    )


def check_mode_role(
    ctx: UseContext, primitive: str, role: str, usual: str, does: str
) -> Iterator[Finding]:
    """A primitive that flies in one of the autopilot's mode roles needs the profile to name it.

    Args:
        ctx: The use being checked.
        primitive: The primitive's name, for the message.
        role: The autopilot profile key (``land_mode``, ``rtl_mode``).
        usual: The mode ArduPilot usually has for it (``LAND``), suggested when the
            autopilot has a mode of that name.
        does: What the mode does, for the message ("lands").
    """
    autopilot = ctx.agent.hardware.part("autopilot") or {}
    if autopilot.get(role) is not None:
        return
    profile = ctx.agent.hardware.part_profiles.get("autopilot", ctx.agent.profile)
    fix = (
        f"add {role}: {usual} to that profile"
        if usual in ctx.agent.hardware.modes
        else f"add {role} naming one of its modes that {does}, or use another primitive"
    )
    yield error(
        "E-MODE-MISSING",
        ctx.use_location,
        f"{primitive} flies in the autopilot's {role}, and the autopilot profile of "
        f"{ctx.agent.name} ({profile}) names none; {fix}",
    )


def off_the_globe(point: LocalPoint, origin: Origin) -> str | None:
    """Why a local point has no latitude/longitude (past a pole), or None when it has."""
    lat, _lon, _alt = to_global(point, origin)
    if not -90.0 <= lat <= 90.0:
        return (
            f"lies past a pole (latitude {lat:.5f}); positions must stay within "
            "latitude -90..90, so move it or the origin"
        )
    return None


def _check_range(ctx: UseContext, point: LocalPoint, where: Any, label: str) -> Iterator[Finding]:
    own_range = ctx.agent.hardware.radio_range_m
    if not ctx.mission.stations:
        yield from _check_range_to_peers(ctx, point, where, label)
        return
    for station in ctx.mission.stations:
        ranges = [r for r in (own_range, station.hardware.radio_range_m) if r is not None]
        if not ranges:
            continue
        limit = min(ranges)
        distance = point.horizontal_distance_m(station.position)
        if distance > limit:
            yield error(
                "E-RADIO-RANGE",
                where,
                f"{label} is {distance:.0f} m from station {station.name!r}, beyond the "
                f"{limit:.0f} m radio range; move it closer or the station nearer",
                ctx.use_location,
            )


def _check_range_to_peers(
    ctx: UseContext, point: LocalPoint, where: Any, label: str
) -> Iterator[Finding]:
    """Without a station, a point must be within radio range of some other agent's start.

    With no station to measure from, the agent's peers (where they start) are what its
    radio must reach; a lone agent is measured from the mission origin. A point beyond
    every one of them is out of touch with the whole fleet.
    """
    me = ctx.agent
    peers = [a for a in ctx.mission.agents.values() if a.name != me.name]
    references = [(f"the start of agent {a.name!r}", a.position, a) for a in peers]
    if not references:
        references = [("the mission origin", LocalPoint(0.0, 0.0, 0.0), me)]
    nearest: tuple[float, str, float] | None = None
    for what, position, other in references:
        ranges = [r for r in (me.hardware.radio_range_m, other.hardware.radio_range_m) if r]
        if not ranges:
            return  # a radio of unknown range: nothing to measure against
        limit = min(ranges)
        distance = point.horizontal_distance_m(position)
        if distance <= limit:
            return
        if nearest is None or distance < nearest[0]:
            nearest = (distance, what, limit)
    if nearest is not None:
        distance, what, limit = nearest
        yield error(
            "E-RADIO-RANGE",
            where,
            f"{label} is {distance:.0f} m from {what}, the nearest radio it could reach (the "
            f"mission has no station), beyond the {limit:.0f} m radio range; move it closer",
            ctx.use_location,
        )


#: A fixed-wing aircraft never orbits tighter than this multiple of its tightest turn
#: radius (the dry run's model does the same: clark_engine.sim.ardupilot.airframes.fixed_wing).
ORBIT_FACTOR = 1.5
#: ArduPlane flies its loiter circle about this much wider than WP_LOITER_RAD (92-93 m
#: for 80 m at 22 m/s on ArduPlane SITL; the dry run's model uses the same factor).
LOITER_RADIUS_FACTOR = 1.15
#: ArduPlane's defaults of the parameters that set the circle (m, m/s).
DEFAULT_WP_LOITER_RAD_M = 60.0
DEFAULT_AIRSPEED_CRUISE_M_S = 15.0
GRAVITY_M_S2 = 9.80665


def orbit_radius_m(
    airframe: Mapping[str, Any],
    autopilot: Mapping[str, Any] | None = None,
    speed_m_s: float | None = None,
) -> float | None:
    """How far from a guided target a fixed-wing aircraft circles it; None for others.

    An aeroplane cannot stop: arriving at a target it circles it, at ArduPlane's
    WP_LOITER_RAD (as flown: :data:`LOITER_RADIUS_FACTOR` wider) unless its speed and
    its bank and turn-rate limits force a wider circle. Parameters come from the
    autopilot profile's ``parameters``, else ArduPlane's defaults.
    """
    if airframe.get("class") != "fixed_wing":
        return None
    params = (autopilot or {}).get("parameters") or {}
    cruise = float(params.get("AIRSPEED_CRUISE", DEFAULT_AIRSPEED_CRUISE_M_S))
    speed = float(speed_m_s or cruise)
    bank = math.radians(float(airframe.get("max_bank_deg") or 45.0))
    by_bank = speed * speed / (GRAVITY_M_S2 * math.tan(bank))
    rate = math.radians(float(airframe.get("max_turn_rate_deg_s") or 0.0))
    by_rate = speed / rate if rate > 0 else by_bank
    loiter = LOITER_RADIUS_FACTOR * float(params.get("WP_LOITER_RAD", DEFAULT_WP_LOITER_RAD_M))
    return max(loiter, ORBIT_FACTOR * max(by_bank, by_rate))


def check_orbit_tolerance(
    ctx: UseContext, circled: str = "a target", reached: str = "the target"
) -> Iterator[Finding]:
    """A fixed-wing target must be 'reached' within a radius the aircraft can fly.

    Args:
        ctx: The use being checked.
        circled: What the aircraft circles, as the message says it ("home in RTL").
        reached: The same, as the subject of "is never reached".
    """
    airframe = ctx.agent.hardware.part("airframe") or {}
    autopilot = ctx.agent.hardware.part("autopilot") or {}
    radius = orbit_radius_m(airframe, autopilot, ctx.params.get("speed_m_s"))
    tolerance = float(ctx.params.get("tolerance_m", 5.0))
    if radius is not None and tolerance < radius:
        yield warning(
            "W-ORBIT-TOLERANCE",
            ctx.locate("tolerance_m"),
            f"{ctx.agent.name} ({ctx.agent.profile}) is a fixed-wing aircraft: it circles "
            f"{circled} about {radius:.0f} m away and never comes within tolerance_m "
            f"{tolerance:g} m, so {reached} is never reached; set tolerance_m to at least "
            f"{math.ceil(radius)} m",
            ctx.use_location,
        )


def check_speed(ctx: UseContext) -> Iterator[Finding]:
    """A commanded speed must be one the airframe can fly."""
    speed = ctx.params.get("speed_m_s")
    airframe = ctx.agent.hardware.part("airframe")
    if speed is None or airframe is None:
        return
    top = airframe.get("max_speed_m_s")
    low = airframe.get("min_speed_m_s", 0)
    if top is not None and speed > top:
        yield error(
            "E-SPEED-RANGE",
            ctx.locate("speed_m_s"),
            f"{speed:g} m/s is above the {ctx.agent.profile} airframe's maximum of {top:g} m/s; "
            "fly slower",
            ctx.use_location,
        )
    if low and speed < low:
        yield error(
            "E-SPEED-RANGE",
            ctx.locate("speed_m_s"),
            f"{speed:g} m/s is below the {ctx.agent.profile} airframe's minimum of {low:g} m/s "
            "(stall margin); fly faster",
            ctx.use_location,
        )


def check_mode(ctx: UseContext, param: str = "mode") -> Iterator[Finding]:
    """A mode name must be one the agent's autopilot firmware has."""
    mode = ctx.params.get(param)
    modes = ctx.agent.hardware.modes
    if mode is not None and mode not in modes:
        yield error(
            "E-MODE-UNKNOWN",
            ctx.locate(param),
            f"the autopilot of {ctx.agent.name} ({ctx.agent.profile}) has no mode {mode!r}; "
            + suggest(str(mode), modes),
            ctx.use_location,
        )


def status_gap(sender: Agent, receiver: str) -> str | None:
    """Why ``receiver`` never hears ``sender``'s position, or None when it does.

    For the behaviours that go by another agent's Agent Status (follow_agent, orbit):
    the start of their error, ``'slash_a' sends no agent_status`` and the like.
    """
    status = sender.telemetry.get("agent_status")
    if status is None:
        return "sends no agent_status"
    if not status.reaches(receiver):
        return f"sends agent_status only to {', '.join(status.to)}"
    return None


def check_position_reports(
    ctx: UseContext, peer: Agent, param: str, codes: tuple[str, str], learns: str, doing: str
) -> Iterator[Finding]:
    """The peer's Agent Status reaches this agent, as often as it moves its target by it.

    For the behaviours that go by another agent's position (follow_agent, orbit).

    Args:
        ctx: The use being checked (its ``retarget_hz`` is the rate it needs).
        peer: The agent whose position it goes by.
        param: The parameter naming the peer (where the error points).
        codes: The behaviour's error and warning codes.
        learns: What it never learns without them (``where it is``).
        doing: What it does at ``retarget_hz``, for the warning (``re-targets at 2 Hz``).
    """
    me = ctx.agent
    status = peer.telemetry.get("agent_status")
    retarget_hz = float(ctx.params["retarget_hz"])
    why = status_gap(peer, me.name)
    if status is None or why is not None:
        yield error(
            codes[0],
            ctx.locate(param),
            f"{peer.name!r} {why}, so {me.name!r} never learns {learns}; add agent_status "
            f"to agents.{peer.name}.telemetry (at least {retarget_hz:g} Hz)",
            peer.location,
        )
    elif status.rate_hz < retarget_hz:
        yield warning(
            codes[1],
            ctx.locate("retarget_hz"),
            f"{me.name!r} {doing} but {peer.name!r} reports its position at only "
            f"{status.rate_hz:g} Hz; raise its agent_status rate or lower retarget_hz",
            status.location,
        )


def check_agents_exist(ctx: UseContext, names: Iterable[str], param: str) -> Iterator[Finding]:
    """Every named agent must exist in the mission."""
    for name in names:
        if name not in ctx.mission.agents and name not in ctx.mission.unresolved:
            yield error(
                "E-AGENT-UNKNOWN",
                ctx.locate(param),
                f"there is no agent {name!r} in this mission; {suggest(name, ctx.mission.agents)}",
                ctx.use_location,
            )
