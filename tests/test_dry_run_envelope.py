"""A dry run in which a behaviour asks for targets outside the envelope, and flies inside.

A copter follows a rover 6 m behind it and 12 m up, and its own envelope is a field
100 m long; the rover drives 120 m north, out of the copter's field (its own fence is
the default circle around its home). ``clark validate`` cannot prove where a follow's
target goes (it moves with the leader), so the mission is valid and the copter's
follow asks, every second, for a target past the north edge. The runtime clamps each
one 5 m inside the edge (the envelope's margin), on the simulated autopilot, through
the real MAVLink adapter, and the copter's true track stays inside its fence.
"""

from __future__ import annotations

import io
from pathlib import Path

from clark_engine.dryrun.command import run_dry_run

MISSION = """\
clark: 1
mission:
  id: 903
  name: follow-out-of-the-field
  loop_hz: 10
  heartbeat_timeout_s: 3
  origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}
envelope:
  # Targets 5 m inside: a copter holding 2 m inside the edge (the default margin)
  # reads 0.1 m outside it now and then in the simulated GPS noise, a breach.
  margin_m: 5
agents:
  mcs: {id: 1, profile: mcs_laptop, hardware: {radio: {address: "0013A20040A1B201"}},
        telemetry: {heartbeat: 1}}
  rover:
    id: 2
    profile: traxxas_slash
    hardware: {radio: {address: "0013A20040A1B202"}}
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: waypoint_tour, with: {speed_m_s: 3, waypoints: [[0, 0], [120, 0]]}}
  copter:
    id: 3
    profile: dji_f450
    hardware: {radio: {address: "0013A20040A1B203"}}
    position: [-10, -10]
    launch: {armed_by: engine}
    telemetry: {heartbeat: 1, agent_status: 2}
    envelope:
      geofence: {include: [{polygon: [[-40, -40], [60, -40], [60, 40], [-40, 40]]}]}
    behavior:
      initial: climb
      states:
        climb: {use: takeoff, with: {alt_m: 10}, transitions: {done: follow}}
        follow:
          use: follow_agent
          with: {target: rover, offset: {north_m: -6, up_m: 12}, continuous: true}
sim: {duration_s: 130, seed: 1}
"""

NORTH_EDGE_M = 60.0


def test_a_follow_whose_leader_leaves_the_field_stays_inside_it(tmp_path: Path) -> None:
    path = tmp_path / "follow_out.yaml"
    path.write_text(MISSION, encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(
        path, seed=None, until_s=None, report=tmp_path / "report", speed=None, out=out, err=err
    )
    assert outcome.result is not None, err.getvalue()
    recording = outcome.result.recording
    rover = list(recording.tracks["rover"].samples())
    copter = list(recording.tracks["copter"].samples())
    assert max(north for _, north, _, _ in rover) > 110.0  # the leader left the field
    flying = [(t, north) for t, north, _, up in copter if up > 5.0]
    assert flying, "the copter took off and followed"
    # It went to the edge and no further: the targets were 5 m inside it.
    assert NORTH_EDGE_M - 8.0 < max(north for _, north in flying) < NORTH_EDGE_M
    assert recording.safety.get("copter", []) == []  # no breach, no failsafe
    log = (tmp_path / "report" / "logs" / "copter.mission.log").read_text(encoding="utf-8")
    first = [line for line in log.splitlines() if "envelope: Goto clamped (fence)" in line]
    assert len(first) == 1, first  # once per episode, not once per Goto
    closing = [line for line in log.splitlines() if "envelope.summary" in line]
    assert len(closing) == 1 and "clamped (fence " in closing[0], closing
    assert "no breach acted on" in closing[0]
