"""``clark dry-run`` and ``clark campaign``: a mission flown on a simulated fleet, once or often.

Separate because these two share their options' rules (the simulated autopilot or
SITL, real time, the station's view of a rehearsal) and the modules they load (the dry
run, SITL, the campaign), each imported inside its command.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from clark_engine.errors import UsageError

if TYPE_CHECKING:
    from clark_engine.dryrun.command import LiveView, LiveViewOpener
    from clark_engine.mission.model import Mission


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


__all__ = ["cmd_campaign", "cmd_dry_run"]
