"""The simulated ArduPilot's RC overrides: RC_CHANNELS_OVERRIDE as ArduPilot takes them.

:class:`RcOverrides` keeps the channels a ground station (MAV_GCS_SYSID only) overrides,
hands their widths to the vehicle model, counts each override as the station's heartbeat,
releases a channel on 0 (channels 1-8) or UINT16_MAX - 1 (9-18), and lets every override
lapse RC_OVERRIDE_TIME after it was last sent (never, when negative; none taken at 0).

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because the overrides
are a state of their own that only this reads and changes: a helper object the autopilot
owns (``SimAutopilot.rc_overrides``), handed each RC_CHANNELS_OVERRIDE, asked to expire them
at each step and to clear them when a failsafe does.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Final

from clark_engine.sim.ardupilot.telemetry import (
    UINT16_MAX,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot


_RC_RELEASE_HIGH: Final = UINT16_MAX - 1


class RcOverrides:
    """The RC overrides of one simulated autopilot (owned by it, acting on its model).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap
        self.channels: dict[int, tuple[int, float]] = {}
        """Channel -> (pulse width in us, time it was set) of every override in force."""

    def receive(self, msg: Any, now_s: float) -> None:
        """RC_CHANNELS_OVERRIDE, taken from MAV_GCS_SYSID only."""
        if msg.get_srcSystem() != self._ap._gcs_sysid():
            return  # ArduPilot takes overrides only from its ground station
        self._ap.gcs_failsafe.seen(now_s)  # (an override is its heartbeat too)
        if self._ap._params["RC_OVERRIDE_TIME"].value == 0:
            return  # overrides disabled
        changes: dict[int, int] = {}
        for channel in range(1, 19):
            value = getattr(msg, f"chan{channel}_raw")
            if channel <= 8:
                if value == UINT16_MAX:
                    continue
                release = value == 0
            else:
                if value in (0, UINT16_MAX):
                    continue
                release = value == _RC_RELEASE_HIGH
            if release:
                if self.channels.pop(channel, None) is not None:
                    changes[channel] = 0
            else:
                self.channels[channel] = (int(value), now_s)
                changes[channel] = int(value)
        if changes:
            self._ap.model.set_rc_override(changes)

    def expire(self, now_s: float) -> None:
        """Release the overrides older than RC_OVERRIDE_TIME."""
        timeout_s = self._ap._params["RC_OVERRIDE_TIME"].value
        if timeout_s < 0 or not self.channels:
            return  # negative: overrides never time out
        expired = {ch: 0 for ch, (_pwm, at_s) in self.channels.items() if now_s - at_s > timeout_s}
        for channel in expired:
            del self.channels[channel]
        if expired:
            self._ap.model.set_rc_override(expired)

    def clear(self) -> None:
        """Drop every override (``RC_Channels::clear_overrides``, as a failsafe does)."""
        if self.channels:
            released = dict.fromkeys(self.channels, 0)
            self.channels.clear()
            self._ap.model.set_rc_override(released)
