"""The autopilot adapter carrying out the safety set-up: set, upload, read back, answer.

:class:`SafetySetup` runs one
:class:`~clark_engine.runtime.commands.SetUpAutopilotSafety` for the
:class:`~clark_engine.io.autopilot.AutopilotAdapter` (docs/safety.md#held-by-the-autopilot),
one step at a time, each once the one before it took, and ends with an
:class:`~clark_engine.runtime.events.AutopilotSafetyResult`:

1. The ground-station id. Each of the command's names for it is read
   (PARAM_REQUEST_READ); the newest the autopilot answers to is set to the adapter's own
   system id, and a HEARTBEAT follows at once: ArduPlane's failsafe clock runs from
   boot, so without a heartbeat from the new id before the failsafe is switched on it
   would fire at once.
2. Each step: a parameter set (PARAM_SET) and read back from ArduPilot's answer to it,
   the PARAM_VALUE echo of what it stored (``AP_Param::save_sync``); an ``at_most``
   parameter read first and set only when above the value; the fence list uploaded
   (:mod:`clark_engine.io.mission_upload`); a pause (by :meth:`SafetySetup.poll`).

What counts as taken: the echo equals the value asked, as the parameter's type holds it
(float32, or for an integer parameter the value truncated as ArduPilot truncates:
``AP_Param::set_float`` adds 0.01 away from zero, then casts). ArduPilot clamps an
integer to its type's range and never enforces a parameter's documented range, so
FENCE_TYPE 300 reads 127: not taken. A name the autopilot does not have gets no answer
at all (``GCS_MAVLINK::handle_param_set``); after the adapter's retries (three sends,
one second apart) that is reported as not taken. An internal parameter is refused with
"Param write denied" and its old value: not taken.

The first step that does not take ends the set-up (the later ones are not sent): a
failsafe must not be switched on without its id, nor a fence without its type. A
set-up cut short by the autopilot's silence or reboot ends with ``retry``, so that the
runtime asks again once the autopilot is back.
"""

from __future__ import annotations

import math
import struct
from collections.abc import Callable
from typing import Any, Final, Protocol

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.mission_upload import MissionUpload, mission_result_name
from clark_engine.runtime.commands import Pause, SetParam, SetUpAutopilotSafety, UploadFence
from clark_engine.runtime.events import AutopilotSafetyResult

INTEGER_TYPES: Final[dict[int, tuple[int, int]]] = {
    int(mavlink2.MAV_PARAM_TYPE_UINT8): (0, 255),
    int(mavlink2.MAV_PARAM_TYPE_INT8): (-128, 127),
    int(mavlink2.MAV_PARAM_TYPE_UINT16): (0, 65535),
    int(mavlink2.MAV_PARAM_TYPE_INT16): (-32768, 32767),
    int(mavlink2.MAV_PARAM_TYPE_UINT32): (0, 4294967295),
    int(mavlink2.MAV_PARAM_TYPE_INT32): (-2147483648, 2147483647),
}
"""MAV_PARAM_TYPEs that hold integers, and their ranges."""

ParamAnswer = Callable[[float | None, int | None, float], None]
"""Hears one parameter's answer: its value and type, or None twice when none came."""


class SetupLink(Protocol):
    """What the set-up needs of the adapter (implemented by ``AdapterSetupLink``)."""

    def setup_read(self, name: str, now_s: float, answer: ParamAnswer) -> None:
        """Read a parameter (tracked, resent); ``answer`` hears its value or its silence."""

    def setup_write(self, name: str, value: float, now_s: float, answer: ParamAnswer) -> None:
        """Set a parameter (tracked, resent); ``answer`` hears its echo or its silence."""

    def setup_forget(self, name: str) -> None:
        """Stop waiting for a parameter's answer (the set-up no longer needs it)."""

    def setup_heartbeat(self, now_s: float) -> None:
        """Send our HEARTBEAT now."""

    def setup_upload(self, zones: UploadFence, now_s: float) -> MissionUpload:
        """Start uploading the fence list."""

    def setup_heard_since(self, t_s: float) -> bool:
        """True when the autopilot was heard (HEARTBEAT) at or after ``t_s``."""

    def setup_reasons(self, since_s: float, now_s: float) -> str:
        """The autopilot's warnings (STATUSTEXT) from ``since_s`` to now, joined."""

    def setup_note(self, text: str) -> None:
        """Write a line about the set-up to the interface log."""

    @property
    def own_system_id(self) -> int:
        """The adapter's own MAVLink system id."""


def took(asked: float, echoed: float, param_type: int | None) -> bool:
    """True when an echo shows the value asked, as the parameter's type stores it."""
    limits = INTEGER_TYPES.get(param_type) if param_type is not None else None
    if limits is not None:
        low, high = limits
        stored = math.trunc(asked + math.copysign(0.01, asked))
        return low <= stored <= high and echoed == float(stored)
    return echoed == float(struct.unpack("<f", struct.pack("<f", asked))[0])


class SafetySetup:
    """One safety set-up under way, driven by the adapter.

    Args:
        command: What to set up.
        link: The adapter's link (:class:`~clark_engine.io.autopilot_setup_link.AdapterSetupLink`).
        report: Called once with the result.
    """

    def __init__(
        self,
        command: SetUpAutopilotSafety,
        link: SetupLink,
        report: Callable[[AutopilotSafetyResult], None],
    ) -> None:
        self.command = command
        self._link = link
        self._report = report
        self._steps = list(command.steps)
        self._upload: MissionUpload | None = None
        self._resume_s: float | None = None  # a pause under way ends then
        self._upload_started_s = 0.0
        self._step_started_s = 0.0
        self._reading: dict[str, tuple[float | None, bool]] = {}  # name -> (value, answered)
        self.done = False
        self.took_names: set[str] = set()
        """Parameters this set-up wrote and read back (the adapter's close reverts some)."""

    def start(self, now_s: float) -> None:
        """Send the first step."""
        self._step_started_s = now_s
        if self.command.gcs_id_names:
            self._resolve_gcs_id(now_s)
        else:
            self._next(now_s)

    # -- the adapter's hooks ------------------------------------------------------------

    def on_mission(self, msg: Any, own: tuple[int, int], now_s: float) -> bool:
        """A mission-protocol message from the autopilot; True when the upload took it."""
        upload = self._upload
        if upload is None or not upload.handle(msg, own, now_s):
            return False
        if upload.done:
            self._upload_over(now_s)
        return True

    def poll(self, now_s: float) -> None:
        """Time passes: a pause ends; a silent upload is restarted or given up."""
        if self._resume_s is not None and now_s >= self._resume_s:
            self._resume_s = None
            self._next(now_s)
            return
        upload = self._upload
        if upload is None:
            return
        upload.poll(now_s)
        if upload.done:
            self._upload_over(now_s)

    def interrupted(self, why: str) -> None:
        """The autopilot fell silent or rebooted: the set-up ends, to be asked again."""
        self._fail(f"the autopilot {why} during the set-up", None, retry=True)

    # -- the ground-station id -------------------------------------------------------------

    def _resolve_gcs_id(self, now_s: float) -> None:
        names = self.command.gcs_id_names
        self._reading = {}
        for name in names:
            self._reading[name] = (None, False)
            self._link.setup_read(name, now_s, self._gcs_id_read(name))

    def _gcs_id_read(self, name: str) -> ParamAnswer:
        def answer(value: float | None, _param_type: int | None, now_s: float) -> None:
            if self.done or name not in self._reading:
                return
            self._reading[name] = (value, True)
            names = self.command.gcs_id_names
            for candidate in names:
                got, answered = self._reading[candidate]
                if not answered:
                    return  # a newer name may still answer: wait for it
                if got is not None:
                    for other in names:
                        if other != candidate and not self._reading[other][1]:
                            self._link.setup_forget(other)
                    self._reading = {}
                    self._write(
                        SetParam((candidate,), float(self._link.own_system_id)),
                        candidate,
                        now_s,
                        then=self._gcs_id_set,
                    )
                    return
            self._fail(
                f"none of {', '.join(names)} answers: the autopilot has no parameter naming "
                "its ground station, so its failsafe cannot watch this computer (not "
                "ArduPilot, or a version the engine does not know)",
                names[0],
                retry=not self._link.setup_heard_since(self._step_started_s),
            )

        return answer

    def _gcs_id_set(self, now_s: float) -> None:
        self._link.setup_heartbeat(now_s)  # the failsafe's clock starts from this computer now
        self._next(now_s)

    # -- the steps ----------------------------------------------------------------------

    def _next(self, now_s: float) -> None:
        if self.done:
            return
        self._step_started_s = now_s
        if not self._steps:
            self.done = True
            self._report(AutopilotSafetyResult())
            return
        step = self._steps.pop(0)
        if isinstance(step, Pause):
            self._resume_s = now_s + step.seconds
            return
        if isinstance(step, UploadFence):
            self._upload_started_s = now_s
            self._upload = self._link.setup_upload(step, now_s)
            if self._upload.done:
                self._upload_over(now_s)
            return
        name = step.name
        if step.at_most:
            self._link.setup_read(name, now_s, self._at_most_read(step))
            return
        self._write(step, name, now_s, then=self._next)

    def _at_most_read(self, step: SetParam) -> ParamAnswer:
        def answer(value: float | None, _param_type: int | None, now_s: float) -> None:
            if self.done:
                return
            if value is None:
                self._silent(step.name, step.value)
            elif value <= step.value:
                self._link.setup_note(f"{step.name} = {value:g}, kept (at most {step.value:g})")
                self._next(now_s)  # already low enough: the pilot's choice stands
            else:
                self._write(step, step.name, now_s, then=self._next)

        return answer

    def _write(
        self, step: SetParam, name: str, now_s: float, *, then: Callable[[float], None]
    ) -> None:
        def answer(value: float | None, param_type: int | None, at_s: float) -> None:
            if self.done:
                return
            if value is None:
                self._silent(name, step.value)
            elif took(step.value, value, param_type):
                self.took_names.add(name)
                self._link.setup_note(f"{name} = {value:g} (read back)")
                then(at_s)
            else:
                reason = self._link.setup_reasons(self._step_started_s, at_s)
                self._fail(
                    f"{name} did not take: reads {value:g}, asked {step.value:g}"
                    + (f" ({reason})" if reason else ""),
                    name,
                    retry=False,
                )

        self._link.setup_write(name, step.value, now_s, answer)

    def _silent(self, name: str, value: float) -> None:
        heard = self._link.setup_heard_since(self._step_started_s)
        self._fail(
            f"{name} did not take: the autopilot did not answer for it ({value:g} asked)"
            + ("; it may have no such parameter" if heard else "; the autopilot fell silent"),
            name,
            retry=not heard,
        )

    def _upload_over(self, now_s: float) -> None:
        upload = self._upload
        assert upload is not None
        self._upload = None
        if upload.result == mavlink2.MAV_MISSION_ACCEPTED:
            self._link.setup_note(
                f"fence list of {upload.count} item(s) accepted"
                if upload.count
                else "fence list cleared (no zones declared)"
            )
            self._next(now_s)
            return
        if upload.gave_up:
            heard = self._link.setup_heard_since(self._upload_started_s)
            self._fail(
                "the fence list upload got no answer"
                + ("" if heard else "; the autopilot fell silent"),
                None,
                retry=not heard,
            )
            return
        assert upload.result is not None
        reason = self._link.setup_reasons(self._upload_started_s, now_s)
        self._fail(
            f"the autopilot refused the fence list: {mission_result_name(upload.result)}"
            + (f" ({reason})" if reason else ""),
            None,
            retry=False,
        )

    def _fail(self, problem: str, parameter: str | None, *, retry: bool) -> None:
        if self.done:
            return
        self.done = True
        for name in self._reading:
            self._link.setup_forget(name)
        self._reading = {}
        self._upload = None
        self._report(AutopilotSafetyResult(problem, parameter, retry))
