"""The real-time shell's links: the autopilot and the radio, opened (and reopened) by factory.

:class:`~clark_engine.shells.realtime.RealtimeShell` opens them, watches them and, when one
fails, closes it and opens it again from its loop with a growing back-off
(:data:`REOPEN_BACKOFF_S`). Kept apart from the shell because ``clark run``
(:mod:`clark_engine.shells.agent`) and the tests build them, each from its own transport
or radio factory, without the loop.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Final

from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.radio import Radio
from clark_engine.io.transports import Transport

REOPEN_BACKOFF_S: Final = (0.5, 1.0, 2.0, 4.0, 8.0)
"""Waits before each successive attempt to reopen a failed link; the last one repeats."""


class _Reopen:
    """When a failed link may be tried again, with a growing back-off."""

    def __init__(self) -> None:
        self.failures = 0
        self.next_s = -math.inf
        self.last_error: str | None = None

    def failed(self, now_s: float, error: str) -> float:
        wait = REOPEN_BACKOFF_S[min(self.failures, len(REOPEN_BACKOFF_S) - 1)]
        self.failures += 1
        self.next_s = now_s + wait
        self.last_error = error
        return wait

    def succeeded(self) -> None:
        self.failures = 0
        self.last_error = None


class AutopilotLink:
    """The autopilot: a transport opened (and reopened) from a factory, and its adapter.

    Args:
        adapter: The MAVLink adapter (pure).
        open_transport: Opens the transport; raises TransportError when it cannot.
        describe: The link in words (``serial /dev/ttyACM0``, ``tcp 127.0.0.1:5760``).
    """

    def __init__(
        self,
        adapter: AutopilotAdapter,
        open_transport: Callable[[], Transport],
        describe: str,
    ) -> None:
        self.adapter = adapter
        self.open_transport = open_transport
        self.describe = describe
        self.transport: Transport | None = None
        self.started = False
        self.reopen = _Reopen()


class RadioLink:
    """The radio, opened (and reopened) from a factory.

    Args:
        open_radio: Builds, opens and verifies the radio; raises RadioError.
        describe: The radio in words.
    """

    def __init__(self, open_radio: Callable[[], Radio], describe: str) -> None:
        self.open_radio = open_radio
        self.describe = describe
        self.radio: Radio | None = None
        self.reopen = _Reopen()
