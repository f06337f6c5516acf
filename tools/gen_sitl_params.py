"""Generate the full parameter lists the simulated autopilot reports, from ArduPilot SITL.

    .venv/bin/python tools/gen_sitl_params.py [rover copter plane] [--sitl PATH] [--speedup X]
    .venv/bin/python tools/gen_sitl_params.py --check

A ground station that downloads the parameters of an ArduPilot vehicle gets about 1,300
of them; the simulated autopilot acts on about 40. So that a station sees the same list
from the simulation as from SITL (count, order, names, types and values), this boots each
SITL build of ``../shared/ardupilot-sitl`` as ``clark dry-run --autopilot sitl`` runs it
(a fresh vehicle with SITL's own default parameter file, at the missions' origin), waits
until the parameters it sets by itself at boot have settled (10 s of autopilot time),
downloads the whole list (PARAM_REQUEST_LIST, the missing ones asked for by index) and
writes it to ``clark_engine/sim/ardupilot/sitl_params/<firmware>.csv.gz``: one ``name,type,value``
line per parameter in ArduPilot's index order (type: MAV_PARAM_TYPE; value: the float a
PARAM_VALUE carries, written so that it reads back exactly). The files are package data,
loaded lazily by ``clark_engine.sim.ardupilot.params``.

``--check`` reads the shipped files back and checks them (every firmware present, names
unique, types known) without SITL. Run the generator again for a new SITL build, and say
in docs/autopilot-fidelity.md what changed.
"""

from __future__ import annotations

import argparse
import gzip
import io
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools" / "sitl_measurements"))

from clark_engine.sim.ardupilot import params as ap_params  # noqa: E402
from clark_engine.sitl.launcher import VEHICLES, SitlInstall, SitlNotFound  # noqa: E402

SETTLE_S = 10.0
"""Autopilot seconds after boot before the download: SITL sets EK3_SRC1_POSXY and
ArduPlane's ARSPD_OFFSET by itself at about 4 s."""

NORMALISED = {"SIM_SPEEDUP": 1.0}
"""Values that depend on how the generator ran SITL, written as a real-time run has them."""

FIRMWARE_OF_VEHICLE = {"rover": "ardurover", "copter": "arducopter", "plane": "arduplane"}


def download(install: SitlInstall, vehicle: str, speedup: float) -> list[tuple[str, int, float]]:
    """Boot one fresh SITL ``vehicle`` and download its whole parameter list, in index order.

    Raises:
        RuntimeError: The list came back incomplete (an index missing after retries).
    """
    from gcs import Gcs, Options  # tools/sitl_measurements: boots and talks to one SITL

    out = Path(tempfile.mkdtemp(prefix=f"gen-sitl-params-{vehicle}-"))
    options = Options(install=install, out=out, speedup=speedup, vehicle=vehicle)
    with Gcs(options, vehicle, f"params_{vehicle}") as g:
        g.echo_text = False
        g.start(streams=())
        g.run_for(max(0.0, SETTLE_S - g.now))
        by_index, count = _download_list(g)
    rows = [
        (str(by_index[i].param_id), int(by_index[i].param_type), float(by_index[i].param_value))
        for i in range(count)
    ]
    return [(n, t, NORMALISED.get(n, v)) for n, t, v in rows]


def _download_list(g: Any) -> tuple[dict[int, Any], int]:
    """PARAM_REQUEST_LIST, then each index still missing by PARAM_REQUEST_READ.

    Kept by index: ArduPilot also sends PARAM_VALUEs unasked (index 65535) while it runs.

    Raises:
        RuntimeError: The count changed during the download, or indices stay missing.
    """
    from gcs import mav

    g.send(mav.MAVLink_param_request_list_message(g.target, 1))
    asked_s = g.now
    by_index: dict[int, Any] = {}
    counts: set[int] = set()
    quiet_since = g.now
    for _ in range(20):
        while g.now - quiet_since < 3.0:
            for m in g.pump():
                if m.get_type() == "PARAM_VALUE" and m.param_index != 65535:
                    by_index[m.param_index] = m
                    counts.add(m.param_count)
                    quiet_since = g.now
        if len(counts) > 1:
            raise RuntimeError(f"param_count changed during the download: {sorted(counts)}")
        missing = [i for i in range(max(counts, default=0)) if i not in by_index]
        if counts and not missing:
            last_s = max(t for t, m in g.history if m.get_type() == "PARAM_VALUE")
            print(f"  the list took {last_s - asked_s:.2f} s of autopilot time", flush=True)
            return by_index, counts.pop()
        for i in missing[:100]:
            g.send(mav.MAVLink_param_request_read_message(g.target, 1, b"", i))
        quiet_since = g.now
    raise RuntimeError(f"indices still missing after 20 rounds: {missing[:10]}")


def write(path: Path, rows: Sequence[tuple[str, int, float]]) -> None:
    """One ``name,type,value`` line per parameter, gzip'd reproducibly (no time stamp)."""
    text = io.StringIO()
    text.write(ap_params.HEADER + "\n")
    for name, kind, value in rows:
        text.write(f"{name},{kind},{value!r}\n")
    path.write_bytes(gzip.compress(text.getvalue().encode("ascii"), mtime=0))


def check() -> int:
    """Read every shipped list back; 0 when all are sound, 1 otherwise."""
    bad = 0
    for firmware in FIRMWARE_OF_VEHICLE.values():
        try:
            table = ap_params.sitl_table(firmware)
        except (OSError, ValueError) as exc:
            print(f"{firmware}: {exc}", file=sys.stderr)
            bad += 1
            continue
        print(f"{firmware}: {len(table.names)} parameters, {table.names[0]} .. {table.names[-1]}")
    return 1 if bad else 0


def main(argv: Sequence[str] | None = None) -> int:
    """Generate the lists named on the command line (all three by default)."""
    head, _, tail = (__doc__ or "").strip().partition("\n\n")
    parser = argparse.ArgumentParser(
        description=head, epilog=tail, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("vehicles", nargs="*", metavar="VEHICLE", help="rover, copter, plane")
    parser.add_argument("--sitl", default=None, help="the SITL folder or launcher")
    parser.add_argument("--speedup", type=float, default=10.0, help="SITL's speed-up (10)")
    parser.add_argument("--check", action="store_true", help="check the shipped files only")
    args = parser.parse_args(argv)
    if args.check:
        return check()
    unknown = [v for v in args.vehicles if v not in VEHICLES]
    if unknown:
        parser.error(f"unknown vehicle {unknown[0]!r}; use {', '.join(VEHICLES)}")
    try:
        install = SitlInstall.find(args.sitl)
    except SitlNotFound as exc:
        parser.error(str(exc))
    for vehicle in args.vehicles or VEHICLES:
        rows = download(install, vehicle, args.speedup)
        path = ap_params.DATA_DIR / f"{FIRMWARE_OF_VEHICLE[vehicle]}.csv.gz"
        write(path, rows)
        print(f"{vehicle}: {len(rows)} parameters -> {path.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
