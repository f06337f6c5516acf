"""SITL instance numbers: the ports each one binds, which are free, and the lock that reserves one.

Several SITL processes run at once beside colleagues' own (a test suite, a campaign): an
instance is taken only when every port it binds is free (a bind probe, the question
SITL's own bind asks) and its lock file is held, so that two processes of one suite never
pick the same one. Apart from the launcher (:mod:`clark_engine.sitl.launcher`) because
this is the machine's side (ports, lock files, the user's allowed range), not SITL's;
the launcher's docstring says how the ports were measured.
"""

from __future__ import annotations

import errno
import fcntl
import os
import socket
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Final

from clark_engine.sitl.errors import SitlError

MAVLINK_TCP_BASE_PORT: Final = 5760
"""SERIAL0 (MAVLink) of instance 0; instance ``I`` adds ``10*I`` to every port."""

SERIAL1_TCP_BASE_PORT: Final = 5762
SERIAL2_TCP_BASE_PORT: Final = 5763
RC_INPUT_UDP_BASE_PORT: Final = 5501
"""ArduPilot's ``_simin_port``: 8 or 16 little-endian uint16 pulse widths per datagram."""

IRLOCK_UDP_BASE_PORT: Final = 9005
PORT_STEP: Final = 10

DEFAULT_INSTANCES: Final = range(0, 100)
"""Instance numbers tried, lowest first (ports up to 5763 + 990)."""

ENV_SITL_INSTANCES: Final = "CLARK_SITL_INSTANCES"
"""The instance numbers this user's runs may take, ``FIRST-LAST`` (``--sitl-instances``):
on a lab machine shared by several people or CI jobs, each keeps to its own range."""

MAX_INSTANCE: Final = 255
"""The highest instance number ArduPilot takes: SITL keeps ``-I`` in a ``uint8_t``
(``SITL_State::_instance``), so instance 300 listens on instance 44's ports (5760 + 440)
while the engine connects to 8760: the range is refused rather than wrapped."""


def parse_instances(text: str, how: str = "--sitl-instances") -> range:
    """``FIRST-LAST`` (or one number) as the range of instance numbers it names.

    Raises:
        SitlError: Not two numbers in order within 0..MAX_INSTANCE; the message says
            what to write.
    """
    first, dash, last = text.strip().partition("-")
    try:
        low = int(first)
        high = int(last) if dash else low
    except ValueError:
        low, high = -1, -1
    if not (0 <= low <= high <= MAX_INSTANCE) or len(text) > 32:
        raise SitlError(
            f"{how} {text[:32]!r}: give the SITL instance numbers to use as FIRST-LAST, "
            f"each 0..{MAX_INSTANCE} (ArduPilot's limit), FIRST not above LAST "
            "(e.g. 20-39: ports 5960-6153)"
        )
    return range(low, high + 1)


@dataclass(frozen=True, slots=True)
class InstancePorts:
    """The ports one SITL instance uses (see the module docstring for how they were found)."""

    instance: int

    @property
    def mavlink_tcp_port(self) -> int:
        """SERIAL0: the MAVLink server a ground station connects to."""
        return MAVLINK_TCP_BASE_PORT + PORT_STEP * self.instance

    @property
    def serial1_tcp_port(self) -> int:
        """SERIAL1: a second MAVLink server, free for a ground station during a run."""
        return SERIAL1_TCP_BASE_PORT + PORT_STEP * self.instance

    @property
    def serial2_tcp_port(self) -> int:
        """SERIAL2: a third MAVLink server (where a dry run's SITL backend reads its streams)."""
        return SERIAL2_TCP_BASE_PORT + PORT_STEP * self.instance

    @property
    def rc_input_udp_port(self) -> int:
        """Where SITL reads the pilot's RC inputs from."""
        return RC_INPUT_UDP_BASE_PORT + PORT_STEP * self.instance

    @property
    def tcp_ports(self) -> tuple[int, ...]:
        """Every TCP port the instance listens on."""
        offset = PORT_STEP * self.instance
        return (
            MAVLINK_TCP_BASE_PORT + offset,
            SERIAL1_TCP_BASE_PORT + offset,
            SERIAL2_TCP_BASE_PORT + offset,
        )

    @property
    def udp_ports(self) -> tuple[int, ...]:
        """Every UDP port the instance binds (or may bind)."""
        offset = PORT_STEP * self.instance
        return (RC_INPUT_UDP_BASE_PORT + offset, IRLOCK_UDP_BASE_PORT + offset)


def port_free(port: int, kind: int) -> bool:
    """True when this machine could bind ``port`` on every address, as SITL will.

    A bind probe rather than a parse of ``ss``: it asks the kernel the very question
    SITL's own bind will ask (SO_REUSEADDR on TCP, as ArduPilot sets it, so that a
    closed connection lingering in TIME_WAIT does not count as busy).

    Args:
        port: The port number.
        kind: ``socket.SOCK_STREAM`` (TCP) or ``socket.SOCK_DGRAM`` (UDP).
    """
    with socket.socket(socket.AF_INET, kind) as probe:
        if kind == socket.SOCK_STREAM:
            probe.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        try:
            probe.bind(("0.0.0.0", port))
            if kind == socket.SOCK_STREAM:
                probe.listen(1)  # a listener conflicts where a plain bind might not
        except OSError as exc:
            if exc.errno in (errno.EADDRINUSE, errno.EACCES):
                return False
            raise
    return True


def instance_free(instance: int) -> bool:
    """True when every port of SITL instance ``instance`` is free."""
    ports = InstancePorts(instance)
    return all(port_free(p, socket.SOCK_STREAM) for p in ports.tcp_ports) and all(
        port_free(p, socket.SOCK_DGRAM) for p in ports.udp_ports
    )


def default_lock_dir() -> Path:
    """Where instance lock files live: one folder per user in the temp folder."""
    return Path(tempfile.gettempdir()) / f"clark-sitl-locks-{os.getuid()}"


class InstanceLock:
    """An exclusive lock on one SITL instance number, held until :meth:`release`.

    A lock file per instance (``instance-I.lock``), locked with ``flock``: the kernel
    drops the lock when the holder dies, so a crashed test run never leaves an
    instance reserved. The file itself stays (deleting lock files races with the
    next locker).
    """

    def __init__(self, instance: int, fd: int, path: Path) -> None:
        self.instance = instance
        self.path = path
        self._fd: int | None = fd

    @classmethod
    def try_acquire(cls, instance: int, lock_dir: Path) -> InstanceLock | None:
        """The lock on ``instance``, or None when another process holds it."""
        lock_dir.mkdir(parents=True, exist_ok=True)
        path = lock_dir / f"instance-{instance}.lock"
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC, 0o644)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return None
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        return cls(instance, fd, path)

    @property
    def held(self) -> bool:
        """True until released."""
        return self._fd is not None

    def release(self) -> None:
        """Give the instance back (closing the file drops the lock); idempotent."""
        if self._fd is not None:
            os.close(self._fd)
            self._fd = None


def reserve_instance(
    candidates: Iterable[int] = DEFAULT_INSTANCES, lock_dir: Path | None = None
) -> InstanceLock:
    """Lock the first instance number nobody else holds and whose ports are all free.

    The lock is taken before the ports are probed, so that of two processes of this
    suite only one ever probes (and then starts) a given instance.

    Raises:
        SitlError: Every candidate is locked or busy.
    """
    folder = lock_dir or default_lock_dir()
    tried = []
    for instance in candidates:
        tried.append(instance)
        lock = InstanceLock.try_acquire(instance, folder)
        if lock is None:
            continue
        if instance_free(instance):
            return lock
        lock.release()
    span = f"{tried[0]}..{tried[-1]}" if tried else "none"
    raise SitlError(
        f"no free SITL instance among {span}: each is locked by another test process "
        f"(lock files in {folder}) or one of its ports (TCP 5760+10*I, 5762+10*I, 5763+10*I, "
        "UDP 5501+10*I, 9005+10*I) is taken; stop some SITL processes or allow more instances"
    )
