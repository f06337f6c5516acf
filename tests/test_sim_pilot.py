"""The simulated pilot behaves as a pilot (issue 19): it arms only the vehicles the
mission's launch gives it, and its throttle stick rests where a pilot leaves it.

- A copter's stick is centred a pilot's reaction after the copter is seen leaving the
  ground, so a mission's hold (LOITER, which takes the stick as a climb rate) holds the
  height the takeoff reached. The pilot used to wait for a once-a-second
  EXTENDED_SYS_STATE saying IN_AIR, and the hold sank with the stick low first.
- Once the copter is down and disarmed the stick goes back to the bottom, so that a
  ground station can arm it again (ArduCopter refuses with "Throttle too high" or
  "Throttle (RC3) is not neutral" otherwise).
"""

from __future__ import annotations

from pathlib import Path

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.backend import SimulatedBackend
from clark_engine.dryrun.engine import DryRun
from clark_engine.dryrun.pilot import REACTION_S
from clark_engine.validation import validate_file

HERE = Path(__file__).resolve().parent
PILOT_ARMED = HERE / "dryrun" / "copter_pilot_takeoff.yaml"
ENGINE_ARMED = HERE.parent / "missions" / "copter_takeoff_land.yaml"
THROTTLE = 3
STEP_S = 0.02


def _run(path: Path, until_s: float) -> DryRun:
    validation = validate_file(path, str(path))
    assert validation.mission is not None
    run = DryRun(validation.mission, path, seed=1, until_s=until_s)
    run.run()
    return run


def _ground_station_arms(backend: SimulatedBackend, t_s: float) -> tuple[int, list[str]]:
    """A ground station (system 255) sends an arm command; the COMMAND_ACK's result and
    the texts said meanwhile."""
    out = bytearray()

    class _Sink:
        def write(self, data: bytes) -> None:
            out.extend(data)

    mav = mavlink2.MAVLink(_Sink(), srcSystem=255, srcComponent=190)
    # Its heartbeat first: the engine's adapter, the ground station this test replaces
    # once the run ended, set the GCS failsafe up, and a silent one blocks arming.
    mav.heartbeat_send(mavlink2.MAV_TYPE_GCS, mavlink2.MAV_AUTOPILOT_INVALID, 0, 0, 0)
    backend.send(bytes(out), t_s)
    out.clear()
    for _ in range(25):
        t_s += STEP_S
        backend.step(t_s, STEP_S)
    mav.command_long_send(backend.system_id, 1, 400, 0, 1, 0, 0, 0, 0, 0, 0)
    backend.send(bytes(out), t_s)
    parser = mavlink2.MAVLink(None)
    texts: list[str] = []
    for _ in range(10):
        t_s += STEP_S
        for msg in parser.parse_buffer(backend.step(t_s, STEP_S)) or []:
            if msg.get_type() == "STATUSTEXT":
                texts.append(str(msg.text))
            if msg.get_type() == "COMMAND_ACK" and msg.command == 400:
                return int(msg.result), texts
    raise AssertionError("no COMMAND_ACK")


def test_a_copter_hold_keeps_the_takeoff_height_and_the_stick_rests_after_landing() -> None:
    run = _run(PILOT_ARMED, 75.0)
    agent = run.agents["f450"]
    backend, pilot = agent.backend, agent.pilot
    assert isinstance(backend, SimulatedBackend) and pilot is not None
    climb = run.recording.entered_by("f450", "climb", 75.0)
    hover = run.recording.entered_by("f450", "hover", 75.0)
    assert climb is not None and hover is not None
    samples = list(run.recording.tracks["f450"].samples())
    # Centred a reaction after it left the ground, long before the hold began.
    lift_s = next(t for t, _, _, up in samples if up > 1.0)
    assert lift_s + REACTION_S < hover
    # The hold (LOITER) keeps the height the takeoff reached (done 1 m under 10 m, still
    # climbing: it stops a little above), it does not sink.
    held = [up for t, _, _, up in samples if t >= hover + 2.0]
    assert held and min(held) >= 9.0, min(held)
    assert max(held) - min(held) <= 0.1
    assert backend.rc_inputs()[THROTTLE - 1] == 1500
    # Down and disarmed: the stick goes back to the bottom, and a ground station arms it.
    assert backend.model.set_mode("LAND")
    t_s = 75.0
    while backend.model.armed or t_s < 100.0:
        t_s += STEP_S
        data = backend.step(t_s, STEP_S)
        if data:
            pilot.hear(data, t_s)
        assert t_s < 130.0, "it never landed and disarmed"
    for _ in range(round(2 * REACTION_S / STEP_S)):
        t_s += STEP_S
        pilot.hear(backend.step(t_s, STEP_S), t_s)
    assert backend.rc_inputs()[THROTTLE - 1] == 1100
    assert backend.model.set_mode("STABILIZE")
    assert _ground_station_arms(backend, t_s) == (
        mavlink2.MAV_RESULT_ACCEPTED,
        ["Arming motors"],
    )


def test_the_pilot_never_arms_a_vehicle_the_engine_arms() -> None:
    # copter_takeoff_land's F450 is armed by the engine at its activation (50 s); its
    # autopilot is ready at about 42 s, and nobody may arm it before 50 s.
    run = _run(ENGINE_ARMED, 49.0)
    agent = run.agents["f450"]
    assert agent.pilot is not None and agent.autopilot is not None
    assert agent.pilot.sees_ready  # ready, and left alone
    assert not agent.backend.flight_status()[0]  # type: ignore[union-attr]
    assert agent.pilot.armed_at_s is None
