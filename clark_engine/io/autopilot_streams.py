"""What the adapter asks the autopilot to send: its streams, its version, its home.

ArduPilot streams nothing to a new ground station until asked: the adapter asks for
each of :data:`STREAMED_MESSAGES` (SET_MESSAGE_INTERVAL, the slow ones at
:data:`SLOW_STREAMS`' rates), again after a reconnection or a reboot, when no position
came for :data:`STREAM_SILENCE_S`, or when positions come at under half the rate asked
for (an acknowledgement does not prove the rate: :data:`STREAM_RATE_CHECK_S`); it probes
for AUTOPILOT_VERSION until answered and asks for HOME_POSITION until it comes.

Separate from the adapter because keeping the data flowing is one concern, measured on
SITL, apart from commanding. :class:`StreamRequests` is owned by the adapter and works
through a back-reference: the requests it queues are tracked with the adapter's others,
and the positions it counts are the decoder's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_requests import (
    ACK_TIMEOUT_S,
    Request,
    command_result_name,
    message_id,
)
from clark_engine.runtime.log_events import LogEvent

if TYPE_CHECKING:
    from clark_engine.io.autopilot import AutopilotAdapter

STREAM_SILENCE_S: Final = 3.0
"""No GLOBAL_POSITION_INT for this long while heartbeats arrive: ask for the streams again
(the autopilot rebooted, or another ground station turned them off)."""

STREAM_RATE_CHECK_S: Final = 2.0
"""Every this long, once the stream requests are answered, the positions that came are
counted: fewer than half the rate asked for, and the streams are asked for again.
ArduPilot acknowledges a SET_MESSAGE_INTERVAL sent before its first HEARTBEAT and then
streams at its own default (ArduRover SITL: GLOBAL_POSITION_INT at 1 Hz, measured), so an
acknowledgement does not prove the rate: a mission computer powered up with its
autopilot drove on 1 Hz positions, sending its guided targets up to a second late."""

STREAMED_MESSAGES: Final = (
    "GLOBAL_POSITION_INT",
    "ATTITUDE",
    "VFR_HUD",
    "SYSTEM_TIME",
    "RC_CHANNELS",
    "SERVO_OUTPUT_RAW",
    "SYS_STATUS",
    "GPS_RAW_INT",
    "EKF_STATUS_REPORT",
    "EXTENDED_SYS_STATE",
)
"""Messages :meth:`AutopilotAdapter.start` asks for."""

SLOW_STREAMS: Final = {
    "SYSTEM_TIME": 1.0,
    "SYS_STATUS": 1.0,
    "GPS_RAW_INT": 2.0,
    "SERVO_OUTPUT_RAW": 2.0,
    "EKF_STATUS_REPORT": 1.0,
    "EXTENDED_SYS_STATE": 1.0,
}
"""Messages the runtime needs only now and then, asked for at these rates (Hz) or the
profile's ``stream_rate_hz`` when slower: the clock's sync, health, readiness and raw
GPS do not need the loop rate, and a serial link at 57600 baud has little to spare."""

OPTIONAL_STREAMS: Final = frozenset({"EXTENDED_SYS_STATE"})
"""Streams an ArduPilot firmware may not have (ArduRover has no landed state): a refusal
is noted in the interface log, not reported as a refused command."""

HOME_REQUEST_PERIOD_S: Final = 2.0
"""HOME_POSITION is asked for this often until it arrives. ArduPilot sends it by itself
when home is set, but not to a ground station that connects afterwards."""


class StreamRequests:
    """The streams and one-off messages one adapter asks of its autopilot.

    Args:
        adapter: The adapter that owns it.
    """

    def __init__(self, adapter: AutopilotAdapter) -> None:
        self._adapter = adapter
        self._settings = adapter.settings
        self._log = adapter._log

    def keep_up(self, now_s: float) -> None:
        """While the autopilot is heard: the streams asked for (again) when due or too slow."""
        last_position_s = (
            -math.inf if self._adapter._position_s is None else self._adapter._position_s
        )
        if self._adapter._setup_due:
            self.queue(now_s)
        elif now_s - max(self._adapter._setup_s, last_position_s) >= STREAM_SILENCE_S:
            self._log.info(
                "autopilot sends no position; asking for the streams again",
                extra=LogEvent.AUTOPILOT_STREAMS.extra,
            )
            self.queue(now_s)
        elif now_s - self._adapter._rate_check_s >= STREAM_RATE_CHECK_S - 1e-9:
            self._check_rate(now_s)
        if self._adapter._legacy_streams_due:
            self._adapter._legacy_streams_due = False
            self._adapter._mav.send(
                self._adapter._mav.request_data_stream_encode(
                    self._settings.system_id,
                    self._settings.component_id,
                    mavlink2.MAV_DATA_STREAM_ALL,
                    max(1, round(self._settings.stream_rate_hz)),
                    1,
                )
            )

    def verify(self, now_s: float) -> None:
        """Ask for AUTOPILOT_VERSION (untracked: repeated until it arrives)."""
        # Untracked on purpose: it repeats until AUTOPILOT_VERSION arrives. Every other
        # attempt uses the older MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, for firmware
        # that predates MAV_CMD_REQUEST_MESSAGE.
        s = self._settings
        if self._adapter._verify_attempts % 2 == 0:
            command, p1 = (
                mavlink2.MAV_CMD_REQUEST_MESSAGE,
                mavlink2.MAVLINK_MSG_ID_AUTOPILOT_VERSION,
            )
        else:
            command, p1 = mavlink2.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES, 1
        self._adapter._mav.send(
            self._adapter._mav.command_long_encode(
                s.system_id, s.component_id, command, 0, p1, 0, 0, 0, 0, 0, 0
            )
        )
        self._adapter._verify_attempts += 1
        self._adapter._next_verify_s = now_s + ACK_TIMEOUT_S

    def request_home(self, now_s: float) -> None:
        """Ask for HOME_POSITION (untracked: repeated until home is set and sent)."""
        # Untracked, like the version probe: until home is set ArduPilot has none to send.
        s = self._settings
        self._adapter._mav.send(
            self._adapter._mav.command_long_encode(
                s.system_id,
                s.component_id,
                mavlink2.MAV_CMD_REQUEST_MESSAGE,
                0,
                mavlink2.MAVLINK_MSG_ID_HOME_POSITION,
                0,
                0,
                0,
                0,
                0,
                0,
            )
        )
        self._adapter._next_home_request_s = now_s + HOME_REQUEST_PERIOD_S

    def _check_rate(self, now_s: float) -> None:
        """Ask for the streams again when positions come at under half the rate asked for.

        Counted over the :data:`STREAM_RATE_CHECK_S` since the last check, and only once
        every stream request has been answered (until then the rate is not yet asked for).
        """
        window_s = now_s - self._adapter._rate_check_s
        counted, self._adapter._positions_counted = self._adapter._positions_counted, 0
        self._adapter._rate_check_s = now_s
        if any(r.setup for r in self._adapter._requests) or not math.isfinite(window_s):
            return
        rate_hz = counted / window_s
        asked_hz = 1e6 / self._adapter._interval_us
        if counted and rate_hz < 0.5 * asked_hz:
            self._log.info(
                "autopilot streams positions at %.1f Hz where %.1f Hz was asked for; "
                "asking for the streams again",
                rate_hz,
                asked_hz,
                extra=LogEvent.AUTOPILOT_STREAMS.extra,
            )
            self.queue(now_s)

    def queue(self, now_s: float) -> None:
        """Queue the stream requests afresh, as tracked requests due now."""
        self._adapter._setup_s = now_s
        self._adapter._rate_check_s = now_s
        self._adapter._positions_counted = 0
        self._adapter._setup_due = False
        self._adapter._requests = [r for r in self._adapter._requests if not r.setup]
        for name in STREAMED_MESSAGES:
            msg_id = message_id(name)
            interval_us = self._adapter._interval_us
            if name in SLOW_STREAMS:
                interval_us = max(interval_us, round(1e6 / SLOW_STREAMS[name]))
            self._adapter._requests.append(
                Request(
                    "MAV_CMD_SET_MESSAGE_INTERVAL",
                    mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL,
                    f"stream {name} every {interval_us} us",
                    self._adapter._tracker.long_builder(
                        mavlink2.MAV_CMD_SET_MESSAGE_INTERVAL, (msg_id, interval_us)
                    ),
                    setup=True,
                    answered=self._optional_stream(name) if name in OPTIONAL_STREAMS else None,
                    due_s=now_s,
                )
            )

    def _optional_stream(self, name: str) -> Callable[[int | None, float], None]:
        def answered(result: int | None, _now_s: float) -> None:
            if result != mavlink2.MAV_RESULT_ACCEPTED:
                why = "no answer" if result is None else command_result_name(result)
                self._log.info(
                    "autopilot does not stream %s (%s)",
                    name,
                    why,
                    extra=LogEvent.AUTOPILOT_STREAMS.extra,
                )

        return answered
