"""The adapter's side of the safety set-up: the link a set-up drives, and its hooks.

:class:`~clark_engine.io.autopilot_setup.SafetySetup` carries out a
:class:`~clark_engine.runtime.commands.SetUpAutopilotSafety` through a
:class:`~clark_engine.io.autopilot_setup.SetupLink`; :class:`AdapterSetupLink` is that
link for an :class:`~clark_engine.io.autopilot.AutopilotAdapter` (parameters read and set
as tracked requests, the fence list's upload, the autopilot's warnings as reasons), and
the adapter's hooks around a set-up: its start, its result reported as an event, and the
clean stop that switches off what it switched on.

Separate from the adapter because the safety set-up is one procedure with its own
protocol, and from :mod:`~clark_engine.io.autopilot_setup` because this side knows the
adapter's MAVLink encoder and requests. It works through a back-reference: the set-up
under way and the parameters' answers are the adapter's, which its decoder feeds.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from pymavlink.dialects.v20 import ardupilotmega as mavlink2

from clark_engine.io.autopilot_requests import Request, param_id_bytes
from clark_engine.io.autopilot_setup import ParamAnswer, SafetySetup
from clark_engine.io.mission_upload import MissionUpload, fence_items
from clark_engine.runtime.commands import SetUpAutopilotSafety, UploadFence
from clark_engine.runtime.events import AutopilotSafetyResult
from clark_engine.runtime.log_events import LogEvent
from clark_engine.untrusted import printable

if TYPE_CHECKING:
    from clark_engine.io.autopilot import AutopilotAdapter


class AdapterSetupLink:
    """The safety set-up's link to one adapter, and the adapter's hooks around a set-up.

    Args:
        adapter: The adapter that owns it.
    """

    def __init__(self, adapter: AutopilotAdapter) -> None:
        self._adapter = adapter
        self._settings = adapter.settings
        self._log = adapter._log

    def start(self, cmd: SetUpAutopilotSafety, now_s: float) -> None:
        """Start a safety set-up; one under way is dropped (the runtime asks once at a time)."""
        if self._adapter._safety is not None:
            self._log.warning(
                "a new safety set-up replaces the one under way",
                extra=LogEvent.AUTOPILOT_SAFETY.extra,
            )
            self._adapter._param_answers.clear()
        self._log.info(
            "safety set-up: %s",
            cmd.summary or "(no summary)",
            extra=LogEvent.AUTOPILOT_SAFETY.extra,
        )
        self._adapter._safety = SafetySetup(cmd, self, self._over)
        self._adapter._safety.start(now_s)

    def _over(self, result: AutopilotSafetyResult) -> None:
        safety, self._adapter._safety = self._adapter._safety, None
        if safety is not None:
            # What it switched on, a clean stop switches off, whether or not the rest took.
            close = dict(self._adapter._on_close)
            close.update(
                (p.name, p.value) for p in safety.command.on_close if p.name in safety.took_names
            )
            self._adapter._on_close = tuple(close.items())
        if result.ok:
            self._log.info(
                "safety set-up: every parameter took", extra=LogEvent.AUTOPILOT_SAFETY.extra
            )
        else:
            self._log.error(
                "safety set-up failed: %s",
                printable(result.problem),
                extra=LogEvent.AUTOPILOT_SAFETY.extra,
            )
        self._adapter._late_events.append(result)

    def close(self, now_s: float) -> None:
        """A clean stop: write the set-up's on_close (the failsafe switched off).

        Only what a set-up switched on (its value read back) is switched off, whether or
        not the set-up as a whole took. Sent at once and tracked: the autopilot's echo
        answers it, :meth:`poll` resends it meanwhile, and a shell that may wait does
        (:attr:`unanswered`); one that may not has sent it once.
        """
        for name, value in self._adapter._on_close:
            self._log.info(
                "leaving on purpose: %s = %g", name, value, extra=LogEvent.AUTOPILOT_SAFETY.extra
            )
            self._adapter._param_set(name, value, now_s, lambda _result, _at_s: None)
        self._adapter.left_on_purpose = tuple(name for name, _value in self._adapter._on_close)
        self._adapter._on_close = ()

    def _param_silent(self, name: str, now_s: float) -> None:
        for answer in self._adapter._param_answers.pop(name, ()):
            answer(None, None, now_s)

    def setup_read(self, name: str, now_s: float, answer: ParamAnswer) -> None:
        """Read a parameter for the safety set-up; ``answer`` hears it or its silence."""
        self._adapter._param_answers.setdefault(name, []).append(answer)
        param_id = param_id_bytes(name)
        s = self._settings
        self._adapter._tracker.track(
            Request(
                "PARAM_REQUEST_READ",
                name,
                f"read {name}",
                lambda _attempt: self._adapter._mav.param_request_read_encode(
                    s.system_id, s.component_id, param_id, -1
                ),
                answered=lambda _result, at_s: self._param_silent(name, at_s),
            ),
            now_s,
        )

    def setup_write(self, name: str, value: float, now_s: float, answer: ParamAnswer) -> None:
        """Set a parameter for the safety set-up; ``answer`` hears its echo or its silence."""
        self._adapter._param_answers.setdefault(name, []).append(answer)
        self._adapter._param_set(
            name, value, now_s, lambda _result, at_s: self._param_silent(name, at_s)
        )

    def setup_forget(self, name: str) -> None:
        """Stop asking for a parameter the set-up no longer needs."""
        self._adapter._param_answers.pop(name, None)
        self._adapter._requests = [r for r in self._adapter._requests if r.key != name]

    def setup_heartbeat(self, now_s: float) -> None:
        """Send our HEARTBEAT now, off its 1 Hz grid."""
        self._adapter._heartbeat_out(now_s)

    def setup_upload(self, zones: UploadFence, now_s: float) -> MissionUpload:
        """Start replacing the autopilot's fence list."""
        s = self._settings
        return MissionUpload(
            self._adapter._mav,
            (s.system_id, s.component_id),
            fence_items(zones.zones),
            int(mavlink2.MAV_MISSION_TYPE_FENCE),
            now_s,
        )

    def setup_heard_since(self, t_s: float) -> bool:
        """True when a HEARTBEAT from the autopilot arrived at or after ``t_s``."""
        return self._adapter._heartbeat_s is not None and self._adapter._heartbeat_s >= t_s

    def setup_reasons(self, since_s: float, now_s: float) -> str:
        """The autopilot's warnings since ``since_s`` (escaped), joined by ``; ``."""
        return "; ".join(text for t, text in self._adapter._warnings if since_s <= t <= now_s)

    def setup_note(self, text: str) -> None:
        """A line of the safety set-up for the interface log."""
        self._log.info("safety set-up: %s", text, extra=LogEvent.AUTOPILOT_SAFETY.extra)

    @property
    def own_system_id(self) -> int:
        """Our MAVLink system id: the one the autopilot's ground-station failsafe watches."""
        return self._settings.source_system_id
