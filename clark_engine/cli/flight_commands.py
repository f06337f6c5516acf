"""``clark run`` and ``clark check``: one agent on its real interfaces.

Separate because these load the runtime and its flight libraries (pymavlink,
digi-xbee), inside each command, through :mod:`clark_engine.shells.commands`.
"""

from __future__ import annotations

import argparse


def cmd_run(args: argparse.Namespace) -> int:
    """Run one agent on its real interfaces (the real-time shell) until stopped."""
    from clark_engine.shells.commands import run

    return run(args)


def cmd_check(args: argparse.Namespace) -> int:
    """Check one interface of an agent: connect, verify, print what is seen."""
    from clark_engine.shells.commands import check

    return check(args)


__all__ = ["cmd_check", "cmd_run"]
