"""Real ArduPilot SITL behind a dry run's vehicle (``clark dry-run --autopilot sitl``).

The promise of a dry run is that what passes it flies on the real autopilot, and
the strongest evidence is to run the same mission with the real autopilot's code.
:class:`SitlBackend` puts one ArduPilot SITL process (:mod:`clark_engine.sitl.launcher`)
behind the dry run's :class:`~clark_engine.dryrun.backend.VehicleBackend`: the
engine's runtime and MAVLink adapter, the radio mesh, the cameras, the operator
script and the checks stay exactly as in a simulated run.

Two links. The engine's adapter (and the simulated pilot) speak to SITL on its
SERIAL0, as they would to a flight controller's telemetry port: that link carries
only what they ask for. The backend reads its own streams on SERIAL2, so that
asking for them never changes the rates the adapter set: a message with a time
stamp 40 times a second as its clock, SIM_STATE (the simulator's true position and
attitude) 20 times a second for the tracks, the checks and the radio ranges, and
RC_CHANNELS and SERVO_OUTPUT_RAW 40 times a second for the checks of what the
autopilot received. SERIAL1 stays free for a ground station.

Time. SITL runs on its own clock (real time times its speed-up) and cannot be
paused, so it sets the pace: :meth:`SitlBackend.step` returns once the SITL
vehicle's clock (the ``time_boot_ms`` of what it sends) has passed the run's time,
so the engine is never ahead of any autopilot. ArduCopter streams nothing with a time stamp for its
first seconds (it loses stream requests until about 2.5 s, and its heartbeats
carry no time), so until the first time stamp the clock is the wall time since
the connection times the speed-up: what SITL sends in those seconds reaches the
engine when it was sent, and the adapter hears the heartbeats come. The run must
not fall behind SITL either: the RC inputs and servo outputs a tick commanded are
matched to SITL's reports as they stream in (:meth:`SitlBackend.report_later`), a tick
waiting only for the previous one's value to show when it has not yet
(:meth:`SitlBackend.wait_shown`), and :attr:`SitlBackend.pace` records how far behind SITL
the run fell (a machine too busy for the speed-up). An engine that falls behind anyway
slows SITL down (:mod:`clark_engine.dryrun.sitl_pace`, through :meth:`SitlBackend.set_speedup`).

Set-up. Before the run, each SITL autopilot is given the parameters the simulated
autopilot flies with (the firmware's defaults the simulation uses, and the
profile's ``parameters``), since SITL's own parameter files differ (its ArduRover
drives at 5 m/s). A vehicle the mission hands over in flight
(``launch.airborne``) is flown up before the run by the backend, as its pilot
would: ready, armed, taken off (ArduCopter's guided takeoff, ArduPlane's TAKEOFF
mode), flown to its ``position`` and left in its hold mode with the throttle
stick centred; the run starts after that, with its clock at that moment (the
pre-flight is :mod:`clark_engine.dryrun.sitl_preflight`, mixed into the backend).

The backend speaks to SITL from system 255, component 26 (MAV_COMP_ID_USER2); the
simulated pilot uses component 25 and the engine's adapter 191.
"""

from __future__ import annotations

import collections
import math
import select
import socket
import time
from collections.abc import Collection, Mapping
from dataclasses import dataclass
from typing import Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.backend import VehicleBackend
from clark_engine.dryrun.sitl_preflight import SitlPreflight
from clark_engine.expectations.recording import Pace
from clark_engine.mission.geo import EARTH_RADIUS_M, Origin
from clark_engine.sim.ardupilot.vehicle_model import Truth
from clark_engine.sim.gps_error import GpsError
from clark_engine.sitl.errors import SitlError
from clark_engine.sitl.launcher import SitlProcess

CLOCK_MESSAGE: Final = "SCALED_PRESSURE"
"""A cheap time-stamped message: the backend's clock."""
FAST_INTERVAL_US: Final = 25_000
"""40 Hz, the fastest ArduPilot streams (measured)."""
TRUTH_INTERVAL_US: Final = 50_000
"""SIM_STATE at 20 Hz: the true position for tracks (sampled at 10 Hz) and radio ranges."""
OWN_STREAMS: Final[Mapping[str, int]] = {
    CLOCK_MESSAGE: FAST_INTERVAL_US,
    "SIM_STATE": TRUTH_INTERVAL_US,
    "VFR_HUD": TRUTH_INTERVAL_US,
}
"""What the backend asks SITL to send on its own link, message -> interval."""
REPORT_STREAMS: Final[Mapping[str, int]] = {
    "RC_CHANNELS": FAST_INTERVAL_US,
    "SERVO_OUTPUT_RAW": FAST_INTERVAL_US,
}
"""...and what it asks for only when a recorded signal is on them
(:meth:`SitlBackend.want_reports`): at 40 Hz they were half the backend's messages, and
parsing them was 5-9 % of the engine's CPU in a copter's run that records no signal."""
REQUEST_RETRY_WALL_S: Final = 0.3
"""Stream requests are repeated this often (wall clock) until the stream arrives:
ArduPilot acknowledges and loses those sent before it is ready (measured)."""
STREAM_CHECK_S: Final = 0.5
"""A stream asked for is counted over this much of SITL's clock before it is taken as
arriving at its interval (at least half its messages must have come)."""
STALL_WALL_S: Final = 60.0
"""Wall seconds without a byte from SITL after which the run gives up on it."""
REPORT_AFTER_S: Final = 0.25
"""How long (SITL's clock) after a tick an RC input or servo output it commanded must show in
SITL's reports: ArduPlane's RC_CHANNELS showed an RC override 40 ms after it was sent at
the median and 100 ms at worst (60 overrides at speed-up 10, measured). A tick's value is
the first report after the tick that shows what the tick asked for, or else the first
report this long after it (what SITL made of it: the check then fails). The reports are
matched as they stream in (:class:`LaterReport`); a tick waits for the previous tick's
value to show this long at most (:meth:`SitlBackend.wait_shown`)."""
TRUTHS_KEPT: Final = 200
"""SIM_STATEs kept (10 s of SITL's at 20 Hz), so that the truth recorded at the run's time
is SITL's at that time when SITL is ahead of the run (:meth:`SitlBackend.truth`)."""
HEARTBEAT_PERIOD_S: Final = 1.0
"""ArduPilot sends HEARTBEAT on every link once a second of its own clock, from boot:
before its first time stamp, the only sign of how far SITL's clock has got."""
PARAM_RETRY_WALL_S: Final = 1.0
"""A parameter not echoed is set again this often; one SITL lacks is given up after 5."""

GPS_ERROR_EVERY_S: Final = 0.5
"""Simulated seconds between two updates of SITL's GPS offset (``sim.gps_error``): a
walk with a time constant of minutes moves millimetres in that time, and a glitch starts
at most this late."""
GPS_ERROR_STEP_M: Final = 0.05
"""A change of the GPS error smaller than this is not sent (it would only load the link)."""

REPORT_KINDS: Final[Mapping[str, str]] = {
    "rc_override": "RC_CHANNELS",
    "servo": "SERVO_OUTPUT_RAW",
}
"""A signal's ``via`` -> the report that shows what the autopilot made of it."""


@dataclass(slots=True)
class LaterReport:
    """One tick's RC input or servo output, read from a report SITL makes after the tick.

    SITL runs on while the engine works and cannot be paused: waiting after each tick
    for a report (as the run did) put the engine 0.15 s further behind SITL at every
    tick of a sweep (ArduPlane's GCS failsafe flew RTL in such runs). The report is
    matched as it streams in instead (:meth:`SitlBackend.report_later`).
    """

    kind: str
    """RC_CHANNELS or SERVO_OUTPUT_RAW."""
    index: int
    """The channel or output, from 0."""
    after_s: float
    """SITL's clock when the tick's commands had been sent: only a later report counts."""
    want_us: int | None
    """What the tick asked for (an RC override or a DO_SET_SERVO still in force); None: nothing."""
    pwm_us: int | None = None
    """What SITL reported; None until it did."""

    def take(self, boot_s: float, values: tuple[int, ...]) -> bool:
        """Consider one report made at ``boot_s`` (SITL's clock); True once resolved.

        The first report after the tick showing the value asked for, within
        :data:`REPORT_AFTER_S`; or else the first report that long after the tick.
        """
        if boot_s <= self.after_s:
            return False
        value = values[self.index] if self.index < len(values) else 0
        if value == self.want_us or boot_s >= self.after_s + REPORT_AFTER_S:
            self.pwm_us = value
            return True
        return False


_USEC_WRAP_S: Final = 2**32 / 1e6
_SYSTEM, _COMPONENT = 255, 26
_M_PER_DEG_LAT: Final = math.radians(1.0) * EARTH_RADIUS_M


def _same_float32(reported: float, wanted: float) -> bool:
    """True when ``reported`` is ``wanted`` as PARAM_VALUE's float32 carries it.

    A float32 keeps about 7 significant digits.
    """
    return math.isclose(reported, wanted, rel_tol=1e-6, abs_tol=1e-6)


def _link_parser() -> Any:
    """A pymavlink parser for the engine's link that skips what it cannot frame."""
    parser = mavlink2.MAVLink(None, _SYSTEM, _COMPONENT)
    parser.robust_parsing = True
    return parser


class SitlBackend(SitlPreflight, VehicleBackend):
    """One vehicle's autopilot and physics as a real ArduPilot SITL process.

    Args:
        process: The started SITL process (listening, not yet connected).
        origin: The mission origin (the local frame of tracks and checks).
        firmware: ``ardurover``, ``arducopter`` or ``arduplane``.
        system_id: The autopilot's MAVLink system id.
        component_id: Its component id.
        params: Parameters to set before the run (ArduPilot names and units).
        modes: Mode name -> ArduPilot custom_mode number (the autopilot profile's), to
            name the mode its HEARTBEAT reports.
        gps_error: The vehicle's GPS error over the run (``sim.gps_error``), played
            through SITL's own GPS offset (SIM_GPS1_GLTCH_X and _Y, in degrees of
            latitude and longitude): SITL's EKF fuses the offset position and the
            vehicle flies it, so its true track (SIM_STATE) is displaced, as in the
            simulated run. None: SITL's GPS as it is.
    """

    def __init__(
        self,
        process: SitlProcess,
        *,
        origin: Origin,
        firmware: str,
        system_id: int = 1,
        component_id: int = 1,
        params: Mapping[str, float] | None = None,
        modes: Mapping[str, int] | None = None,
        gps_error: GpsError | None = None,
    ) -> None:
        self.process = process
        self.gps_error = gps_error
        self._gps_sent_m = (0.0, 0.0)
        self._next_gps_s = 0.0
        self._mode_names = {int(number): name for name, number in (modes or {}).items()}
        self.origin = origin
        self.firmware = firmware
        self._target = (system_id, component_id)
        self._params_due: dict[str, float] = dict(params or {})
        self._param_tries: dict[str, int] = {}
        self._next_param_wall = 0.0
        self._sock: socket.socket | None = None  # SERIAL0: the engine's link
        self._own: socket.socket | None = None  # SERIAL2: the backend's streams
        self._out = bytearray()
        self._mav = mavlink2.MAVLink(self, srcSystem=_SYSTEM, srcComponent=_COMPONENT)
        self._parser = mavlink2.MAVLink(None, _SYSTEM, _COMPONENT)
        self._parser.robust_parsing = True
        # The engine's link, parsed only to tell when SITL sent each frame: a frame is
        # handed to the engine's adapter (as the bytes it came in) at the run's time it was
        # sent, not before (:meth:`step`).
        self._link_parser = _link_parser()
        self._live = False  # the engine's link is parsed and held (not in a pre-flight)
        self._held: collections.deque[tuple[float, bytes, Any]] = collections.deque()
        self._link_stamp_s: float | None = None  # SITL's time of the last stamped frame
        self.heard: list[Any] = []
        """The messages :meth:`step` last handed over, parsed (for the simulated pilot)."""
        self._truths: collections.deque[tuple[float, Truth]] = collections.deque(maxlen=TRUTHS_KEPT)
        self._want_s: float | None = None  # SITL's time of the run's last step
        self._clock_s: float | None = None
        self._connected_wall: float | None = None
        self._beats = 0  # HEARTBEATs on the backend's own link
        self._offset_s = 0.0
        self._streams_wanted = dict(OWN_STREAMS)
        self._streams_seen: set[str] = set()  # arriving at their interval (at least half)
        self._stream_counts: dict[str, tuple[float, int]] = {}  # since (clock), messages
        self._next_request_wall = 0.0
        self._last_byte_wall = time.monotonic()
        self._latest: dict[str, Any] = {}
        home = process.home  # where SITL stands until its first SIM_STATE
        self._truth = self._truth_at(
            home.lat_deg, home.lon_deg, home.alt_m, (0.0, 0.0, 0.0),
            (0.0, 0.0, math.radians(home.heading_deg)),
        )  # fmt: skip
        self._handover: tuple[float, float, float, float, Mapping[str, int], str] | None = None
        """A plane handed over in flight: :meth:`_plane_over`'s arguments, to go round again."""
        self._rc: tuple[int, ...] = ()
        self._servos: tuple[int, ...] = ()
        self._later: list[LaterReport] = []  # asked for and not yet reported, in order
        self._shows: dict[tuple[str, int], bool] = {}  # SITL showed the last value asked for
        self._sent_clock_s: float | None = None
        self._pilot_us = [0] * 16
        self.pace = Pace(start_speedup=process.speedup)
        """How far behind SITL the run fell, and the engine link's longest silence."""
        self._speedup = float(process.speedup)
        self.behind_s = 0.0
        """How far SITL's clock was past the run's time at the last step (0 when it was not)."""

    # -- the interface ----------------------------------------------------------------------

    @property
    def system_id(self) -> int:
        """The SITL autopilot's system id."""
        return self._target[0]

    @property
    def clock_s(self) -> float | None:
        """The SITL vehicle's own time (its boot clock), None before the connection.

        Before SITL's first time stamp (ArduCopter streams nothing for its first
        seconds), the wall time since the connection times the speed-up (SITL's clock
        starts when it is connected), but never more than a heartbeat period past the
        heartbeats SITL has sent (:data:`HEARTBEAT_PERIOD_S`): a SITL starved of CPU
        while it boots runs slower than its speed-up, and a run on the wall's estimate
        got ahead of it, heard no heartbeat for the autopilot's timeout and lost the
        autopilot at the start (a campaign's four SITLs on two cores).
        """
        if self._clock_s is not None:
            return self._clock_s
        if self._connected_wall is None:
            return None
        by_wall_s = (time.monotonic() - self._connected_wall) * self.speedup
        return min(by_wall_s, (self._beats + 1) * HEARTBEAT_PERIOD_S)

    def want_reports(self, vias: Collection[str]) -> None:
        """Stream the reports of ``vias`` (``rc_override``, ``servo``): before :meth:`connect`.

        The RC inputs and servo outputs that :meth:`report_later` reads; a vehicle that
        records no signal on them does not pay for parsing them.
        """
        if self._own is not None:
            raise SitlError("the reports to stream are chosen before the connection")
        for via in vias:
            kind = REPORT_KINDS[via]
            self._streams_wanted[kind] = REPORT_STREAMS[kind]

    def connect(self, timeout_s: float = 30.0) -> None:
        """Connect the engine's link (SITL's clock starts) and the backend's own."""
        self._sock = self.process.connect(timeout_s=timeout_s)
        self._sock.setblocking(False)
        self._connected_wall = self._last_byte_wall = time.monotonic()
        self._live = True
        self._own = self.process.connect(timeout_s, port=self.process.ports.serial2_tcp_port)
        self._own.setblocking(False)
        self._duties()

    def drain(self) -> None:
        """Read what SITL sent meanwhile, before the run: while another vehicle is flown up.

        Its own streams keep the clock and truth current (reading a backlog of minutes
        later would take the run's first wall second, while the last vehicle flown up
        flies on); what came on the engine's link is dropped: the engine's adapter starts
        with the run.
        """
        self._live = False
        while self._read(0.0):
            pass
        self._duties()
        self._held.clear()

    def start_run_here(self) -> None:
        """Make the SITL vehicle's current time the run's time 0 (after a pre-flight).

        What SITL sent the engine's link before is dropped unparsed, not handed to the
        engine's adapter at its first step: after a pre-flight that is minutes of SITL's
        own streams, which took the adapter 0.7 s of wall time to parse (7 s of SITL's, a
        plane handed over 130 m on) before the run's first step was over. From here on
        the engine's link is parsed and held (:meth:`_hold`).
        """
        self._live = False
        if self._sock is not None and self._own is not None:
            while self._read(0.0):
                pass
        self._held.clear()
        self._link_parser = _link_parser()  # no frame begun before time 0
        self._link_stamp_s = None
        self._live = True
        self._offset_s = self.clock_s or 0.0
        self._want_s = self._offset_s  # the truth at the run's time 0 until its first step
        self._sent_clock_s = None  # the engine's link is silent until the run starts

    def step(self, t_s: float, dt_s: float) -> bytes:
        """Wait until SITL has passed the run's time ``t_s``; what it sent since the last step.

        Several SITL processes run side by side, each on its own clock; the run waits
        for the slowest, so another may be ahead of it. What that one sent meanwhile
        is all taken and returned.

        Raises:
            SitlError: SITL exited, or sent nothing for :data:`STALL_WALL_S`.
        """
        if self.gps_error is not None and t_s >= self._next_gps_s:
            self._next_gps_s = t_s + GPS_ERROR_EVERY_S
            self._send_gps_error(t_s)
        want_s = t_s + self._offset_s
        # What SITL sent while the engine worked: how far past the run's time it is now.
        while self._read(0.0):
            pass
        if self._clock_s is not None:
            self.behind_s = max(0.0, self._clock_s - want_s)
            if self.behind_s > self.pace.behind_s:
                self.pace.behind_s, self.pace.behind_at_s = self.behind_s, t_s
        while (clock_s := self.clock_s) is None or clock_s < want_s:
            self._duties()
            wait_wall_s = 0.05 if clock_s is None else (want_s - clock_s) / self.speedup
            self._read(min(0.05, max(0.001, wait_wall_s)))
        # A SITL ahead of the run (the engine fell behind it, or waited for a slower one)
        # has sent more: that is held until the run's time reaches it. Handed over at
        # once, a second or three of SITL's messages came in one tick, and nothing in the
        # ticks the run took to catch up: the adapter heard its autopilot silent for its
        # timeout and lost it (a campaign's early autopilot_lost).
        while self._read(0.0):
            pass
        self._want_s = want_s
        return self._release(want_s)

    def _release(self, until_s: float) -> bytes:
        """The held frames SITL sent by its time ``until_s``, in order; parsed in :attr:`heard`."""
        frames: list[bytes] = []
        self.heard = []
        held = self._held
        while held and held[0][0] <= until_s:
            _, frame, msg = held.popleft()
            frames.append(frame)
            self.heard.append(msg)
        return b"".join(frames)

    @property
    def speedup(self) -> float:
        """SITL's speed-up now: its launch's, or lower once the run slowed it down."""
        return self._speedup

    def set_speedup(self, speedup: float, t_s: float) -> None:
        """Run SITL at ``speedup`` from now on (its ``SIM_SPEEDUP``); recorded in the pace.

        SITL takes a new speed-up while it runs (measured: 10x to 2x within half a wall
        second). ArduPilot's loops and SITL's physics keep their rates against SITL's own
        clock; only that clock runs slower against the wall.
        """
        self._speedup = float(speedup)
        self.pace.speedups.append((t_s, self._speedup))
        self._mav.param_set_send(
            self._target[0], self._target[1], b"SIM_SPEEDUP", self._speedup,
            mavlink2.MAV_PARAM_TYPE_REAL32,
        )  # fmt: skip
        self._flush()

    def _send_gps_error(self, t_s: float) -> None:
        """Give SITL's GPS the error at ``t_s``, when it moved by :data:`GPS_ERROR_STEP_M`."""
        assert self.gps_error is not None
        north_m, east_m = self.gps_error.offset_m(t_s)
        sent_n, sent_e = self._gps_sent_m
        if math.hypot(north_m - sent_n, east_m - sent_e) < GPS_ERROR_STEP_M and t_s > 0.0:
            return
        self._gps_sent_m = (north_m, east_m)
        per_deg_lon = _M_PER_DEG_LAT * math.cos(math.radians(self.origin.lat_deg))
        for name, value in (
            ("SIM_GPS1_GLTCH_X", north_m / _M_PER_DEG_LAT),
            ("SIM_GPS1_GLTCH_Y", east_m / per_deg_lon),
        ):
            # Sent at once, not queued with the set-up's parameters (those are retried
            # once a wall second, too slow for a glitch); the next update repeats it.
            self._mav.param_set_send(
                self._target[0], self._target[1], name.encode("ascii"), float(value),
                mavlink2.MAV_PARAM_TYPE_REAL32,
            )  # fmt: skip
        self._flush()

    def send(self, data: bytes, t_s: float) -> None:
        """Bytes to SITL (the engine's adapter, or the simulated pilot)."""
        if data and self._sock is not None:
            now_s = self._clock_s
            last_s = self._sent_clock_s
            if now_s is not None and last_s is not None and now_s - last_s > self.pace.silent_s:
                self.pace.silent_s, self.pace.silent_at_s = now_s - last_s, t_s
            self._sent_clock_s = now_s
            self._sock.setblocking(True)
            try:
                self._sock.sendall(data)
            except OSError as exc:
                raise self.process.failure(f"the MAVLink connection broke ({exc})") from exc
            finally:
                self._sock.setblocking(False)

    def truth(self) -> Truth:
        """The simulator's true state (SIM_STATE), with VFR_HUD's airspeed and throttle.

        SITL's at the run's time, as what the engine hears (:meth:`step`): a state entered
        on what SITL said is recorded where SITL was when it said it (a copter's "landed"
        was recorded 9 m up when the engine heard SITL's present and the truth was taken
        at the run's time). SITL's latest before the run and when the run has caught up.
        """
        want_s = self._want_s
        if want_s is None or not self._truths or self._truths[-1][0] <= want_s:
            return self._truth
        for stamp_s, truth in reversed(self._truths):
            if stamp_s <= want_s:
                return truth
        return self._truths[0][1]

    def flight_status(self) -> tuple[bool, str]:
        """Arming and mode from SITL's latest HEARTBEAT on the backend's own link.

        ArduPilot sends HEARTBEAT on every MAVLink channel once a second; before the
        first, the vehicle is disarmed in no known mode (``""``). A mode the profile
        does not name reads ``mode N``.
        """
        beat = self._latest.get("HEARTBEAT")
        if beat is None:
            return False, ""
        armed = bool(int(beat.base_mode) & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)
        number = int(beat.custom_mode)
        return armed, self._mode_names.get(number, f"mode {number}")

    def rc_inputs(self) -> tuple[int, ...]:
        """SITL's latest RC_CHANNELS (it does not wait: a tick's are :meth:`report_later`'s)."""
        return self._rc

    def servo_outputs(self) -> tuple[int, ...]:
        """SITL's latest SERVO_OUTPUT_RAW (it does not wait, as :meth:`rc_inputs`)."""
        return self._servos

    def report_later(self, via: str, number: int, want_us: int | None) -> LaterReport:
        """This tick's RC input or servo output, as SITL will report it: call after the tick.

        Returned at once and resolved (its ``pwm_us`` set) as SITL's reports arrive, while
        the run goes on (:meth:`step`), or at the end by :meth:`settle_reports`.

        Args:
            via: ``rc_override`` (RC_CHANNELS) or ``servo`` (SERVO_OUTPUT_RAW).
            number: The RC channel or servo output, from 1.
            want_us: What the engine asked for on it and still holds (its RC override, the
                last DO_SET_SERVO), None when it asks for nothing there.
        """
        if self._sock is not None and self._own is not None:
            while self._read(0.0):  # SITL's clock now, not when the engine last read it
                pass
        report = LaterReport(REPORT_KINDS[via], number - 1, self.clock_s or 0.0, want_us)
        self._later.append(report)
        return report

    def wait_shown(self) -> None:
        """Before a tick: let SITL show what the last tick asked for, if it has not yet.

        A run on time finds it shown already (40 ms after the command at the median,
        100 ms at worst, against a tick of 100 ms at 10 Hz). A run late by more than a
        tick would send two ticks' commands at once, and ArduPilot takes only the second:
        the first would never reach the autopilot's inputs, and the check comparing every
        pulse width would fail for the engine's lateness rather than the mission's. So the
        tick waits until the value shows, :data:`REPORT_AFTER_S` at most, and not at all on
        a channel where SITL's last report did not show what was asked (an override
        ArduPilot refuses: waiting would only put the run behind, as it did before).
        """
        if not self._later:
            return
        last_s = self._later[-1].after_s
        waiting = [
            r
            for r in self._later
            if r.want_us is not None
            and r.after_s >= last_s
            and self._shows.get((r.kind, r.index), True)
        ]
        until_s = last_s + REPORT_AFTER_S
        while waiting and (self._clock_s or 0.0) < until_s:
            self._duties()
            self._read(0.01)
            waiting = [r for r in waiting if r.pwm_us is None]

    def settle_reports(self) -> None:
        """Read SITL until every :meth:`report_later` is resolved (the run's end).

        Each is resolved by a report :data:`REPORT_AFTER_S` after its tick at the latest,
        a fraction of a wall second. Should SITL stop sending that report, those still
        open a second of its clock later take its last one, so that the run ends.
        """
        if not self._later:
            return
        until_s = self._later[-1].after_s + REPORT_AFTER_S + 1.0
        while self._later and self._sock is not None and (self._clock_s or 0.0) < until_s:
            self._duties()
            self._read(0.05)
        for report in self._later:
            values = self._rc if report.kind == "RC_CHANNELS" else self._servos
            report.pwm_us = values[report.index] if report.index < len(values) else 0
        self._later.clear()

    def set_pilot(self, pwm_us: Mapping[int, int]) -> None:
        """The pilot's sticks and switches, to SITL's RC input (its radio receiver)."""
        for channel, value in pwm_us.items():
            if 1 <= channel <= 16:
                self._pilot_us[channel - 1] = int(value)
        self.process.rc_input(self._pilot_us)

    def close(self) -> None:
        """Close the connections and stop SITL."""
        for sock in (self._sock, self._own):
            if sock is not None:
                sock.close()
        self._sock = self._own = None
        self.process.stop()

    # -- what the backend does itself -------------------------------------------------------

    def write(self, data: bytes) -> None:
        """Where the backend's own pymavlink encoder puts its frames."""
        self._out += data

    def _flush(self) -> None:
        """Send what the backend's own encoder wrote, on its own link."""
        if self._out and self._own is not None:
            data, self._out = bytes(self._out), bytearray()
            self._own.setblocking(True)
            try:
                self._own.sendall(data)
            except OSError as exc:
                raise self.process.failure(f"the MAVLink connection broke ({exc})") from exc
            finally:
                self._own.setblocking(False)

    def _duties(self) -> None:
        """Ask for the backend's streams until they come; set the parameters until echoed."""
        now = time.monotonic()
        if now >= self._next_request_wall:
            self._next_request_wall = now + REQUEST_RETRY_WALL_S
            system, component = self._target
            for name, interval_us in self._streams_wanted.items():
                if name not in self._streams_seen:
                    msg_id = int(getattr(mavlink2, f"MAVLINK_MSG_ID_{name}"))
                    self._mav.command_long_send(
                        system, component, mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, 0,
                        msg_id, interval_us, 0, 0, 0, 0, 0,
                    )  # fmt: skip
        if self._params_due and now >= self._next_param_wall:
            self._next_param_wall = now + PARAM_RETRY_WALL_S
            for name, value in list(self._params_due.items()):
                tries = self._param_tries.get(name, 0) + 1
                if tries > 5:  # SITL has no such parameter (it never answers those)
                    del self._params_due[name]
                    continue
                self._param_tries[name] = tries
                self._mav.param_set_send(
                    self._target[0], self._target[1], name.encode("ascii"), float(value),
                    mavlink2.MAV_PARAM_TYPE_REAL32,
                )  # fmt: skip
        self._flush()

    def _read(self, timeout_s: float) -> bool:
        """Read what SITL sent on both links (waiting up to ``timeout_s``); False when nothing.

        The engine's link is kept as bytes for :meth:`step`; the backend's own is parsed.
        """
        if self._sock is None or self._own is None:
            raise SitlError("the SITL backend is not connected")
        ready, _, _ = select.select([self._sock, self._own], [], [], timeout_s)
        if not ready:
            if time.monotonic() - self._last_byte_wall > STALL_WALL_S:
                self.process.raise_if_exited()
                raise self.process.failure(f"sent nothing for {STALL_WALL_S:g} s")
            return False
        for sock in ready:
            try:
                data = sock.recv(65536)
            except BlockingIOError:
                continue
            except OSError as exc:
                raise self.process.failure(f"the MAVLink connection broke ({exc})") from exc
            if not data:
                self.process.raise_if_exited()
                raise self.process.failure("closed the MAVLink connection")
            self._last_byte_wall = time.monotonic()
            if sock is self._sock:
                if self._live:
                    self._hold(data)
            else:
                for msg in self._parser.parse_buffer(data) or []:
                    self._note(msg)
        return True

    def _hold(self, data: bytes) -> None:
        """Queue what came on the engine's link, each frame with SITL's time it was sent.

        A frame's time is its own ``time_boot_ms``, or that of the last stamped frame
        before it (HEARTBEAT, STATUSTEXT and the like carry none; SITL sends its streams
        interleaved, so that is at most a stream period early), or SITL's clock as read
        before its first stamped frame. Bytes the parser could not frame go with the
        frames around them: the adapter hears every byte, in order, as it came.
        """
        for msg in self._link_parser.parse_buffer(data) or []:
            if msg.get_type() == "BAD_DATA":
                frame = bytes(msg.data)
            else:
                frame = bytes(msg.get_msgbuf())
                boot_ms = getattr(msg, "time_boot_ms", None)
                if isinstance(boot_ms, int) and boot_ms > 0:
                    self._link_stamp_s = boot_ms / 1000.0
            stamp_s = self._link_stamp_s if self._link_stamp_s is not None else self.clock_s
            self._held.append((stamp_s or 0.0, frame, msg))

    def _note(self, msg: Any) -> None:
        if (msg.get_srcSystem(), msg.get_srcComponent()) != self._target:
            return
        kind = msg.get_type()
        if kind == "BAD_DATA":
            return
        self._latest[kind] = msg
        if kind == "HEARTBEAT":
            self._beats += 1
        boot_ms = getattr(msg, "time_boot_ms", None)
        if isinstance(boot_ms, int) and boot_ms > 0:
            clock_s = boot_ms / 1000.0
            if self._clock_s is None or clock_s > self._clock_s:
                self._clock_s = clock_s
        if kind in self._streams_wanted and kind not in self._streams_seen:
            self._stream_arrived(kind)
        if kind == "SIM_STATE":
            self._truth = self._truth_from(msg)
            self._truths.append((self._clock_s or 0.0, self._truth))
        elif kind == "RC_CHANNELS":
            self._rc = tuple(
                0 if v == 65535 else int(v)
                for v in (getattr(msg, f"chan{i}_raw") for i in range(1, 19))
            )
            if isinstance(boot_ms, int):
                self._match(kind, boot_ms / 1000.0, self._rc)
        elif kind == "SERVO_OUTPUT_RAW":
            self._servos = tuple(int(getattr(msg, f"servo{i}_raw")) for i in range(1, 17))
            # Stamped in microseconds since boot (uint32: it wraps every 71.6 minutes),
            # not time_boot_ms: unwrapped to the one nearest SITL's clock.
            usec_s = int(msg.time_usec) / 1e6
            turns = round(((self._clock_s or 0.0) - usec_s) / _USEC_WRAP_S)
            self._match(kind, usec_s + turns * _USEC_WRAP_S, self._servos)
        elif kind == "PARAM_VALUE":
            name = str(msg.param_id)
            due = self._params_due.get(name)
            # Echoed only with the value set: an answer with the old value (a request of
            # ours answered before SITL took the set) is not an echo, and set again.
            if due is not None and _same_float32(float(msg.param_value), due):
                del self._params_due[name]

    def _stream_arrived(self, kind: str) -> None:
        """Count a wanted stream's message; it is seen once it comes at its interval.

        Not at its first message: ArduPilot sends some of them at its own default rate
        (SRn_*, once a second) until it takes the request, and it loses requests made
        before it is ready. A stream taken as seen at its first message was never asked
        again, and in one run in three the clock came once a second: the run then
        advanced in jumps of a second of SITL's time, every tick's commands sent at once.
        """
        clock_s = self._clock_s
        if clock_s is None:
            return
        since_s, count = self._stream_counts.get(kind, (clock_s, 0))
        count += 1
        span_s = clock_s - since_s
        if span_s < STREAM_CHECK_S:
            self._stream_counts[kind] = (since_s, count)
            return
        interval_s = self._streams_wanted[kind] / 1e6
        if count - 1 >= 0.5 * span_s / interval_s:
            self._streams_seen.add(kind)
            self._stream_counts.pop(kind, None)
        else:  # too slow: count again (the request is repeated meanwhile)
            self._stream_counts[kind] = (clock_s, 1)

    def _match(self, kind: str, boot_s: float, values: tuple[int, ...]) -> None:
        """Resolve the :meth:`report_later` requests this report (made at ``boot_s``) answers."""
        if not self._later:
            return
        pending = []
        for r in self._later:
            if r.kind == kind and r.take(boot_s, values):
                if r.want_us is not None:
                    self._shows[(kind, r.index)] = r.pwm_us == r.want_us
            else:
                pending.append(r)
        self._later = pending

    def _truth_from(self, msg: Any) -> Truth:
        return self._truth_at(
            float(msg.lat_int) / 1e7, float(msg.lon_int) / 1e7, float(msg.alt),
            (float(msg.vn), float(msg.ve), float(msg.vd)),
            (float(msg.roll), float(msg.pitch), float(msg.yaw)),
        )  # fmt: skip

    def _truth_at(
        self,
        lat: float,
        lon: float,
        alt_m: float,
        velocity_ned_m_s: tuple[float, float, float],
        attitude_rad: tuple[float, float, float],
    ) -> Truth:
        """A true state in the mission's local frame (flat earth around the origin)."""
        origin = self.origin
        north = (lat - origin.lat_deg) * _M_PER_DEG_LAT
        east = (lon - origin.lon_deg) * _M_PER_DEG_LAT * math.cos(math.radians(origin.lat_deg))
        up = alt_m - origin.alt_amsl_m
        if self.firmware == "ardurover":
            up = 0.0  # a rover is on the ground; SITL's terrain height is not the origin's
        vn, ve, vd = velocity_ned_m_s
        roll, pitch, yaw_rad = attitude_rad
        ground = math.hypot(vn, ve)
        yaw = math.degrees(yaw_rad)
        hud = self._latest.get("VFR_HUD")
        return Truth(
            north_m=north,
            east_m=east,
            up_m=up,
            lat_deg=lat,
            lon_deg=lon,
            velocity_north_m_s=vn,
            velocity_east_m_s=ve,
            climb_rate_m_s=-vd,
            roll_deg=math.degrees(roll),
            pitch_deg=math.degrees(pitch),
            yaw_deg=yaw,
            ground_speed_m_s=ground,
            heading_deg=yaw % 360.0,
            airspeed_m_s=float(hud.airspeed) if hud is not None else ground,
            throttle_pct=float(hud.throttle) if hud is not None else 0.0,
        )
