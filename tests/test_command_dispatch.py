"""Every shell carries out every command type, and refuses one it does not know.

The runtime's commands (:data:`clark_engine.runtime.commands.Command`) are carried out by
the dry run (``dryrun/engine.py``), the real-time shell (``shells/realtime.py``) and, for the
autopilot's, the autopilot adapter (``io/autopilot.py``). Each dispatches through one
table checked against the command types when its module loads; a type a shell does not
know is an engine bug and raises, naming the type. The dry run used to drop such a
command in silence where the real-time shell forwarded it: a rehearsal that is not one.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import get_args

import pytest

from clark_engine.dryrun.engine import _ROUTES, DryRun
from clark_engine.io.autopilot import _NOT_THE_AUTOPILOTS, AutopilotAdapter
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.mission.compiler import agent_config
from clark_engine.mission.validate import validate_path
from clark_engine.runtime.commands import (
    AUTOPILOT_COMMANDS,
    COMMAND_TYPES,
    Command,
    Goto,
    SendPacket,
    UnknownCommandError,
    check_dispatch,
)
from clark_engine.runtime.config import config_from_dict
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.realtime import _CARRY_OUT, RealtimeShell

ROOT = Path(__file__).resolve().parent.parent
MISSION = ROOT / "missions" / "single_vehicle_mode_change.yaml"


@dataclass(frozen=True, slots=True)
class Teleport:
    """A command type no shell knows (as a new one would be before its shells learn it)."""

    where: str = "mars"


def test_the_command_types_are_the_union_s_members() -> None:
    members = set(get_args(Command))
    assert members == COMMAND_TYPES
    assert len(members) == 11  # a new command type: add it to every shell (this file)


@pytest.mark.parametrize(
    ("shell", "handled"),
    [
        ("the dry run", set(_ROUTES)),
        ("the real-time shell", set(_CARRY_OUT)),
        ("the autopilot adapter", {*AUTOPILOT_COMMANDS, *_NOT_THE_AUTOPILOTS}),
    ],
)
def test_every_shell_handles_every_command_type(shell: str, handled: set[type]) -> None:
    for command_type in get_args(Command):
        assert command_type in handled, f"{shell} does not carry out {command_type.__name__}"
    assert handled <= COMMAND_TYPES, f"{shell} dispatches a type that is no command"


def test_a_dispatch_missing_a_type_or_adding_one_fails_its_check() -> None:
    with pytest.raises(UnknownCommandError, match=r"the dry run: .*missing: Goto; not commands"):
        check_dispatch(COMMAND_TYPES - {Goto}, "the dry run")
    with pytest.raises(UnknownCommandError, match=r"not commands: Teleport"):
        check_dispatch({*COMMAND_TYPES, Teleport}, "the real-time shell")
    check_dispatch(COMMAND_TYPES, "complete")  # no error


def test_the_dry_run_refuses_an_unknown_command_type() -> None:
    """It used to drop it in silence (``_route`` had no else)."""
    result = validate_path(MISSION, MISSION.name)
    assert result.mission is not None
    dry = DryRun(result.mission, MISSION, seed=1, until_s=1.0)
    agent = dry.agents["slash"]
    with pytest.raises(UnknownCommandError, match=r"the dry run: .*a Teleport command"):
        dry._route(agent, [Teleport()], 0.0)  # type: ignore[list-item]


def test_the_realtime_shell_refuses_an_unknown_command_type() -> None:
    """It used to hand it to the autopilot adapter, which answered nothing."""
    result = validate_path(MISSION, MISSION.name)
    assert result.mission is not None
    config = config_from_dict(agent_config(result.mission, result.mission.agents["slash"]))
    runtime = AgentRuntime(config, logbook=Logbook.in_memory(config), gps_epoch_ms=0)
    shell = RealtimeShell(runtime)
    try:
        with pytest.raises(UnknownCommandError, match=r"real-time shell: .*a Teleport command"):
            shell._carry_out([Teleport()], 0.0)  # type: ignore[list-item]
        # A known command still goes its way: a packet with no radio is counted as dropped.
        shell._carry_out([SendPacket(b"x")], 0.0)
        assert shell.stats.dropped_commands["SendPacket"] == 1
    finally:
        shell._close_all()


def test_the_autopilot_adapter_refuses_an_unknown_command_type() -> None:
    adapter = AutopilotAdapter(AutopilotSettings(modes={"MANUAL": 0, "GUIDED": 15}))
    with pytest.raises(UnknownCommandError, match=r"autopilot adapter: .*a Teleport command"):
        adapter.command(Teleport(), 0.0)  # type: ignore[arg-type]
    for not_its in _NOT_THE_AUTOPILOTS:
        assert not_its in COMMAND_TYPES
    assert adapter.command(SendPacket(b"x"), 0.0) == b""
