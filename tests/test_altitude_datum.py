"""One altitude datum: a copter following a rover flies its offset above the rover, not
above the field's height above sea level.

The bug this reproduces (issue 17): ArduRover sets its home before its EKF has an origin,
at its barometer's height (about 0 m above sea level), so GLOBAL_POSITION_INT's
``relative_alt`` of a rover on a 90 m field reads about +90 m. The engine took that as
the rover's height, sent it in Agent Status, and follow_agent added ``up_m`` to it: a
copter told to follow 12 m up climbed to about 102 m (132.6 m with ``up_m: 40``, over a
120 m ceiling), on the simulated autopilot and on ArduCopter SITL alike. Altitudes above
the origin now come from the AMSL ``alt`` less the origin's ``alt_amsl_m``.
"""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from clark_engine.dryrun.command import run_dry_run
from clark_engine.sitl.launcher import SitlInstall

MISSION = """\
clark: 1
mission:
  id: 901
  name: follow-climb
  loop_hz: 10
  heartbeat_timeout_s: 3
  origin: {{lat: 30.6372, lon: -96.4787, alt_amsl_m: {origin_amsl_m}}}
agents:
  mcs: {{id: 1, profile: mcs_laptop, hardware: {{radio: {{address: "0013A20040A1B201"}}}},
        telemetry: {{heartbeat: 1}}}}
  rover:
    id: 2
    profile: traxxas_slash
    hardware: {{radio: {{address: "0013A20040A1B202"}}}}
    telemetry: {{heartbeat: 1, agent_status: 2}}
    behavior:
      use: waypoint_tour
      with: {{loop: true, speed_m_s: 2, waypoints: [[0, 0], [30, 0], [30, 30]]}}
  copter:
    id: 3
    profile: dji_f450
    hardware: {{radio: {{address: "0013A20040A1B203"}}}}
    position: [-10, -10]
    launch: {{armed_by: engine}}
    telemetry: {{heartbeat: 1, agent_status: 2}}
    behavior:
      initial: climb
      states:
        climb: {{use: takeoff, with: {{alt_m: 10}}, transitions: {{done: follow}}}}
        follow:
          use: follow_agent
          with: {{target: rover, offset: {{north_m: -6, up_m: {up_m}}}, continuous: true}}
          timeout_s: 45
          transitions: {{timeout: down}}
        down: {{use: land, transitions: {{done: landed}}}}
        landed: {{use: wait, final: true}}
sim: {{duration_s: {duration_s}, seed: 1}}
"""


def fly(
    tmp_path: Path,
    *,
    origin_amsl_m: float,
    up_m: float,
    duration_s: float = 110,
    sitl: SitlInstall | None = None,
) -> tuple[float, float]:
    """Dry-run the follow; the copter's highest altitude above the origin and the rover's."""
    path = tmp_path / "follow_climb.yaml"
    path.write_text(
        MISSION.format(origin_amsl_m=origin_amsl_m, up_m=up_m, duration_s=duration_s),
        encoding="utf-8",
    )
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(
        path, seed=None, until_s=None, report=None, speed=None, out=out, err=err, sitl=sitl
    )
    assert outcome.result is not None, err.getvalue()
    tracks = outcome.result.recording.tracks
    copter_top = max(up for _, _, _, up in tracks["copter"].samples())
    rover_top = max(abs(up) for _, _, _, up in tracks["rover"].samples())
    return copter_top, rover_top


@pytest.mark.parametrize(
    ("origin_amsl_m", "up_m"), [(90, 12), (90, 40), (300, 12)], ids=["90m-12up", "90m-40up", "300m"]
)
def test_a_copter_follows_a_rover_at_its_offset_above_the_ground(
    tmp_path: Path, origin_amsl_m: float, up_m: float
) -> None:
    """Before the fix: 102 m, 132.6 m and past 240 m."""
    copter_top, rover_top = fly(tmp_path, origin_amsl_m=origin_amsl_m, up_m=up_m)
    assert rover_top < 1.0
    assert up_m - 2.0 < copter_top < up_m + 2.0


def test_the_rover_reports_its_height_above_the_origin(tmp_path: Path) -> None:
    """Agent Status carries metres above the origin: a rover on the field reads about 0."""
    path = tmp_path / "follow_climb.yaml"
    path.write_text(MISSION.format(origin_amsl_m=90, up_m=12, duration_s=60), encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    outcome = run_dry_run(
        path, seed=None, until_s=None, report=tmp_path / "report", speed=None, out=out, err=err
    )
    assert outcome.result is not None, err.getvalue()
    fleet = (tmp_path / "report" / "logs" / "mcs.fleet.csv").read_text().splitlines()
    header = fleet[0].split(",")
    alt = header.index("alt_m")
    name = header.index("name")
    heights = [
        float(row.split(",")[alt])
        for row in fleet[1:]
        if row.split(",")[name] == "rover" and row.split(",")[alt]
    ]
    assert heights, "the station heard the rover's Agent Status"
    assert max(abs(h) for h in heights) < 3.0  # GPS noise; the bug read about 90


@pytest.mark.slow
@pytest.mark.sitl
def test_on_arducopter_and_ardurover_sitl(tmp_path: Path, sitl_install: SitlInstall) -> None:
    """The same follow on real ArduPilot SITL (rover and copter): 12 m up, not 102 m."""
    copter_top, rover_top = fly(
        tmp_path, origin_amsl_m=90, up_m=12, duration_s=120, sitl=sitl_install
    )
    assert rover_top < 2.0
    # 12 m over a rover whose reported height wanders by a metre or two: ArduCopter SITL's
    # highest was 15.09 m in one run of a loaded machine (the bug: 102 m).
    assert 9.0 < copter_top < 18.0
