"""The station's view over the cooperative-follow rehearsal, driven in a real browser.

One real-time rehearsal (``clark dry-run missions/cooperative_follow.yaml --realtime
--station --no-operator-script``: the simulated fleet at wall-clock speed, the station's
view served on loopback, the mission's operator actions left to the page) and one page
of headless Chromium, taken through the mission in order, step by step, by one test (so
that however the suite is spread over processes, the steps stay together and in order):

1. the agents appear with their states and health, each vehicle's envelope is drawn on the
   map (its default geofence, a mile around its start, its ceiling in its row), and the
   checks pane lists the mission's checks;
2. the link between the station and slash_a drops from 20 s to 26 s (a fault of the
   run): slash_a is flagged STALE, then LOST, then live again;
3. once both vehicles' behaviours have started (about 32 s), Activate for slash_b: its
   command shows pending, then done, it chases slash_a on the map (its label moves, its
   track grows) and parks, and the checks pane shows the checks passing;
4. a mode change from the page (slash_b to MANUAL) shows in its row;
5. the link between the station and slash_b drops from 60 s to 66 s (a second fault of
   the run): slash_b loses its station and its failsafe holds it; once heard again, the
   page raises a failsafe alarm, once, in its banner and its mission log;
6. Terminate from the dialog: slash_a alone stops where it is; then all: the station
   terminates slash_b, takes its confirmation and terminates itself, and slash_b's alarm
   is cleared.

Every step waits on the page's own content (its clock, rows, commands, labels), never
on a fixed sleep; a failure names its step. The rehearsal is the slow part: about 80 s
of mission, the whole test about a minute and a quarter. The simulated autopilots are
ready 30 s after power-on (``sim.autopilot_ready_s``; ArduRover takes 42 s): the page
waits less for what it does not test.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from station_page import (
    MISSION,
    VIEWPORT,
    PageWatch,
    ServedStation,
    served_station,
)

sync_api = pytest.importorskip(
    "playwright.sync_api",
    reason="Playwright is not installed (pip install -e '.[test]'; make test does it)",
)
expect = sync_api.expect

pytestmark = [pytest.mark.browser, pytest.mark.slow, pytest.mark.xdist_group("browser")]

READY_S = 30
"""When the simulated autopilots are ready, seconds after power-on."""

LINK_DOWN_S = (20, 26)
"""The station and slash_a cannot hear each other then: before the vehicles' behaviours
start (about 32 s), so that the drop changes nothing in the mission but the view."""

SLASH_B_DOWN_S = (60, 66)
"""The station and slash_b cannot hear each other then: after slash_b has parked (about
48 s) and its mode was changed, so that its failsafe changes nothing but the view."""

UNTIL_S = 115
"""The rehearsal's end, at the latest (the steps are over by about 80 s)."""

STEP_TIMEOUT_MS = 60_000
"""The longest a step waits for what it expects (a timeout, never a measured time)."""

NOTHING = "\N{EN DASH}"
"""What a cell shows when there is nothing to show yet."""

MOVED_PX = 20.0
"""How far on screen a label must move to count as moving (the map's scale: about
5 pixels a metre; a vehicle at rest jitters with its GPS noise, well under a metre)."""

# What the page shows, read by its attributes (data-testid, data-agent, data-field).
RECORDER = """
() => {
  const history = window.__clarkHistory = {};
  const note = (key, value) => {
    const list = history[key] || (history[key] = []);
    if (list[list.length - 1] !== value) { list.push(value); }
  };
  const look = () => {
    document.querySelectorAll("#agents-body tr[data-agent]").forEach(row => {
      if (row.dataset.liveness) { note(row.dataset.agent + " liveness", row.dataset.liveness); }
    });
    document.querySelectorAll("#commands li[data-testid]").forEach(item => {
      note(item.dataset.testid, item.dataset.status);
    });
  };
  new MutationObserver(look).observe(document.body,
    {subtree: true, childList: true, characterData: true, attributes: true});
  look();
}
"""
"""Records every value a row's link state and a command's status take, in order, as the
page shows them: a state that lasts only one update (a command's ``pending``) is seen."""

LABEL_BOX = """
name => {
  const labels = [...document.querySelectorAll(".agent-label")]
    .filter(label => label.textContent.split(" ")[0] === name);
  if (labels.length !== 1) { return null; }
  const box = labels[0].getBoundingClientRect();
  return {x: box.x, y: box.y};
}
"""
"""Where an agent's name label (its permanent Leaflet tooltip) is on screen."""

TRACK_BOX = """
name => {
  const cell = document.querySelector(`tr[data-agent="${name}"] td[data-field="name"]`);
  const colour = getComputedStyle(cell).borderLeftColor;
  const tracks = [...document.querySelectorAll(".leaflet-overlay-pane path")]
    .filter(path => getComputedStyle(path).stroke === colour
      && path.getAttribute("stroke-opacity") === "0.8");
  if (tracks.length !== 1) { return null; }
  const box = tracks[0].getBBox();
  return {width: box.width, height: box.height};
}
"""
"""The on-screen extent of an agent's track: the line of its colour (the colour of its
row's name cell) drawn at the track's opacity."""


def _clock_s(page: Any) -> float:
    text = page.get_by_test_id("station-clock").text_content() or ""
    match = re.match(r"t = (-?[\d.]+) s", text)
    assert match, f"the station's clock reads {text!r}"
    return float(match.group(1))


def _wait_clock(page: Any, at_least_s: float) -> None:
    """Wait until the page's station clock reads ``at_least_s`` or later."""
    page.wait_for_function(
        """t => {
          const m = /t = (-?[\\d.]+) s/.exec(
            document.querySelector("[data-testid=station-clock]").textContent);
          return m !== null && parseFloat(m[1]) >= t;
        }""",
        arg=at_least_s,
        timeout=STEP_TIMEOUT_MS,
    )


def _history(page: Any, key: str) -> list[str]:
    return list(page.evaluate("key => window.__clarkHistory[key] || []", key))


def _heard_history(page: Any, name: str) -> list[str]:
    """The link states an agent's row took since it was first heard."""
    history = _history(page, f"{name} liveness")
    assert "ok" in history, history
    first = history.index("ok")
    assert set(history[:first]) <= {"not-heard"}, history
    return history[first:]


def _label(page: Any, name: str) -> dict[str, float]:
    box = page.evaluate(LABEL_BOX, name)
    assert box is not None, f"no single map label for {name}"
    return box  # type: ignore[no-any-return]


def _wait_moved(page: Any, name: str, start: dict[str, float]) -> dict[str, float]:
    """Wait until ``name``'s map label is :data:`MOVED_PX` away from ``start``."""
    page.wait_for_function(
        """([name, start, px]) => {
          const labels = [...document.querySelectorAll(".agent-label")]
            .filter(label => label.textContent.split(" ")[0] === name);
          if (labels.length !== 1) { return false; }
          const box = labels[0].getBoundingClientRect();
          return Math.hypot(box.x - start.x, box.y - start.y) >= px;
        }""",
        arg=[name, start, MOVED_PX],
        timeout=STEP_TIMEOUT_MS,
    )
    return _label(page, name)


def _row(page: Any, name: str) -> Any:
    return page.get_by_test_id(f"agent-row-{name}")


def _cell(page: Any, name: str, field: str) -> Any:
    return _row(page, name).locator(f'[data-field="{field}"]')


def _command(page: Any, what: str) -> Any:
    """The newest command of the Commands pane whose description is ``what``."""
    return (
        page.get_by_test_id("commands")
        .locator("li")
        .filter(has=page.locator(".command-what", has_text=re.compile(rf"^#\d+ {what}$")))
        .first
    )


@pytest.fixture
def rehearsal(tmp_path: Path) -> Iterator[ServedStation]:
    """The cooperative-follow rehearsal in real time, its view on a free loopback port."""
    argv = [
        "dry-run",
        str(MISSION),
        "--realtime",
        "--station",
        "--view",
        "127.0.0.1:0",
        "--no-operator-script",
        "--fault",
        f"link_drop:mcs,slash_a@{LINK_DOWN_S[0]}-{LINK_DOWN_S[1]}",
        "--fault",
        f"link_drop:mcs,slash_b@{SLASH_B_DOWN_S[0]}-{SLASH_B_DOWN_S[1]}",
        "--until",
        str(UNTIL_S),
        # The example's world without its radio's bad spells: a command sent from the page
        # at a wall-clock moment must not fall in one (a campaign measures those).
        "--vary",
        "sim.radio_bursts.loss_bad=0",
        "--vary",
        f"sim.autopilot_ready_s={READY_S}",
        "--quiet",
    ]
    with served_station(argv, tmp_path) as station:
        station.wait_for_url()
        yield station


@pytest.fixture
def view(browser: Any, rehearsal: ServedStation) -> Iterator[Any]:
    """The one page of the scenario, opened as the rehearsal starts; the steps' timeout."""
    context = browser.new_context(viewport=VIEWPORT)
    expect.set_options(timeout=STEP_TIMEOUT_MS)
    try:
        page = context.new_page()
        watch = PageWatch(page)
        page.set_default_timeout(STEP_TIMEOUT_MS)
        assert rehearsal.url is not None
        page.goto(rehearsal.url)
        expect(page.get_by_test_id("connection")).to_have_text("live")
        page.evaluate(RECORDER)
        yield page
        watch.check()
    finally:
        expect.set_options(timeout=None)  # Playwright's default again
        context.close()


@contextmanager
def step(what: str) -> Iterator[None]:
    """One step of the scenario: a failure in it says which."""
    try:
        yield
    except Exception as exc:
        exc.add_note(f"in the step: {what}")
        raise


def test_the_cooperative_follow_rehearsal_through_the_page(view: Any) -> None:
    with step("the agents appear with their states"):
        agents_appear_with_their_states(view)
    with step("slash_a, unheard, is flagged STALE, then LOST, then live again"):
        an_agent_whose_heartbeats_stop_is_flagged_stale_then_lost(view)
    with step("Activate for slash_b: it chases slash_a on the map and parks"):
        activating_the_follower_makes_it_chase_on_the_map(view)
    with step("a mode change from the page shows in the row"):
        a_mode_change_from_the_page_shows_in_its_row(view)
    with step("slash_b's failsafe raises an alarm, once"):
        a_failsafe_raises_an_alarm_once(view)
    with step("Terminate from the dialog stops one vehicle, then every agent"):
        terminate_stops_every_agent(view)


# -- the steps ----------------------------------------------------------------------------


def agents_appear_with_their_states(page: Any) -> None:
    expect(page.get_by_test_id("mission-name")).to_have_text("cooperative-follow (mission 521)")
    expect(page.get_by_test_id("mission-detail")).to_contain_text("station mcs")
    rows = page.get_by_test_id("agents-body").locator("tr")
    expect(rows).to_have_count(2)  # every vehicle; the station is the header's
    for name, number in (("slash_a", 2), ("slash_b", 3)):
        expect(_cell(page, name, "name")).to_have_text(f"{name} #{number}")
        expect(_cell(page, name, "airframe")).to_have_text("rover")
        expect(_row(page, name)).to_have_attribute("data-liveness", "ok")
        expect(_cell(page, name, "liveness")).to_have_text("live")
        expect(_cell(page, name, "heard")).to_have_text(re.compile(r"^\d+\.\d s ago$"))
        expect(_cell(page, name, "condition")).to_have_text("ok")
        expect(_cell(page, name, "mode")).to_have_text("MANUAL (0)")  # their pilots' mode
        expect(_cell(page, name, "behaviour")).to_have_text(NOTHING)  # not started yet
        # their Vehicle Health, every 2 s: on the ground, unarmed, the simulated battery
        expect(_cell(page, name, "armed")).to_have_text("disarmed")
        expect(_cell(page, name, "battery")).to_have_text("12.6 V 100 %")
        expect(_cell(page, name, "ceiling")).to_have_text("120")  # the legal ceiling
    # each vehicle's envelope: its default geofence, a circle of the XBee's range (a mile)
    # around its start, dashed in its colour; drawn even where it is off the map's view
    fences = page.locator("path.envelope-include")
    expect(fences).to_have_count(2)
    for name in ("slash_a", "slash_b"):
        expect(page.locator(f"path.envelope-of-{name}")).to_have_count(1)
    # drawn as circles (an SVG arc), each far wider than the field the map shows
    page.wait_for_function(
        """() => [...document.querySelectorAll("path.envelope-include")].every(path =>
          /a[\\d.]+,[\\d.]+ /.test(path.getAttribute("d") || "")
          && path.getBBox().width > document.getElementById("map").clientWidth)""",
        timeout=STEP_TIMEOUT_MS,
    )
    expect(page.get_by_test_id("alarms")).to_be_hidden()  # no alarm yet
    # the rehearsal evaluates the mission's checks as it runs
    expect(page.get_by_test_id("checks-none")).to_be_hidden()
    checks = page.get_by_test_id("checks").locator("li")
    expect(checks).to_have_count(3)
    expect(checks.nth(0)).to_contain_text("Slash B reaches Slash A")
    expect(checks.nth(1)).to_have_attribute("data-status", "pending")


def an_agent_whose_heartbeats_stop_is_flagged_stale_then_lost(page: Any) -> None:
    up_s = LINK_DOWN_S[1]
    expect(_row(page, "slash_a")).to_have_attribute("data-liveness", "lost")
    expect(_cell(page, "slash_a", "liveness")).to_have_text("LOST")
    labels = page.locator(".agent-label")
    expect(labels.filter(has_text="slash_a (LOST)")).to_be_visible()  # and so says the map
    expect(_row(page, "slash_b")).to_have_attribute("data-liveness", "ok")  # slash_b heard
    assert _clock_s(page) < up_s + 1.0  # lost while the link was down
    expect(_row(page, "slash_a")).to_have_attribute("data-liveness", "ok")
    expect(labels.filter(has_text=re.compile(r"^slash_a$"))).to_be_visible()
    assert _clock_s(page) > up_s  # live again once it came back
    assert _heard_history(page, "slash_a") == ["ok", "stale", "lost", "ok"]
    assert _heard_history(page, "slash_b") == ["ok"]


def activating_the_follower_makes_it_chase_on_the_map(page: Any) -> None:
    # both behaviours have started: slash_a on its tour, slash_b waiting in idle
    expect(_cell(page, "slash_b", "behaviour")).to_have_text("idle ← start")
    expect(_cell(page, "slash_a", "behaviour")).to_have_text("(behaviour) ← start")
    for name in ("slash_a", "slash_b"):  # armed by their pilots once their autopilots were ready
        expect(_cell(page, name, "armed")).to_have_text("ARMED")
        expect(_cell(page, name, "prearm")).to_have_text("passing")
        expect(_cell(page, name, "gps")).to_have_text("3-D fix, 10 sats")
    before = _label(page, "slash_b")
    track = page.evaluate(TRACK_BOX, "slash_b")
    assert track is not None, "no track of slash_b on the map"

    page.get_by_test_id("operator-name").fill("tess")
    page.get_by_test_id("activate-slash_b").click()
    command = _command(page, "activate slash_b")
    expect(command).to_have_attribute("data-status", "done")
    expect(command.locator(".command-by")).to_contain_text("by tess at 127.0.0.1")
    expect(command.locator(".command-detail")).to_have_text(
        "its Behavior State shows the activation"
    )
    command_id = command.get_attribute("data-testid")
    assert _history(page, command_id) == ["pending", "done"]
    expect(_cell(page, "slash_b", "behaviour")).to_have_text("chase ← activate")

    # it drives: its label moves across the map and its track grows behind it
    after = _wait_moved(page, "slash_b", before)
    assert (after["x"], after["y"]) != (before["x"], before["y"])
    page.wait_for_function(
        f"([name, size]) => {{ const box = ({TRACK_BOX})(name);"
        " return box !== null && box.width + box.height >= size; }",
        arg=["slash_b", track["width"] + track["height"] + 2 * MOVED_PX],
        timeout=STEP_TIMEOUT_MS,
    )
    expect(page.get_by_test_id("mission-log")).to_contain_text("operator: activate slash_b")

    # it reaches slash_a and parks; the checks pane says so
    expect(_cell(page, "slash_b", "behaviour")).to_have_text("parked ← done")
    checks = page.get_by_test_id("checks").locator("li")
    expect(checks.filter(has_text="Slash B parks")).to_have_attribute("data-status", "passed")
    expect(checks.filter(has_text="Slash B reaches Slash A")).to_have_attribute(
        "data-status", "passed"
    )


def a_mode_change_from_the_page_shows_in_its_row(page: Any) -> None:
    expect(_cell(page, "slash_b", "mode")).to_have_text("HOLD (4)")  # parked
    page.get_by_test_id("mode-select-slash_b").select_option("MANUAL")
    page.get_by_test_id("mode-set-slash_b").click()
    command = _command(page, "mode slash_b MANUAL")
    expect(command).to_have_attribute("data-status", "done")
    expect(command.locator(".command-detail")).to_have_text("its Agent Status reports MANUAL")
    expect(_cell(page, "slash_b", "mode")).to_have_text("MANUAL (0)")
    expect(_cell(page, "slash_a", "mode")).to_have_text("GUIDED (15)")  # the other unchanged


def a_failsafe_raises_an_alarm_once(page: Any) -> None:
    _wait_clock(page, SLASH_B_DOWN_S[1])  # the link is back: slash_b is heard again
    alarm = page.get_by_test_id("alarm-list").locator('li[data-kind="failsafe"]')
    expect(alarm).to_have_count(1)
    expect(page.get_by_test_id("alarms")).to_be_visible()
    expect(alarm).to_have_attribute("data-status", "active")
    expect(alarm.locator(".alarm-text")).to_have_text("slash_b in failsafe: hold: mcs_lost")
    expect(_cell(page, "slash_b", "condition")).to_have_text("failsafe (hold: mcs_lost)")
    expect(_row(page, "slash_b")).to_have_attribute("data-alarm", "1")
    log = page.get_by_test_id("mission-log")
    expect(log).to_contain_text("failsafe: slash_b in failsafe")
    # raised once per episode: seconds later, still one alarm and one log line
    _wait_clock(page, _clock_s(page) + 3.0)
    expect(alarm).to_have_count(1)
    raised = log.locator("li").filter(has_text=re.compile(r"ALARM \d+ failsafe: slash_b"))
    expect(raised).to_have_count(1)


def _terminate(page: Any, target: str) -> None:
    page.get_by_test_id("terminate-open").click()
    dialog = page.get_by_test_id("terminate-dialog")
    expect(dialog).to_be_visible()
    page.get_by_test_id("terminate-target").select_option(target)
    page.get_by_test_id("terminate-confirm").click()
    expect(dialog).to_be_hidden()


def terminate_stops_every_agent(page: Any) -> None:
    # slash_a is still driving its tour
    before = _label(page, "slash_a")
    _wait_moved(page, "slash_a", before)

    # the dialog can be cancelled: nothing is sent
    page.get_by_test_id("terminate-open").click()
    page.get_by_test_id("terminate-cancel").click()
    expect(page.get_by_test_id("terminate-dialog")).to_be_hidden()

    # slash_a alone: it stops where it is, while the station's clock runs on
    _terminate(page, "slash_a")
    command = _command(page, "terminate slash_a")
    expect(command).to_have_attribute("data-status", "done")
    expect(command.locator(".command-detail")).to_have_text("its heartbeat reports it terminated")
    expect(_row(page, "slash_a")).to_have_attribute("data-liveness", "terminated")
    expect(_cell(page, "slash_a", "condition")).to_have_text("terminated")
    stopped = _label(page, "slash_a")
    position = _cell(page, "slash_a", "local").text_content()
    _wait_clock(page, _clock_s(page) + 3.0)
    now = _label(page, "slash_a")
    assert abs(now["x"] - stopped["x"]) < 1 and abs(now["y"] - stopped["y"]) < 1
    expect(_cell(page, "slash_a", "local")).to_have_text(position or "")
    expect(_cell(page, "slash_a", "liveness")).to_have_text("TERMINATED (lost)")

    # then all: the station terminates the rest of the fleet, waits for each
    # confirmation, then terminates itself; the page's controls go off
    _terminate(page, "all")
    command = _command(page, "terminate all")
    expect(command).to_have_attribute("data-status", "done")
    expect(command.locator(".command-detail")).to_have_text("its heartbeat reports it terminated")
    expect(_row(page, "slash_b")).to_have_attribute("data-liveness", "terminated")
    expect(_cell(page, "slash_b", "condition")).to_have_text("terminated")
    expect(page.get_by_test_id("station-clock")).to_contain_text("station TERMINATED")
    expect(page.get_by_test_id("activate-slash_b")).to_be_disabled()
    # slash_b's failsafe ended with it: its alarm is cleared, visibly (the station, which
    # terminated in the same tick, has closed its log: the clearing is not logged)
    alarm = page.get_by_test_id("alarm-list").locator('li[data-kind="failsafe"]')
    expect(alarm).to_have_attribute("data-status", "cleared")
    expect(alarm.locator(".alarm-time")).to_contain_text("cleared at t = ")
    sent = ["terminate all", "terminate slash_a", "mode slash_b MANUAL", "activate slash_b"]
    expect(page.get_by_test_id("commands").locator(".command-what")).to_have_text(
        [re.compile(rf"^#\d+ {what}$") for what in sent]  # newest first; none on cancel
    )
