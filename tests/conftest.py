"""Shared fixtures: no network beyond loopback, paths to the shipped data."""

from __future__ import annotations

import ipaddress
import socket
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parent.parent
MISSIONS = sorted((ROOT / "missions").glob("*.yaml"))


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


@pytest.fixture
def root() -> Path:
    """The repository root."""
    return ROOT


def pytest_collection_modifyitems(config: pytest.Config, items: list[pytest.Item]) -> None:
    """Run the slow tests (real ArduPilot SITL, real-time rehearsals, wheels) first.

    `make test` spreads the suite over the machine's cores (pytest-xdist, `-n auto`); a
    long test dealt out last would keep one core busy while the others idle, so they are
    dealt out first. The order of the rest is unchanged (the sort is stable), and every
    test is independent of order.
    """
    items.sort(
        key=lambda item: (
            0 if item.get_closest_marker("sitl") or item.get_closest_marker("slow") else 1
        )
    )
