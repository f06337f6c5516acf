"""The ``clark`` command.

Exit codes, everywhere: 0 good (warnings allowed), 1 the input is invalid or a
check failed, 2 usage or I/O error. No user mistake prints a traceback.

Imports of engine layers happen inside the commands, so ``clark validate``
loads only the mission layer (never pymavlink or digi-xbee) and starts fast.

This package holds the parser (:func:`build_parser`, one declaration of the whole
command line, in the order ``clark --help`` lists it) and :func:`main`; the commands
live by group: :mod:`~clark_engine.cli.mission_commands` (validate, compile, explain,
schema, behaviors, keygen, examples), :mod:`~clark_engine.cli.dry_run_commands`
(dry-run, campaign), :mod:`~clark_engine.cli.log_commands` (analyze),
:mod:`~clark_engine.cli.flight_commands` (run, check) and
:mod:`~clark_engine.cli.standin_commands` (payload-sim, autopilot-sim, radio-sim);
``clark replay`` is :mod:`clark_engine.station.replay_command`'s. Their exit codes,
parser class and argument types are :mod:`~clark_engine.cli.arguments`'.
"""

from __future__ import annotations

import argparse
import importlib.metadata
import signal
import sys
import threading
from collections.abc import Sequence
from typing import NoReturn

from clark_engine import __version__
from clark_engine.cli.arguments import (
    EXIT_INVALID,
    EXIT_OK,
    EXIT_USAGE,
    WORKERS_REMOVED,
    Parser,
    Removed,
    count_arg,
    period_s_arg,
    retries_arg,
    runs_arg,
    seed_arg,
    share_arg,
    speed_arg,
    until_s_arg,
)
from clark_engine.cli.dry_run_commands import cmd_campaign, cmd_dry_run
from clark_engine.cli.flight_commands import cmd_check, cmd_run
from clark_engine.cli.log_commands import cmd_analyze
from clark_engine.cli.mission_commands import (
    cmd_behaviors,
    cmd_compile,
    cmd_examples,
    cmd_explain,
    cmd_keygen,
    cmd_profiles,
    cmd_schema,
    cmd_validate,
)
from clark_engine.cli.standin_commands import cmd_autopilot_sim, cmd_payload_sim, cmd_radio_sim
from clark_engine.errors import ClarkError, UsageError
from clark_engine.mission.faults import FAULT_HELP
from clark_engine.station.replay_command import add_replay_parser


def _version() -> str:
    """The installed package's version (its metadata); the source's when not installed."""
    try:
        return importlib.metadata.version("clark-engine")
    except importlib.metadata.PackageNotFoundError:
        return __version__


def _interface_options(p: argparse.ArgumentParser) -> None:
    """The options `clark run` and `clark check` share: where the agent and its links are."""
    p.add_argument("mission", metavar="MISSION", help="mission file, or an agent's compiled .json")
    p.add_argument("--agent", metavar="NAME", help="the agent to run (required with a mission)")
    p.add_argument(
        "--autopilot-connection",
        metavar="KIND:WHERE",
        help="instead of the profile's: tcp:HOST:PORT (SITL: tcp:127.0.0.1:5760), "
        "udp:HOST:PORT (listen), udpout:HOST:PORT, serial:DEVICE[:BAUD]",
    )
    p.add_argument(
        "--radio", choices=("udp", "xbee"), help="radio kind, instead of the profile's link"
    )
    p.add_argument(
        "--radio-address", metavar="ADDRESS", help="this agent's radio address (udp: HOST:PORT)"
    )
    p.add_argument(
        "--radio-device",
        metavar="DEVICE",
        help="an XBee's serial device, instead of the profile's (/dev/ttyUSB0; an emulated "
        "radio's path from `clark radio-sim xbee`)",
    )
    p.add_argument(
        "--peer",
        action="append",
        metavar="NAME=ADDRESS",
        help="a peer's radio address, instead of the mission's (repeatable)",
    )
    p.add_argument("--key", metavar="FILE", help="the mission key (mission.key_file by default)")


def build_parser() -> argparse.ArgumentParser:
    """The argument parser of ``clark`` and its subcommands."""
    from clark_engine.mission.schemas import SCHEMA_NAMES

    parser = Parser(
        prog="clark",
        description="Clark Engine: validate, explain, dry-run (on a simulated fleet), "
        "campaign (many dry runs), compile and analyze multi-vehicle missions. "
        "`clark COMMAND --help` for each.",
        epilog="Exit codes: 0 good, 1 invalid input or failed check, 2 usage or I/O error.",
    )
    parser.add_argument("--version", action="version", version=f"clark-engine {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=Parser)
    quiet = Parser(add_help=False)
    quiet.add_argument(
        "-q",
        "--quiet",
        action="store_true",
        help="hide warnings (errors, the verdict and the exit code are unchanged)",
    )

    p = sub.add_parser(
        "validate",
        parents=[quiet],
        help="report every problem in missions, blocks or profiles",
    )
    p.add_argument("paths", nargs="+", metavar="PATH", help="mission, block or profile files")
    p.add_argument(
        "--format",
        choices=("text", "json"),
        default="text",
        help="text for people (default) or json for tools",
    )
    p.set_defaults(func=cmd_validate)

    p = sub.add_parser("compile", parents=[quiet], help="write one JSON config per agent")
    p.add_argument("mission", metavar="MISSION")
    p.add_argument(
        "-o",
        "--output",
        required=True,
        metavar="DIR",
        help="configs go to DIR/<mission name>/<agent>.json",
    )
    p.add_argument("--agent", action="append", metavar="NAME", help="only this agent (repeatable)")
    p.set_defaults(func=cmd_compile)

    p = sub.add_parser("explain", parents=[quiet], help="show the resolved state machine of agents")
    p.add_argument("mission", metavar="MISSION")
    p.add_argument(
        "--agent",
        action="append",
        metavar="NAME",
        help="only this agent (repeatable; every agent when omitted)",
    )
    p.add_argument(
        "--format",
        choices=("tree", "mermaid", "both"),
        default="both",
        help="tree: the states as an indented tree; mermaid: a Mermaid state diagram "
        "(for Markdown viewers); both (the default)",
    )
    p.set_defaults(func=cmd_explain)

    p = sub.add_parser(
        "dry-run",
        parents=[quiet],
        help="run the mission against a simulated fleet and evaluate its checks",
    )
    p.add_argument("mission", metavar="MISSION")
    p.add_argument(
        "--seed",
        type=seed_arg,
        metavar="N",
        help="random seed, a whole number >= 0 (the mission's sim.seed by default)",
    )
    p.add_argument(
        "--until",
        type=until_s_arg,
        metavar="SECONDS",
        help="simulated seconds to run (the mission's sim.duration_s by default)",
    )
    p.add_argument("--report", metavar="DIR", help="write logs, CSV, plots and summary.md here")
    p.add_argument(
        "--speed",
        type=speed_arg,
        metavar="X",
        help="pace the run at X times real time, X > 0 (as fast as possible by default)",
    )
    p.add_argument(
        "--workers", nargs="?", action=Removed, const=WORKERS_REMOVED, help=argparse.SUPPRESS
    )
    p.add_argument(
        "--fault",
        action="append",
        metavar="FAULT",
        help=f"inject a fault (repeatable): {FAULT_HELP}",
    )
    p.add_argument(
        "--vary",
        action="append",
        metavar="PATH=VALUE",
        help="fix a value the mission varies instead of drawing it (repeatable): "
        "sim.radio_loss=0.05, faults.0.kill.at_s=52, faults.0.kill.injected=false "
        "(docs/reference.md#varied-values)",
    )
    p.add_argument(
        "--realtime",
        action="store_true",
        help="run at wall-clock speed with MAVLink ports for a ground station "
        "(until --until or Ctrl-C)",
    )
    p.add_argument(
        "--mavlink-port",
        type=int,
        metavar="BASE",
        help="with --realtime: vehicle k's autopilot listens on UDP port BASE+k; a station "
        "connects with udpout:127.0.0.1:BASE+k",
    )
    p.add_argument(
        "--mavlink-host",
        metavar="ADDRESS",
        help="with --realtime: the address to listen on (127.0.0.1 by default; 0.0.0.0 "
        "for stations on other machines)",
    )
    p.add_argument(
        "--autopilot",
        choices=("sim", "sitl"),
        default="sim",
        help="sim: the simulated autopilot (the default); sitl: real ArduPilot SITL for every "
        "vehicle, the states compared with the simulated autopilot's run",
    )
    p.add_argument(
        "--sitl",
        metavar="PATH",
        help="with --autopilot sitl: the folder with the `sitl` launcher ($CLARK_SITL by default)",
    )
    p.add_argument(
        "--sitl-speedup",
        type=speed_arg,
        metavar="X",
        help="with --autopilot sitl: run SITL X times faster than real time (10 by default)",
    )
    p.add_argument(
        "--sitl-instances",
        metavar="FIRST-LAST",
        help="with --autopilot sitl: the SITL instance numbers (ports 5760+10*I...) its "
        "vehicles may take, to keep runs on a shared machine apart ($CLARK_SITL_INSTANCES; "
        "0-99 by default)",
    )
    p.add_argument(
        "--station",
        action="store_true",
        help="with --realtime: serve the station agent's live web view of the rehearsal "
        "(the page of clark run --view; docs/realtime.md)",
    )
    p.add_argument(
        "--view",
        metavar="[HOST:]PORT",
        help="with --station: where to serve it (127.0.0.1:8080 by default; port 0 picks one)",
    )
    p.add_argument(
        "--view-token",
        metavar="TOKEN",
        help="with --station: the token the view requires (required off loopback; a file is safer)",
    )
    p.add_argument(
        "--view-token-file",
        metavar="FILE",
        help="with --station: read the view's token from the first line of FILE",
    )
    p.add_argument(
        "--view-hz",
        type=period_s_arg,
        metavar="HZ",
        help="with --station: view updates per second (5 by default, at most the station's "
        "loop rate)",
    )
    p.add_argument(
        "--no-operator-script",
        action="store_true",
        help="with --station: do not play the mission's operator actions for the station "
        "(activate, deactivate, mode, terminate): the person at the page commands; the "
        "pilots' rc actions still play",
    )
    p.set_defaults(func=cmd_dry_run)

    p = sub.add_parser(
        "campaign",
        parents=[quiet],
        help="fly the mission many times, each run with its own seed and draw of its "
        "variations, and report each check's pass rate",
    )
    p.add_argument("mission", metavar="MISSION")
    p.add_argument(
        "--runs",
        type=runs_arg,
        metavar="N",
        help="how many runs (the mission's campaign.runs by default, else 100)",
    )
    p.add_argument(
        "--seed",
        type=seed_arg,
        metavar="N",
        help="the campaign's seed: run i's seed is derived from it and i (the mission's "
        "campaign.seed, else sim.seed, by default)",
    )
    p.add_argument(
        "--until",
        type=until_s_arg,
        metavar="SECONDS",
        help="simulated seconds of each run (the mission's sim.duration_s by default)",
    )
    p.add_argument(
        "--fault", action="append", metavar="FAULT", help=f"inject in every run: {FAULT_HELP}"
    )
    p.add_argument(
        "--vary",
        action="append",
        metavar="PATH=VALUE",
        help="fix a varied value in every run instead of drawing it (repeatable)",
    )
    p.add_argument(
        "--workers",
        type=count_arg,
        metavar="N",
        help="local processes flying runs at once (every usable core by default; 1: in "
        "this process)",
    )
    p.add_argument(
        "--scheduler",
        metavar="ADDRESS",
        help="send the runs to the Dask cluster whose scheduler is at ADDRESS "
        "(tcp://host:8786); needs the cluster extra (pip install 'clark-engine[cluster]')",
    )
    p.add_argument(
        "--autopilot",
        choices=("sim", "sitl"),
        default="sim",
        help="sim: the simulated autopilot (the default); sitl: every run on ArduPilot SITL",
    )
    p.add_argument("--sitl", metavar="PATH", help="with --autopilot sitl: as for clark dry-run")
    p.add_argument(
        "--sitl-speedup", type=speed_arg, metavar="X", help="with --autopilot sitl: (10 by default)"
    )
    p.add_argument(
        "--sitl-instances",
        metavar="FIRST-LAST",
        help="with --autopilot sitl: the instance numbers runs may take ($CLARK_SITL_INSTANCES)",
    )
    p.add_argument(
        "--sitl-per-worker",
        type=count_arg,
        metavar="K",
        help="with --autopilot sitl, locally: at most K runs (SITL stacks) at once (2 by "
        "default); on a cluster, each worker's --resources sitl=K says it",
    )
    p.add_argument(
        "--run-timeout-s",
        type=period_s_arg,
        metavar="SECONDS",
        help="stop a run (its whole process group) after this much wall time and retry it "
        "(1800 s by default on SITL; none on the simulated autopilot)",
    )
    p.add_argument(
        "--retries",
        type=retries_arg,
        default=2,
        metavar="N",
        help="retries of a run that failed for want of infrastructure (2 by default)",
    )
    p.add_argument(
        "--report",
        metavar="DIR",
        help="write summary.md, runs.csv and the plots here (replacing an earlier report)",
    )
    p.add_argument(
        "--failure-reports",
        action="store_true",
        help="with --report: each failing run's dry-run report under DIR/runs/<i>/",
    )
    p.add_argument(
        "--min-pass-rate",
        type=share_arg,
        metavar="SHARE",
        help="exit 1 unless this share of runs passes (the mission's "
        "campaign.min_pass_rate by default)",
    )
    p.set_defaults(func=cmd_campaign)

    p = sub.add_parser(
        "examples",
        help="copy the example missions (and the schemas they name) into DIR/missions and "
        "DIR/schemas, to try and edit",
    )
    p.add_argument("dir", metavar="DIR", help="the folder to copy into (created if need be)")
    p.set_defaults(func=cmd_examples)

    p = sub.add_parser("keygen", help="write a new ClarkLink key file for mission.key_file")
    p.add_argument("path", metavar="PATH", help="where to write the key (must not exist)")
    p.set_defaults(func=cmd_keygen)

    p = sub.add_parser(
        "analyze",
        parents=[quiet],
        help="message latency and loss per link from a folder of agents' logs, or (with "
        "--checks) a mission's checks judged on them",
    )
    p.add_argument("logdir", metavar="LOGDIR", help="folder with the agents' <agent>.messages.csv")
    p.add_argument(
        "--checks",
        metavar="MISSION",
        help="instead of the link tables: evaluate MISSION's checks on the logs (exit 1 when "
        "one fails; a check the logs cannot support is 'not evaluated')",
    )
    p.add_argument(
        "--format",
        choices=("text", "json"),
        default="text",
        help="text for people (default) or json for tools",
    )
    p.add_argument(
        "--period-s",
        type=period_s_arg,
        metavar="SECONDS",
        help="sample period for the deviation from ideal (default: period_s from the "
        "mission logs' header lines)",
    )
    p.set_defaults(func=cmd_analyze)

    add_replay_parser(sub)

    p = sub.add_parser(
        "schema", help="print a JSON Schema (mission, behavior, hardware-profile, agent-config)"
    )
    p.add_argument("name", metavar="NAME", help=f"one of: {', '.join(SCHEMA_NAMES)}")
    p.set_defaults(func=cmd_schema)

    p = sub.add_parser(
        "behaviors",
        aliases=["behaviours"],
        help="list every behaviour a mission can use, built-in or from a plugin",
    )
    p.add_argument("--json", action="store_true", help="print JSON: name, origin, summary")
    p.add_argument(
        "--blocks",
        action="store_true",
        help="list the behaviour blocks instead (YAML, shipped or from a plugin): name, origin, "
        "description (with --json: and file)",
    )
    p.set_defaults(func=cmd_behaviors)

    p = sub.add_parser(
        "profiles",
        help="list every hardware profile a mission can name, shipped or from a plugin",
    )
    # clark_engine.mission.profiles.PROFILE_KINDS, written out so that parsing the
    # command line imports no mission code (tests/test_plugins.py holds them equal).
    kinds = ("airframe", "autopilot", "radio", "computer", "payload", "platform")
    p.add_argument("--kind", choices=kinds, help="only profiles of this kind")
    p.add_argument(
        "--json", action="store_true", help="print JSON: name, kind, origin, file, description"
    )
    p.set_defaults(func=cmd_profiles)

    p = sub.add_parser(
        "payload-sim", help="play a payload (the thesis's camera) against a payload adapter"
    )
    p.add_argument("kind", choices=("camera",), help="the payload to play")
    p.add_argument(
        "--connect",
        required=True,
        metavar="HOST:PORT",
        help="the mission computer's payload adapter (its TCP server, or UDP with --udp)",
    )
    p.add_argument("--udp", action="store_true", help="send datagrams instead of connecting")
    p.add_argument(
        "--capture-delay-s",
        type=float,
        default=0.8,
        metavar="SECONDS",
        help="time from CAPTURE to PHOTO (0.8 by default, as raspberry_pi_camera.yaml)",
    )
    p.add_argument(
        "--retry-s",
        type=float,
        default=1.0,
        metavar="SECONDS",
        help="time between connection attempts while the server is away (1 by default)",
    )
    p.set_defaults(func=cmd_payload_sim)

    p = sub.add_parser(
        "autopilot-sim",
        help="serve one vehicle's autopilot (simulated or ArduPilot SITL) for `clark run`",
    )
    p.add_argument("mission", metavar="MISSION", help="the mission file")
    p.add_argument("--agent", required=True, metavar="NAME", help="the vehicle")
    p.add_argument(
        "--autopilot",
        choices=("sim", "sitl"),
        default="sim",
        help="sim: the simulated autopilot on UDP (default); sitl: real ArduPilot SITL",
    )
    p.add_argument("--sitl", metavar="PATH", help="SITL folder or launcher ($CLARK_SITL)")
    p.add_argument(
        "--sitl-instances",
        metavar="FIRST-LAST",
        help="sitl: the instance numbers it may take ($CLARK_SITL_INSTANCES; 0-99 by default)",
    )
    p.add_argument(
        "--listen",
        metavar="HOST:PORT",
        help="sim: the UDP address it answers on (127.0.0.1:14550 by default)",
    )
    p.add_argument(
        "--ready-s",
        type=period_s_arg,
        metavar="SECONDS",
        help="sim: ready this long after power-on instead of the firmware's boot time",
    )
    p.add_argument("--until", type=period_s_arg, metavar="SECONDS", help="stop after this long")
    p.set_defaults(func=cmd_autopilot_sim)

    p = sub.add_parser(
        "radio-sim", help="emulate the mission's XBee 900HP radios on pseudo-terminals"
    )
    p.add_argument("kind", choices=("xbee",), help="the radios to emulate")
    p.add_argument("mission", metavar="MISSION", help="the mission file (its agents' addresses)")
    p.add_argument(
        "--dir", required=True, metavar="DIR", help="where each agent's radio appears as DIR/NAME"
    )
    p.add_argument(
        "--loss", type=float, default=0.0, metavar="SHARE", help="share of frames lost (0..1)"
    )
    p.add_argument(
        "--latency-s", type=float, default=0.0, metavar="SECONDS", help="added to every frame"
    )
    p.add_argument(
        "--throughput-bps",
        type=period_s_arg,
        metavar="BPS",
        help="the shared channel's throughput (the radio profile's, 33000, by default)",
    )
    p.add_argument("--seed", type=seed_arg, default=0, metavar="N", help="seeds the loss draws")
    p.add_argument("--until", type=period_s_arg, metavar="SECONDS", help="stop after this long")
    p.set_defaults(func=cmd_radio_sim)

    p = sub.add_parser("run", help="run one agent on its real interfaces (Ctrl-C stops)")
    _interface_options(p)
    p.add_argument("--logs", metavar="DIR", help="log folder (logs/<mission>-<time> by default)")
    p.add_argument(
        "--state",
        metavar="DIR",
        help="folder of the packet counter and replay stores (DIR/../state beside --logs)",
    )
    p.add_argument("--overwrite", action="store_true", help="replace this agent's logs in DIR")
    p.add_argument("--no-autopilot", action="store_true", help="testing mode: no autopilot")
    p.add_argument("--no-radio", action="store_true", help="testing mode: no radio")
    p.add_argument("--no-payload", action="store_true", help="testing mode: no payloads")
    p.add_argument(
        "--script", action="store_true", help="station: play the mission's operator script"
    )
    p.add_argument("--no-console", action="store_true", help="station: ignore the terminal")
    p.add_argument("--plain", action="store_true", help="status lines, not a screen")
    p.add_argument("--until", type=period_s_arg, metavar="SECONDS", help="stop after this long")
    p.add_argument("--loop-hz", type=period_s_arg, metavar="HZ", help="instead of mission.loop_hz")
    p.add_argument(
        "--view",
        metavar="[HOST:]PORT",
        help="station: serve the live web view (127.0.0.1 unless HOST says; port 0 picks one)",
    )
    p.add_argument(
        "--view-token",
        metavar="TOKEN",
        help="station: the token the view requires (required off loopback; a file is safer)",
    )
    p.add_argument(
        "--view-token-file",
        metavar="FILE",
        help="station: read the view's token from the first line of FILE",
    )
    p.add_argument(
        "--view-hz",
        type=period_s_arg,
        metavar="HZ",
        help="station: view updates per second (5 by default, at most the loop's rate)",
    )
    p.set_defaults(func=cmd_run)

    p = sub.add_parser(
        "check", help="check an agent's autopilot, radio or payload (thesis 2.3.1-2.3.3)"
    )
    p.add_argument("what", choices=("autopilot", "radio", "payload"), help="the interface")
    _interface_options(p)
    p.add_argument(
        "--seconds",
        type=period_s_arg,
        default=5.0,
        metavar="SECONDS",
        help="how long to watch (5 by default)",
    )
    p.set_defaults(func=cmd_check)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    """Run ``clark``; returns the exit code."""
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # as typed, for reports
    if getattr(args, "func", None) is None:
        parser.print_help(sys.stderr)
        return EXIT_USAGE
    try:
        return int(args.func(args))
    except UsageError as exc:
        print(f"clark {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except ClarkError as exc:
        print(f"clark {args.command}: error: {exc}", file=sys.stderr)
        return EXIT_INVALID
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        return EXIT_OK


def console_main() -> NoReturn:
    """The ``clark`` command: :func:`main`, then an exit no signal can turn into a kill.

    Once a command has finished, a late Ctrl-C or SIGTERM (a third one as ``clark run``'s
    stop ends) landed in the interpreter's shutdown, where Python has put back the
    default action: the process died of the signal (exit -2) instead of exiting 130 with
    its stop done. What is left to do then is only the exit, so signals are ignored.
    (:func:`main` itself leaves the signal handlers alone: tests call it in-process.)
    """
    try:
        code = main()
    except KeyboardInterrupt:  # between the command's end and main's return
        code = 130
    if threading.current_thread() is threading.main_thread():
        for sig in (signal.SIGINT, signal.SIGTERM):
            signal.signal(sig, signal.SIG_IGN)
    sys.exit(code)


__all__ = ["EXIT_INVALID", "EXIT_OK", "EXIT_USAGE", "build_parser", "console_main", "main"]
