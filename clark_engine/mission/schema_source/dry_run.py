"""Schema of the mission's dry-run sections: checks, operator, faults, sim, campaign.

Each agent's ``sim`` (how its vehicle starts in a dry run) is here too.

Why separate: :mod:`.mission` declares the mission a vehicle flies (its settings, agents,
hardware, telemetry, behaviour); these sections say only how ``clark dry-run`` and
``clark campaign`` rehearse it (what the run must observe, what the operator does, the
faults, the simulated world, the campaign's variations), and the engine in flight ignores
them.
"""

from __future__ import annotations

from clark_engine.behaviors.shared import AGENT_NAME_SCHEMA, POINT_SCHEMA
from clark_engine.mission.schema_source.common import (
    Schema,
    altitude_m,
    array,
    count,
    distance_m,
    integer,
    number,
    obj,
    share,
    speed_m_s,
    string,
    time_s,
)
from clark_engine.mission.schema_source.states import STATE_PATH_PATTERN
from clark_engine.mission.variation import varied

#: Largest random seed: 2^32 seeds are more runs than anyone makes, and a bound keeps a
#: pasted 400-digit number out of the report's command line.
SEED_MAX = 2**32 - 1


def check() -> Schema:
    """One item of ``checks``: an expectation the dry run evaluates."""
    agents2 = array("Two agents.", AGENT_NAME_SCHEMA, min_items=2) | {"maxItems": 2}
    return obj(
        "An expectation the dry run evaluates; exactly one kind per item.",
        {
            "name": string("A label for the report."),
            "by_s": time_s("Simulated time by which the expectation must hold."),
            "distance_m": obj(
                "Distance between two agents: with max, they come within max of each other "
                "by by_s; with min, they are at least min apart at by_s. 3-D when either is "
                "an aircraft (any airframe but a rover); on the ground between two rovers.",
                {
                    "between": agents2,
                    "max": distance_m("Largest allowed distance."),
                    "min": distance_m("Smallest allowed distance."),
                },
                required=["between"],
            ),
            "reached": obj(
                "An agent comes within tolerance of a position by by_s: 3-D for an aircraft "
                "(a point without a height is on the ground), on the ground for a rover.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "to": POINT_SCHEMA,
                    "tolerance_m": distance_m(
                        "Distance that counts as reached.", exclusive_minimum=0, default=5
                    ),
                },
                required=["agent", "to"],
            ),
            "separation_m": obj(
                "Minimum distance between any two of the vehicles at every moment: 3-D for "
                "a pair with an aircraft, on the ground between two rovers.",
                {
                    "min": distance_m("Smallest allowed separation."),
                    "agents": array(
                        "Vehicles to consider; all when omitted.", AGENT_NAME_SCHEMA, min_items=2
                    ),
                },
                required=["min"],
            ),
            "altitude_m": obj(
                "An agent's altitude above the mission origin stays within min and max at "
                "every moment until by_s (the end of the run when by_s is omitted); give "
                "min, max or both.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "min": altitude_m("Lowest allowed altitude above the origin."),
                    "max": altitude_m("Highest allowed altitude above the origin."),
                },
                required=["agent"],
            ),
            "ends_at": obj(
                "An agent's position at by_s (the end of the run when by_s is omitted) is "
                "within within_m of a point: where it ends up. 3-D for an aircraft (a point "
                "without a height is on the ground), on the ground for a rover.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "to": POINT_SCHEMA,
                    "within_m": distance_m(
                        "Largest distance from the point.", exclusive_minimum=0, default=5
                    ),
                },
                required=["agent", "to"],
            ),
            "state": obj(
                "An agent's behaviour reaches a state by by_s.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "reached": string("Dotted path of the state.", pattern=STATE_PATH_PATTERN),
                },
                required=["agent", "reached"],
            ),
            "sequence": obj(
                "An agent's behaviour enters these states in this order, the last by by_s "
                "(each after the one before it; other states may come in between).",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "states": array(
                        "Dotted paths of the states, in the order they must be entered.",
                        string("Dotted path of a state.", pattern=STATE_PATH_PATTERN),
                        min_items=2,
                    ),
                },
                required=["agent", "states"],
            ),
            "photos": obj(
                "Number of pictures an agent takes over the run.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "min": count("Fewest pictures."),
                    "max": count("Most pictures."),
                },
                required=["agent"],
            ),
            "no_failsafe": obj(
                "No failsafe is triggered on the listed agents (all when omitted).",
                {"agents": array("Agents to watch.", AGENT_NAME_SCHEMA)},
            ),
            "failsafe": obj(
                "A safety reaction happens on an agent by by_s (for missions that inject "
                "faults): the mcs_lost failsafe (hold, rtl, land) or autopilot_lost.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "event": string(
                        "Which reaction.",
                        enum=["hold", "rtl", "land", "autopilot_lost", "any"],
                        default="any",
                    ),
                },
                required=["agent"],
            ),
            "signal": obj(
                "The servo signal an agent commands in a state matches its primitive "
                "(doublet shape, sweep frequency law).",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "state": string(
                        "Dotted path of a doublet or sine_sweep state.", pattern=STATE_PATH_PATTERN
                    ),
                },
                required=["agent", "state"],
            ),
        },
    ) | {"minProperties": 1}


def _window() -> dict[str, Schema]:
    return {
        "from_s": varied(time_s("Start of the fault, simulated time.")),
        "to_s": varied(time_s("End of the fault, simulated time.", exclusive_minimum=0)),
        "chance": _chance(),
    }


def _chance() -> Schema:
    return share(
        "The share of runs in which this fault is injected (drawn once per run from the "
        "run's seed; clark dry-run --vary faults.N.KIND.injected=true fixes it). Always "
        "when omitted."
    )


def operator() -> Schema:
    """One item of ``operator``: what the operator or a pilot does, and when."""
    target = string("Agent name, or all.", pattern=r"^([a-z][a-z0-9_]*|all)$")
    return obj(
        "Something the station operator or a pilot does during a dry run, at a time; "
        "exactly one action per item.",
        {
            "at_s": time_s("When, in simulated seconds from the start."),
            "activate": target | {"description": "Activate Controller to this agent (or all)."},
            "deactivate": target
            | {"description": "Deactivate the controller of this agent (or all)."},
            "mode": obj(
                "Mode Change Request from the station.",
                {"agent": AGENT_NAME_SCHEMA, "mode": string("Mode name of its autopilot.")},
                required=["agent", "mode"],
            ),
            "terminate": target | {"description": "Terminate this agent (or all): the mission."},
            "rc": obj(
                "A pilot moves a switch or stick: the RC input of one channel.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "channel": integer("RC channel.", minimum=1, maximum=18),
                    "pwm_us": integer("Pulse width.", unit="us", minimum=800, maximum=2200),
                },
                required=["agent", "channel", "pwm_us"],
            ),
        },
        required=["at_s"],
    ) | {"minProperties": 2, "maxProperties": 2}


def fault() -> Schema:
    """One item of ``faults``: a fault the dry run injects."""
    return obj(
        "A fault the dry run injects; exactly one kind per item.",
        {
            "kill": obj(
                "An agent's mission computer dies: its runtime stops and its radio goes "
                "silent; the autopilot flies on in its last mode.",
                {
                    "agent": AGENT_NAME_SCHEMA,
                    "at_s": varied(time_s("When.")),
                    "chance": _chance(),
                },
                required=["agent", "at_s"],
            ),
            "link_drop": obj(
                "The radio link between two agents drops, both ways.",
                {
                    "between": array("Two agents.", AGENT_NAME_SCHEMA, min_items=2)
                    | {"maxItems": 2},
                    **_window(),
                },
                required=["between", "from_s", "to_s"],
            ),
            "station_silent": obj(
                "Every station's radio goes silent (the operator's side fails).",
                _window(),
                required=["from_s", "to_s"],
            ),
            "autopilot_disconnect": obj(
                "An agent's autopilot link goes silent both ways.",
                {"agent": AGENT_NAME_SCHEMA, **_window()},
                required=["agent", "from_s", "to_s"],
            ),
            "corrupt": obj(
                "A share of the radio packets delivered arrive with bytes flipped.",
                {
                    "share": varied(share("Share of packets corrupted.")),
                    **_window(),
                },
                required=["share"],
            ),
        },
    ) | {"minProperties": 1, "maxProperties": 1}


def sim() -> Schema:
    """The mission's ``sim``: how the dry run simulates it."""
    return obj(
        "How the dry run simulates this mission (clark dry-run).",
        {
            "duration_s": time_s(
                "How long to simulate when --until is not given.",
                exclusive_minimum=0,
                maximum=86400,
                default=300,
            ),
            "seed": integer(
                "Random seed when --seed is not given (up to 2^32 - 1).",
                minimum=0,
                maximum=SEED_MAX,
                default=0,
            ),
            "radio_loss": varied(
                share("Share of packets lost at random, before range losses.", default=0.0)
            ),
            "radio_latency_s": varied(
                time_s("Latency of the radio beyond serialisation.", maximum=60, default=0.005)
            ),
            "gps_noise_m": varied(
                distance_m(
                    "Standard deviation of simulated GPS error (thesis 5.1.5: 0.62 m mean error).",
                    maximum=1000,
                    default=0.5,
                )
            ),
            "autopilot_ready_s": varied(
                number(
                    "Seconds from power-on until a simulated autopilot can arm and fly: its GPS "
                    "fix, EKF position and pre-arm checks come in ArduPilot's order, sooner or "
                    "later. Each firmware's own timing measured on ArduPilot SITL when omitted "
                    "(about 42 s for ArduRover and ArduCopter, 23 s for ArduPlane).",
                    unit="s",
                    exclusive_minimum=0,
                    maximum=600,
                )
            ),
            "gps_error": _gps_error(),
            "radio_bursts": _radio_bursts(),
            "jitter": _jitter(),
            "wind": _wind(),
            "sitl_tolerance": _sitl_tolerance(),
        },
    )


def _sitl_tolerance() -> Schema:
    # The defaults and their reasons: docs/autopilot-fidelity.md, "The same mission both
    # ways"; clark_engine/dryrun/timeline.py applies them.
    return obj(
        "With clark dry-run --autopilot sitl: how close the mission on ArduPilot SITL must "
        "come to the same mission on the simulated autopilot for the comparison to pass. "
        "Each state's first entry is allowed a share of its leg (the time since the agent's "
        "previous state change on SITL), never less than time_floor_s; positions and "
        "altitudes at each state change and at the end, and every check's verdict and "
        "figures, are compared too.",
        {
            "time_floor_s": time_s(
                "The least a state's entry time may differ whatever its leg: the jitter of "
                "two runs' messages and ticks.",
                exclusive_minimum=0,
                maximum=3600,
                default=3.0,
            ),
            "sim_sooner_share": share(
                "How much sooner than on SITL the simulated run may get through a leg, as a "
                "share of SITL's leg: the simulation must not be kinder than ArduPilot "
                "(0.9x SITL's time at the quickest, as the conformance suite holds it).",
                default=0.1,
            ),
            "sim_later_share": share(
                "How much later than on SITL the simulated run may get through a leg, as a "
                "share of SITL's leg (up to 1.3x SITL's time, as the conformance suite "
                "allows).",
                default=0.3,
            ),
            "position_m": distance_m(
                "How far apart (horizontally) the vehicle may be in the two runs when it "
                "enters each state, at the end of the run, and in a check's distances.",
                maximum=10000,
                default=10.0,
            ),
            "altitude_m": distance_m(
                "How far apart an aircraft's altitudes may be in the two runs when it "
                "enters each state, at the end of the run, and in a check's altitudes.",
                maximum=10000,
                default=3.0,
            ),
            "count_share": share(
                "How far apart a check's counts (photos) may be, as a share of SITL's "
                "count, never less than one.",
                default=0.1,
            ),
        },
    )


def _wind() -> Schema:
    return obj(
        "The wind every simulated aircraft flies in: one air mass for the whole fleet, "
        "ArduPilot SITL's own wind model, and under --autopilot sitl given to SITL as its "
        "SIM_WIND_* parameters (docs/dry-run.md, Wind). Still air when omitted.",
        {
            "speed_mps": varied(
                speed_m_s(
                    "Mean wind speed at and above the profile's full_alt_m (SIM_WIND_SPD).",
                    maximum=100,
                    default=0,
                )
            ),
            "from_deg": varied(
                number(
                    "True direction the wind blows from, degrees clockwise from north "
                    "(SIM_WIND_DIR; 270 is a west wind, blowing toward the east).",
                    unit="deg",
                    minimum=0,
                    maximum=360,
                    default=180,
                )
            ),
            "turbulence_mps": varied(
                speed_m_s(
                    "Standard deviation of the wind's random variation in flight "
                    "(SIM_WIND_TURB): SITL's fast, direction-less turbulence, about 0.04 s "
                    "correlated.",
                    maximum=50,
                    default=0,
                )
            ),
            "profile": obj(
                "How the mean wind changes with height above home (SIM_WIND_T and its parameters).",
                {
                    "type": string(
                        "sqrt: the mean times sqrt(height / full_alt_m) below full_alt_m, no "
                        "wind on the ground (SITL's default); linear: the mean plus "
                        "(height - full_alt_m) * linear_mps_per_m, never below 0; none: the "
                        "mean at every height.",
                        enum=["sqrt", "linear", "none"],
                        default="sqrt",
                    ),
                    "full_alt_m": varied(
                        altitude_m(
                            "Height above home where the mean wind blows in full (SIM_WIND_T_ALT).",
                            minimum=0,
                            maximum=10000,
                            default=60,
                        )
                    ),
                    "linear_mps_per_m": varied(
                        number(
                            "The linear profile's change of wind speed per metre of height "
                            "(SIM_WIND_T_COEF).",
                            unit="1/s",
                            minimum=-1,
                            maximum=1,
                            default=0.01,
                        )
                    ),
                },
            ),
            "gusts": obj(
                "Gusts along the mean wind, at random times (exponential intervals), each a "
                "smooth rise and fall scaled by the profile. Simulated only: SITL has no "
                "gust model, so --autopilot sitl flies without them.",
                {
                    "speed_mps": varied(
                        speed_m_s("A gust's peak, added to the mean.", maximum=100, default=0)
                    ),
                    "every_s": varied(
                        time_s(
                            "Mean time between gusts.",
                            exclusive_minimum=0,
                            maximum=86400,
                            default=60,
                        )
                    ),
                    "duration_s": varied(
                        time_s(
                            "How long one gust lasts, rise and fall.",
                            exclusive_minimum=0,
                            maximum=600,
                            default=4,
                        )
                    ),
                },
            ),
        },
    )


MAX_CAMPAIGN_RUNS = 100_000
"""Most runs a mission's campaign may declare (and ``clark campaign --runs`` take)."""


def campaign() -> Schema:
    """The mission's ``campaign``: how clark campaign flies it many times."""
    return obj(
        "How clark campaign flies this mission many times, each run with its own seed and "
        "its own draw of the mission's variations, and what share of runs must pass.",
        {
            "runs": integer(
                "How many runs when --runs is not given.",
                minimum=1,
                maximum=MAX_CAMPAIGN_RUNS,
                default=100,
            ),
            "seed": integer(
                "The campaign's seed when --seed is not given (run i's seed is derived from "
                "it and i); sim.seed when omitted.",
                minimum=0,
                maximum=SEED_MAX,
            ),
            "min_pass_rate": share(
                "Share of runs that must pass every check and their safety judgement, or "
                "clark campaign exits 1 (--min-pass-rate overrides it)."
            ),
            "min_pass_rates": {
                "type": "object",
                "description": "Per check, by its name (or a safety row's, `safety: cub`): "
                "the share of the runs that judged it in which it must hold, or clark "
                "campaign exits 1.",
                "propertyNames": {"minLength": 1, "maxLength": 200},
                "additionalProperties": share("The check's minimum pass rate."),
            },
        },
    )


def _gps_error() -> Schema:
    return obj(
        "Each vehicle's slowly wandering GPS error, beyond the white gps_noise_m of each fix "
        "(docs/dry-run.md, A world with errors). The simulated autopilot reports and flies "
        "by its estimate (truth plus this error), so a vehicle holding a point truly "
        "wanders with it. Nothing when omitted.",
        {
            "walk_m": varied(
                distance_m(
                    "Steady-state standard deviation of the horizontal random walk (a "
                    "first-order Gauss-Markov error), per axis. A standalone GPS: about 1-2 m.",
                    maximum=1000,
                    default=0.0,
                )
            ),
            "walk_time_constant_s": varied(
                time_s(
                    "The walk's correlation time: errors this far apart are correlated by "
                    "1/e (0.37). Minutes for a GPS (the atmosphere and the satellites move "
                    "slowly).",
                    exclusive_minimum=0,
                    maximum=86400,
                    default=300.0,
                )
            ),
            "common_share": varied(
                share(
                    "Share of the walk's variance common to the whole fleet (vehicles under "
                    "the same sky): two vehicles' errors are correlated by this much.",
                    default=0.0,
                )
            ),
            "glitch_rate_per_h": varied(
                number(
                    "Glitches per hour of simulated time, per vehicle (a Poisson process).",
                    unit="1/h",
                    minimum=0,
                    maximum=3600,
                    default=0.0,
                )
            ),
            "glitch_m": varied(
                distance_m(
                    "How far a glitch moves the reported position, in a random direction.",
                    maximum=10000,
                    default=0.0,
                )
            ),
            "glitch_s": varied(
                time_s(
                    "How long a glitch lasts before the position comes back.",
                    maximum=3600,
                    default=0.0,
                )
            ),
        },
    )


def _radio_bursts() -> Schema:
    return obj(
        "Bursty radio loss on every link (pair of agents): a two-state Gilbert-Elliott chain "
        "in simulated time, one per link, on top of radio_loss and the distance law "
        "(docs/radios.md). Nothing when omitted.",
        {
            "good_s": varied(
                time_s(
                    "Mean time a link stays in its good state (exponentially distributed).",
                    exclusive_minimum=0,
                    maximum=86400,
                    default=60.0,
                )
            ),
            "bad_s": varied(
                time_s(
                    "Mean time a link stays in its bad state, a burst (exponentially distributed).",
                    exclusive_minimum=0,
                    maximum=86400,
                    default=2.0,
                )
            ),
            "loss_good": varied(share("Share of packets the good state loses.", default=0.0)),
            "loss_bad": varied(share("Share of packets the bad state loses.", default=1.0)),
        },
    )


def _jitter() -> Schema:
    return obj(
        "Seeded jitter on times a real run never keeps exactly (docs/dry-run.md). Nothing "
        "when omitted.",
        {
            "operator_s": varied(
                time_s(
                    "Each operator action happens up to this many seconds before or after its "
                    "at_s (uniform); actions keep the order they are written in.",
                    maximum=3600,
                    default=0.0,
                )
            ),
            "ready_s": varied(
                time_s(
                    "Each simulated autopilot's boot timeline is shifted by up to this many "
                    "seconds earlier or later (uniform, per vehicle; never before power-on).",
                    maximum=600,
                    default=0.0,
                )
            ),
            "pilot_s": varied(
                time_s(
                    "The simulated pilot arms up to this many seconds after the vehicle "
                    "shows ready (uniform, per vehicle): a person's reaction.",
                    maximum=600,
                    default=0.0,
                )
            ),
        },
    )


def agent_sim() -> Schema:
    """An agent's ``sim``: how its vehicle starts in a dry run."""
    return obj(
        "How this agent's vehicle starts in a dry run.",
        {
            "mode": string(
                "Flight mode at the start; the autopilot's hold mode for aircraft and its "
                "manual mode for rovers when omitted."
            ),
            "heading_deg": number(
                "Heading at the start.", unit="deg", minimum=0, maximum=360, default=0
            ),
        },
    )
