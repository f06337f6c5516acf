"""The simulated ArduPilot's streams: their requests and their schedule.

:class:`Streams` answers what a ground station asks of the streams (REQUEST_DATA_STREAM
setting a group's MAV1_* rate parameter, MAV_CMD_SET_MESSAGE_INTERVAL and
GET_MESSAGE_INTERVAL per message, MAV_CMD_REQUEST_MESSAGE) with ArduPilot's refusals and
texts, and works out every stream's interval (its own override, else its group's rate,
HEARTBEAT at 1 Hz) in emission order for the autopilot's ``advance``. The messages
themselves are :class:`~clark_engine.sim.ardupilot.telemetry.Telemetry`'s.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because which message
goes out how often is one concept: a helper object the autopilot owns
(``SimAutopilot.streams``). The intervals and due times stay on the autopilot, whose
``advance`` (the hot path) reads them at every step and whose parameter changes reset them;
this reads and sets them through it.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any, Final

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.sim.ardupilot.telemetry import (
    STREAM_GROUPS,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot

_INFO: Final = mavlink2.MAV_SEVERITY_INFO
_ACCEPTED: Final = int(mavlink2.MAV_RESULT_ACCEPTED)
_DENIED: Final = int(mavlink2.MAV_RESULT_DENIED)
_FAILED: Final = int(mavlink2.MAV_RESULT_FAILED)

HEARTBEAT_INTERVAL_US: Final = 1_000_000
MIN_INTERVAL_US: Final = 25_000
"""The fastest stream ArduPilot grants (40 Hz; a faster request is DENIED, measured)."""
NOT_STREAMED: Final[Mapping[str, frozenset[str]]] = {}
"""Streams a firmware does not have (none yet: ArduRover streams EXTENDED_SYS_STATE too,
with an undefined landed state)."""
_DATA_STREAM_PARAMS: Final[Mapping[int, str]] = {
    mavlink2.MAV_DATA_STREAM_RAW_SENSORS: "MAV1_RAW_SENS",
    mavlink2.MAV_DATA_STREAM_EXTENDED_STATUS: "MAV1_EXT_STAT",
    mavlink2.MAV_DATA_STREAM_RC_CHANNELS: "MAV1_RC_CHAN",
    mavlink2.MAV_DATA_STREAM_RAW_CONTROLLER: "MAV1_RAW_CTRL",
    mavlink2.MAV_DATA_STREAM_POSITION: "MAV1_POSITION",
    mavlink2.MAV_DATA_STREAM_EXTRA1: "MAV1_EXTRA1",
    mavlink2.MAV_DATA_STREAM_EXTRA2: "MAV1_EXTRA2",
    mavlink2.MAV_DATA_STREAM_EXTRA3: "MAV1_EXTRA3",
}
STREAM_RATES: Final = frozenset(_DATA_STREAM_PARAMS.values())
"""The stream-rate parameters REQUEST_DATA_STREAM sets (those of the groups it streams start
at the firmware's default rate)."""


class Streams:
    """The stream requests and schedule of one simulated autopilot (owned by it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap

    def request_data_stream(self, msg: Any) -> None:
        """REQUEST_DATA_STREAM: a group's rate parameter set (0 stops it)."""
        rate_hz = msg.req_message_rate if msg.start_stop else 0
        if msg.req_stream_id == mavlink2.MAV_DATA_STREAM_ALL:
            params = list(_DATA_STREAM_PARAMS.values())
        else:
            param = _DATA_STREAM_PARAMS.get(msg.req_stream_id)
            params = [] if param is None else [param]
        for param in params:
            self._ap.parameters.set(param, rate_hz)

    def streamed_name(self, msg_id: int) -> str | None:
        """The name of a message it streams, None if it streams no such message."""
        entry = mavlink2.mavlink_map.get(msg_id)
        name = None if entry is None else str(entry.msgname)
        return name if name in STREAM_GROUPS and name not in self._ap._absent else None

    def message_interval(self, msg_id: int, interval_us: int, now_s: float) -> int:
        """MAV_CMD_SET_MESSAGE_INTERVAL for one message; returns MAV_RESULT."""
        name = self.streamed_name(msg_id)
        if name is None:
            self._ap._text(_INFO, f"No ap_message for mavlink id ({msg_id})")
            return _DENIED  # ArduPilot: no such message to stream
        if 0 < interval_us < MIN_INTERVAL_US:
            self._ap._text(
                _INFO, f"Requested rate for message ID {msg_id} too fast. Increase SCHED_LOOP_RATE"
            )
            return _DENIED
        if (
            self._ap.fw.early_stream_requests_lost
            and not self._ap._heartbeat_sent
            and now_s <= self._ap.boot_s
        ):
            return _ACCEPTED  # before the first HEARTBEAT: acknowledged, and lost (measured)
        if interval_us == 0:
            self._ap._interval_us.pop(name, None)
            self._ap._schedule = None
            default = self._default_interval_us(name)
            if default is not None:
                self._ap._due_us[name] = round(now_s * 1e6) + default
        elif interval_us < 0:
            self._set_interval(name, None, now_s)
        else:
            self._set_interval(name, interval_us, now_s)
        return _ACCEPTED

    def request_message(self, msg_id: int) -> int:
        """MAV_CMD_REQUEST_MESSAGE: the message queued, sent after the ack; MAV_RESULT."""
        entry = mavlink2.mavlink_map.get(msg_id)
        name = None if entry is None else str(entry.msgname)
        if (
            name not in (*STREAM_GROUPS, "HOME_POSITION", "AUTOPILOT_VERSION")
            or name in self._ap._absent
        ):
            return _FAILED
        # ArduPilot acknowledges first and sends the message from its next update (and
        # HOME_POSITION only once home is set).
        self._ap._deferred.append(str(name))
        return _ACCEPTED

    def schedule(self) -> tuple[tuple[str, int | None], ...]:
        """(message, interval in us or None when stopped) for every stream, in emission order."""
        if self._ap._schedule is None:
            self._ap._schedule = tuple(
                (name, None if name in self._ap._absent else self.interval_us(name))
                for name in STREAM_GROUPS
            )
        return self._ap._schedule

    def interval_us(self, name: str) -> int | None:
        """A stream's interval (us): its own override, else its group's rate."""
        if name in self._ap._interval_us:
            return self._ap._interval_us[name]
        return self._default_interval_us(name)

    def _default_interval_us(self, name: str) -> int | None:
        group = STREAM_GROUPS.get(name)
        if group is None:
            return HEARTBEAT_INTERVAL_US if name == "HEARTBEAT" else None
        rate_hz = self._ap._params[group].value
        return round(1e6 / rate_hz) if rate_hz > 0 else None

    def _set_interval(self, name: str, interval_us: int | None, now_s: float) -> None:
        self._ap._next_due_us = 0  # the schedule changed: look at every stream next time
        self._ap._schedule = None
        self._ap._interval_us[name] = interval_us
        if interval_us is not None:
            self._ap._due_us[name] = round(now_s * 1e6) + interval_us
