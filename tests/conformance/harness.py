"""The conformance harness: one test ground station, two kinds of autopilot behind it.

A :class:`Peer` is a minimal ground station (pymavlink's ardupilotmega dialect,
MAVLink 2, system 255, component 190) that talks MAVLink bytes to the autopilot
under test through a link:

- :class:`SimLink`: the engine's simulated ArduPilot, built from a tiny mission
  exactly as ``clark dry-run`` builds it (see :func:`build_sim_link`), on a
  virtual clock: every pump steps the vehicle model by the dry run's physics step
  and collects what the autopilot emits, so a scenario runs in milliseconds.
- :class:`SitlLink`: real ArduPilot SITL (:mod:`clark_engine.sitl.launcher`) over TCP,
  with wall-clock deadlines derived from the vehicle-time ones and the speed-up.

Scenarios are written once, in the autopilot's time: ``now_s`` is the latest
``time_boot_ms`` the autopilot reported (the ground station asks for SYSTEM_TIME
at 10 Hz as its clock, since ArduPilot's default streams may be as slow as 1 Hz),
and every wait is measured against it, never against the wall clock.
"""

from __future__ import annotations

import functools
import math
import os
import select
import socket
import time
from collections import deque
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.dryrun.engine import PHYSICS_STEP_S
from clark_engine.dryrun.world import build_vehicle
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.model import Mission
from clark_engine.runtime.config import config_from_dict
from clark_engine.sim.ardupilot.autopilot import SimAutopilot
from clark_engine.sim.ardupilot.vehicle_model import VehicleModel
from clark_engine.sitl.errors import SitlError
from clark_engine.sitl.launcher import ENV_SITL, Home, SitlInstall, SitlProcess
from clark_engine.validation import validate_file

ROOT = Path(__file__).resolve().parents[2]
MISSIONS = Path(__file__).resolve().parent / "missions"
KINDS = ("rover", "copter", "plane")
SIM_BACKENDS = tuple(f"sim-{kind}" for kind in KINDS)
SITL_BACKENDS = tuple(f"sitl-{kind}" for kind in KINDS)
BACKENDS = SIM_BACKENDS + SITL_BACKENDS
AGENT = "vehicle"
"""The vehicle's agent name in every mission under missions/."""

GCS_SYSTEM_ID = 255
FORCE = 21196
"""MAV_CMD_COMPONENT_ARM_DISARM param2 that skips ArduPilot's checks."""
GCS_COMPONENT_ID = 190
CLOCK_INTERVAL_US = 100_000
"""SYSTEM_TIME interval the ground station asks for: its clock's resolution."""

SITL_SPEEDUP = float(os.environ.get("CLARK_SITL_SPEEDUP_TESTS", "10"))
"""Speed-up of the SITL backends (env CLARK_SITL_SPEEDUP_TESTS)."""

WALL_SLACK_S = 20.0
"""Wall seconds added to every SITL wait (process scheduling on a shared machine)."""
WALL_FACTOR = 3.0
"""SITL may run this many times slower than its speed-up before a wait gives up."""

STATUS_MESSAGES = ("SYS_STATUS", "GPS_RAW_INT", "EKF_STATUS_REPORT")
"""Asked for at 1 Hz on connecting (see :meth:`Peer.start`)."""

_RECENT = 12  # messages quoted when a wait fails


# -- the SITL install -------------------------------------------------------------------------


def find_sitl() -> tuple[SitlInstall | None, str]:
    """The SITL launcher for the tests ($CLARK_SITL, else ROOT/../shared/ardupilot-sitl).

    Returns:
        The install, or None and the reason the SITL backends skip.
    """
    default = ROOT.parent / "shared" / "ardupilot-sitl"
    if not os.environ.get(ENV_SITL) and not default.is_dir():
        return None, (
            f"no ArduPilot SITL: set {ENV_SITL} to the folder with the `sitl` launcher "
            f"({default} is absent)"
        )
    try:
        # $CLARK_SITL when set (find() reads it), else the shared folder.
        return SitlInstall.find(None if os.environ.get(ENV_SITL) else str(default)), ""
    except SitlError as exc:
        return None, f"no usable ArduPilot SITL: {exc}"


SITL_INSTALL, SITL_SKIP_REASON = find_sitl()


# -- the vehicles --------------------------------------------------------------------------


@dataclass(frozen=True)
class VehicleSpec:
    """One vehicle kind as its mission file resolves it."""

    kind: str
    path: Path
    mission: Mission

    @property
    def autopilot(self) -> Mapping[str, Any]:
        """The resolved autopilot profile."""
        return self.mission.agents[AGENT].hardware.parts["autopilot"]

    @property
    def modes(self) -> Mapping[str, int]:
        """Mode name -> custom_mode number, from the profile."""
        modes: Mapping[str, int] = self.autopilot["modes"]
        return modes

    @property
    def system_id(self) -> int:
        """The autopilot's MAVLink system id."""
        return int((self.autopilot.get("mavlink") or {}).get("system_id", 1))

    @property
    def home(self) -> Home:
        """The mission origin, where SITL boots too."""
        origin = self.mission.origin
        return Home(origin.lat_deg, origin.lon_deg, origin.alt_amsl_m, 0.0)


@functools.cache
def vehicle_spec(kind: str) -> VehicleSpec:
    """Validate missions/<kind>.yaml (as ``clark validate`` does) and resolve it."""
    path = MISSIONS / f"{kind}.yaml"
    result = validate_file(path)
    if result.mission is None:
        problems = "; ".join(str(f) for f in result.errors)
        raise AssertionError(f"{path} is not a valid mission: {problems}")
    return VehicleSpec(kind, path, result.mission)


# -- links -----------------------------------------------------------------------------------


class Link(Protocol):
    """Bytes to and from the autopilot under test."""

    describe: str

    def send(self, data: bytes) -> None:
        """Hand bytes to the autopilot."""

    def pump(self) -> bytes:
        """The next bytes the autopilot emitted (may be empty); advances virtual time."""

    def pending(self) -> bytes:
        """Bytes that already arrived, without waiting or advancing virtual time."""

    @property
    def clock_s(self) -> float | None:
        """The autopilot's time when the link knows it exactly (virtual time), else None."""

    def wall_budget_s(self, vehicle_s: float) -> float:
        """Wall seconds a wait of ``vehicle_s`` vehicle seconds may take."""

    def check(self) -> None:
        """Raise if the autopilot behind the link is gone (with why)."""

    def close(self) -> None:
        """End the link (and what it started)."""


class SimLink:
    """The engine's simulated ArduPilot on a virtual clock, stepped by :meth:`pump`."""

    def __init__(self, model: VehicleModel, autopilot: SimAutopilot, describe: str) -> None:
        self.model = model
        self.autopilot = autopilot
        self.describe = describe
        self._steps = 0
        self._t_s = 0.0
        self._started = False

    @property
    def clock_s(self) -> float | None:
        return self._t_s

    def send(self, data: bytes) -> None:
        self.autopilot.receive(data, self._t_s)

    def pump(self) -> bytes:
        # As DryRun._physics: at 0 the autopilot speaks without a step; then every
        # PHYSICS_STEP_S the model steps and the autopilot emits what is due.
        if self._started:
            self._steps += 1
            self._t_s = self._steps * PHYSICS_STEP_S
            self.model.step(PHYSICS_STEP_S)
        self._started = True
        return self.autopilot.advance(self._t_s)

    def pending(self) -> bytes:
        return b""  # nothing happens between pumps on a virtual clock

    def wall_budget_s(self, vehicle_s: float) -> float:
        return math.inf  # the virtual clock always moves on

    def check(self) -> None:
        pass

    def close(self) -> None:
        pass


def build_sim_link(spec: VehicleSpec) -> SimLink:
    """The simulated vehicle and autopilot, built by the dry run's own :func:`build_vehicle`.

    The same function ``clark dry-run`` builds every vehicle with (the agent's
    compiled channels, hardware parts, the mission's origin, ``sim`` settings and
    seed), but without the engine's MAVLink adapter and pilot: the test ground
    station is the only one talking.
    """
    mission = spec.mission
    agent = mission.agents[AGENT]
    config = config_from_dict(agent_config(mission, agent))
    backend, _pilot = build_vehicle(mission, agent, config, int(mission.sim.get("seed", 0)))
    return SimLink(backend.model, backend.autopilot, f"simulated {spec.autopilot['firmware']}")


class SitlLink:
    """Real ArduPilot SITL over its MAVLink TCP port; stops the process on close."""

    def __init__(self, process: SitlProcess, sock: socket.socket) -> None:
        self.process = process
        self.sock = sock
        self.sock.setblocking(False)
        self.describe = f"ArduPilot SITL {process.vehicle} (instance {process.instance})"

    @classmethod
    def start(cls, spec: VehicleSpec) -> SitlLink:
        """Boot a fresh SITL vehicle of ``spec``'s kind at its home and connect to it."""
        if SITL_INSTALL is None:
            pytest.skip(SITL_SKIP_REASON)
        process = SitlProcess(SITL_INSTALL, spec.kind, spec.home, speedup=SITL_SPEEDUP)
        process.start()
        try:
            return cls(process, process.connect(timeout_s=30.0))
        except BaseException:
            process.stop()
            raise

    @property
    def clock_s(self) -> float | None:
        return None

    def send(self, data: bytes) -> None:
        self.sock.setblocking(True)
        try:
            self.sock.sendall(data)
        except OSError as exc:
            self.process.raise_if_exited()
            raise self.process.failure(f"refused a write ({exc})") from exc
        finally:
            self.sock.setblocking(False)

    def pump(self) -> bytes:
        return self._read(0.05)

    def pending(self) -> bytes:
        return self._read(0.0)

    def _read(self, wait_s: float) -> bytes:
        ready, _, _ = select.select([self.sock], [], [], wait_s)
        if not ready:
            return b""
        try:
            data = self.sock.recv(1 << 16)
        except BlockingIOError:
            return b""
        except OSError as exc:
            self.process.raise_if_exited()
            raise self.process.failure(f"dropped the connection ({exc})") from exc
        if not data:
            self.process.raise_if_exited()
            raise self.process.failure("closed the connection")
        return data

    def wall_budget_s(self, vehicle_s: float) -> float:
        return vehicle_s / self.process.speedup * WALL_FACTOR + WALL_SLACK_S

    def check(self) -> None:
        self.process.raise_if_exited()

    def close(self) -> None:
        try:
            self.sock.close()
        finally:
            self.process.stop()


# -- the ground station ------------------------------------------------------------------------


@dataclass(frozen=True)
class StatusText:
    """A STATUSTEXT the autopilot sent (its chunks joined, when it sent several).

    Attributes:
        time_s: When it (its last chunk) was seen.
        severity: MAV_SEVERITY.
        text: The text.
        place: Its last chunk's place in :attr:`Peer.history` (compare with a mark).
    """

    time_s: float
    severity: int
    text: str
    place: int = 0


STATUSTEXT_CHUNK = 50
"""Characters in one STATUSTEXT: ArduPilot sends a longer text as several with one id."""


Awaited = str | Callable[[Any], bool]


def _describe(what: Awaited, where: Callable[[Any], bool] | None, describe: str | None) -> str:
    if describe:
        return describe
    name = what if isinstance(what, str) else (what.__doc__ or getattr(what, "__name__", "?"))
    if where is not None:
        name += f" where {where.__doc__ or getattr(where, '__name__', '?')}"
    return name


def _short(msg: Any) -> str:
    fields = msg.to_dict()
    fields.pop("mavpackettype", None)
    text = ", ".join(f"{k}={v}" for k, v in fields.items())
    return f"{msg.get_type()}({text[:160]})"


@dataclass(repr=False)
class Peer:
    """A test ground station talking to one autopilot through a link.

    Attributes:
        link: The autopilot behind it.
        backend: ``sim-rover`` ... ``sitl-plane``.
        spec: The vehicle kind's mission and profile.
        statustexts: Every STATUSTEXT seen (time, severity, text), in order.
        history: Every message from the autopilot with the time it was seen at.
    """

    link: Link
    backend: str
    spec: VehicleSpec
    statustexts: list[StatusText] = field(default_factory=list)
    history: list[tuple[float, Any]] = field(default_factory=list)

    def __repr__(self) -> str:
        return f"Peer({self.backend}, t={self._now_s:.3f} s)"

    def __post_init__(self) -> None:
        self._mav = mavlink2.MAVLink(None, srcSystem=GCS_SYSTEM_ID, srcComponent=GCS_COMPONENT_ID)
        self._parser = mavlink2.MAVLink(None)
        self._parser.robust_parsing = True
        self._now_s = 0.0
        self._heartbeat_due_s = 0.0
        self._recent: deque[tuple[float, Any]] = deque(maxlen=_RECENT)
        self._times: dict[int, float] = {}
        self.last: dict[str, Any] = {}
        """Message type -> the latest message of that type."""
        self.subscribed: dict[str, int] = {}
        """Status message -> MAV_RESULT of the request for it at 1 Hz (see :meth:`start`)."""
        self.heartbeat_from: tuple[int, ...] = (GCS_SYSTEM_ID,)
        """System ids this ground station sends a HEARTBEAT as, once a second each (empty:
        silent, as a ground station or mission computer that died)."""
        self.heartbeat_sent_s: dict[int, float] = {}
        """System id -> the autopilot's time when its last HEARTBEAT was sent."""
        self._senders: dict[int, Any] = {GCS_SYSTEM_ID: self._mav}
        self._chunks: dict[int, list[str]] = {}  # STATUSTEXT id -> the chunks so far

    # -- time --------------------------------------------------------------------------

    @property
    def now_s(self) -> float:
        """The autopilot's boot time: the latest time_boot_ms it reported, in seconds."""
        return self._now_s

    @property
    def kind(self) -> str:
        """``rover``, ``copter`` or ``plane``."""
        return self.spec.kind

    def mark(self) -> int:
        """The present place in the history, for ``wait_for(since=...)`` and :meth:`texts_since`.

        What already arrived is read first, so that the mark is now, not some time ago.
        """
        self.sync()
        return len(self.history)

    def sync(self) -> None:
        """Read every byte that already arrived, so that :attr:`now_s` is the present.

        A SITL vehicle runs on between scenarios while nobody reads it; what it said
        meanwhile waits in the socket. Commands are sent after it is read, so that
        their deadlines count from the autopilot's present.
        """
        while True:
            data = self.link.pending()
            if not data:
                return
            self._take(data)

    def time_of(self, msg: Any) -> float:
        """When ``msg`` was seen, in the autopilot's time."""
        return self._times[id(msg)]

    # -- sending -----------------------------------------------------------------------

    def send(self, msg: Any) -> None:
        """Encode a pymavlink message as this ground station and send it (after a sync)."""
        self.sync()
        self.link.send(msg.pack(self._mav))

    def start(self, within_s: float = 30.0) -> Peer:
        """Hear the first HEARTBEAT, ask for the clock, wait for the streams, ask for status.

        As a ground station does on connecting: SYSTEM_TIME at 10 Hz is the clock
        (required). It is asked for after the first HEARTBEAT, since every firmware
        loses a stream request that arrives before that (test_streams.py), and waited
        for: it comes once ArduPilot is ready ("ArduPilot Ready", 1.8-2.5 s after
        power-on), so a scenario gets a vehicle whose streams are alive. Then
        SYS_STATUS, GPS_RAW_INT and EKF_STATUS_REPORT at 1 Hz tell when the vehicle
        gets ready to arm (ArduCopter streams none of them by default). The answers to
        those three are kept in :attr:`subscribed`, not asserted: scenarios judge them.
        """
        self.wait_for("HEARTBEAT", within_s)
        ack = self.message_interval("SYSTEM_TIME", CLOCK_INTERVAL_US, within_s=10)
        assert ack.result == mavlink2.MAV_RESULT_ACCEPTED, f"clock request refused: {ack}"
        self.wait_for("SYSTEM_TIME", within_s, describe="the clock (SYSTEM_TIME): no streams")
        for name in STATUS_MESSAGES:
            self.subscribed[name] = self.message_interval(name, 1_000_000).result
        return self

    def message_interval(self, name: str, interval_us: int, within_s: float = 5.0) -> Any:
        """MAV_CMD_SET_MESSAGE_INTERVAL for a message type; returns the COMMAND_ACK."""
        msg_id = getattr(mavlink2, f"MAVLINK_MSG_ID_{name}")
        return self.command_long(
            mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, interval_us, within_s=within_s
        )

    def command_long(self, command: int, *params: float, within_s: float = 5.0) -> Any:
        """Send COMMAND_LONG (params 1..7, missing ones 0); return its COMMAND_ACK.

        Waits for the acknowledgement of this command number (ArduPilot may send
        IN_PROGRESS first; that counts as the answer too).
        """
        values = [float(p) for p in params] + [0.0] * (7 - len(params))
        self.send(self._mav.command_long_encode(self.spec.system_id, 1, command, 0, *values[:7]))

        def acks_it(msg: Any) -> bool:
            return bool(msg.command == command)

        acks_it.__doc__ = f"command == {command}"
        return self.wait_for("COMMAND_ACK", within_s, where=acks_it)

    def set_mode(self, name: str, within_s: float = 5.0) -> Any:
        """MAV_CMD_DO_SET_MODE to the profile's mode ``name``; returns the COMMAND_ACK."""
        return self.set_mode_number(self.spec.modes[name], within_s)

    def set_mode_number(self, custom_mode: int, within_s: float = 5.0) -> Any:
        """MAV_CMD_DO_SET_MODE to a custom_mode number; returns the COMMAND_ACK."""
        return self.command_long(
            mavlink2.MAV_CMD_DO_SET_MODE,
            mavlink2.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            custom_mode,
            within_s=within_s,
        )

    def arm(self, force: bool = False, within_s: float = 5.0) -> Any:
        """MAV_CMD_COMPONENT_ARM_DISARM to arm (forced: ArduPilot's magic 21196)."""
        return self.command_long(
            mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 1, FORCE if force else 0, within_s=within_s
        )

    def disarm(self, force: bool = False, within_s: float = 5.0) -> Any:
        """MAV_CMD_COMPONENT_ARM_DISARM to disarm (forced: even in the air)."""
        return self.command_long(
            mavlink2.MAV_CMD_COMPONENT_ARM_DISARM, 0, FORCE if force else 0, within_s=within_s
        )

    def wait_ready(self, within_s: float = 90.0) -> None:
        """Wait until the EKF has an absolute position and the pre-arm checks pass.

        Every firmware is then ready to arm in every mode that allows arming (about
        42 s after boot on SITL; at once on a vehicle that already is).
        """

        def positioned(msg: Any) -> bool:
            """the EKF has an absolute horizontal position"""
            return bool(msg.flags & mavlink2.EKF_POS_HORIZ_ABS)

        def prearm_ok(msg: Any) -> bool:
            """the pre-arm checks pass"""
            return bool(msg.onboard_control_sensors_health & mavlink2.MAV_SYS_STATUS_PREARM_CHECK)

        self.wait_for("EKF_STATUS_REPORT", within_s, where=positioned)
        self.wait_for("SYS_STATUS", within_s, where=prearm_ok)

    def heartbeat(self, within_s: float = 2.0) -> Any:
        """The next HEARTBEAT (one sent after everything seen so far)."""
        return self.wait_for("HEARTBEAT", within_s)

    def is_armed(self, within_s: float = 2.0) -> bool:
        """Whether the next HEARTBEAT says armed."""
        return bool(self.heartbeat(within_s).base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED)

    def mode_name(self, custom_mode: int) -> str:
        """The profile's name of a custom_mode number (the number itself if it has none)."""
        for name, number in self.spec.modes.items():
            if number == custom_mode:
                return name
        return str(custom_mode)

    def param_get(self, name: str, within_s: float = 5.0) -> Any:
        """PARAM_REQUEST_READ by name; returns the PARAM_VALUE."""
        self.send(
            self._mav.param_request_read_encode(self.spec.system_id, 1, name.encode("ascii"), -1)
        )
        return self.wait_for("PARAM_VALUE", within_s, where=_param_named(name))

    def param_set(
        self,
        name: str,
        value: float,
        param_type: int = mavlink2.MAV_PARAM_TYPE_REAL32,
        within_s: float = 5.0,
    ) -> Any:
        """PARAM_SET; returns the PARAM_VALUE the autopilot echoes."""
        self.send(
            self._mav.param_set_encode(
                self.spec.system_id, 1, name.encode("ascii"), float(value), param_type
            )
        )
        return self.wait_for("PARAM_VALUE", within_s, where=_param_named(name))

    # -- receiving -----------------------------------------------------------------------

    def _pump(self) -> list[Any]:
        """One pump of the link: parse, record, keep the ground station's heartbeat going."""
        if self._now_s >= self._heartbeat_due_s:
            for sysid in self.heartbeat_from:
                sender = self._senders.get(sysid)
                if sender is None:
                    sender = mavlink2.MAVLink(None, srcSystem=sysid, srcComponent=GCS_COMPONENT_ID)
                    self._senders[sysid] = sender
                heartbeat = sender.heartbeat_encode(
                    mavlink2.MAV_TYPE_GCS,
                    mavlink2.MAV_AUTOPILOT_INVALID,
                    0,
                    0,
                    mavlink2.MAV_STATE_ACTIVE,
                )
                self.link.send(heartbeat.pack(sender))
                self.heartbeat_sent_s[sysid] = self._now_s
            self._heartbeat_due_s = self._now_s + 1.0
        return self._take(self.link.pump())

    def _take(self, data: bytes) -> list[Any]:
        """Parse bytes from the autopilot; record and return its messages."""
        clock = self.link.clock_s
        if clock is not None and clock > self._now_s:
            self._now_s = clock
        received = []
        for msg in self._parser.parse_buffer(data) or []:
            if msg.get_type() == "BAD_DATA" or msg.get_srcSystem() != self.spec.system_id:
                continue
            boot_ms = getattr(msg, "time_boot_ms", None)
            if boot_ms is not None and boot_ms / 1000.0 > self._now_s:
                self._now_s = boot_ms / 1000.0
            self._record(msg)
            received.append(msg)
        return received

    def _record(self, msg: Any) -> None:
        kind = msg.get_type()
        self._times[id(msg)] = self._now_s
        self.history.append((self._now_s, msg))
        self._recent.append((self._now_s, msg))
        self.last[kind] = msg
        if kind == "STATUSTEXT":
            self._statustext(msg)

    def _statustext(self, msg: Any) -> None:
        """Record a STATUSTEXT, joining ArduPilot's chunks of a long one (same id != 0)."""
        text, text_id = str(msg.text), int(getattr(msg, "id", 0) or 0)
        if text_id:
            parts = self._chunks.setdefault(text_id, [])
            parts.append(text)
            if len(text) >= STATUSTEXT_CHUNK:
                return  # more to come
            text = "".join(self._chunks.pop(text_id))
        place = len(self.history) - 1
        self.statustexts.append(StatusText(self._now_s, msg.severity, text, place))

    def _recent_text(self) -> str:
        return "\n".join(f"  t={t:8.3f} s  {_short(m)}" for t, m in self._recent) or "  (none)"

    def wait_for(
        self,
        what: Awaited,
        within_s: float,
        *,
        where: Callable[[Any], bool] | None = None,
        since: int | None = None,
        describe: str | None = None,
    ) -> Any:
        """The first message of a type (or matching a predicate) within ``within_s``.

        Args:
            what: A message type name or a predicate on messages.
            within_s: How long to wait, in the autopilot's time.
            where: A further predicate (with a type name).
            since: Also accept messages already seen since this :meth:`mark` (0: since
                the connection), such as an answer that overtook an acknowledgement.
            describe: What was awaited, for the failure message.

        Raises:
            AssertionError: It did not come; the message names it and quotes the
                last messages seen.
        """

        def matches(msg: Any) -> bool:
            if isinstance(what, str):
                if msg.get_type() != what:
                    return False
            elif not what(msg):
                return False
            return where is None or bool(where(msg))

        if since is not None:
            for _t, msg in self.history[since:]:
                if matches(msg):
                    return msg
        start_s = self._now_s
        deadline_s = start_s + within_s
        wall_deadline = time.monotonic() + self.link.wall_budget_s(within_s)
        while True:
            for msg in self._pump():
                if matches(msg) and self.time_of(msg) <= deadline_s:
                    return msg
            if self._now_s > deadline_s:
                self._fail(_describe(what, where, describe), start_s, within_s)
            if time.monotonic() > wall_deadline:
                self.link.check()
                raise AssertionError(
                    f"{self.link.describe}: waiting for {_describe(what, where, describe)}, its "
                    f"clock got only from t={start_s:.3f} s to t={self._now_s:.3f} s in "
                    f"{self.link.wall_budget_s(within_s):.0f} s of wall time; last messages:\n"
                    + self._recent_text()
                )

    def _fail(self, awaited: str, start_s: float, within_s: float) -> None:
        raise AssertionError(
            f"{self.link.describe}: no {awaited} within {within_s:g} s "
            f"(t={start_s:.3f} s to t={self._now_s:.3f} s); last messages seen:\n"
            + self._recent_text()
        )

    def run_for(self, seconds: float) -> list[Any]:
        """Let ``seconds`` of the autopilot's time pass; returns the messages seen."""
        start_s = self._now_s
        end_s = start_s + seconds
        wall_deadline = time.monotonic() + self.link.wall_budget_s(seconds)
        seen: list[Any] = []
        while self._now_s < end_s:
            seen.extend(self._pump())
            if time.monotonic() > wall_deadline:
                self.link.check()
                raise AssertionError(
                    f"{self.link.describe}: running for {seconds:g} s, its clock got only from "
                    f"t={start_s:.3f} s to t={self._now_s:.3f} s; last messages:\n"
                    + self._recent_text()
                )
        return seen

    def first_seen(self, predicate: Callable[[Any], bool]) -> tuple[float, Any] | None:
        """The first message in the history that matches, with its time; None if none."""
        for t, msg in self.history:
            if predicate(msg):
                return t, msg
        return None

    def texts_since(self, mark: int) -> list[StatusText]:
        """STATUSTEXTs seen since a :meth:`mark` (long ones joined)."""
        return [s for s in self.statustexts if s.place >= mark]

    def close(self) -> None:
        """End the link (stops a SITL process it started)."""
        self.link.close()


def _param_named(name: str) -> Callable[[Any], bool]:
    def named(msg: Any) -> bool:
        return bool(msg.param_id == name)

    named.__doc__ = f"param_id == {name!r}"
    return named


def open_peer(backend: str, *, start: bool = True) -> Peer:
    """A peer on a new vehicle of ``backend`` (``sim-rover`` ... ``sitl-plane``).

    Args:
        backend: Which autopilot.
        start: Hear its first HEARTBEAT and wait for its streams (:meth:`Peer.start`);
            False: connected and nothing sent yet (the autopilot's first instants).
    """
    source, kind = backend.split("-", 1)
    spec = vehicle_spec(kind)
    link: Link = build_sim_link(spec) if source == "sim" else SitlLink.start(spec)
    peer = Peer(link, backend, spec)
    if not start:
        return peer
    try:
        return peer.start()
    except BaseException:
        peer.close()
        raise


# -- parametrisation -------------------------------------------------------------------------


def backend_params(
    gaps: Mapping[str, str] | None = None, kinds: tuple[str, ...] = KINDS
) -> list[Any]:
    """pytest params for every backend, SITL ones marked ``sitl`` (and skipped without SITL).

    Args:
        gaps: Backend (or ``sim`` for all three simulated ones) -> the reason, starting
            ``sim:``, why that backend does not yet do what real ArduPilot does; those
            parametrisations are strict xfails (an unexpected pass fails, so that the
            mark is removed when the simulation is fixed).
        kinds: Only the backends of these vehicle kinds (for what one firmware does).
    """
    wanted: dict[str, str] = {}
    for key, reason in (gaps or {}).items():
        for backend in SIM_BACKENDS if key == "sim" else (key,):
            if backend not in BACKENDS:
                raise ValueError(f"no backend {backend!r}")
            wanted[backend] = reason
    params = []
    for backend in BACKENDS:
        if backend.split("-", 1)[1] not in kinds:
            continue
        marks: list[Any] = []
        if backend in SITL_BACKENDS:
            marks.append(pytest.mark.sitl)
            if SITL_INSTALL is None:
                marks.append(pytest.mark.skip(reason=SITL_SKIP_REASON))
        if backend in wanted:
            marks.append(pytest.mark.xfail(strict=True, reason=wanted[backend]))
        params.append(pytest.param(backend, marks=marks, id=backend))
    return params


def backends(
    fixture: str = "peer",
    gaps: Mapping[str, str] | None = None,
    kinds: tuple[str, ...] = KINDS,
) -> Any:
    """Parametrise a scenario's peer fixture over every backend (of ``kinds``)."""
    return pytest.mark.parametrize(fixture, backend_params(gaps, kinds), indirect=True)
