"""How a SITL run keeps SITL's pace (issue 19), without SITL: the rules on SITL's messages.

The run on real SITL: test_the_engine_keeps_sitls_pace_through_a_sweep in
tests/test_dry_run_sitl.py. Here the backend is given ArduPilot's own messages, encoded by
pymavlink, as SITL sends them.
"""

from __future__ import annotations

import itertools
import time
from types import SimpleNamespace
from typing import Any

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from sitl_here import NO_SITL, real_install

from clark_engine.dryrun import sitl_pace
from clark_engine.dryrun.report import pace_lines
from clark_engine.dryrun.sitl_backend import (
    REPORT_AFTER_S,
    REPORT_STREAMS,
    LaterReport,
    SitlBackend,
)
from clark_engine.dryrun.sitl_pace import GENTLEST, MARGIN, RAISE, RAISE_AFTER_WALL_S, SitlPace
from clark_engine.expectations.recording import Pace
from clark_engine.mission.geo import Origin
from clark_engine.sitl.launcher import Home, SitlProcess

ORIGIN = Origin(30.6372, -96.4787, 90.0)


def backend() -> SitlBackend:
    """A backend not connected to anything: only its handling of SITL's messages is used."""
    process: Any = SimpleNamespace(home=Home(30.6372, -96.4787, 90.0), speedup=10.0)
    return SitlBackend(process, origin=ORIGIN, firmware="arduplane")


def feed(sitl: SitlBackend, *messages: Any) -> None:
    """Messages as SITL's SERIAL2 sends them, parsed by the backend's own parser."""
    sender = mavlink2.MAVLink(None, 1, 1)
    for msg in messages:
        for parsed in sitl._parser.parse_buffer(msg.pack(sender)) or []:
            sitl._note(parsed)


def rc(boot_s: float, chan1_us: int) -> Any:
    return mavlink2.MAVLink_rc_channels_message(
        round(boot_s * 1000), 16, chan1_us, *[1500] * 17, 255
    )


def pressure(boot_s: float) -> Any:
    return mavlink2.MAVLink_scaled_pressure_message(round(boot_s * 1000), 1013.0, 0.0, 2000)


def test_rc_and_servo_reports_stream_only_for_a_recorded_signal() -> None:
    """At 40 Hz they were half the backend's messages in every run; now only when a
    doublet or sweep records a signal on them (``want_reports``, before connecting)."""
    sitl = backend()
    assert not set(REPORT_STREAMS) & set(sitl._streams_wanted)
    sitl.want_reports({"servo"})
    assert "SERVO_OUTPUT_RAW" in sitl._streams_wanted
    assert "RC_CHANNELS" not in sitl._streams_wanted
    sitl.want_reports({"rc_override", "servo"})
    assert set(REPORT_STREAMS) <= set(sitl._streams_wanted)


def heartbeat() -> Any:
    return mavlink2.MAVLink_heartbeat_message(
        mavlink2.MAV_TYPE_QUADROTOR, mavlink2.MAV_AUTOPILOT_ARDUPILOTMEGA, 0, 0, 3, 3
    )


def test_before_sitls_first_time_stamp_the_run_waits_for_its_heartbeats() -> None:
    """A SITL starved of CPU at boot runs slower than its speed-up: the run's clock on the
    wall's estimate alone got ahead of it, heard no heartbeat for 3 s of that clock, and
    lost the autopilot at the start (a campaign's early autopilot_lost)."""
    sitl = backend()
    assert sitl.clock_s is None  # not connected
    sitl._connected_wall = time.monotonic() - 5.0  # 50 s of SITL's clock at 10x, by the wall
    assert sitl.clock_s == pytest.approx(1.0)  # no heartbeat yet: its first second at most
    feed(sitl, heartbeat(), heartbeat())
    assert sitl.clock_s == pytest.approx(3.0)
    feed(sitl, pressure(2.4))  # its own clock, once it stamps one
    assert sitl.clock_s == pytest.approx(2.4)
    on_time = backend()
    on_time._connected_wall = time.monotonic() - 5.0
    feed(on_time, *(heartbeat() for _ in range(100)))
    clock_s = on_time.clock_s
    assert clock_s is not None and 50.0 <= clock_s < 101.0  # the wall's estimate, the lower


def test_the_engine_hears_what_sitl_sent_at_the_runs_time_it_was_sent() -> None:
    """SITL ahead of the run: a tick heard everything SITL had sent (3 s of it at once),
    the ticks catching up heard nothing, and the adapter lost its autopilot (its 3 s
    timeout). Now each frame waits for the run's time it was sent at: its own time stamp,
    or the last stamped frame's (HEARTBEAT has none). Every byte still comes, in order."""
    sitl = backend()
    sender = mavlink2.MAVLink(None, 1, 1)
    sent = [
        heartbeat(),
        pressure(1.0),
        heartbeat(),  # stamped as the frame before it: 1.0 s
        pressure(2.0),
        heartbeat(),
        pressure(3.5),
    ]
    stream = b"".join(bytes(msg.pack(sender)) for msg in sent)
    sitl._connected_wall = time.monotonic()  # before any stamp: SITL's clock as read
    sitl._hold(stream[:37])  # a frame cut in two, as TCP may deliver it
    sitl._hold(stream[37:])
    early = sitl._release(0.5)
    assert [m.get_type() for m in sitl.heard] == ["HEARTBEAT"]
    at_1 = sitl._release(1.5)
    assert [m.get_type() for m in sitl.heard] == ["SCALED_PRESSURE", "HEARTBEAT"]
    at_3 = sitl._release(3.0)
    assert [m.get_type() for m in sitl.heard] == ["SCALED_PRESSURE", "HEARTBEAT"]
    assert sitl._release(3.4) == b""
    rest = sitl._release(3.5)
    assert early + at_1 + at_3 + rest == stream


def sim_state(alt_amsl_m: float) -> Any:
    zero = [0.0] * 13
    return mavlink2.MAVLink_sim_state_message(
        1.0, *zero[:12], 0.0, 0.0, alt_amsl_m, 0.0, 0.0, 0.0, 0.0, 0.0, 306372000, -964787000
    )


def test_the_truth_recorded_at_a_tick_is_sitls_at_the_runs_time() -> None:
    """As the engine hears SITL at the run's time, the truth is taken at that time too:
    a state entered on what SITL said is recorded where SITL was when it said it."""
    sitl = backend()  # a plane: its height is SITL's altitude over the origin's
    feed(sitl, pressure(1.0), sim_state(100.0), pressure(2.0), sim_state(110.0))
    assert sitl.truth().up_m == pytest.approx(20.0)  # before the run: SITL's latest
    sitl._want_s = 1.5
    assert sitl.truth().up_m == pytest.approx(10.0)
    sitl._want_s = 2.5
    assert sitl.truth().up_m == pytest.approx(20.0)


def test_a_tick_takes_the_first_report_showing_what_it_asked_for() -> None:
    report = LaterReport("RC_CHANNELS", 0, after_s=10.0, want_us=1650)
    assert not report.take(9.99, (1650,))  # made before the tick's commands
    assert not report.take(10.02, (1500,))  # not yet applied
    assert report.take(10.04, (1650,))
    assert report.pwm_us == 1650


def test_a_value_never_shown_is_what_sitl_reported_after_the_wait() -> None:
    """An override ArduPilot refused, or overwritten by the next before it was applied."""
    report = LaterReport("RC_CHANNELS", 0, after_s=10.0, want_us=1650)
    assert not report.take(10.1, (1500,))
    assert report.take(10.0 + REPORT_AFTER_S, (1500,))
    assert report.pwm_us == 1500  # the signal check then fails, as it should
    nothing_asked = LaterReport("RC_CHANNELS", 0, after_s=10.0, want_us=None)
    assert not nothing_asked.take(10.2, (1500,))
    assert nothing_asked.take(10.3, (1490,)) and nothing_asked.pwm_us == 1490


def test_reports_resolve_the_ticks_as_they_stream_in() -> None:
    sitl = backend()
    feed(sitl, pressure(5.0))
    first = sitl.report_later("rc_override", 1, 1600)
    feed(sitl, rc(5.02, 1500), rc(5.04, 1600))
    assert first.pwm_us == 1600
    feed(sitl, pressure(5.1))
    second = sitl.report_later("rc_override", 1, 1700)
    third = sitl.report_later("servo", 2, None)
    feed(sitl, rc(5.12, 1700))
    assert second.pwm_us == 1700 and third.pwm_us is None  # a servo output: another report
    assert sitl._later == [third]


def test_a_stream_at_ardupilots_default_rate_is_asked_for_again() -> None:
    """ArduPilot sent SCALED_PRESSURE once a second before it took the request for 40 Hz."""
    sitl = backend()
    feed(sitl, *(pressure(3.0 + k) for k in range(4)))
    assert "SCALED_PRESSURE" not in sitl._streams_seen  # so it is requested again
    feed(sitl, *(pressure(7.0 + k * 0.025) for k in range(25)))
    assert "SCALED_PRESSURE" in sitl._streams_seen


def test_the_report_says_whether_the_engine_kept_the_pace() -> None:
    kept, late = pace_lines(
        {
            "slash": Pace(behind_s=0.2, behind_at_s=3.0, silent_s=1.1, silent_at_s=20.0),
            "cub": Pace(behind_s=31.0, behind_at_s=58.4, silent_s=1.0, silent_at_s=40.0),
        }
    )
    assert kept.startswith("slash: the engine kept ArduPilot SITL's pace (0.2 s behind")
    assert late.startswith("warning: cub: the engine fell 31.0 s behind ArduPilot SITL's clock")
    assert "(at 58.4 s of the run)" in late and late.endswith("lower --sitl-speedup")


def test_the_runs_end_takes_sitls_last_report_for_what_it_never_reported() -> None:
    sitl = backend()
    feed(sitl, pressure(5.0), rc(5.0, 1520))
    report = sitl.report_later("rc_override", 1, 1600)
    sitl.settle_reports()  # SITL gone: nothing more will come
    assert report.pwm_us == 1520 and not sitl._later


def test_servo_outputs_are_matched_by_their_microsecond_stamp() -> None:
    """SERVO_OUTPUT_RAW has no time_boot_ms: its time_usec, wrapped every 71.6 minutes."""
    sitl = backend()
    wrap_s = 2**32 / 1e6
    feed(sitl, pressure(wrap_s + 10.0))  # SITL past its first wrap of time_usec
    report = sitl.report_later("servo", 6, 1234)
    feed(
        sitl,
        mavlink2.MAVLink_servo_output_raw_message(round(9.99e6), 0, *[1100] * 16),
        mavlink2.MAVLink_servo_output_raw_message(
            round(10.04e6), 0, *[1500] * 5, 1234, *[1100] * 10
        ),
    )
    assert report.pwm_us == 1234


def test_the_report_says_when_sitl_was_slowed_down() -> None:
    (line,) = pace_lines(
        {
            "copter": Pace(
                behind_s=1.4, behind_at_s=40.0, silent_s=1.3, silent_at_s=40.1,
                start_speedup=10.0, speedups=[(40.0, 5.0), (52.5, 2.5)],
            )
        }
    )  # fmt: skip
    assert line.startswith("copter: the engine kept ArduPilot SITL's pace (1.4 s behind")
    assert "SITL's speed-up went from 10x to 5x at 40.0 s, 2.5x at 52.5 s of the run" in line


class _Vehicle:
    """What SitlPace reads of a SITL backend and asks of it (a SitlBackend has both)."""

    def __init__(self) -> None:
        self.behind_s = 0.0
        self.asked: list[tuple[float, float]] = []

    def set_speedup(self, speedup: float, t_s: float) -> None:
        self.asked.append((t_s, speedup))


def test_sitl_is_sped_up_again_once_the_run_keeps_up(monkeypatch: pytest.MonkeyPatch) -> None:
    """A busy spell slows SITL; RAISE_AFTER_WALL_S of keeping up gives speed back, to the
    start's at most. Before: a run slowed once stayed slow (a suite's SITL test ran its
    120 s mission at about real time after one busy spell, 118 s of wall time)."""
    wall = [100.0]
    monkeypatch.setattr(sitl_pace.time, "monotonic", lambda: wall[0])
    vehicle = _Vehicle()
    pace = SitlPace([vehicle], 10.0)  # type: ignore[list-item]
    t_s = 0.0

    def run(wall_s: float, pace_x: float, behind_s: float, more_behind_s: float = 0.0) -> None:
        nonlocal t_s
        for _ in range(round(wall_s / 0.05)):
            wall[0] += 0.05
            t_s += 0.05 * pace_x
            vehicle.behind_s = behind_s
            behind_s += more_behind_s
            pace.after_step(t_s)

    run(2.0, 10.0, 0.0)  # on time
    run(4.0, 2.0, 2.1, more_behind_s=0.05)  # a busy spell: the run keeps 2x, falls behind
    slowed = [x for _, x in vehicle.asked]
    assert slowed[0] == pytest.approx(10.0 * GENTLEST)
    assert len(slowed) >= 2 and all(b < a for a, b in itertools.pairwise(slowed))
    assert slowed[-1] < 2.0 / MARGIN  # what the run kept, with the margin, give or take
    run(RAISE_AFTER_WALL_S - 0.5, slowed[-1], 0.0)  # keeps up, not yet long enough
    assert len(vehicle.asked) == len(slowed)
    run(60.0, 10.0, 0.0)  # keeps up: raised by RAISE every RAISE_AFTER_WALL_S, to 10x
    raised = [x for _, x in vehicle.asked[len(slowed) :]]
    assert raised[0] == pytest.approx(slowed[-1] * RAISE)
    assert all(b > a for a, b in itertools.pairwise(raised))
    assert raised[-1] == 10.0 and pace.speedup == 10.0


REAL = real_install()


@pytest.mark.sitl
@pytest.mark.skipif(REAL is None, reason=NO_SITL)
def test_an_engine_that_falls_behind_slows_sitl_to_the_pace_it_keeps() -> None:
    """An engine that keeps 4x of SITL's 10x (a sleep at each step) slows SITL to it.

    First by :data:`~clark_engine.dryrun.sitl_pace.GENTLEST` (the pace kept is not known
    yet), then to :data:`~clark_engine.dryrun.sitl_pace.MARGIN` of the pace the run kept
    (the run falls :data:`~clark_engine.dryrun.sitl_pace.BEHIND_S` behind in a quarter of a
    wall second at 10x, before half a second of the pace it keeps is known).
    Before: SITL ran on at its launch speed-up whatever the engine kept, and a loaded CI
    run fell 10 s behind ArduCopter SITL, whose ground-station failsafe then flew RTL
    before the copter took off.
    """
    assert REAL is not None
    process = SitlProcess(REAL, "copter", Home(30.6372, -96.4787, 90.0), speedup=10).start()
    sitl = SitlBackend(process, origin=ORIGIN, firmware="arducopter")
    try:
        sitl.connect()
        deadline = time.monotonic() + 30.0
        while sitl._clock_s is None and time.monotonic() < deadline:  # its first time stamp
            sitl.drain()
            time.sleep(0.05)
        assert sitl._clock_s is not None, "SITL sent no time stamp in 30 s"
        sitl.start_run_here()
        pace = SitlPace([sitl], 10.0)
        t_s = 0.0
        while len(sitl.pace.speedups) < 2 and t_s < 12.0:  # a fortieth of a wall second a step
            sitl.step(t_s, 0.1)
            pace.after_step(t_s)
            time.sleep(0.025)
            t_s = round(t_s + 0.1, 1)
        first, second, *_ = sitl.pace.speedups
        assert first[1] == pytest.approx(10.0 * GENTLEST)
        # The engine kept at most 4x (less on a busy machine): that with the margin.
        assert 1.0 <= second[1] <= 4.0 * MARGIN, sitl.pace.speedups
        assert pace.speedup == sitl.pace.speedups[-1][1] == sitl.speedup
        # SITL runs at the new speed-up: its clock against the wall.
        start_clock_s, start_wall = sitl._clock_s, time.monotonic()
        while time.monotonic() - start_wall < 1.0:
            sitl.step(t_s, 0.1)
            t_s = round(t_s + 0.1, 1)
        rate = (sitl._clock_s - start_clock_s) / (time.monotonic() - start_wall)
        assert 0.7 * pace.speedup < rate < 1.3 * pace.speedup, f"SITL ran {rate:.1f}x the wall"
    finally:
        sitl.close()
