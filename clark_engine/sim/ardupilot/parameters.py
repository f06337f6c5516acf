"""The simulated ArduPilot's parameters: PARAM_* answered as ArduPilot 4.7 answers them.

:class:`Parameters` answers PARAM_REQUEST_LIST (the whole list, paced at
:data:`PARAM_LIST_RATE_HZ`), PARAM_REQUEST_READ (by index, or by name with index 65535)
and PARAM_SET (the value stored in the parameter's own type and echoed; unknown names,
NaN and infinities get no answer), and does what setting a parameter does: a stream rate
restarts its group's streams, the fence looks again, the vehicle model is configured anew.
The table itself (SITL's names, types, values and order) is
:class:`~clark_engine.sim.ardupilot.params.ParamStore`'s.

Apart from :class:`~clark_engine.sim.ardupilot.autopilot.SimAutopilot` because the parameter
protocol is one concept: a helper object the autopilot owns (``SimAutopilot.parameters``),
handed each PARAM_* message. It keeps only the progress of the list being sent; the table
and what a change resets (the streams' schedule, the fence's quiet) stay on the autopilot,
which its other parts read at every step.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, Final

from clark_engine.sim.ardupilot.streams import STREAM_RATES
from clark_engine.sim.ardupilot.telemetry import (
    STREAM_GROUPS,
)

if TYPE_CHECKING:
    from clark_engine.sim.ardupilot.autopilot import SimAutopilot


_PARAM_INDEX_BY_NAME: Final = 65535
PARAM_LIST_RATE_HZ: Final = 1000.0
"""PARAM_VALUEs a second in answer to PARAM_REQUEST_LIST (see :meth:`Parameters.send_list`)."""


class Parameters:
    """The parameter protocol of one simulated autopilot (owned by it, acting through it).

    Args:
        ap: The autopilot it belongs to.
    """

    def __init__(self, ap: SimAutopilot) -> None:
        self._ap = ap
        self.list_from_s: float | None = None
        """When the PARAM_REQUEST_LIST being answered came; None: no list being sent."""
        self.list_sent = 0
        """How many of that list were sent."""

    def handle_set(self, msg: Any) -> None:
        """PARAM_SET as ArduPilot's GCS_MAVLINK::handle_param_set.

        An unknown name, NaN or an infinity: no answer at all, nothing changes.
        Otherwise the value is stored (as :meth:`set` converts it) and echoed in
        one PARAM_VALUE with the parameter's own type, index 65535, even when unchanged.
        """
        name = str(msg.param_id)
        value = float(msg.param_value)
        if name not in self._ap.params or not math.isfinite(value):
            return
        self.set(name, value)
        self._send(name, _PARAM_INDEX_BY_NAME)

    def set(self, name: str, value: float) -> None:
        """Store a value as AP_Param::set_float does (:func:`ap_params.stored`).

        The stored type decides, whatever type the sender said. A parameter the
        simulation acts on takes effect at once (stream rates, the fence, the model).
        """
        if not math.isfinite(value) or not self._ap.params.set(name, value):
            return  # (a parameter only listed: stored, nothing acts on it)
        self._ap._next_due_us = 0  # a stream-rate parameter may have changed
        self._ap._schedule = None
        self._ap._fence_quiet = False  # a fence parameter may have changed
        if name in STREAM_RATES:  # a new group rate replaces the per-message intervals
            for stream, group in STREAM_GROUPS.items():
                if group == name:
                    self._ap._interval_us.pop(stream, None)
                    self._ap._due_us.pop(stream, None)
        elif hasattr(self._ap, "model"):
            self._ap.model.configure(self._ap.param_values())  # the whole table, as configure wants

    def _send(self, name: str, index: int) -> None:
        found = self._ap.params.get(name)
        if found is None:
            return
        value, param_type = found
        self._ap._mav.send(
            self._ap._mav.param_value_encode(
                name.encode("ascii"), value, param_type, self._ap.params.count, index
            )
        )

    def send_list(self, now_s: float) -> None:
        """The next part of the list a PARAM_REQUEST_LIST asked for, PARAM_LIST_RATE_HZ paced.

        ArduPilot sends the list a few at a time from its main loop (SITL's TCP link took
        0.4 s for 1,354); sent in one go it would be one 50 kB burst, more than a ground
        station's UDP socket takes at once.
        """
        start_s = self.list_from_s
        assert start_s is not None
        due = min(self._ap.params.count, 1 + int((now_s - start_s) * PARAM_LIST_RATE_HZ))
        for index in range(self.list_sent, due):
            name = self._ap.params.name_at(index)
            if name is not None:
                self._send(name, index)
        self.list_sent = due
        if due >= self._ap.params.count:
            self.list_from_s = None

    def handle_read(self, msg: Any) -> None:
        """PARAM_REQUEST_READ: one parameter by index, or by name (index 65535)."""
        if msg.param_index >= 0:
            name = self._ap.params.name_at(msg.param_index)
            if name is not None:
                self._send(name, msg.param_index)
            return
        name = str(msg.param_id)
        if name in self._ap.params:
            self._send(name, _PARAM_INDEX_BY_NAME)
