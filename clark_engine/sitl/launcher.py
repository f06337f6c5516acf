"""Real ArduPilot SITL processes, for the conformance tests and for rehearsals.

The simulated autopilot (:mod:`clark_engine.sim.ardupilot.autopilot`) is only worth trusting
as far as it behaves like the real one, and the only way to know is to run the
same scenarios against real ArduPilot flight code built for software in the loop
(SITL). This module starts and stops such processes, safely enough for a test
suite that runs several of them at once beside colleagues' own:

- :meth:`SitlInstall.find` locates the ``sitl`` launcher script (the folder
  ``ardupilot-sitl`` ships with, or any script that takes the same arguments:
  ``sitl VEHICLE INSTANCE LAT,LON,ALT,HEADING [ARGS...]`` and that execs the
  vehicle binary with ArduPilot's ``-I INSTANCE``).
- :class:`SitlProcess` starts one vehicle on an instance number whose ports are
  all free, holds a lock file on that number for as long as it runs (so that two
  processes of one test suite never pick the same one), hands out a connected
  MAVLink socket, feeds the pilot's RC inputs in over UDP, and always stops it:
  on :meth:`SitlProcess.stop`, at the end of a ``with`` block, at interpreter
  exit, and (Linux) when the process that started it dies.

What one SITL instance ``I`` binds, as measured with ``ss -lntup`` on these builds
(ArduPilot's ``libraries/AP_HAL_SITL``): TCP ``5760+10*I`` (SERIAL0, MAVLink; a
server that waits for one client before it starts its clock), TCP ``5762+10*I``
and ``5763+10*I`` (SERIAL1 and SERIAL2, bound once SERIAL0 has its client), and
UDP ``5501+10*I`` (the RC input, bound once the clock runs). It also names UDP
``9005+10*I`` for a simulated IR-Lock ("Using Irlock at port"), bound only when
that sensor is simulated; it is checked too, so that an instance chosen here
never meets a port someone else holds.

Which instance numbers are free, and the lock that reserves one, are
:mod:`clark_engine.sitl.instances`; the errors, :mod:`clark_engine.sitl.errors`.

Nothing here reads the mission or MAVLink: the caller speaks MAVLink over the
socket (see ``tests/conformance``; a later ``clark dry-run --autopilot sitl``
does the same).
"""

from __future__ import annotations

import atexit
import contextlib
import ctypes
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import Final, NamedTuple

from clark_engine.sitl.errors import SitlError, SitlNotFound
from clark_engine.sitl.instances import (
    DEFAULT_INSTANCES,
    ENV_SITL_INSTANCES,
    InstanceLock,
    InstancePorts,
    default_lock_dir,
    instance_free,
    parse_instances,
    port_free,
    reserve_instance,
)

VEHICLES: Final = ("rover", "copter", "plane")
"""Vehicles the ``sitl`` launcher starts (ArduRover, ArduCopter, ArduPlane)."""

FIRMWARE_VEHICLES: Final[Mapping[str, str]] = {
    "ardurover": "rover",
    "arducopter": "copter",
    "arduplane": "plane",
}
"""An autopilot profile's ``firmware`` -> the SITL vehicle that runs it."""

LAUNCHER_NAME: Final = "sitl"
"""The launcher script's file name inside a SITL folder."""

ENV_SITL: Final = "CLARK_SITL"
"""Environment variable naming the SITL folder (or the launcher) when ``--sitl`` is not given."""

ENV_SPEEDUP: Final = "CLARK_SITL_SPEEDUP"
"""The launcher's speed-up variable (ArduPilot's ``--speedup``)."""

ENV_WORK: Final = "CLARK_SITL_WORK"
"""The launcher's working-folder variable (eeprom.bin, logs)."""

RC_INPUT_CHANNELS: Final = 16
"""Channels one RC-input datagram carries (ArduPilot also takes 8)."""

STOP_GRACE_S: Final = 5.0
"""How long SITL gets to exit on SIGTERM before it is killed."""

START_TIMEOUT_S: Final = 60.0
"""How long a start may take until SITL listens (the first start unpacks the binary)."""

LOG_TAIL_LINES: Final = 25
START_ATTEMPTS: Final = 5
"""Instances tried in turn when SITL finds a port taken after all (a race with a process
that does not use our lock files)."""

_POLL_S: Final = 0.02
_PR_SET_PDEATHSIG: Final = 1


class Home(NamedTuple):
    """Where a SITL vehicle boots: ArduPilot's ``--home LAT,LON,ALT,HEADING``."""

    lat_deg: float
    lon_deg: float
    alt_m: float
    """Above mean sea level."""
    heading_deg: float = 0.0

    def argument(self) -> str:
        """The launcher's ``LAT,LON,ALT,HEADING`` argument."""
        return f"{self.lat_deg:.7f},{self.lon_deg:.7f},{self.alt_m:g},{self.heading_deg:g}"


def vehicle_for_firmware(firmware: str) -> str:
    """The SITL vehicle (``rover``, ``copter``, ``plane``) for an autopilot profile's firmware.

    Raises:
        SitlError: A firmware SITL cannot run here.
    """
    vehicle = FIRMWARE_VEHICLES.get(firmware)
    if vehicle is None:
        raise SitlError(
            f"no SITL vehicle runs firmware {firmware!r}; "
            f"use one of {', '.join(sorted(FIRMWARE_VEHICLES))}"
        )
    return vehicle


@dataclass(frozen=True, slots=True)
class SitlInstall:
    """A SITL launcher script, found and checked, and the instance numbers it may take.

    Attributes:
        launcher: The ``sitl`` launcher.
        instances: Instance numbers a vehicle started from it may use, lowest first
            (``--sitl-instances`` or ``$CLARK_SITL_INSTANCES``; 0-99 by default).
    """

    launcher: Path
    instances: range = DEFAULT_INSTANCES

    @property
    def folder(self) -> Path:
        """The folder the launcher lives in (its binaries and parameter files)."""
        return self.launcher.parent

    @classmethod
    def find(
        cls,
        given: str | None,
        *,
        instances: str | None = None,
        environ: Mapping[str, str] | None = None,
    ) -> SitlInstall:
        """The launcher from ``--sitl PATH``, else from ``$CLARK_SITL``.

        Args:
            given: ``--sitl PATH``: a folder holding the ``sitl`` launcher, or the
                launcher itself; None when not given.
            instances: ``--sitl-instances FIRST-LAST``, else ``$CLARK_SITL_INSTANCES``,
                else :data:`DEFAULT_INSTANCES`.
            environ: The environment to read ``CLARK_SITL`` from (``os.environ`` by
                default; tests pass their own).

        Raises:
            SitlNotFound: Neither names an executable launcher; the message says what
                to give instead.
            SitlError: The instance range is not ``FIRST-LAST``.
        """
        env = os.environ if environ is None else environ
        if instances is not None:
            allowed = parse_instances(instances)
        elif env.get(ENV_SITL_INSTANCES):
            allowed = parse_instances(env[ENV_SITL_INSTANCES], f"${ENV_SITL_INSTANCES}")
        else:
            allowed = DEFAULT_INSTANCES
        how = "--sitl"
        if given is None:
            given = env.get(ENV_SITL) or None
            how = f"${ENV_SITL}"
        if given is None:
            raise SitlNotFound(
                "no ArduPilot SITL given: pass --sitl PATH or set "
                f"{ENV_SITL} to the folder with the `{LAUNCHER_NAME}` launcher "
                "(e.g. ../shared/ardupilot-sitl)"
            )
        path = Path(given).expanduser()
        launcher = path / LAUNCHER_NAME if path.is_dir() else path
        if not launcher.is_file():
            where = f"{path} has no `{LAUNCHER_NAME}` launcher" if path.is_dir() else "not found"
            raise SitlNotFound(
                f"{how} {given}: {where}; pass --sitl PATH or set {ENV_SITL} to the folder "
                f"with the `{LAUNCHER_NAME}` launcher (e.g. ../shared/ardupilot-sitl)"
            )
        if not os.access(launcher, os.X_OK):
            raise SitlNotFound(
                f"{how} {given}: {launcher} is not executable; make it so "
                f"(chmod +x {launcher}) or point {how} at a working SITL folder"
            )
        return cls(launcher.resolve(), allowed)


def _death_pact(parent_pid: int) -> Callable[[], None]:
    """What the child runs before exec so that it dies with the process that starts it.

    On Linux, ``PR_SET_PDEATHSIG``: the kernel kills the child when the thread that
    started it ends, and the setting survives ``exec`` (the launcher execs the vehicle
    binary), so SITL never outlives a test run killed before it could call
    :meth:`SitlProcess.stop`. libc is loaded here, in the parent: after a fork only
    async-signal-safe work is safe.
    """
    prctl = ctypes.CDLL(None, use_errno=True).prctl if sys.platform.startswith("linux") else None

    def in_child() -> None:
        if prctl is not None:
            prctl(_PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        if os.getppid() != parent_pid:  # the parent died before the request took hold
            os._exit(1)

    return in_child


def _read_tail(path: Path, lines: int) -> str:
    try:
        with path.open("rb") as f:
            f.seek(0, os.SEEK_END)
            size = f.tell()
            f.seek(max(0, size - 16_384))
            text = f.read().decode("utf-8", "replace")
    except OSError:
        return ""
    return "\n".join(text.splitlines()[-lines:])


class SitlProcess:
    """One running ArduPilot SITL vehicle on a free instance number.

    Use it as a context manager (or call :meth:`start` and :meth:`stop`): on entry it
    reserves an instance, starts the launcher in its own process group with the
    speed-up and a fresh working folder, and returns once SITL listens for its
    MAVLink client; on exit it stops the process group, releases the instance and
    removes the working folder (unless ``keep_work``). SITL's stdout and stderr go
    to ``sitl.log`` in the working folder; every error quotes its tail.

    A ground station (the conformance suite, or ``clark dry-run --autopilot sitl``
    with one process per vehicle of a mission) then does::

        install = SitlInstall.find(args.sitl)          # --sitl PATH or $CLARK_SITL
        vehicle = vehicle_for_firmware(autopilot["firmware"])
        with SitlProcess(install, vehicle, Home(lat, lon, alt_m), speedup=10) as sitl:
            sock = sitl.connect(timeout_s=30)          # its clock starts now
            ...                                        # MAVLink over sock
            sitl.rc_input([1500, 1500, 1000, 1500])    # the pilot's sticks

    Start it from the thread that will outlive it (normally the main thread): on
    Linux the kernel kills SITL when the thread that started it ends, so that no
    SITL ever outlives a killed run.

    Args:
        install: The launcher.
        vehicle: ``rover``, ``copter`` or ``plane``.
        home: Where it boots.
        speedup: ArduPilot's ``--speedup`` (1: real time).
        instance: A fixed instance number; None chooses a free one from ``instances``.
        instances: Candidate instance numbers, lowest first; None: the install's.
        work_dir: Its working folder (kept afterwards: it is the caller's); None for a
            fresh temp folder.
        keep_work: Keep the fresh temp folder after stopping (to read its logs).
        lock_dir: Where the instance lock files live (all processes that must not
            share instances must use the same folder).
        extra_args: More ArduPilot command-line arguments.
        stop_grace_s: Seconds between SIGTERM and SIGKILL on :meth:`stop`.
        start_timeout_s: Seconds :meth:`start` waits for SITL to listen.
        environ: The environment to start it with (``os.environ`` by default); the
            speed-up and working folder variables are set on top.

    Raises:
        ValueError: An unknown vehicle or a speed-up not above 0.
    """

    def __init__(
        self,
        install: SitlInstall,
        vehicle: str,
        home: Home | tuple[float, float, float, float],
        *,
        speedup: float = 1.0,
        instance: int | None = None,
        instances: Iterable[int] | None = None,
        work_dir: Path | None = None,
        keep_work: bool = False,
        lock_dir: Path | None = None,
        extra_args: Sequence[str] = (),
        stop_grace_s: float = STOP_GRACE_S,
        start_timeout_s: float = START_TIMEOUT_S,
        environ: Mapping[str, str] | None = None,
    ) -> None:
        if vehicle not in VEHICLES:
            raise ValueError(f"unknown SITL vehicle {vehicle!r}; use one of {', '.join(VEHICLES)}")
        if not speedup > 0:
            raise ValueError(f"the speed-up must be above 0, not {speedup!r}")
        self.install = install
        self.vehicle = vehicle
        self.home = Home(*home)
        self.speedup = float(speedup)
        self._fixed_instance = instance
        self._instances = list(install.instances if instances is None else instances)
        self._given_work_dir = work_dir
        self.keep_work = keep_work
        self.lock_dir = lock_dir or default_lock_dir()
        self.extra_args = tuple(extra_args)
        self.stop_grace_s = stop_grace_s
        self.start_timeout_s = start_timeout_s
        self._environ = dict(os.environ if environ is None else environ)

        self._process: subprocess.Popen[bytes] | None = None
        self._swept = False  # its process group was killed after it ended
        self._lock: InstanceLock | None = None
        self._rc_socket: socket.socket | None = None
        self._work_dir: Path | None = None
        self._owns_work_dir = False
        self._atexit_registered = False

    # -- what it is --------------------------------------------------------------------------

    @property
    def instance(self) -> int:
        """The instance number it runs on (after :meth:`start`)."""
        if self._lock is None:
            raise SitlError("SITL is not running: call start() first")
        return self._lock.instance

    @property
    def ports(self) -> InstancePorts:
        """Its ports (after :meth:`start`)."""
        return InstancePorts(self.instance)

    @property
    def pid(self) -> int | None:
        """Its process id (also its process group id); None before start."""
        return None if self._process is None else self._process.pid

    @property
    def work_dir(self) -> Path:
        """Its working folder (eeprom.bin, logs, ``sitl.log``), after :meth:`start`."""
        if self._work_dir is None:
            raise SitlError("SITL is not running: call start() first")
        return self._work_dir

    @property
    def log_path(self) -> Path:
        """Its stdout and stderr."""
        return self.work_dir / "sitl.log"

    @property
    def running(self) -> bool:
        """True while its process has not exited."""
        return self._process is not None and self._process.poll() is None

    def log_tail(self, lines: int = LOG_TAIL_LINES) -> str:
        """The last lines of its log ('' when there is none yet)."""
        if self._work_dir is None:
            return ""
        return _read_tail(self.log_path, lines)

    def failure(self, what: str) -> SitlError:
        """A :class:`SitlError` saying ``what`` went wrong, with the exit code and log tail."""
        parts = [f"SITL {self.vehicle}"]
        if self._lock is not None:
            parts.append(f"(instance {self._lock.instance})")
        parts.append(what)
        if self._process is not None and self._process.poll() is not None:
            parts.append(f"[exit code {self._process.returncode}]")
        tail = self.log_tail()
        message = " ".join(parts)
        if tail:
            message += f"; the end of its log:\n{tail}"
        elif self._work_dir is not None:
            message += f"; its log ({self.log_path}) is empty"
        return SitlError(message)

    def raise_if_exited(self) -> None:
        """Raise :class:`SitlError` if the process has exited (a link went quiet: say why)."""
        if self._process is not None and self._process.poll() is not None:
            raise self.failure("exited")

    # -- life --------------------------------------------------------------------------------

    def __enter__(self) -> SitlProcess:
        return self.start()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop()

    def start(self) -> SitlProcess:
        """Start SITL on a free instance and wait until it listens for its MAVLink client.

        Returns:
            Itself.

        Raises:
            SitlError: No free instance, SITL exited early (the message has the log's
                tail) or did not listen within ``start_timeout_s``.
        """
        if self._process is not None:
            raise SitlError("this SITL process was already started; make a new SitlProcess")
        if not self._atexit_registered:
            atexit.register(self.stop)  # interpreter exit stops what a caller forgot
            self._atexit_registered = True
        try:
            self._start_somewhere()
        except BaseException:
            self.stop()
            raise
        return self

    def _start_somewhere(self) -> None:
        if self._fixed_instance is not None:
            lock = InstanceLock.try_acquire(self._fixed_instance, self.lock_dir)
            if lock is None or not instance_free(self._fixed_instance):
                if lock is not None:
                    lock.release()
                raise SitlError(
                    f"SITL instance {self._fixed_instance} is locked by another process or "
                    f"one of its ports ({InstancePorts(self._fixed_instance)}) is taken; "
                    "leave the instance to be chosen or stop what holds it"
                )
            self._lock = lock
            self._launch()
            if not self._wait_listening():
                raise self.failure("found one of its ports taken")
            return
        candidates = list(self._instances)
        for _attempt in range(START_ATTEMPTS):
            self._lock = lock = reserve_instance(candidates, self.lock_dir)
            self._launch()
            if self._wait_listening():
                return
            # SITL met a port taken after all (by a process that ignores our lock files,
            # in the moment between our probe and its bind): try the next instance.
            failure = self.failure("found one of its ports taken")
            self._end_process()
            self._remove_work_dir()
            lock.release()
            candidates = [c for c in candidates if c != lock.instance]
        raise failure

    def _launch(self) -> None:
        if self._given_work_dir is not None:
            self._work_dir = self._given_work_dir
            self._work_dir.mkdir(parents=True, exist_ok=True)
            self._owns_work_dir = False
        else:
            self._work_dir = Path(tempfile.mkdtemp(prefix=f"clark-sitl-{self.vehicle}-"))
            self._owns_work_dir = True
        env = dict(self._environ)
        env[ENV_SPEEDUP] = f"{self.speedup:g}"
        env[ENV_WORK] = str(self._work_dir)
        command = [
            str(self.install.launcher),
            self.vehicle,
            str(self.instance),
            self.home.argument(),
            *self.extra_args,
        ]
        in_child = _death_pact(os.getpid())  # (libc is loaded here, before the fork)
        self._swept = False
        with self.log_path.open("wb") as log:
            try:
                self._process = subprocess.Popen(
                    command,
                    stdin=subprocess.DEVNULL,
                    stdout=log,
                    stderr=subprocess.STDOUT,
                    cwd=self._work_dir,
                    env=env,
                    start_new_session=True,  # its own process group, to stop it whole
                    preexec_fn=in_child,
                )
            except OSError as exc:
                raise self.failure(f"could not be started ({command[0]}: {exc.strerror})") from exc

    def _wait_listening(self) -> bool:
        """Wait until SITL listens on its MAVLink port; False if it found a port taken."""
        assert self._process is not None
        port = self.ports.mavlink_tcp_port
        deadline = time.monotonic() + self.start_timeout_s
        while True:
            if self._process.poll() is not None:
                if "Address already in use" in self.log_tail(5):
                    return False
                raise self.failure("exited before it listened for its MAVLink client")
            if not port_free(port, socket.SOCK_STREAM):
                return True  # it listens (the probe's bind is refused)
            if time.monotonic() > deadline:
                raise self.failure(
                    f"did not listen on TCP {port} within {self.start_timeout_s:g} s"
                )
            time.sleep(_POLL_S)

    def connect(self, timeout_s: float = 30.0, *, port: int | None = None) -> socket.socket:
        """A TCP connection to its MAVLink port (SERIAL0), retried until SITL accepts.

        SITL starts its clock when this connection is made, and accepts one client at
        a time on SERIAL0.

        Args:
            timeout_s: Wall-clock seconds to keep trying.
            port: Another of its TCP ports (SERIAL1, SERIAL2), once SERIAL0 is connected.

        Returns:
            A connected, blocking socket with TCP_NODELAY; the caller closes it.

        Raises:
            SitlError: SITL exited, or refused connections for ``timeout_s``.
        """
        if self._process is None:
            raise SitlError("SITL is not running: call start() first")
        address = ("127.0.0.1", self.ports.mavlink_tcp_port if port is None else port)
        deadline = time.monotonic() + timeout_s
        while True:
            self.raise_if_exited()
            try:
                sock = socket.create_connection(address, timeout=max(0.1, timeout_s))
            except OSError as exc:
                if time.monotonic() > deadline:
                    raise self.failure(
                        f"did not accept a connection on TCP {address[1]} within "
                        f"{timeout_s:g} s ({exc})"
                    ) from exc
                time.sleep(_POLL_S)
                continue
            sock.settimeout(None)
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            return sock

    def rc_input(self, pwm_us: Sequence[int]) -> None:
        """Send the pilot's RC inputs (what a receiver would decode) to SITL.

        One UDP datagram of 16 little-endian uint16 pulse widths to ArduPilot's RC
        input port (``5501+10*I``; ``SITL_State::_read_rc_sitl_input``). A width of 0
        leaves that channel as it was, so channels not given are unchanged. SITL
        binds that port once its clock runs (after :meth:`connect`); datagrams sent
        earlier are lost. RC_CHANNELS reports the inputs (unless a ground station
        overrides them).

        Args:
            pwm_us: Pulse widths of channels 1, 2, ... (at most 16), in microseconds.

        Raises:
            ValueError: More than 16 channels, or a width outside 0..65535.
        """
        if not 1 <= len(pwm_us) <= RC_INPUT_CHANNELS:
            raise ValueError(f"give 1 to {RC_INPUT_CHANNELS} pulse widths, not {len(pwm_us)}")
        widths = [int(w) for w in pwm_us]
        for channel, width in enumerate(widths, 1):
            if not 0 <= width <= 0xFFFF:
                raise ValueError(f"channel {channel}: {width} us is not a pulse width (0..65535)")
        widths += [0] * (RC_INPUT_CHANNELS - len(widths))
        if self._rc_socket is None:
            self._rc_socket = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        packet = struct.pack(f"<{RC_INPUT_CHANNELS}H", *widths)
        self._rc_socket.sendto(packet, ("127.0.0.1", self.ports.rc_input_udp_port))

    def stop(self) -> None:
        """End SITL, always: SIGTERM to its process group, SIGKILL after the grace period.

        Then release the instance, close the RC socket and remove the fresh working
        folder (unless ``keep_work``). Idempotent; safe to call from ``atexit``.
        """
        self._end_process()
        if self._rc_socket is not None:
            self._rc_socket.close()
            self._rc_socket = None
        if self._lock is not None:
            self._lock.release()
        self._remove_work_dir()
        if self._atexit_registered:
            atexit.unregister(self.stop)
            self._atexit_registered = False

    def _end_process(self) -> None:
        process = self._process
        if process is None or self._swept:
            return
        group = process.pid  # start_new_session: its pid is its process group id
        if process.poll() is None:
            with contextlib.suppress(ProcessLookupError):
                os.killpg(group, signal.SIGTERM)
            try:
                process.wait(self.stop_grace_s)
            except subprocess.TimeoutExpired:
                with contextlib.suppress(ProcessLookupError):
                    os.killpg(group, signal.SIGKILL)
                process.wait()
        # Anything the launcher left behind in its group (a launcher that does not exec),
        # once: later the group id may name someone else's group.
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(group, signal.SIGKILL)
        self._swept = True

    def _remove_work_dir(self) -> None:
        if self._work_dir is not None and self._owns_work_dir and not self.keep_work:
            shutil.rmtree(self._work_dir, ignore_errors=True)
            self._work_dir = None
