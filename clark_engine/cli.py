"""The ``clark`` command.

Exit codes, everywhere: 0 good (warnings allowed), 1 the input is invalid or a
check failed, 2 usage or I/O error. No user mistake prints a traceback.

Imports of engine layers happen inside the commands, so ``clark validate``
loads only the mission layer (never pymavlink or digi-xbee) and starts fast.
"""

from __future__ import annotations

import argparse
import dataclasses
import importlib.metadata
import json
import signal
import sys
import threading
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NoReturn, TextIO

from clark_engine import __version__
from clark_engine.errors import ClarkError, UsageError
from clark_engine.mission.faults import FAULT_HELP
from clark_engine.station.replay_command import add_replay_parser

if TYPE_CHECKING:
    from clark_engine.dryrun.command import LiveView, LiveViewOpener
    from clark_engine.mission.findings import Finding
    from clark_engine.mission.model import Mission
    from clark_engine.mission.validate import Validation

EXIT_OK = 0
EXIT_INVALID = 1
EXIT_USAGE = 2


class _Parser(argparse.ArgumentParser):
    """argparse, but usage errors exit 2 with a hint and no traceback (its default too)."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _summary(result: Validation) -> str:
    errors = len(result.errors)
    warnings = len(result.findings) - errors
    if errors:
        text = f"{result.file}: invalid ({errors} error{'s' * (errors != 1)}"
        if warnings:
            text += f", {warnings} warning{'s' * (warnings != 1)}"
        return text + ")"
    text = f"{result.file}: valid {result.kind}"
    if warnings:
        text += f" ({warnings} warning{'s' * (warnings != 1)})"
    return text


#: Findings whose message ends in advice that is the same every time: the text from this
#: marker on is given once per command, later findings of the code say "(see above)".
_ADVICE_ONCE = {"W-NO-KEY": ": make one with"}


class _FindingPrinter:
    """Prints a command's findings: warnings hidden by ``--quiet``, repeated advice once."""

    def __init__(self, quiet: bool = False) -> None:
        self.quiet = quiet
        self.advised: set[str] = set()

    def text(self, finding: Finding) -> str:
        """The finding's line, its advice cut when an earlier finding already gave it."""
        marker = _ADVICE_ONCE.get(finding.code)
        if marker is not None and marker in finding.message:
            if finding.code in self.advised:
                short = finding.message.split(marker)[0] + " (see the advice above)"
                finding = dataclasses.replace(finding, message=short)
            self.advised.add(finding.code)
        return finding.format_text()

    def __call__(self, result: Validation, stream: TextIO) -> None:
        for finding in result.findings:
            if self.quiet and not finding.is_error:
                continue
            print(self.text(finding), file=stream)


def cmd_validate(args: argparse.Namespace) -> int:
    """Validate files and report every finding."""
    from clark_engine.validation import validate_file

    results = []
    usage_failed = False
    print_findings = _FindingPrinter(args.quiet)
    for name in args.paths:
        try:
            results.append(validate_file(Path(name), name))
        except UsageError as exc:
            usage_failed = True
            print(f"clark validate: error: {exc}", file=sys.stderr)
    if args.format == "json":
        payload = {
            "files": [
                {
                    "file": r.file,
                    "kind": r.kind,
                    "valid": r.ok,
                    "errors": len(r.errors),
                    "warnings": len(r.findings) - len(r.errors),
                }
                for r in results
            ],
            "findings": [f.to_json() for r in results for f in r.findings],
        }
        print(json.dumps(payload, indent=2))
    else:
        for result in results:
            print_findings(result, sys.stdout)
            print(_summary(result))
    if usage_failed:
        return EXIT_USAGE
    return EXIT_OK if all(r.ok for r in results) else EXIT_INVALID


def _load_valid(path_text: str, command: str, quiet: bool = False) -> Validation | int:
    """Validate a mission for compile/explain: findings to stderr, exit code on failure."""
    from clark_engine.validation import validate_file

    result = validate_file(Path(path_text), path_text)
    if result.kind != "mission" and result.ok:
        print(
            f"clark {command}: error: {path_text} is a {result.kind}, not a mission",
            file=sys.stderr,
        )
        return EXIT_USAGE
    _FindingPrinter(quiet)(result, sys.stderr)
    if result.mission is None:
        print(
            f"{_summary(result)}; nothing {'written' if command == 'compile' else 'shown'}",
            file=sys.stderr,
        )
        return EXIT_INVALID
    return result


def cmd_compile(args: argparse.Namespace) -> int:
    """Compile a mission into one JSON config per agent."""
    from clark_engine.mission.compiler import compile_mission, write_configs

    loaded = _load_valid(args.mission, "compile", args.quiet)
    if isinstance(loaded, int):
        return loaded
    mission = loaded.mission
    assert mission is not None
    files = compile_mission(mission, args.agent or None)
    # With --agent, the other agents' configs from an earlier compile stay; without it, a
    # config of an agent no longer in the mission is removed with the rest of the old output.
    keep = [name for name in mission.agents if name not in files] if args.agent else []
    target = write_configs(files, Path(args.output), mission.name, keep)
    for name in files:
        print(f"wrote {target / (name + '.json')}")
    return EXIT_OK


def cmd_explain(args: argparse.Namespace) -> int:
    """Print the resolved behaviour of one or every agent."""
    from clark_engine.mission.explain import mermaid, tree

    loaded = _load_valid(args.mission, "explain", args.quiet)
    if isinstance(loaded, int):
        return loaded
    mission = loaded.mission
    assert mission is not None
    names = args.agent or list(mission.agents)
    for name in names:
        if name not in mission.agents:
            raise UsageError(
                f"{args.mission}: there is no agent {name!r}; agents: {', '.join(mission.agents)}"
            )
    for i, name in enumerate(names):
        agent = mission.agents[name]
        if i:
            print()
        if args.format in ("tree", "both"):
            sys.stdout.write(tree(mission, agent))
        if args.format == "both":
            print()
        if args.format in ("mermaid", "both"):
            print("```mermaid")
            sys.stdout.write(mermaid(mission, agent))
            print("```")
    return EXIT_OK


def cmd_schema(args: argparse.Namespace) -> int:
    """Print one of the shipped JSON Schemas."""
    from clark_engine.mission.schemas import SCHEMA_NAMES, schema_text

    name = args.name.removesuffix(".schema.json").replace("_", "-")
    if name not in SCHEMA_NAMES:
        raise UsageError(
            f"there is no schema {args.name!r}; choose one of: {', '.join(SCHEMA_NAMES)}"
        )
    sys.stdout.write(schema_text(name))
    return EXIT_OK


def cmd_behaviors(args: argparse.Namespace) -> int:
    """List every behaviour a mission can use: name, origin (built-in or plugin), summary.

    Plugins are installed Python packages that declare behaviours through the
    ``clark_engine.behaviors`` entry-point group (docs/plugins.md); a plugin that
    fails to load is reported here, as everywhere, with exit code 2.
    """
    from clark_engine.behaviors import behaviors

    declared = behaviors()
    if args.json:
        rows = [
            {"name": b.name, "origin": b.origin, "summary": b.summary} for b in declared.values()
        ]
        print(json.dumps(rows, indent=2))
        return EXIT_OK
    name_w = max(len(name) for name in declared)
    origin_w = max(len(b.origin) for b in declared.values())
    for b in declared.values():
        print(f"{b.name:<{name_w}}  {b.origin:<{origin_w}}  {b.summary}")
    return EXIT_OK


def cmd_keygen(args: argparse.Namespace) -> int:
    """Write a new ClarkLink key file (32 random bytes, readable by its owner only)."""
    from clark_engine.link.auth import KeyFileError, generate_key_file

    path = Path(args.path)
    if path.is_dir():
        raise UsageError(
            f"{path} is a directory; give the key file's name (e.g. {path}/mission.key)"
        )
    if path.exists():
        raise UsageError(
            f"{path} exists; keygen never overwrites a key (delete it first if you mean to)"
        )
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        generate_key_file(path)
    except KeyFileError as exc:  # cannot be written: an I/O error, exit 2
        raise UsageError(str(exc)) from None
    except OSError as exc:
        raise UsageError(f"cannot write {path}: {exc.strerror or exc}") from None
    print(f"wrote {path} (mode 600); name it in mission.key_file and copy it to every agent")
    return EXIT_OK


def cmd_examples(args: argparse.Namespace) -> int:
    """Copy the shipped example missions, and the schemas their editors' lines name.

    An installed engine keeps its examples inside the package, where a user should not
    edit them; this gives a copy to work on. ``DIR/missions`` and ``DIR/schemas`` keep the
    repository's layout, so each mission's ``$schema=../schemas/...`` line resolves. The
    copy is made in a hidden folder in DIR and moved into place whole: an error leaves
    nothing half-copied, and nothing of the user's is ever overwritten.
    """
    import shutil
    import tempfile

    from clark_engine.data import data_dir

    target = Path(args.dir)
    if target.exists() and not target.is_dir():
        raise UsageError(f"{target} is a file; give a folder to copy the examples into")
    taken = [target / name for name in ("missions", "schemas") if (target / name).exists()]
    if taken:
        names = " and ".join(str(t) for t in taken)
        raise UsageError(
            f"{names} already {'exists' if len(taken) == 1 else 'exist'}; clark examples "
            "never overwrites: give another folder"
        )
    try:
        target.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory(prefix=".clark-examples-", dir=target) as staging:
            for name in ("missions", "schemas"):
                shutil.copytree(data_dir(name), Path(staging) / name)
            for name in ("missions", "schemas"):
                (Path(staging) / name).rename(target / name)
    except OSError as exc:
        raise UsageError(f"cannot copy the examples into {target}: {exc.strerror or exc}") from None
    missions = sorted(p.name for p in (target / "missions").glob("*.yaml"))
    print(f"wrote {len(missions)} example missions to {target / 'missions'}:")
    for name in missions:
        print(f"  {name}")
    print(f"and the JSON Schemas their editor lines name to {target / 'schemas'}")
    print(f"try: clark dry-run {target / 'missions' / 'cooperative_follow.yaml'}")
    return EXIT_OK


def cmd_analyze(args: argparse.Namespace) -> int:
    """Print the message latency and loss per link from a folder of agents' logs.

    With ``--checks MISSION``, instead: the mission's checks judged on the logs
    (:mod:`clark_engine.expectations.from_logs`), exit 1 when one fails.
    """
    from clark_engine.analysis.latency import analyze_folder, format_text

    folder = Path(args.logdir)
    if not folder.exists():
        raise UsageError(f"{folder}: no such folder")
    if args.checks is not None:
        from clark_engine.expectations.from_logs import run_log_checks

        if args.period_s is not None:
            raise UsageError("--period-s is for the latency report; it does not go with --checks")
        return run_log_checks(
            folder, Path(args.checks), json_format=args.format == "json", quiet=args.quiet
        )
    analysis = analyze_folder(folder, args.period_s)
    for problem in () if args.quiet else analysis.problems:
        print(f"clark analyze: warning: {problem.format_text()}", file=sys.stderr)
    if args.format == "json":
        print(json.dumps(analysis.to_json(), indent=2))
    else:
        sys.stdout.write(format_text(analysis))
    return EXIT_OK


def cmd_dry_run(args: argparse.Namespace) -> int:
    """Fly the mission on a simulated fleet (or ArduPilot SITL) and evaluate its checks."""
    from clark_engine.dryrun.command import DEFAULT_SITL_SPEEDUP, run_dry_run
    from clark_engine.dryrun.rehearsal import DEFAULT_HOST
    from clark_engine.sitl.errors import SitlError
    from clark_engine.sitl.launcher import SitlInstall

    on_sitl = args.autopilot == "sitl"
    station_view = _station_view(args)
    if not on_sitl:
        for given, option in (
            (args.sitl is not None, "--sitl"),
            (args.sitl_speedup is not None, "--sitl-speedup"),
            (args.sitl_instances is not None, "--sitl-instances"),
        ):
            if given:
                raise UsageError(f"{option} only applies with --autopilot sitl")
    elif args.speed is not None:
        raise UsageError(
            "--speed does not go with --autopilot sitl: SITL sets the pace (--sitl-speedup X)"
        )
    if args.realtime:
        if on_sitl:
            for given, option in (
                (args.mavlink_port is not None, "--mavlink-port"),
                (args.mavlink_host is not None, "--mavlink-host"),
                (args.sitl_speedup is not None, "--sitl-speedup"),
            ):
                if given:
                    raise UsageError(
                        f"{option} does not go with --realtime --autopilot sitl: SITL runs at "
                        "real time and a ground station connects to each vehicle's SITL "
                        "directly (its port is printed at the start)"
                    )
        elif args.mavlink_port is None and station_view is None:
            raise UsageError(
                "--realtime needs --mavlink-port BASE (vehicle k's autopilot listens on "
                "UDP port BASE+k, e.g. --mavlink-port 14560; see docs/realtime.md) or "
                "--station (the station's web view)"
            )
        if args.speed is not None:
            raise UsageError("--speed does not go with --realtime, which runs at speed 1")
    else:
        for given, option in (
            (args.mavlink_port is not None, "--mavlink-port"),
            (args.mavlink_host is not None, "--mavlink-host"),
        ):
            if given:
                raise UsageError(f"{option} only applies with --realtime")
    install = None
    if on_sitl:
        try:
            install = SitlInstall.find(args.sitl, instances=args.sitl_instances)
        except SitlError as exc:
            raise UsageError(str(exc)) from None
    outcome = run_dry_run(
        Path(args.mission),
        seed=args.seed,
        until_s=args.until,
        report=Path(args.report) if args.report else None,
        speed=args.speed,
        faults=args.fault or (),
        realtime_base_port=args.mavlink_port if args.realtime and not on_sitl else None,
        realtime_host=args.mavlink_host or DEFAULT_HOST,
        sitl=install,
        sitl_speedup=args.sitl_speedup or DEFAULT_SITL_SPEEDUP,
        realtime=args.realtime,
        quiet=args.quiet,
        command_line=["clark", *args.argv],
        station_view=station_view,
        operator_script=not args.no_operator_script,
        vary=args.vary or (),
    )
    return outcome.exit_code


def cmd_campaign(args: argparse.Namespace) -> int:
    """Fly the mission many times, each run its own seed and draw; report the pass rates."""
    from clark_engine.campaign.command import CampaignOptions, run_campaign
    from clark_engine.sitl.errors import SitlError
    from clark_engine.sitl.launcher import SitlInstall

    on_sitl = args.autopilot == "sitl"
    if not on_sitl:
        for given, option in (
            (args.sitl is not None, "--sitl"),
            (args.sitl_speedup is not None, "--sitl-speedup"),
            (args.sitl_instances is not None, "--sitl-instances"),
            (args.sitl_per_worker is not None, "--sitl-per-worker"),
        ):
            if given:
                raise UsageError(f"{option} only applies with --autopilot sitl")
    if args.failure_reports and args.report is None:
        raise UsageError("--failure-reports goes with --report DIR (they go to DIR/runs/<i>/)")
    if args.scheduler is not None and args.workers is not None:
        raise UsageError(
            "--workers is for the local pool; with --scheduler the cluster's workers fly "
            "the runs (start them with --nthreads 1)"
        )
    if args.scheduler is not None and args.sitl_per_worker is not None:
        raise UsageError(
            "--sitl-per-worker is for the local pool; on a cluster each worker's "
            "--resources sitl=K caps its SITL runs (docs/campaigns.md)"
        )
    install = None
    if on_sitl:
        try:
            install = SitlInstall.find(args.sitl, instances=args.sitl_instances)
        except SitlError as exc:
            raise UsageError(str(exc)) from None
    options = CampaignOptions(
        runs=args.runs,
        seed=args.seed,
        until_s=args.until,
        faults=tuple(args.fault or ()),
        vary=tuple(args.vary or ()),
        workers=args.workers,
        scheduler=args.scheduler,
        sitl=install,
        sitl_speedup=args.sitl_speedup or 10.0,
        sitl_per_worker=args.sitl_per_worker or 2,
        run_timeout_s=args.run_timeout_s,
        retries=args.retries,
        report=Path(args.report) if args.report else None,
        failure_reports=args.failure_reports,
        min_pass_rate=args.min_pass_rate,
        quiet=args.quiet,
    )
    return run_campaign(Path(args.mission), options, command_line=["clark", *args.argv])


def _count(text: str) -> int:
    """A whole number >= 1."""
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 1, not {text!r}")
    return value


def _runs(text: str) -> int:
    """A number of runs: 1 to the most a campaign may fly."""
    from clark_engine.mission.schema_source.mission import MAX_CAMPAIGN_RUNS

    value = _count(text)
    if value > MAX_CAMPAIGN_RUNS:
        raise argparse.ArgumentTypeError(f"at most {MAX_CAMPAIGN_RUNS} runs, not {text!r}")
    return value


def _retries(text: str) -> int:
    """A number of retries: a whole number 0 to 100."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if not 0 <= value <= 100:
        raise argparse.ArgumentTypeError(f"must be a whole number 0..100, not {text!r}")
    return value


def _share(text: str) -> float:
    """A share: a number from 0 to 1."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 <= value <= 1:
        raise argparse.ArgumentTypeError(f"must be a number from 0 to 1, not {text!r}")
    return value


def _station_view(args: argparse.Namespace) -> LiveViewOpener | None:
    """``--station`` and its view options checked (usage errors, exit 2); None without it.

    The opener it returns starts the server once the mission is validated, before
    anything is simulated or written.
    """
    from clark_engine.station.rehearsal_view import open_rehearsal, rehearsal_settings

    view_options = (
        (args.view is not None, "--view"),
        (args.view_token is not None, "--view-token"),
        (args.view_token_file is not None, "--view-token-file"),
        (args.view_hz is not None, "--view-hz"),
        (args.no_operator_script, "--no-operator-script"),
    )
    if not args.station:
        for given, option in view_options:
            if given:
                raise UsageError(f"{option} goes with --station (the station's web view)")
        return None
    if not args.realtime:
        raise UsageError(
            "--station needs --realtime: the station's view follows the rehearsal at "
            "wall-clock speed (clark dry-run MISSION --realtime --station)"
        )
    settings = rehearsal_settings(args.view, args.view_token, args.view_token_file, args.view_hz)

    def opener(mission: Mission, path: Path) -> LiveView:
        return open_rehearsal(settings, mission, path)

    return opener


#: What ``clark dry-run --workers`` answers since the dry run's own split was removed.
WORKERS_REMOVED = (
    "--workers was removed: one dry run no longer splits across processes (beside other "
    "runs it was never faster; docs/performance.md); to use several cores, fly many runs "
    "with clark campaign MISSION --runs N --workers N"
)


class _Removed(argparse.Action):
    """An option that is gone: taking it (with or without a value) is a usage error saying why.

    Kept hidden in the parser so that a user's old command line gets the reason and the
    way forward (exit 2), not argparse's "unrecognized arguments".
    """

    def __call__(
        self,
        parser: argparse.ArgumentParser,
        namespace: argparse.Namespace,
        values: str | Sequence[Any] | None,
        option_string: str | None = None,
    ) -> None:
        parser.error(str(self.const))


def _positive(text: str, refusal: str) -> float:
    """``text`` as a finite number above 0; otherwise a usage error (exit 2) saying ``refusal``."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not 0 < value < float("inf"):
        raise argparse.ArgumentTypeError(refusal.format(text=text))
    return value


def _period_s(text: str) -> float:
    """A positive, finite number of seconds (or hertz)."""
    return _positive(text, "{text!r} is not a positive number of seconds")


def _until_s(text: str) -> float:
    """How long to simulate: seconds above 0, at most the language's longest time."""
    from clark_engine.mission.schema_source.common import TIME_MAX_S

    value = _period_s(text)
    if value > TIME_MAX_S:
        raise argparse.ArgumentTypeError(
            f"{text!r} is longer than any run (at most {TIME_MAX_S} s, as sim.duration_s)"
        )
    return value


def _speed(text: str) -> float:
    """A speed-up factor: a finite number above 0."""
    return _positive(text, "must be a number > 0, not {text!r}")


def _seed(text: str) -> int:
    """A random seed: a whole number >= 0; anything else is a usage error (exit 2)."""
    try:
        value = int(text)
    except ValueError:
        value = -1
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a whole number >= 0, not {text!r}")
    return value


def _version() -> str:
    """The installed package's version (its metadata); the source's when not installed."""
    try:
        return importlib.metadata.version("clark-engine")
    except importlib.metadata.PackageNotFoundError:
        return __version__


def cmd_payload_sim(args: argparse.Namespace) -> int:
    """Play a simulated payload (the thesis's camera) against a payload adapter."""
    from clark_engine.standins.payload_sim import run_camera

    return run_camera(
        args.connect, udp=args.udp, capture_delay_s=args.capture_delay_s, retry_s=args.retry_s
    )


def cmd_autopilot_sim(args: argparse.Namespace) -> int:
    """Serve one vehicle's autopilot (simulated, or ArduPilot SITL) for `clark run`."""
    from clark_engine.standins.autopilot_sim import serve_vehicle

    return serve_vehicle(args)


def cmd_radio_sim(args: argparse.Namespace) -> int:
    """Emulate the mission's XBee radios on pseudo-terminals for `clark run`."""
    from clark_engine.standins.radio_sim import serve_network

    return serve_network(args)


def cmd_run(args: argparse.Namespace) -> int:
    """Run one agent on its real interfaces (the real-time shell) until stopped."""
    from clark_engine.shells.commands import run

    return run(args)


def cmd_check(args: argparse.Namespace) -> int:
    """Check one interface of an agent: connect, verify, print what is seen."""
    from clark_engine.shells.commands import check

    return check(args)


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

    parser = _Parser(
        prog="clark",
        description="Clark Engine: validate, explain, dry-run (on a simulated fleet), "
        "campaign (many dry runs), compile and analyze multi-vehicle missions. "
        "`clark COMMAND --help` for each.",
        epilog="Exit codes: 0 good, 1 invalid input or failed check, 2 usage or I/O error.",
    )
    parser.add_argument("--version", action="version", version=f"clark-engine {_version()}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    quiet = _Parser(add_help=False)
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
        type=_seed,
        metavar="N",
        help="random seed, a whole number >= 0 (the mission's sim.seed by default)",
    )
    p.add_argument(
        "--until",
        type=_until_s,
        metavar="SECONDS",
        help="simulated seconds to run (the mission's sim.duration_s by default)",
    )
    p.add_argument("--report", metavar="DIR", help="write logs, CSV, plots and summary.md here")
    p.add_argument(
        "--speed",
        type=_speed,
        metavar="X",
        help="pace the run at X times real time, X > 0 (as fast as possible by default)",
    )
    p.add_argument(
        "--workers", nargs="?", action=_Removed, const=WORKERS_REMOVED, help=argparse.SUPPRESS
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
        type=_speed,
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
        type=_period_s,
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
        type=_runs,
        metavar="N",
        help="how many runs (the mission's campaign.runs by default, else 100)",
    )
    p.add_argument(
        "--seed",
        type=_seed,
        metavar="N",
        help="the campaign's seed: run i's seed is derived from it and i (the mission's "
        "campaign.seed, else sim.seed, by default)",
    )
    p.add_argument(
        "--until",
        type=_until_s,
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
        type=_count,
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
        "--sitl-speedup", type=_speed, metavar="X", help="with --autopilot sitl: (10 by default)"
    )
    p.add_argument(
        "--sitl-instances",
        metavar="FIRST-LAST",
        help="with --autopilot sitl: the instance numbers runs may take ($CLARK_SITL_INSTANCES)",
    )
    p.add_argument(
        "--sitl-per-worker",
        type=_count,
        metavar="K",
        help="with --autopilot sitl, locally: at most K runs (SITL stacks) at once (2 by "
        "default); on a cluster, each worker's --resources sitl=K says it",
    )
    p.add_argument(
        "--run-timeout-s",
        type=_period_s,
        metavar="SECONDS",
        help="stop a run (its whole process group) after this much wall time and retry it "
        "(1800 s by default on SITL; none on the simulated autopilot)",
    )
    p.add_argument(
        "--retries",
        type=_retries,
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
        type=_share,
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
        type=_period_s,
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
    p.set_defaults(func=cmd_behaviors)

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
        type=_period_s,
        metavar="SECONDS",
        help="sim: ready this long after power-on instead of the firmware's boot time",
    )
    p.add_argument("--until", type=_period_s, metavar="SECONDS", help="stop after this long")
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
        type=_period_s,
        metavar="BPS",
        help="the shared channel's throughput (the radio profile's, 33000, by default)",
    )
    p.add_argument("--seed", type=_seed, default=0, metavar="N", help="seeds the loss draws")
    p.add_argument("--until", type=_period_s, metavar="SECONDS", help="stop after this long")
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
    p.add_argument("--until", type=_period_s, metavar="SECONDS", help="stop after this long")
    p.add_argument("--loop-hz", type=_period_s, metavar="HZ", help="instead of mission.loop_hz")
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
        type=_period_s,
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
        type=_period_s,
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


if __name__ == "__main__":
    console_main()
