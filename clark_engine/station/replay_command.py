"""``clark replay LOGS``: the command that serves a finished run's replay (docs/station-view.md).

Kept apart from :mod:`clark_engine.cli` so that the command's options, its checks and
its serving loop live beside the replay they serve; ``clark_engine.cli`` only adds the parser
(:func:`add_replay_parser`).

Order of business, so that a mistake costs nothing: the options are checked (address,
token: exit 2), the mission is read (``--checks``, or the one a dry-run report's
summary names; an invalid one is exit 1), the logs are loaded (a folder that does not
exist: exit 2; one with nothing to replay: exit 1), and only then is the port bound
(in use: exit 2). It serves until Ctrl-C or SIGTERM, then exits 0.
"""

from __future__ import annotations

import argparse
import contextlib
import io
import signal
import sys
import threading
import time
from pathlib import Path
from types import FrameType
from typing import TYPE_CHECKING, Any, TextIO

from clark_engine.errors import UsageError

if TYPE_CHECKING:  # the engine's layers load when the command runs: `clark validate` stays fast
    from clark_engine.mission.model import Mission
    from clark_engine.station.view_commands import CommandRequest

DEFAULT_VIEW: str = "127.0.0.1:0"
"""Where the replay is served unless ``--view`` says: loopback, a free port (printed)."""

REPLAY_UPDATE_HZ: float = 5.0
"""States a playing page is sent per second."""


def add_replay_parser(subparsers: Any) -> None:
    """Add ``clark replay`` to ``clark``'s sub-commands (``subparsers.add_parser``)."""
    p = subparsers.add_parser(
        "replay",
        help="serve the station's page over a finished run's logs, with a time slider",
    )
    p.add_argument(
        "logs",
        metavar="LOGS",
        help="a run's log folder (clark run's, the agents' folders side by side, or a "
        "dry-run --report folder)",
    )
    p.add_argument(
        "--view",
        metavar="[HOST:]PORT",
        help="where to serve it (127.0.0.1 and a free port by default; the URL is printed)",
    )
    p.add_argument(
        "--view-token",
        metavar="TOKEN",
        help="the token the page requires (required off loopback; a file is safer)",
    )
    p.add_argument(
        "--view-token-file", metavar="FILE", help="read the token from the first line of FILE"
    )
    p.add_argument(
        "--checks",
        metavar="MISSION",
        help="the mission that was run: its plan, modes and its checks judged on the logs "
        "(default: the mission a dry-run report names, if it is still there)",
    )
    p.add_argument("-q", "--quiet", action="store_true", help="hide warnings")
    p.set_defaults(func=cmd_replay)


def _served_at(args: argparse.Namespace) -> tuple[str, int, str | None]:
    """The bind address, port and token from the options.

    Raises:
        UsageError: A bad address or token, both token options, or no token off loopback.
    """
    from clark_engine.station.access import check_token, is_loopback_host, parse_view_address
    from clark_engine.station.live_view import load_token

    if args.view_token is not None and args.view_token_file is not None:
        raise UsageError("give --view-token or --view-token-file, not both")
    view = args.view if args.view is not None else DEFAULT_VIEW
    host, port = parse_view_address(view)
    token = load_token(args.view_token_file) if args.view_token_file is not None else None
    if args.view_token is not None:
        token = check_token(args.view_token)
    if token is None and not is_loopback_host(host):
        raise UsageError(
            f"--view {view}: serving beyond this machine needs a token: add "
            "--view-token-file FILE (or --view-token TOKEN), or bind 127.0.0.1"
        )
    return host, port, token


def _mission(path: Path, quiet: bool, err: TextIO) -> Mission | None:
    """The mission in ``path``, its findings printed; None when it is invalid.

    Raises:
        UsageError: It cannot be read, or is not a mission.
    """
    from clark_engine.mission.validate import validate_path

    validation = validate_path(path, str(path))
    if validation.kind != "mission" and validation.ok:
        raise UsageError(f"{path} is a {validation.kind}, not a mission")
    for finding in validation.findings:
        if finding.is_error or not quiet:
            print(finding.format_text(), file=err)
    return validation.mission


def _refuse(request: CommandRequest) -> None:
    """A replay sends nothing (the server refuses commands before they get here)."""
    raise RuntimeError("this is a replay: it sends no commands")


def cmd_replay(args: argparse.Namespace) -> int:
    """Serve the station's page over a finished run's logs until Ctrl-C; returns the exit code."""
    from clark_engine.station.replay import (
        ReplayError,
        iter_warnings,
        load_replay,
        mission_from_report,
    )
    from clark_engine.station.server import ViewServer

    out, err = sys.stdout, sys.stderr
    host, port, token = _served_at(args)
    folder = Path(args.logs)
    if not folder.exists():
        raise UsageError(f"{folder}: no such folder")
    mission: Mission | None = None
    source = ""
    found_in_report = False
    if args.checks is not None:
        mission = _mission(Path(args.checks), args.quiet, err)
        if mission is None:
            print(f"{args.checks}: invalid; nothing replayed", file=err)
            return 1
        source = f"the mission {Path(args.checks).name}"
    else:
        named = mission_from_report(folder)
        if named is not None:
            with contextlib.suppress(UsageError):
                mission = _mission(named, True, io.StringIO())
            if mission is not None:
                source = f"the mission {named} (named by the report's summary)"
                found_in_report = True
    started = time.perf_counter()
    try:
        replay, load = load_replay(
            folder, mission, mission_source=source, update_hz=REPLAY_UPDATE_HZ
        )
    except ReplayError:
        if not found_in_report:
            raise
        # The report names a mission that has changed since: replay the logs alone.
        replay, load = load_replay(folder, None, update_hz=REPLAY_UPDATE_HZ)
    loaded_s = time.perf_counter() - started
    if not args.quiet:
        for warning in iter_warnings(load):
            print(f"clark replay: warning: {warning}", file=err)
    hello = replay.hello
    print(
        f"clark replay: {hello['mission']['name']}: {len(hello['agents'])} agent(s), "
        f"{replay.start_s:.1f} to {replay.end_s:.1f} s of mission time"
        + (f"; plan and checks from {source}" if source else "; no mission (give --checks)")
        + f"; loaded in {loaded_s:.2f} s",
        file=out,
    )
    server = ViewServer(hello, _refuse, host=host, port=port, token=token, replay=replay)
    server.start()
    stop = threading.Event()

    def stopping(signum: int, frame: FrameType | None) -> None:
        stop.set()

    previous = {sig: signal.signal(sig, stopping) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        print(f"clark replay: serving at {server.url}; Ctrl-C stops", file=out, flush=True)
        while not stop.wait(0.5):
            pass
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, handler)
        server.stop()
    print("clark replay: stopped", file=out, flush=True)
    return 0


__all__ = ["add_replay_parser", "cmd_replay"]
