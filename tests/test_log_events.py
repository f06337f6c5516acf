"""Logs as a declared interface: every agent-log call names a declared, documented event.

The scan reads the package's source (no import, milliseconds): a call to a logger's
``debug``/``info``/``warning``/``error``/``critical``/``exception``/``log`` must pass
``extra=LogEvent.NAME.extra`` with a declared NAME, logged at one of the levels the event
declares, unless its logger is a module's own ``logging.getLogger(...)`` (those never
reach an agent's logs: the logbook's loggers are unregistered and nothing propagates to
them) or one of :data:`NOT_AGENT_LOGS`.
"""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

from clark_engine.runtime.log_events import LEGACY_NAMES, SPECS, LogEvent, event_of, events_table

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "clark_engine"
LEVELS = {"debug", "info", "warning", "error", "critical", "exception", "log"}

#: (file, receiver) of calls that are not logging into an agent's logs.
NOT_AGENT_LOGS = {
    ("cli/arguments.py", "parser"),  # argparse's error
    ("station/log_throttle.py", "self.logger"),  # aiohttp's access logger, throttled
}


def _module_loggers(tree: ast.Module) -> set[str]:
    """Names a module binds at its top level to ``logging.getLogger(...)``."""
    names = set()
    for node in tree.body:
        if (
            isinstance(node, ast.Assign)
            and isinstance(node.value, ast.Call)
            and ast.unparse(node.value.func) == "logging.getLogger"
        ):
            names |= {t.id for t in node.targets if isinstance(t, ast.Name)}
    return names


def undeclared_calls(source: str, rel: str) -> list[str]:
    """Where ``source`` logs to an agent's log without a declared event, or at a level the
    event does not declare: ``file:line: why`` each."""
    tree = ast.parse(source)
    exempt = _module_loggers(tree)
    found = []
    for node in ast.walk(tree):
        if not (
            isinstance(node, ast.Call)
            and isinstance(node.func, ast.Attribute)
            and node.func.attr in LEVELS
        ):
            continue
        receiver = ast.unparse(node.func.value)
        if receiver in exempt or receiver == "math" or (rel, receiver) in NOT_AGENT_LOGS:
            continue
        where = f"{rel}:{node.lineno}"
        extra = next((k.value for k in node.keywords if k.arg == "extra"), None)
        match = re.fullmatch(r"LogEvent\.([A-Z_]+)\.extra", ast.unparse(extra)) if extra else None
        if match is None or match[1] not in LogEvent.__members__:
            found.append(f"{where}: {receiver}.{node.func.attr}(...) declares no LogEvent")
            continue
        event = LogEvent[match[1]]
        level = "ERROR" if node.func.attr == "exception" else node.func.attr.upper()
        if node.func.attr != "log" and level not in SPECS[event].levels:
            found.append(f"{where}: {event.value} is not declared at {level}")
    return found


def test_every_agent_log_call_declares_an_event() -> None:
    problems = []
    for path in sorted(PACKAGE.rglob("*.py")):
        rel = path.relative_to(PACKAGE).as_posix()
        problems += undeclared_calls(path.read_text(encoding="utf-8"), rel)
    assert not problems, "\n".join(problems)


@pytest.mark.parametrize(
    "call",
    [
        'self.logbook.mission.info("found %s", name)',
        'ctx.log.warning("x", extra={"clark_event": "made.up"})',
        'log.error("x", extra=LogEvent.NOT_DECLARED.extra)',
        'self._log.error("x", extra=LogEvent.FLEET_FOUND.extra)',  # fleet.found is INFO
    ],
)
def test_the_scan_fails_on_an_undeclared_call(call: str) -> None:
    assert undeclared_calls(f"def f():\n    {call}\n", "x.py")


def test_the_scan_passes_a_declared_call_and_module_loggers() -> None:
    source = (
        "import logging\n_LOG = logging.getLogger(__name__)\n"
        "def f():\n"
        '    _LOG.warning("library")\n'
        '    self.logbook.mission.info("found %s", n, extra=LogEvent.FLEET_FOUND.extra)\n'
    )
    assert undeclared_calls(source, "x.py") == []


def test_event_names_are_stable_dotted_lower_case_and_unique() -> None:
    values = [e.value for e in LogEvent]
    assert len(values) == len(set(values))
    for value in values:
        assert re.fullmatch(r"[a-z]+\.[a-z_]+", value), value
    assert set(SPECS) == set(LogEvent)
    assert all(spec.meaning and spec.levels for spec in SPECS.values())


def test_legacy_names_are_read_as_their_events() -> None:
    assert event_of("runtime._on_change") == "behavior.change"
    assert event_of("runtime._apply_failsafe") == "failsafe.act"
    assert event_of("behavior.change") == "behavior.change"
    assert all(name.count(".") == 1 for name in LEGACY_NAMES)


def test_docs_logs_md_holds_the_events_table() -> None:
    """docs/logs.md's table is made by ``python -m clark_engine.runtime.log_events``."""
    text = (ROOT / "docs" / "logs.md").read_text(encoding="utf-8")
    begin, end = "<!-- events: begin -->\n", "<!-- events: end -->"
    assert begin in text and end in text, "docs/logs.md has no generated events table"
    table = text.split(begin, 1)[1].split(end, 1)[0]
    assert table.strip() == events_table().strip(), (
        "docs/logs.md's events table is stale: run python -m clark_engine.runtime.log_events"
    )
