"""The harness itself: the simulated vehicle is the dry run's, and failures say what."""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from harness import AGENT, KINDS, Peer, build_sim_link, open_peer, vehicle_spec

from clark_engine.dryrun.engine import PHYSICS_STEP_S, DryRun


@pytest.mark.parametrize("kind", KINDS)
def test_the_sim_vehicle_is_the_one_the_dry_run_builds(kind: str) -> None:
    spec = vehicle_spec(kind)
    seed = int(spec.mission.sim.get("seed", 0))
    dry_run = DryRun(spec.mission, spec.path, seed=seed, until_s=1.0)
    theirs = dry_run.agents[AGENT]
    ours = build_sim_link(spec)
    assert theirs.model is not None and theirs.autopilot is not None
    assert type(ours.model) is type(theirs.model)
    assert (ours.model.armed, ours.model.mode) == (theirs.model.armed, theirs.model.mode)
    assert ours.autopilot.modes == theirs.autopilot.modes
    assert ours.autopilot.sysid == theirs.autopilot.sysid
    assert ours.autopilot.firmware == theirs.autopilot.firmware
    for _ in range(100):  # same start, same physics, same seeded GPS errors
        ours.model.step(PHYSICS_STEP_S)
        theirs.model.step(PHYSICS_STEP_S)
        assert ours.model.truth() == theirs.model.truth()
        assert ours.model.gps_fix() == theirs.model.gps_fix()  # type: ignore[attr-defined]


@pytest.fixture
def sim_rover() -> Iterator[Peer]:
    peer = open_peer("sim-rover")
    yield peer
    peer.close()


def test_a_wait_that_fails_names_what_and_quotes_the_last_messages(sim_rover: Peer) -> None:
    with pytest.raises(AssertionError) as caught:
        sim_rover.wait_for("HOME_POSITION", 1.5)
    message = str(caught.value)
    assert message.startswith("simulated ardurover: no HOME_POSITION within 1.5 s (t=")
    assert "last messages seen:\n" in message
    assert "SYSTEM_TIME(time_unix_usec=" in message


def test_waits_and_runs_are_in_the_autopilots_time(sim_rover: Peer) -> None:
    start_s = sim_rover.now_s
    seen = sim_rover.run_for(2.0)
    assert 2.0 <= sim_rover.now_s - start_s < 2.1
    times = [m.time_boot_ms for m in seen if m.get_type() == "SYSTEM_TIME"]
    assert len(times) == 20  # the ground station's 10 Hz clock
    sent_s = sim_rover.now_s
    ack = sim_rover.command_long(511, 33, 200_000)  # SET_MESSAGE_INTERVAL
    assert 0.0 < sim_rover.time_of(ack) - sent_s <= 0.05  # answered at the next step
