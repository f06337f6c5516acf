"""Fixtures of the conformance suite: one test ground station per backend.

``peer`` is parametrised over every backend (``sim-rover`` ... ``sitl-plane``). A
simulated vehicle is built afresh for every test (it costs milliseconds); a SITL
vehicle of each kind is booted once and shared by the scenarios that leave it as
they found it (reading, streams and mode changes put back), since its time to get
ready costs wall time. ``fresh_peer`` always boots a new vehicle, for scenarios that
change state (arming) or need the first seconds after boot.

The scenarios are run grouped by backend (all of ``sitl-rover``, then all of
``sitl-copter``...), and only one shared SITL vehicle runs at a time: a SITL
vehicle runs on whether or not anyone reads it, so interleaving the kinds would
keep three of them busy on a two-core machine.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from flight import COPTER_SPEED_CM_S, ROVER_SPEED_M_S, disarmed, flight_params, streaming
from harness import BACKENDS, Peer, backend_params, open_peer
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

HERE = Path(__file__).resolve().parent
FIXTURES = ("peer", "fresh_peer", "connecting_peer")
"""The fixtures a scenario's backend is a parameter of."""


#: Files whose scenarios run last in their backend's group, in this order: they wait for the
#: vehicle to get ready (about 40 s of its time), and that wait overlaps the other
#: scenarios if they ran first on the shared vehicle.
RUN_LAST = (
    "test_readiness.py",
    "test_arming.py",
    "test_mode_rules.py",
    "test_commands.py",
    "test_rc.py",
    "test_guided.py",
    "test_rtl.py",
    "test_mission.py",
    "test_fence.py",  # fences switched on and breached; put back after each scenario
    "test_gcs_failsafe.py",  # the ground station's heartbeats stopped and restarted
    "test_home.py",  # locks home (DO_SET_HOME): after the scenarios that move it
    "test_plane.py",  # the plane stays in the air
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Run this folder's scenarios grouped by backend, in file order within a group."""
    places = [i for i, item in enumerate(items) if HERE in item.path.parents]

    def order(item: pytest.Item) -> tuple[int, int]:
        callspec = getattr(item, "callspec", None)
        params = callspec.params if callspec is not None else {}
        backend = next((params[k] for k in FIXTURES if k in params), None)
        group = BACKENDS.index(backend) if backend in BACKENDS else -1
        name = item.path.name
        return group, RUN_LAST.index(name) + 1 if name in RUN_LAST else 0

    grouped = sorted((items[i] for i in places), key=order)
    for place, item in zip(places, grouped, strict=True):
        items[place] = item


class SharedSitl:
    """The shared SITL vehicle: one at a time, booted on first use, stopped when another
    kind is asked for and at the end of the session."""

    def __init__(self) -> None:
        self._backend = ""
        self._peer: Peer | None = None

    def get(self, backend: str) -> Peer:
        """The shared peer of ``backend``, booting it (again, if it died) as needed."""
        peer = self._peer
        if peer is not None and self._backend == backend:
            try:
                peer.link.check()
            except Exception:
                self.close()
            else:
                peer.sync()  # what it said since the last scenario
                return peer
        self.close()
        self._peer = open_peer(backend)
        self._backend = backend
        return self._peer

    def close(self) -> None:
        """Stop the shared SITL process."""
        peer, self._peer = self._peer, None
        if peer is not None:
            peer.close()


@pytest.fixture(scope="session")
def shared_sitl() -> Iterator[SharedSitl]:
    pool = SharedSitl()
    try:
        yield pool
    finally:
        pool.close()


@pytest.fixture(params=backend_params())
def peer(request: pytest.FixtureRequest, shared_sitl: SharedSitl) -> Iterator[Peer]:
    """A ground station on the backend's vehicle (shared for SITL: leave it as found)."""
    backend: str = request.param
    if backend.startswith("sitl-"):
        yield shared_sitl.get(backend)
        return
    fresh = open_peer(backend)
    try:
        yield fresh
    finally:
        fresh.close()


@pytest.fixture(params=backend_params())
def fresh_peer(request: pytest.FixtureRequest) -> Iterator[Peer]:
    """A ground station on a vehicle booted for this test alone."""
    fresh = open_peer(request.param)
    try:
        yield fresh
    finally:
        fresh.close()


@pytest.fixture(params=backend_params())
def connecting_peer(request: pytest.FixtureRequest) -> Iterator[Peer]:
    """A ground station just connected to a vehicle booted for this test: nothing sent yet."""
    fresh = open_peer(request.param, start=False)
    try:
        yield fresh
    finally:
        fresh.close()


@pytest.fixture
def rover(peer: Peer) -> Iterator[Peer]:
    """A ready rover in HOLD, disarmed, WP_SPEED 3, streaming for a drive; disarmed after."""
    peer.wait_ready()
    with flight_params(peer, {"WP_SPEED": ROVER_SPEED_M_S}), streaming(peer):
        assert peer.set_mode("HOLD").result == mavlink2.MAV_RESULT_ACCEPTED
        yield peer
        peer.disarm()
        peer.set_mode(str(peer.spec.autopilot["manual_mode"]))


@pytest.fixture
def copter(peer: Peer) -> Iterator[Peer]:
    """A ready copter in GUIDED, disarmed, WPNAV_SPEED 500, streaming for a flight; landed
    and disarmed after."""
    peer.wait_ready()
    with flight_params(peer, {"WPNAV_SPEED": COPTER_SPEED_CM_S}), streaming(peer):
        assert peer.set_mode("GUIDED").result == mavlink2.MAV_RESULT_ACCEPTED
        yield peer
        if peer.is_armed():
            peer.set_mode("LAND")
            peer.wait_for("HEARTBEAT", 60.0, where=disarmed)
        peer.set_mode("STABILIZE")
