"""The events of the mission and interface logs: their stable names and what readers parse.

Why: ``clark replay``, ``clark analyze --checks`` and the station's view rebuild a run from
its text log lines. Lines used to name the Python module and function that wrote them
(``runtime._on_change``), so renaming or moving a private method broke every reader and
every log written before. Each line now names an **event** instead (``behavior.change``),
declared here once with the log it goes to, its levels, what it means and the fields of
its message that readers rely on. The name says what happened, never where the code is:
moving or renaming code changes no log byte. An event's name and fields are an interface
(docs/logs.md, "Compatibility"): renaming one is a breaking change.

The scheme: ``<subject>.<what happened>``, lower case, one dot. Subjects: ``log`` (the
logbook itself), ``air`` (per-packet accounting), ``agent``, ``behavior``, ``launch``,
``failsafe``, ``envelope``, ``fleet``, ``station``, ``command``, ``terminate``,
``autopilot``, ``radio``, ``photo``, ``shell``, ``view``, ``alarm``, ``sim``.

A call site declares its event with ``extra=LogEvent.X.extra``::

    self.logbook.mission.info("found %s", name, extra=LogEvent.FLEET_FOUND.extra)

The standard ``logging.Logger`` API is kept (the loggers are passed to primitives, the
autopilot adapter and the shells as plain loggers), with no wrapper that would need every
caller to change type; ``.extra`` is one mapping per event, built once, so a call costs
no allocation for it. ``tests/test_log_events.py`` scans the package and fails on any
call to an agent's logger without a declared event, and checks docs/logs.md's table.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from enum import StrEnum
from types import MappingProxyType
from typing import Literal

#: The log record attribute that carries the event name (the line format's field).
RECORD_ATTRIBUTE = "clark_event"
#: What a line names when its call declared no event (a bug the tests catch).
UNDECLARED = "undeclared"


class LogEvent(StrEnum):
    """Every event an agent's mission or interface log line can name (see :data:`SPECS`)."""

    LOG_OPEN = "log.open"
    AIR_REJECTED = "air.rejected"
    AIR_SUMMARY = "air.summary"
    AGENT_START = "agent.start"
    AGENT_NO_ENVELOPE = "agent.no_envelope"
    AGENT_TERMINATING = "agent.terminating"
    AGENT_TERMINATED = "agent.terminated"
    AGENT_REPLAY_MARKS = "agent.replay_marks"
    BEHAVIOR_CHANGE = "behavior.change"
    BEHAVIOR_EVENT_IGNORED = "behavior.event_ignored"
    BEHAVIOR_ERROR = "behavior.error"
    LAUNCH_WAIT = "launch.wait"
    LAUNCH_START = "launch.start"
    LAUNCH_UNPROTECTED = "launch.unprotected"
    SAFETY_SETUP = "safety.setup"
    FAILSAFE_ACT = "failsafe.act"
    FAILSAFE_NO_MODE = "failsafe.no_mode"
    FAILSAFE_HANDLED = "failsafe.handled"
    ENVELOPE_BREACH = "envelope.breach"
    ENVELOPE_BREACH_OVER = "envelope.breach_over"
    ENVELOPE_LIMIT = "envelope.limit"
    ENVELOPE_SUMMARY = "envelope.summary"
    FLEET_FOUND = "fleet.found"
    FLEET_LOST = "fleet.lost"
    FLEET_FOREIGN = "fleet.foreign"
    STATION_SILENT = "station.silent"
    STATION_LOST = "station.lost"
    STATION_COMMAND = "station.command"
    COMMAND_RECEIVED = "command.received"
    COMMAND_IGNORED = "command.ignored"
    COMMAND_SCHEDULED = "command.scheduled"
    COMMAND_MODE_REQUEST = "command.mode_request"
    COMMAND_TERMINATE = "command.terminate"
    COMMAND_RESEND = "command.resend"
    COMMAND_VOIDED = "command.voided"
    TERMINATE_FLEET = "terminate.fleet"
    AUTOPILOT_FOUND = "autopilot.found"
    AUTOPILOT_READINESS = "autopilot.readiness"
    AUTOPILOT_MODE = "autopilot.mode"
    AUTOPILOT_TEXT = "autopilot.text"
    AUTOPILOT_STREAMS = "autopilot.streams"
    AUTOPILOT_SAFETY = "autopilot.safety"
    AUTOPILOT_MISSION = "autopilot.mission"
    AUTOPILOT_REFUSED = "autopilot.refused"
    AUTOPILOT_UNANSWERED = "autopilot.unanswered"
    AUTOPILOT_COMMAND = "autopilot.command"
    AUTOPILOT_IDENTITY = "autopilot.identity"
    AUTOPILOT_PARSER = "autopilot.parser"
    AUTOPILOT_LOST = "autopilot.lost"
    AUTOPILOT_BACK = "autopilot.back"
    AUTOPILOT_LINK = "autopilot.link"
    RADIO_OPEN = "radio.open"
    RADIO_LINK = "radio.link"
    RADIO_FAILED = "radio.failed"
    PHOTO_NO_POSITION = "photo.no_position"
    PHOTO_REFUSED = "photo.refused"
    PHOTO_FAILED = "photo.failed"
    SHELL_START = "shell.start"
    SHELL_OVERRUN = "shell.overrun"
    SHELL_STOP = "shell.stop"
    SHELL_SUMMARY = "shell.summary"
    VIEW_COMMAND = "view.command"
    VIEW_FAILED = "view.failed"
    ALARM_RAISED = "alarm.raised"
    ALARM_CLEARED = "alarm.cleared"
    SIM_FAULT = "sim.fault"

    @property
    def extra(self) -> Mapping[str, str]:
        """The ``extra=`` of a logging call that logs this event (one mapping, built once)."""
        return _EXTRAS[self]


Log = Literal["mission", "interface", "both"]


@dataclass(frozen=True, slots=True)
class EventSpec:
    """What one event is, for docs/logs.md and for the tests.

    Attributes:
        log: The log its lines go to.
        levels: The levels it is logged at (the tests check every call site's).
        meaning: What happened, in a sentence.
        fields: The message's form where a reader parses it (empty when none does): a
            change of it is a breaking change (docs/logs.md, "Compatibility").
    """

    log: Log
    levels: tuple[str, ...]
    meaning: str
    fields: str = ""


_I, _W, _E = ("INFO",), ("WARNING",), ("ERROR",)

#: Every event's declaration; docs/logs.md's table is made from it.
SPECS: Mapping[LogEvent, EventSpec] = MappingProxyType(
    {
        LogEvent.LOG_OPEN: EventSpec(
            "both",
            _I,
            "The first line of each text log, written whatever the level.",
            "`logbook opened: clark_engine=V mission=M mission_id=N agent=A agent_id=N "
            "role=R loop_hz=F period_s=F level=L` (key=value pairs; `clark analyze` takes "
            "`period_s`, the readers `mission`, `agent`, `role` and `level`)",
        ),
        LogEvent.AIR_REJECTED: EventSpec(
            "interface", _I, "A packet was rejected (while the interval's allowance lasts)."
        ),
        LogEvent.AIR_SUMMARY: EventSpec(
            "both",
            _W,
            "The per-packet lines of a summary interval that were counted, not written "
            "one by one (rejected packets, packets from strangers, commands).",
        ),
        LogEvent.AGENT_START: EventSpec(
            "mission",
            _I,
            "The runtime started: agent, mission, rate.",
        ),
        LogEvent.AGENT_NO_ENVELOPE: EventSpec(
            "mission", _W, "A vehicle's config has no envelope: nothing is watched."
        ),
        LogEvent.AGENT_TERMINATING: EventSpec("mission", _W, "The agent begins to terminate."),
        LogEvent.AGENT_TERMINATED: EventSpec("mission", _W, "The agent terminated."),
        LogEvent.AGENT_REPLAY_MARKS: EventSpec(
            "interface", _W, "The replay-protection store could not be trimmed."
        ),
        LogEvent.BEHAVIOR_CHANGE: EventSpec(
            "mission",
            _I,
            "The behaviour's active states changed.",
            "`EVENT: SOURCE -> TARGET (active: A, B)`; SOURCE `(start)` at the start, "
            "TARGET `(behavior)` for the whole behaviour, an empty active list for the "
            "root of a one-primitive behaviour",
        ),
        LogEvent.BEHAVIOR_EVENT_IGNORED: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "An event no state took: before the start, after a failsafe, or no active "
            "state has a transition on it.",
        ),
        LogEvent.BEHAVIOR_ERROR: EventSpec(
            "mission",
            _E,
            "A primitive cannot do its work (a profile without the mode it needs, a "
            "vehicle disarmed before its take-off), or raised as its state was entered or "
            "while it ran (the state fails) or as it was left (it is left all the same).",
        ),
        LogEvent.LAUNCH_WAIT: EventSpec(
            "mission",
            _I,
            "The behaviour waits for what is still missing before it starts.",
            "`launch: the behaviour waits for WHAT, WHAT` (the state and sequence checks "
            "quote WHAT)",
        ),
        LogEvent.LAUNCH_START: EventSpec(
            "mission",
            _I,
            "The autopilot is ready and the behaviour starts.",
            "`launch: the autopilot is ready; HOW; the behaviour starts`",
        ),
        LogEvent.LAUNCH_UNPROTECTED: EventSpec(
            "mission",
            _W,
            "The behaviour starts without the autopilot's own fence and dead-computer "
            "reaction set.",
        ),
        LogEvent.SAFETY_SETUP: EventSpec(
            "mission",
            ("INFO", "ERROR"),
            "The runtime's view of the autopilot's safety set-up: asked for, done, cut "
            "short, failed.",
        ),
        LogEvent.FAILSAFE_ACT: EventSpec(
            "mission",
            _E,
            "A failsafe is applied.",
            "`failsafe ACTION` (`continue` is no failsafe; the first one is the run's)",
        ),
        LogEvent.FAILSAFE_NO_MODE: EventSpec(
            "mission",
            _W,
            "A failsafe sent no mode: the pilot had taken the vehicle into a mode of its own.",
        ),
        LogEvent.FAILSAFE_HANDLED: EventSpec(
            "mission", _W, "The behaviour handles `mcs_lost` itself: no failsafe."
        ),
        LogEvent.ENVELOPE_BREACH: EventSpec(
            "mission",
            ("WARNING", "ERROR"),
            "The envelope watch found a breach (and what was done about it).",
        ),
        LogEvent.ENVELOPE_BREACH_OVER: EventSpec("mission", _I, "A breach is over."),
        LogEvent.ENVELOPE_LIMIT: EventSpec(
            "mission",
            _W,
            "A target was clamped or refused by the envelope, or an episode of them ended.",
        ),
        LogEvent.ENVELOPE_SUMMARY: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "The envelope's counts when the logbook closes.",
        ),
        LogEvent.FLEET_FOUND: EventSpec(
            "mission",
            _I,
            "Another agent was heard for the first time.",
        ),
        LogEvent.FLEET_LOST: EventSpec("mission", _W, "Another agent fell silent."),
        LogEvent.FLEET_FOREIGN: EventSpec("mission", _W, "An agent of another mission was heard."),
        LogEvent.STATION_SILENT: EventSpec("mission", _E, "No station heard for a while."),
        LogEvent.STATION_LOST: EventSpec("mission", _E, "Every station is silent: `mcs_lost`."),
        LogEvent.STATION_COMMAND: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "The station's runtime took (INFO) or refused (WARNING) an operator's command; "
            "the station's view reads the refusals.",
        ),
        LogEvent.COMMAND_RECEIVED: EventSpec(
            "mission", _I, "A station's activate or deactivate arrived (or was coalesced)."
        ),
        LogEvent.COMMAND_IGNORED: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "Commands not obeyed: not from a station, unauthenticated, or a copy.",
        ),
        LogEvent.COMMAND_SCHEDULED: EventSpec(
            "mission", ("INFO", "WARNING"), "A command for a GPS time: held, or not."
        ),
        LogEvent.COMMAND_MODE_REQUEST: EventSpec(
            "mission", ("INFO", "WARNING"), "A station asked for an autopilot mode."
        ),
        LogEvent.COMMAND_TERMINATE: EventSpec("mission", _W, "A Terminate for this agent arrived."),
        LogEvent.COMMAND_RESEND: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "A command the runtime confirms by what the vehicle reports was sent again, "
            "took, or never did.",
        ),
        LogEvent.COMMAND_VOIDED: EventSpec(
            "mission", _I, "Requests of a state active while the autopilot was lost: not sent."
        ),
        LogEvent.TERMINATE_FLEET: EventSpec(
            "mission",
            ("INFO", "WARNING", "ERROR"),
            "The station's terminate of the fleet: who it waits for, who confirmed.",
        ),
        LogEvent.AUTOPILOT_FOUND: EventSpec(
            "interface", _I, "The autopilot answered: its firmware and version."
        ),
        LogEvent.AUTOPILOT_READINESS: EventSpec(
            "interface", _I, "The autopilot is ready, or what it waits for."
        ),
        LogEvent.AUTOPILOT_MODE: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "The autopilot's mode changed, or a mode command's number disagreed with the "
            "profile (interface log).",
        ),
        LogEvent.AUTOPILOT_TEXT: EventSpec(
            "interface",
            ("DEBUG", "INFO", "WARNING", "ERROR", "CRITICAL"),
            "A STATUSTEXT from the autopilot, at the level of its severity.",
        ),
        LogEvent.AUTOPILOT_STREAMS: EventSpec(
            "interface", _I, "The autopilot's telemetry streams: asked again, slower, absent."
        ),
        LogEvent.AUTOPILOT_SAFETY: EventSpec(
            "interface",
            ("INFO", "WARNING", "ERROR"),
            "The adapter's steps of the safety set-up: parameters written and read back.",
        ),
        LogEvent.AUTOPILOT_MISSION: EventSpec(
            "both",
            ("INFO", "WARNING", "ERROR"),
            "A mission uploaded to fly in AUTO (a survey's `fly_as: auto`): the upload started, "
            "accepted or refused with ArduPilot's MAV_MISSION_RESULT (interface log: the "
            "adapter's detail; mission log: as the behaviour saw it, and the progress of its "
            "items).",
        ),
        LogEvent.AUTOPILOT_REFUSED: EventSpec(
            "both",
            _W,
            "The autopilot refused a command (mission log: as the runtime saw it; "
            "interface log: the adapter's detail).",
        ),
        LogEvent.AUTOPILOT_UNANSWERED: EventSpec(
            "interface", _W, "The autopilot did not answer a command after every send."
        ),
        LogEvent.AUTOPILOT_COMMAND: EventSpec(
            "interface",
            ("INFO", "ERROR"),
            "A command to the autopilot could not be sent as asked (no such mode in the "
            "profile, a width out of range, a speed not taken).",
        ),
        LogEvent.AUTOPILOT_IDENTITY: EventSpec(
            "interface", _E, "The autopilot is not the one the config names."
        ),
        LogEvent.AUTOPILOT_PARSER: EventSpec(
            "interface", _E, "The MAVLink parser failed; its buffer was dropped."
        ),
        LogEvent.AUTOPILOT_LOST: EventSpec(
            "interface",
            ("INFO", "ERROR"),
            "The autopilot fell silent (or, in testing mode, was never there).",
            "`autopilot silent for SECONDS s: lost` (the first one is the run's `autopilot_lost`)",
        ),
        LogEvent.AUTOPILOT_BACK: EventSpec(
            "interface",
            ("INFO", "WARNING"),
            "The autopilot was heard again after a silence: what is sent again, what not.",
        ),
        LogEvent.AUTOPILOT_LINK: EventSpec(
            "interface",
            ("WARNING", "ERROR"),
            "The real-time shell's link to the autopilot failed or opened again.",
        ),
        LogEvent.RADIO_OPEN: EventSpec("interface", ("INFO", "WARNING"), "The radio opened."),
        LogEvent.RADIO_LINK: EventSpec(
            "interface", ("WARNING", "ERROR"), "The radio's link was lost or came back."
        ),
        LogEvent.RADIO_FAILED: EventSpec(
            "interface", _E, "The radio failed, or a packet could not be sent."
        ),
        LogEvent.PHOTO_NO_POSITION: EventSpec(
            "mission",
            _W,
            "A picture taken before any position: no Picture Data sent.",
            "`AGENT: picture N (NAME) taken before any position ...` (counted as a photo)",
        ),
        LogEvent.PHOTO_REFUSED: EventSpec("mission", _I, "A payload refused a capture."),
        LogEvent.PHOTO_FAILED: EventSpec("mission", _W, "A payload's capture failed."),
        LogEvent.SHELL_START: EventSpec(
            "interface", _I, "The real-time shell started: rate, autopilot, radio, payloads."
        ),
        LogEvent.SHELL_OVERRUN: EventSpec("interface", _W, "A tick started late."),
        LogEvent.SHELL_STOP: EventSpec(
            "interface",
            ("INFO", "WARNING", "ERROR"),
            "The real-time shell's stop, step by step.",
        ),
        LogEvent.SHELL_SUMMARY: EventSpec(
            "interface",
            _I,
            "The real-time shell's closing figures.",
        ),
        LogEvent.VIEW_COMMAND: EventSpec(
            "mission",
            ("INFO", "WARNING"),
            "A command from the station's view: taken, refused, unanswered or not sent.",
        ),
        LogEvent.VIEW_FAILED: EventSpec(
            "both", _E, "Part of the station's view failed (its checks, its server)."
        ),
        LogEvent.ALARM_RAISED: EventSpec("mission", _W, "The station's view raised an alarm."),
        LogEvent.ALARM_CLEARED: EventSpec("mission", _I, "An alarm cleared."),
        LogEvent.SIM_FAULT: EventSpec("mission", _E, "A dry run's scenario killed the agent."),
    }
)

_EXTRAS: Mapping[LogEvent, Mapping[str, str]] = MappingProxyType(
    {event: MappingProxyType({RECORD_ATTRIBUTE: event.value}) for event in LogEvent}
)

#: Where logs written before events (clark_engine 0.x up to this change) named
#: ``module.function``: the old name -> the event the readers take it for. Only names a
#: reader keys on; the message is still matched as before, so a function that logged
#: several kinds of line (``launch.update``) maps to one event whose reader tells them
#: apart by the message, as it always did.
LEGACY_NAMES: Mapping[str, LogEvent] = MappingProxyType(
    {
        "logbook.__init__": LogEvent.LOG_OPEN,
        "runtime._on_change": LogEvent.BEHAVIOR_CHANGE,
        "runtime._apply_failsafe": LogEvent.FAILSAFE_ACT,
        "runtime._timeouts": LogEvent.AUTOPILOT_LOST,
        "launch.update": LogEvent.LAUNCH_WAIT,
        "photo_trigger.on_payload": LogEvent.PHOTO_NO_POSITION,
    }
)


def event_of(name: str) -> str:
    """The event a log line's second field names: itself, or a legacy name's event."""
    legacy = LEGACY_NAMES.get(name)
    return name if legacy is None else legacy.value


def events_table() -> str:
    """docs/logs.md's events table, in Markdown (``tests/test_log_events.py`` compares)."""
    rows = [
        "| event | log | level | meaning | message readers parse |",
        "| --- | --- | --- | --- | --- |",
    ]
    for event in LogEvent:
        spec = SPECS[event]
        rows.append(
            f"| `{event.value}` | {spec.log} | {', '.join(spec.levels)} | {spec.meaning} | "
            f"{spec.fields or '-'} |"
        )
    return "\n".join(rows) + "\n"


def _write_docs(path: str = "docs/logs.md") -> int:
    """Replace the events table between its markers in docs/logs.md (run from the root)."""
    from pathlib import Path

    doc = Path(path)
    text = doc.read_text(encoding="utf-8")
    begin, end = "<!-- events: begin -->\n", "<!-- events: end -->"
    head, rest = text.split(begin, 1)
    _, tail = rest.split(end, 1)
    doc.write_text(head + begin + events_table() + end + tail, encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(_write_docs())
