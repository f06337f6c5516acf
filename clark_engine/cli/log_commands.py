"""``clark analyze``: a finished run's logs read again, for its latency tables or its checks.

Separate from the commands that fly: it reads log folders only. ``clark replay``, which
reads them too, is :mod:`clark_engine.station.replay_command`'s, beside the station's
view it serves.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from clark_engine.cli.arguments import EXIT_OK
from clark_engine.errors import UsageError


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


__all__ = ["cmd_analyze"]
