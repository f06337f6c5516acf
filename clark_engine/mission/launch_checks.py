"""Checks of how each vehicle starts: its ``launch``, its start height, its takeoff.

Why separate: they join what ArduPilot does on the ground (a copter disarms if it does not
take off soon after arming, an aircraft on the ground ignores guided targets) to the
agent's ``launch`` and the first states of its behaviour, a concern of its own between the
agent's declaration and its states. :func:`clark_engine.mission.cross_checks.run_all` runs
them.
"""

from __future__ import annotations

from collections.abc import Iterator

from clark_engine.mission.check_help import raw_loc
from clark_engine.mission.findings import Finding, error, warning
from clark_engine.mission.flow import entry_leaves
from clark_engine.mission.model import Agent, State


def check_launch(agent: Agent) -> Iterator[Finding]:
    """``launch`` fits the agent, and the start position's height agrees with it.

    A station has nothing to launch; only an aircraft can be handed over in flight,
    and only by the pilot who armed it; a vehicle on the ground starts at no height,
    and one handed over in flight starts at the height the pilot hands it over at
    (the dry run starts it there, flying).
    """
    if not agent.is_vehicle:
        if "launch" in agent.raw:
            yield error(
                "E-LAUNCH-STATION",
                raw_loc(agent, "launch"),
                f"{agent.name} is a station (role mcs) and has no vehicle to arm or fly; "
                "remove launch",
            )
        return
    launch = agent.launch
    if launch is None:
        return
    rover = agent.airframe_class == "rover"
    position = agent.position
    if launch.airborne and rover:
        yield error(
            "E-LAUNCH-AIRBORNE",
            launch.locate("airborne"),
            f"{agent.name} ({agent.profile}) is a rover and never flies; remove launch.airborne",
        )
        return
    if launch.airborne and launch.engine_arms:
        yield error(
            "E-LAUNCH-AIRBORNE",
            launch.locate("airborne"),
            f"airborne: true says the pilot arms {agent.name} and takes off before its "
            "behaviour starts, so the engine never arms it; write armed_by: pilot, or leave "
            "airborne out and take off in a takeoff state",
            launch.locate("armed_by"),
        )
    if launch.airborne and position.up_m <= 0:
        yield error(
            "E-LAUNCH-HEIGHT",
            raw_loc(agent, "position") if "position" in agent.raw else launch.locate("airborne"),
            f"{agent.name} starts airborne, but its position has no height above the origin; "
            "say at what height the pilot hands it over: position: "
            f"[{position.north_m:.0f}, {position.east_m:.0f}, <up_m>]",
            launch.locate("airborne"),
        )
    if not launch.airborne and position.up_m > 0:
        fix = (
            "remove up_m"
            if rover
            else "remove up_m, or declare launch: {airborne: true} if the pilot takes off "
            "before the behaviour starts"
        )
        yield error(
            "E-LAUNCH-HEIGHT",
            raw_loc(agent, "position"),
            f"{agent.name} starts on the ground{' (a rover)' if rover else ''}, but its position "
            f"is {position.up_m:g} m above the origin; {fix}",
            *([launch.location] if "launch" in agent.raw else []),
        )


#: Why an aircraft on the ground goes nowhere for a guided target, by airframe class.
_GROUNDED = {
    "multirotor": "ArduCopter ignores guided targets until it has taken off",
    "fixed_wing": "ArduPlane does not take off to reach a guided target",
}


def check_takeoff(agent: Agent, root: State) -> Iterator[Finding]:
    """An aircraft that starts on the ground takes off before it flies to guided targets."""
    launch = agent.launch
    grounded = _GROUNDED.get(agent.airframe_class or "")
    if launch is None or launch.airborne or grounded is None:
        return
    states = root.walk()
    if any(state.traits.takes_off for state in states):
        return
    guided = next((s for s in states if s.traits.guided), None)
    if guided is None:
        return
    what = f"state {guided.dotted} ({guided.primitive})" if guided.path else guided.primitive
    yield warning(
        "W-TAKEOFF-MISSING",
        guided.mission_use or guided.use_location or guided.location,
        f"{agent.name} ({agent.profile}) starts on the ground and its {what} flies to a "
        f"guided target, but no state takes off, and {grounded}; add a takeoff state before "
        "the first guided one, or declare launch: {airborne: true} if the pilot takes off",
    )


#: How long ArduCopter stays armed on the ground without taking off (DISARM_DELAY's default).
DISARM_DELAY_S = 10


def check_launch_flight(agent: Agent, root: State) -> Iterator[Finding]:
    """A ground-start multirotor armed by its pilot takes off in its first state.

    ArduCopter disarms a copter that was armed on the ground and has not taken off
    after DISARM_DELAY (10 s). The safety pilot arms it once it is ready, whatever the
    behaviour is doing; a first state that waits (for an activation, a timer, a
    transition) before its takeoff leaves the copter disarmed by the time the takeoff
    comes, and the takeoff then fails. A behaviour without any takeoff is
    W-TAKEOFF-MISSING's.
    """
    launch = agent.launch
    if (
        launch is None
        or launch.airborne
        or launch.engine_arms
        or agent.airframe_class != "multirotor"
        or not any(state.traits.takes_off for state in root.walk())
    ):
        return
    first = entry_leaves(root)
    if not first or any(leaf.traits.takes_off or leaf.unresolved for leaf in first):
        return
    leaf = first[0]
    what = leaf.primitive or ("a final state" if leaf.final else "an empty state")
    default = "" if "armed_by" in dict(launch.key_locations) else ", the default"
    yield warning(
        "W-LAUNCH-NO-FLIGHT",
        launch.locate("armed_by"),
        f"{agent.name} ({agent.profile}) starts on the ground and its pilot arms it "
        f"(launch.armed_by: pilot{default}), but its first state {leaf.dotted} ({what}) does "
        f"not take off: ArduCopter disarms a copter that has not taken off {DISARM_DELAY_S} s "
        "after it was armed (DISARM_DELAY), so the takeoff that comes later fails; write "
        "launch: {armed_by: engine}, so that the engine arms it when it takes off, or make "
        "takeoff its first state",
        leaf.mission_use or leaf.use_location or leaf.location,
    )
