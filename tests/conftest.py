"""Shared fixtures: no network beyond loopback, paths to the shipped data."""

from __future__ import annotations

import ipaddress
import os
import signal
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sitl_here import NO_SITL, real_install

from clark_engine.sitl.launcher import SitlInstall

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = sorted((ROOT / "missions").glob("*.yaml"))


TEST_SITL_INSTANCES = "150-199"
"""SITL instance numbers the tests take unless ``$CLARK_SITL_INSTANCES`` says otherwise:
TCP ports 7260 and up, clear of instance 0's 5760 and the low instances a person's own
SITL or ground station holds (the engine's default range starts at 0)."""


def pytest_configure(config: pytest.Config) -> None:
    """Give Ctrl-C back to a suite started as a background job; keep SITL to high instances.

    A shell without job control starts `make test &` with SIGINT ignored, and every child
    inherits that: the tests that stop a `clark` child with SIGINT, as a person's Ctrl-C,
    then wait in vain. A Python handler is reset to the default when a child starts, an
    ignored signal is not. The instance range is set in the environment, so that it holds
    for every worker and every `clark` the tests start.
    """
    os.environ.setdefault("CLARK_SITL_INSTANCES", TEST_SITL_INSTANCES)
    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)


def _is_loopback(address: Any) -> bool:
    if isinstance(address, tuple) and address:
        host = address[0]
    else:
        return True  # AF_UNIX paths and the like never leave the machine
    if host in ("localhost", ""):
        return True
    try:
        return ipaddress.ip_address(host).is_loopback
    except ValueError:
        return False


@pytest.fixture(autouse=True)
def _no_network(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Fail any test that tries to reach beyond loopback."""
    real_connect = socket.socket.connect

    def guarded(self: socket.socket, address: Any) -> Any:
        if not _is_loopback(address):
            raise AssertionError(f"test tried to reach the network: {address!r}")
        return real_connect(self, address)

    monkeypatch.setattr(socket.socket, "connect", guarded)
    yield


GROUND_STATION_PORT = 14550
"""MAVLink's well-known UDP port, where a user's MAVProxy or QGroundControl listens."""


@pytest.fixture(scope="session", autouse=True)
def _ground_station_port_held() -> Iterator[None]:
    """Hold UDP 14550 for the whole session, as a user's ground station would.

    Tests take free ports only: one that used the well-known port failed on a user's
    machine with a ground station running. Holding it here makes any such test fail here
    too. Already held (a ground station, another test worker): nothing to do.
    """
    sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    try:
        sock.bind(("0.0.0.0", GROUND_STATION_PORT))
    except OSError:
        sock.close()
        yield
        return
    try:
        yield
    finally:
        sock.close()


@pytest.fixture
def root() -> Path:
    """The repository root."""
    return ROOT


@pytest.fixture(scope="session")
def sitl_install() -> SitlInstall:
    """ArduPilot SITL's launcher (tests/sitl_here.py); skips the test, saying why, without."""
    install = real_install()
    if install is None:
        pytest.skip(NO_SITL)
    return install


LONGEST_MODULES = ("test_run_end_to_end.py",)
"""Modules whose tests each take over a minute (real-time rehearsals): dealt out first."""

WALL_CLOCK_MODULES = (
    "test_run_end_to_end.py",
    "test_browser_rehearsal.py",
    "test_computer_lost.py",
    "test_cli_run_stop.py",
    "test_run_replay_restart.py",
    "test_gcs_rehearsal.py",
    "test_realtime.py",
    "test_cli_sims.py",
    "test_cli_run.py",
)
"""Modules whose tests mostly wait on the wall clock: real-time rehearsals of ``clark``
processes, ArduPilot SITL at real time, a browser following a live run. Measured alone
they use 4-60 % of a core (about 440 s of wall time, 100 s of CPU); they run one after
the other on a test worker of their own, beside one worker per core for the rest."""
WALL_CLOCK_TESTS = ("test_a_wall_clock_dry_run_stamps_every_log_on_one_time_base",)
"""Single tests elsewhere that wait on the wall clock too (14 s, 4 % of a core)."""


def _waits_on_the_wall_clock(item: pytest.Item) -> bool:
    return item.path.name in WALL_CLOCK_MODULES or item.name in WALL_CLOCK_TESTS


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``-n auto``: a worker per core, one for the tests that wait on the wall clock, one
    for the second SITL group.

    Those would otherwise hold a core's worker idle for minutes; on their own worker
    they wait beside the CPU-bound tests (7.5 min of waiting on 2 cores).
    """
    return (os.cpu_count() or 1) + 2


SPED_UP_SITL_MODULES = ("test_dry_run_sitl.py", "test_sitl.py")
"""Modules that run ArduPilot SITL at a speed-up (as do the conformance suite's sitl-*)."""


def _sped_up_sitl(item: pytest.Item) -> bool:
    """SITL at a speed-up: the conformance suite's sitl-*, those modules, and every other
    test marked ``sitl`` that does not wait on the wall clock (a campaign's two SITLs, a
    safety set-up on ArduCopter SITL...): one of them beside another made three SITLs at
    ten times real time, and the engine fell 9.5 s behind one of them."""
    return (
        "[sitl-" in item.nodeid
        or item.path.name in SPED_UP_SITL_MODULES
        or (item.get_closest_marker("sitl") is not None and not _waits_on_the_wall_clock(item))
    )


SITL_RERUNS = 1
"""Runs more of a SITL test at a speed-up that failed (pytest-rerunfailures; `R` in the
output, each listed at the end). SITL at ten times real time on a 2-core machine shares it
with the CPU-bound rest of the suite and cannot always keep its pace: two full suites on
the final code of session 5 had 3 such failures each, different tests each time
(a rover's chase overshooting by 1.3-1.8 m past the bound, a plane handed over 28 m off,
an auto-disarm text a step early), against none of the same tests alone. A second failure
fails the suite. Only these tests: every other test must pass the first time."""


BATCH_NICE = 10
"""Niceness a test worker takes before its first test that neither flies SITL at a
speed-up, nor waits on the wall clock, nor drives a browser: the CPU-bound rest of the
suite. SITL cannot be paused, so a SITL test starved of CPU by the rest falls behind
SITL's clock; the engine then slows SITL down (dryrun/sitl_pace.py) and the test takes two to
three times as long (the suite's critical path), or an ungoverned conformance test fails.
At niceness 10 the rest gets what SITL and the wall-clock tests leave (a tenth of a core
beside each of theirs) and still all of an idle core. A worker never goes back to 0
(only root may): xdist deals the groups out first, the largest first, so the SITL
worker and the wall-clock worker run their groups before any other test."""


def _is_batch(item: pytest.Item) -> bool:
    return not (
        _waits_on_the_wall_clock(item)
        or _sped_up_sitl(item)
        or item.get_closest_marker("browser") is not None
    )


@pytest.hookimpl(tryfirst=True)
def pytest_runtest_setup(item: pytest.Item) -> None:
    """Under xdist, yield the CPU to SITL and the wall-clock tests (:data:`BATCH_NICE`)."""
    if "PYTEST_XDIST_WORKER" in os.environ and _is_batch(item):
        current = os.getpriority(os.PRIO_PROCESS, 0)
        if current < BATCH_NICE:
            os.nice(BATCH_NICE - current)


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Deal the slow tests out first, and run SITL at a speed-up in two groups, one each.

    First of the hooks: pytest-xdist's own, on each worker, reads the ``xdist_group``
    marks to name each test's group, so marks added after it are never seen (they were
    not, until this ran first: every SITL test was spread over every worker, three SITLs
    at ten times real time at once on two cores).

    `make test` spreads the suite over the machine's cores (pytest-xdist, `-n auto
    --dist loadgroup`). A long test dealt out last would keep one core busy while the
    others idle, so the longest go first, then the other slow ones. SITL at ten times
    real time needs a core of its own to keep ArduPilot's loops on time: two at once
    beside the rest of the suite made a rover stop short and a stream request race
    (seen on this 2-core machine), so those tests share two groups (the conformance
    scenarios; the dry runs on SITL), each of which xdist runs on one worker, one test
    after the other, while the rest yields the CPU to them (:data:`BATCH_NICE`). The
    tests that wait on the wall clock share another
    group, dealt out first (:func:`pytest_xdist_auto_num_workers` gives them a worker of
    their own). The order of the rest is unchanged (the sort is stable), and every test
    is independent of order. The SITL tests at a speed-up are run once more after a
    failure (:data:`SITL_RERUNS`).
    """

    def rank(item: pytest.Item) -> int:
        if item.path.name in LONGEST_MODULES:
            return 0
        if _waits_on_the_wall_clock(item):
            return 1
        if item.get_closest_marker("sitl") or item.get_closest_marker("slow"):
            return 2
        return 3

    items.sort(key=rank)
    rerun_sitl = config.pluginmanager.hasplugin("rerunfailures")
    for item in items:
        if _waits_on_the_wall_clock(item):
            item.add_marker(pytest.mark.xdist_group("wall-clock"))
        elif _sped_up_sitl(item):
            # Two SITL groups side by side, each on a worker of its own: the conformance
            # scenarios (one SITL vehicle at a time, about half a core) and the dry runs,
            # campaigns and set-ups on SITL (the engine governs their pace). One group was
            # the suite's longest chain (641 s of 668); beside a rest of the same priority
            # the split failed four SITL tests (session 5), beside a rest that yields
            # (BATCH_NICE) it is tried again.
            group = "sitl-conformance" if "[sitl-" in item.nodeid else "sitl-speedup"
            item.add_marker(pytest.mark.xdist_group(group))
            if rerun_sitl:
                item.add_marker(pytest.mark.flaky(reruns=SITL_RERUNS))
