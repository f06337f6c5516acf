"""What ``clark validate`` proves about the safety envelope before flight (issue 17 item 3).

Each test writes a small mission and asserts the exact findings: their codes, the line
each points at (marked in the mission text with ``#@name``), and what the message says
to change. The cases that must *not* be reported sit beside the ones that must, so a
check that fires everywhere fails as surely as one that fires nowhere.
"""

from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from clark_engine.mission.fence import Zone
from clark_engine.mission.findings import Finding
from clark_engine.validation import validate_file

HEAD = """\
clark: 1
mission: {id: 1, name: demo, loop_hz: 10, origin: {lat: 30.6372, lon: -96.4787, alt_amsl_m: 90}}
"""


class Checked:
    """A mission's findings, with the lines its ``#@name`` markers are on."""

    def __init__(self, tmp_path: Path, body: str) -> None:
        self.text = HEAD + textwrap.dedent(body)
        path = tmp_path / "mission.yaml"
        path.write_text(self.text, encoding="utf-8")
        result = validate_file(path, "mission.yaml")
        self.findings = [f for f in result.findings if f.code != "W-NO-KEY"]
        self.ok = result.ok

    def line(self, marker: str) -> int:
        """The line (1-based) that carries ``#@marker``."""
        for number, text in enumerate(self.text.splitlines(), start=1):
            if f"#@{marker}" in text:
                return number
        raise AssertionError(f"no #@{marker} in the mission")

    @property
    def codes(self) -> list[tuple[str, int | None]]:
        """(code, line) of every finding, in report order."""
        return [(f.code, f.location.line) for f in self.findings]

    def one(self, code: str) -> Finding:
        """The only finding with ``code``."""
        found = [f for f in self.findings if f.code == code]
        assert len(found) == 1, [f.format_text() for f in self.findings]
        return found[0]


# ----------------------------------------------------------------------------- points


def test_an_aircraft_waypoint_under_the_floor_is_an_error(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope: {floor_m: 20}  #@floor
        agents:
          f450:
            id: 2
            profile: dji_f450
            launch: {armed_by: engine}
            telemetry: {heartbeat: 1}
            behavior:
              initial: climb
              states:
                climb: {use: takeoff, with: {alt_m: 10}, transitions: {done: low}}  #@takeoff
                low: {use: waypoint, with: {to: [30, 0, 10]}, transitions: {done: down}}  #@low
                down: {use: land, final: true}
        """,
    )
    # A takeoff climbs through the floor: only the guided waypoint is under it.
    assert m.codes == [("E-ALTITUDE-FLOOR", m.line("low"))]
    finding = m.one("E-ALTITUDE-FLOOR")
    assert "under f450's floor of 20 m" in finding.message
    assert "at least 22 m up" in finding.message  # the floor plus the 2 m margin
    assert m.line("floor") in [r.line for r in finding.related]


def test_a_rover_ignores_heights(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope: {floor_m: 20}
        agents:
          slash:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior: {use: waypoint, with: {to: [30, 0]}}
        """,
    )
    assert m.codes == []


ZONES = """\
envelope:
  geofence:
    include: [{polygon: [[-50, -50], [200, -50], [200, 200], [-50, 200]]}]  #@include
    exclude: [{circle: {center: [100, 100], radius_m: 20}}]  #@exclude
agents:
  slash:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1}
    behavior:
      use: waypoint_tour
      with:
        waypoints:
          - [0, 0]
          - POINT  #@point
"""


def _tour(tmp_path: Path, point: str) -> Checked:
    return Checked(tmp_path, ZONES.replace("POINT", point))


def test_a_waypoint_outside_an_inclusion_zone_names_it(tmp_path: Path) -> None:
    m = _tour(tmp_path, "[250, 0]")
    assert m.codes == [("E-GEOFENCE-POINT", m.line("point"))]
    finding = m.one("E-GEOFENCE-POINT")
    assert "50.0 m outside the inclusion polygon envelope.geofence.include[0]" in finding.message
    assert m.line("include") in [r.line for r in finding.related]


def test_a_waypoint_inside_an_exclusion_zone_names_it(tmp_path: Path) -> None:
    m = _tour(tmp_path, "[100, 95]")
    finding = m.one("E-GEOFENCE-POINT")
    assert finding.location.line == m.line("point")
    assert "15.0 m inside the exclusion circle envelope.geofence.exclude[0]" in finding.message
    assert m.line("exclude") in [r.line for r in finding.related]


def test_a_waypoint_near_the_edge_is_sent_short(tmp_path: Path) -> None:
    m = _tour(tmp_path, "[199, 0]")
    assert m.codes == [("W-ENVELOPE-MARGIN", m.line("point"))]
    assert "only 1.0 m from the edge" in m.one("W-ENVELOPE-MARGIN").message
    assert _tour(tmp_path, "[197, 0]").codes == []  # 3 m in: clear of the 2 m margin


def test_the_default_fence_is_the_radio_range_around_home(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        agents:
          slash:
            id: 2
            profile: traxxas_slash
            position: [100, 0]
            telemetry: {heartbeat: 1}
            behavior: {use: waypoint, with: {to: [1800, 0]}}  #@far
        """,
    )
    finding = m.one("E-GEOFENCE-POINT")
    assert finding.location.line == m.line("far")
    assert "its default geofence, the 1609 m circle around its start" in finding.message
    assert "declare a geofence of your own" in finding.message


def test_heights_near_the_ceiling_and_floor_are_sent_short(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope: {floor_m: 10, ceiling_m: 100}
        agents:
          f450:
            id: 2
            profile: dji_f450
            position: [0, 0, 50]
            launch: {airborne: true}
            telemetry: {heartbeat: 1}
            behavior:
              use: waypoint_tour
              with:
                waypoints:
                  - [0, 0, 99]  #@high
                  - [0, 0, 11]  #@low
                  - [0, 0, 50]
        """,
    )
    assert m.codes == [
        ("W-ENVELOPE-MARGIN", m.line("high")),
        ("W-ENVELOPE-MARGIN", m.line("low")),
    ]
    high, low = (f.message for f in m.findings)
    assert "sends it at 98 m" in high and "sends it at 12 m" in low


def test_a_plane_target_near_the_fence_is_an_error_a_copter_one_is_not(tmp_path: Path) -> None:
    body = """\
    envelope:
      geofence: {include: [{polygon: [[-300, -300], [300, -300], [300, 300], [-300, 300]]}]}
    agents:
      plane:
        id: 2
        profile: PROFILE
        position: [0, 0, 60]
        launch: {airborne: true}
        telemetry: {heartbeat: 1}
        behavior: {use: waypoint, with: {to: [250, 0, 60], tolerance_m: 80}}  #@target
    """
    m = Checked(tmp_path, body.replace("PROFILE", "super_cub"))
    assert m.codes == [("E-ORBIT-FENCE", m.line("target"))]
    message = m.one("E-ORBIT-FENCE").message
    assert "only 50.0 m from the edge" in message and "circles its target about 69 m" in message
    assert Checked(tmp_path, body.replace("PROFILE", "dji_f450")).codes == []


# ----------------------------------------------------------------------------- legs


def test_a_tour_leg_through_an_exclusion_zone_is_an_error(tmp_path: Path) -> None:
    m = _tour(tmp_path, "[150, 150]")  # (0, 0) to (150, 150) passes (100, 100)
    assert m.codes == [("E-GEOFENCE-LEG", m.line("point"))]
    message = m.one("E-GEOFENCE-LEG").message
    assert message.startswith("the leg from waypoint 0 to waypoint 1 crosses the exclusion")
    assert "121 m along its 212 m" in message
    assert _tour(tmp_path, "[150, 60]").codes == []  # passes beside it


def test_a_looping_tour_checks_its_closing_leg(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope:
          geofence: {exclude: [{circle: {center: [50, 25], radius_m: 5}}]}
        agents:
          slash:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior:
              use: waypoint_tour
              with:
                loop: true
                waypoints:
                  - [0, 0]  #@first
                  - [100, 0]
                  - [100, 50]  #@last
        """,
    )
    finding = m.one("E-GEOFENCE-LEG")
    assert finding.location.line == m.line("first")
    assert "the leg from waypoint 2 to waypoint 0" in finding.message
    assert m.line("last") in [r.line for r in finding.related]


def test_a_leg_out_of_a_concave_fence_is_an_error(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope:  # an L: the corner at (100, 50) is cut out
          geofence:
            include: [{polygon: [[0, -10], [200, -10], [200, 50], [100, 50], [100, 200], [0, 200]]}]
        agents:
          slash:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior: {use: waypoint_tour, with: {waypoints: [[190, 0], [50, 190]]}}  #@tour
        """,
    )
    assert m.codes == [("E-GEOFENCE-LEG", m.line("tour"))]
    assert "leaves the inclusion polygon" in m.one("E-GEOFENCE-LEG").message


def test_a_small_zone_on_a_long_leg_is_found_exactly(tmp_path: Path) -> None:
    # The fence's sampled search steps 5.9 m along a 1500 m leg: a 1 m circle between
    # two samples is found by the exact crossing.
    zone = Zone.circle((703.0, 0.4), 1.0)
    assert zone.first_crossing((0.0, 0.0), (1500.0, 0.0)) == pytest.approx(
        (703.0 - (1.0 - 0.4**2) ** 0.5) / 1500.0
    )
    m = Checked(
        tmp_path,
        """\
        envelope:
          geofence:
            include: [{circle: {center: [0, 0], radius_m: 1600}}]
            exclude: [{circle: {center: [703, 0.4], radius_m: 1}}]
        agents:
          slash:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior: {use: waypoint_tour, with: {waypoints: [[0, 0], [1500, 0]]}}  #@tour
        """,
    )
    assert m.codes == [("E-GEOFENCE-LEG", m.line("tour"))]


def test_first_crossing_is_exact_and_ignores_touching() -> None:
    square = Zone.polygon([(0, 0), (10, 0), (10, 10), (0, 10)])
    assert square.first_crossing((-5, 5), (15, 5)) == pytest.approx(0.25)
    assert square.first_crossing((-5, 0), (15, 0)) is None  # along an edge
    assert square.first_crossing((2, 2), (8, 8)) is None  # inside
    circle = Zone.circle((0, 0), 5)
    assert circle.first_crossing((-10, 5), (10, 5)) is None  # tangent
    assert circle.first_crossing((-10, 0), (10, 0)) == pytest.approx(0.25)
    assert circle.first_crossing((-1, 0), (1, 0)) is None  # inside


def test_the_leg_from_the_start_to_the_first_target_is_checked(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope:
          geofence: {exclude: [{circle: {center: [30, 0], radius_m: 5}}]}
        agents:
          f450:
            id: 2
            profile: dji_f450
            position: [0, 0]  #@start
            launch: {armed_by: engine}
            telemetry: {heartbeat: 1}
            behavior:
              initial: climb
              states:
                climb: {use: takeoff, with: {alt_m: 10}, transitions: {done: out}}
                out: {use: waypoint, with: {to: [60, 0, 10]}, transitions: {done: back}}  #@out
                back: {use: waypoint, with: {to: [0, 10, 10]}, transitions: {done: down}}  #@back
                down: {use: land, final: true}
        """,
    )
    # start -> out crosses the zone; out -> back (a finished waypoint to the next) does too.
    assert m.codes == [
        ("E-GEOFENCE-LEG", m.line("out")),
        ("E-GEOFENCE-LEG", m.line("back")),
    ]
    first, second = m.findings
    assert "the leg from its start position, 10 m up after its takeoff, to waypoint" in (
        first.message
    )
    assert m.line("start") in [r.line for r in first.related]
    assert "the leg from waypoint of state out to waypoint of state back" in second.message


def test_a_leg_from_an_unknown_place_is_not_checked(tmp_path: Path) -> None:
    # The station moves the rover on mid-tour: where it is then is not known before flight.
    m = Checked(
        tmp_path,
        """\
        envelope:
          geofence: {exclude: [{circle: {center: [30, 0], radius_m: 5}}]}
        agents:
          mcs: {id: 1, profile: mcs_laptop, position: [0, -30], telemetry: {heartbeat: 1}}
          slash:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior:
              initial: patrol
              states:
                patrol:
                  use: waypoint_tour
                  with: {loop: true, waypoints: [[60, 10], [60, -10]]}
                  transitions: {activate: home}
                home: {use: waypoint, with: {to: [0, 0]}, final: true}
        """,
    )
    # The start (0, 0) to (60, 10) passes 3.3 m from the zone's centre: that one is known.
    assert [c for c, _ in m.codes] == ["E-GEOFENCE-LEG"]
    assert "its start position to waypoint 0 of state patrol" in m.findings[0].message


# ----------------------------------------------------------------------------- follow_agent

FOLLOW = """\
envelope: {ENVELOPE}
agents:
  slash:
    id: 2
    profile: traxxas_slash
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: waypoint_tour, with: {loop: true, waypoints: [[0, 0], [40, 0]]}}
  f450:
    id: 3
    profile: dji_f450
    position: [-20, 0, 30]
    launch: {airborne: true}
    telemetry: {heartbeat: 1, agent_status: 2}
    behavior: {use: follow_agent, with: {target: TARGET, OFFSET continuous: true}}  #@follow
  cub:
    id: 4
    profile: super_cub
    position: [0, -300, 60]
    launch: {airborne: true}
    telemetry: {heartbeat: 1, agent_status: 2}
"""


def _follow(tmp_path: Path, offset: str, target: str = "slash", envelope: str = "{}") -> Checked:
    text = FOLLOW.replace("OFFSET", offset).replace("TARGET", target)
    return Checked(tmp_path, text.replace("{ENVELOPE}", envelope))


def test_a_follow_always_over_the_ceiling_is_an_error(tmp_path: Path) -> None:
    # The example: a copter following a rover 130 m up under a 120 m ceiling.
    m = _follow(tmp_path, "offset: {up_m: 130},")
    assert m.codes == [("E-FOLLOW-HEIGHT", m.line("follow"))]
    message = m.one("E-FOLLOW-HEIGHT").message
    assert "at least 130 m above the origin, over its ceiling of 120 m" in message
    assert "lower offset.up_m to at most 118 m" in message


def test_the_102_m_follow_is_now_12_m_and_fine(tmp_path: Path) -> None:
    # 12 m above a rover is 12 m above the origin (the datum fix); only the dry run can
    # judge the pair's separation on the way.
    m = _follow(tmp_path, "offset: {up_m: 12, north_m: -6},")
    assert m.codes == [("W-ENVELOPE-REACTIVE", m.line("follow"))]


def test_a_follow_always_under_the_floor_is_an_error(tmp_path: Path) -> None:
    m = _follow(tmp_path, "offset: {up_m: 10, north_m: -6},", envelope="{floor_m: 30}")
    assert m.codes == [("E-FOLLOW-HEIGHT", m.line("follow"))]
    assert "under its floor of 30 m" in m.one("E-FOLLOW-HEIGHT").message
    assert "raise offset.up_m to at least 32 m" in m.one("E-FOLLOW-HEIGHT").message


def test_a_follower_held_above_its_target_is_proved_apart(tmp_path: Path) -> None:
    # Floor 30 m over a rover on the ground: the pair is always more than 5 m apart.
    m = _follow(tmp_path, "offset: {up_m: 40},", envelope="{floor_m: 30}")
    assert m.codes == []


def test_an_aircraft_target_that_may_climb_is_a_warning(tmp_path: Path) -> None:
    m = _follow(tmp_path, "offset: {up_m: 30},", target="cub")
    assert m.codes == [("W-ENVELOPE-REACTIVE", m.line("follow"))]
    message = m.one("W-ENVELOPE-REACTIVE").message
    assert "over its ceiling of 120 m whenever cub flies above 90 m" in message
    assert message.count("W-ENVELOPE-REACTIVE") == 0 and "dry run judges it" in message


def test_no_offset_and_a_tiny_tolerance_is_an_error(tmp_path: Path) -> None:
    # The example: tolerance_m 0.1 and no offset validated clean.
    m = Checked(
        tmp_path,
        """\
        agents:
          slash_a: {id: 2, profile: traxxas_slash, telemetry: {heartbeat: 1, agent_status: 2}}
          slash_b:
            id: 3
            profile: traxxas_slash
            position: [-10, 0]
            telemetry: {heartbeat: 1}
            behavior: {use: follow_agent, with: {target: slash_a, tolerance_m: 0.1}}  #@follow
        """,
    )
    assert m.codes == [("E-FOLLOW-SEPARATION", m.line("follow"))]
    assert "aims 0.0 m from slash_a, inside the 5 m" in m.one("E-FOLLOW-SEPARATION").message


ROVERS = """\
envelope: ENVELOPE
agents:
  slash_a: {id: 2, profile: traxxas_slash, telemetry: {heartbeat: 1, agent_status: 2}}
  slash_b:
    id: 3
    profile: traxxas_slash
    position: [-10, 0]
    telemetry: {heartbeat: 1}
    behavior:
      use: follow_agent
      with: {target: slash_a, offset: OFFSET, tolerance_m: TOLERANCE}  #@follow
"""


def _rovers(tmp_path: Path, offset: str, tolerance: str = "5", envelope: str = "{}") -> Checked:
    text = ROVERS.replace("OFFSET", offset).replace("TOLERANCE", tolerance)
    return Checked(tmp_path, text.replace("ENVELOPE", envelope))


def test_rovers_compare_their_offset_on_the_ground(tmp_path: Path) -> None:
    # up_m means nothing to a rover: 3 m north and 10 m up is 3 m.
    m = _rovers(tmp_path, "{north_m: -3, up_m: 10}")
    assert m.codes == [("E-FOLLOW-SEPARATION", m.line("follow"))]
    assert "aims 3.0 m from slash_a" in m.one("E-FOLLOW-SEPARATION").message


def test_a_tolerance_that_lets_the_follower_stop_inside_is_a_warning(tmp_path: Path) -> None:
    m = _rovers(tmp_path, "{north_m: -6}", tolerance="3")
    assert m.codes == [("W-FOLLOW-SEPARATION", m.line("follow"))]
    assert "may stop 3.0 m from it" in m.one("W-FOLLOW-SEPARATION").message
    assert "at most 1.0 m" in m.one("W-FOLLOW-SEPARATION").message
    # Within the separation it cannot stop: only the dry run's judgement remains.
    assert [c for c, _ in _rovers(tmp_path, "{north_m: -6}", tolerance="1").codes] == [
        "W-ENVELOPE-REACTIVE"
    ]


def test_a_pair_separation_lets_two_rovers_close_in(tmp_path: Path) -> None:
    pair = "{separation: [{between: [slash_a, slash_b], min_m: 1}]}"
    m = _rovers(tmp_path, "{east_m: -3}", tolerance="2", envelope=pair)
    assert [c for c, _ in m.codes] == ["W-ENVELOPE-REACTIVE"]
    assert "keeps 1 m from slash_a" in m.one("W-ENVELOPE-REACTIVE").message


def test_a_rover_under_an_aircraft_is_as_far_as_it_is_high(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        agents:
          f450:
            id: 2
            profile: dji_f450
            position: [0, 0, 30]
            launch: {airborne: true}
            telemetry: {heartbeat: 1, agent_status: 2}
          slash:
            id: 3
            profile: traxxas_slash
            position: [-10, 0]
            telemetry: {heartbeat: 1}
            behavior: {use: follow_agent, with: {target: f450, continuous: true}}  #@follow
        """,
    )
    # Right under the copter: 120 m from it at its ceiling, 0 m if it lands.
    assert m.codes == [("W-ENVELOPE-REACTIVE", m.line("follow"))]
    assert "when f450 flies low" in m.one("W-ENVELOPE-REACTIVE").message


def test_no_reactive_warning_while_the_target_reports_nothing(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        agents:
          slash_a: {id: 2, profile: traxxas_slash, telemetry: {heartbeat: 1}}
          slash_b:
            id: 3
            profile: traxxas_slash
            position: [-10, 0]
            telemetry: {heartbeat: 1}
            behavior: {use: follow_agent, with: {target: slash_a, offset: {north_m: -10}}}
        """,
    )
    assert [c for c, _ in m.codes] == ["E-FOLLOW-STATUS"]


# ----------------------------------------------------------------------------- separation


def test_vehicles_that_start_too_close_are_an_error(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        agents:
          slash_a: {id: 2, profile: traxxas_slash, telemetry: {heartbeat: 1}}  #@a
          slash_b: {id: 3, profile: traxxas_slash, position: [3, 3], telemetry: {heartbeat: 1}}  #@b
          cub:  # 60 m above slash_a: far enough
            id: 4
            profile: super_cub
            position: [0, 0, 60]
            launch: {airborne: true}
            telemetry: {heartbeat: 1}
        """,
    )
    assert m.codes == [("E-SEPARATION-START", m.line("b"))]
    finding = m.one("E-SEPARATION-START")
    assert "slash_b starts 4.2 m from slash_a" in finding.message
    assert m.line("a") in [r.line for r in finding.related]


def test_start_positions_against_the_pair_separation(tmp_path: Path) -> None:
    body = """\
    envelope: {min_separation_m: MIN}
    agents:
      slash_a: {id: 2, profile: traxxas_slash, telemetry: {heartbeat: 1}}
      slash_b: {id: 3, profile: traxxas_slash, position: [3, 4], telemetry: {heartbeat: 1}}  #@b
    """
    assert Checked(tmp_path, body.replace("MIN", "5")).codes == []  # exactly 5 m apart
    m = Checked(tmp_path, body.replace("MIN", "8"))
    assert m.codes == [("E-SEPARATION-START", m.line("b"))]
    assert "slash_b starts 5.0 m from slash_a (slash_a writes no position:" in (
        m.one("E-SEPARATION-START").message
    )


def test_crossing_plans_are_warned_once_per_pair(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        agents:
          slash_a:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior:
              use: waypoint_tour
              with: {loop: true, waypoints: [[0, 0], [40, 0], [40, 40]]}
          slash_b:
            id: 3
            profile: traxxas_slash
            position: [20, 30]
            telemetry: {heartbeat: 1}
            behavior:
              use: waypoint_tour
              with: {loop: true, waypoints: [[20, 30], [20, -20]]}  #@b
          f450:  # the same square, 50 m up: clear of both
            id: 4
            profile: dji_f450
            position: [0, 60, 50]
            launch: {airborne: true}
            telemetry: {heartbeat: 1}
            behavior: {use: waypoint_tour, with: {waypoints: [[0, 0, 50], [40, 0, 50]]}}
        """,
    )
    assert m.codes == [("W-SEPARATION-PLAN", m.line("b"))]
    message = m.one("W-SEPARATION-PLAN").message
    assert "comes within 0.0 m of slash_a's leg" in message and "the dry run judges" in message


# ----------------------------------------------------------------------------- endurance

HOVER = """\
agents:
  VEHICLE:
    id: 2
    profile: PROFILE
    launch: {armed_by: engine}
    telemetry: {heartbeat: 1}
    behavior:
      initial: climb
      states:
        climb: {use: takeoff, with: {alt_m: 15}, transitions: {done: hover}}
        hover: {use: hold, timeout_s: 7200, transitions: {timeout: down}}  #@hover
        down: {use: land, final: true}
"""


def test_a_two_hour_hover_is_an_error(tmp_path: Path) -> None:
    m = Checked(tmp_path, HOVER.replace("VEHICLE", "f450").replace("PROFILE", "dji_f450"))
    assert m.codes == [("E-ENDURANCE-TIMEOUT", m.line("hover"))]
    message = m.one("E-ENDURANCE-TIMEOUT").message
    assert "7200 s (120 min), longer than its endurance of 600 s" in message


def test_endurance_counts_only_states_that_keep_the_vehicle_going(tmp_path: Path) -> None:
    # A wait on the ground keeps nothing armed.
    text = HOVER.replace("VEHICLE", "f450").replace("PROFILE", "dji_f450")
    m = Checked(tmp_path, text.replace("{use: hold, timeout_s", "{use: wait, timeout_s"))
    assert m.codes == []


def test_a_vehicle_envelope_sets_the_endurance(tmp_path: Path) -> None:
    text = HOVER.replace("VEHICLE", "f450").replace("PROFILE", "dji_f450")
    text = text.replace("timeout_s: 7200", "timeout_s: 500")
    own = "launch: {armed_by: engine}\n    envelope: {endurance_s: 300}  #@endurance"
    text = text.replace("launch: {armed_by: engine}", own)
    m = Checked(tmp_path, text)
    finding = m.one("E-ENDURANCE-TIMEOUT")
    assert "endurance of 300 s (envelope.endurance_s)" in finding.message
    assert m.line("endurance") in [r.line for r in finding.related]


FLYING = """\
agents:
  mcs: {id: 1, profile: mcs_laptop, position: [0, -20], telemetry: {heartbeat: 1}}
  f450:
    id: 2
    profile: dji_f450
    launch: {armed_by: engine}
    telemetry: {heartbeat: 1}
    behavior:
      initial: climb
      states:
        climb: {use: takeoff, with: {alt_m: 15}, transitions: {done: hover}}
        hover: {use: hold, transitions: {activate: LANDING}}
        down: {use: land, final: true}
sim: {duration_s: DURATION}  #@duration
"""


def test_a_dry_run_longer_than_the_endurance_that_never_lands_is_warned(tmp_path: Path) -> None:
    # The hover is never left for the landing: only a transition to itself.
    never = FLYING.replace("LANDING", "hover")
    m = Checked(tmp_path, never.replace("DURATION", "900"))
    assert m.codes == [
        ("W-STATE-UNREACHABLE", m.line("duration") - 1),
        ("W-ENDURANCE-DURATION", m.line("duration")),
    ]
    assert "lasts 900 s (sim.duration_s), longer than f450's endurance of 600 s" in (
        m.one("W-ENDURANCE-DURATION").message
    )
    assert [c for c, _ in Checked(tmp_path, never.replace("DURATION", "500")).codes] == [
        "W-STATE-UNREACHABLE"
    ]
    lands = FLYING.replace("LANDING", "down").replace("DURATION", "900")
    assert Checked(tmp_path, lands).codes == []


# ----------------------------------------------------------------------------- launch

LAUNCH = """\
agents:
  mcs: {id: 1, profile: mcs_laptop, position: [0, -20], telemetry: {heartbeat: 1}}
  f450:
    id: 2
    profile: PROFILE
    LAUNCH
    telemetry: {heartbeat: 1}
    behavior:
      initial: FIRST
      states:
        ready: {use: wait, transitions: {activate: climb}}  #@ready
        climb: {use: takeoff, with: {alt_m: 10}, transitions: {done: down}}
        down: {use: land, final: true}
"""


def _launch(
    tmp_path: Path, launch: str = "", first: str = "ready", profile: str = "dji_f450"
) -> Checked:
    text = LAUNCH.replace("LAUNCH", launch or "position: [0, 0]").replace("FIRST", first)
    return Checked(tmp_path, text.replace("PROFILE", profile))


def test_a_pilot_armed_copter_that_waits_before_its_takeoff_is_warned(tmp_path: Path) -> None:
    m = _launch(tmp_path)
    finding = m.one("W-LAUNCH-NO-FLIGHT")
    assert [c for c, _ in m.codes] == ["W-LAUNCH-NO-FLIGHT"]
    assert "launch.armed_by: pilot, the default" in finding.message
    assert "first state ready (wait)" in finding.message and "DISARM_DELAY" in finding.message
    assert m.line("ready") in [r.line for r in finding.related]
    written = _launch(tmp_path, launch="launch: {armed_by: pilot}  #@launch")
    assert written.one("W-LAUNCH-NO-FLIGHT").location.line == written.line("launch")


@pytest.mark.parametrize(
    ("launch", "first", "profile"),
    [
        ("launch: {armed_by: engine}", "ready", "dji_f450"),  # the engine arms at the takeoff
        ("", "climb", "dji_f450"),  # takes off first
        ("", "ready", "super_cub"),  # ArduPlane does not disarm so
    ],
)
def test_launches_that_fly_are_not_warned(
    tmp_path: Path, launch: str, first: str, profile: str
) -> None:
    codes = [c for c, _ in _launch(tmp_path, launch, first, profile).codes]
    assert "W-LAUNCH-NO-FLIGHT" not in codes


# ----------------------------------------------------------------------------- blocks


def test_a_block_waypoint_outside_the_fence_points_at_the_use(tmp_path: Path) -> None:
    blocks = tmp_path / "my_blocks"
    blocks.mkdir()
    (blocks / "far_point.yaml").write_text(
        "block: far_point\n"
        "description: Drive to a fixed far point.\n"
        "machine: {use: waypoint, with: {to: [500, 0]}}\n",
        encoding="utf-8",
    )
    m = Checked(
        tmp_path,
        """\
        include: {behaviors: [my_blocks]}
        envelope:
          geofence: {include: [{circle: {center: [0, 0], radius_m: 100}}]}
        agents:
          slash:
            id: 2
            profile: traxxas_slash
            telemetry: {heartbeat: 1}
            behavior: {use: far_point}  #@use
        """,
    )
    finding = m.one("E-GEOFENCE-POINT")
    assert (finding.location.file, finding.location.line) == ("mission.yaml", m.line("use"))
    assert any(r.file.endswith("far_point.yaml") for r in finding.related)


def test_a_broken_vehicle_named_in_a_separation_is_not_reported_again(tmp_path: Path) -> None:
    m = Checked(
        tmp_path,
        """\
        envelope:
          separation: [{between: [slash_a, slash_b], min_m: 1}]
        agents:
          slash_a:
            id: 2
            profile: traxxas_slash
            hardware: {radio: {throughput_bps: -5}}  #@broken
            telemetry: {heartbeat: 1}
          slash_b: {id: 3, profile: traxxas_slash, position: [10, 0], telemetry: {heartbeat: 1}}
        """,
    )
    assert m.codes == [("E-RANGE", m.line("broken"))]
