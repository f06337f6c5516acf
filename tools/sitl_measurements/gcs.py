"""The small ground station every measurement script in this folder flies with.

Each script boots one fresh ArduPilot SITL vehicle through
:class:`clark_engine.sitl.launcher.SitlProcess` (a free instance, held under its lock and always
stopped), talks MAVLink 2 (ardupilotmega) to it as system 255 / component 190, and keeps
its own clock from the autopilot's ``time_boot_ms`` (SYSTEM_TIME is asked for at 10 Hz, so
every time is the autopilot's, to about 0.1 s, whatever the wall clock or the machine's
load does). Every message it receives goes, with that time as ``_t``, to
``<out>/<tag>.jsonl``, so that a finding can be checked against the raw record later.

Heartbeats: :attr:`Gcs.hb_sysids` lists the system ids it sends a GCS HEARTBEAT as, once
a second of autopilot time; an empty list stops them (it keeps reading). The GCS failsafe
measurements turn them on and off per system id.

The facts these scripts measured are in docs/sitl-measurements.md; the README beside this
file says what each script does and how to run it.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import select
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType
from typing import IO, Any

from pymavlink.dialects.v20 import ardupilotmega as mav

import clark_engine
from clark_engine.sitl.errors import SitlNotFound
from clark_engine.sitl.launcher import ENV_SPEEDUP, VEHICLES, Home, SitlInstall, SitlProcess

__all__ = ["ORIGIN", "Gcs", "Options", "dist_m", "mav", "offset", "parse_args"]

ORIGIN = Home(30.6372, -96.4787, 90.0, 0.0)
"""Where every vehicle boots: the project's missions' origin, 90 m AMSL."""

DEFAULT_SPEEDUP = 8.0
"""SITL's speed-up when neither ``--speedup`` nor ``$CLARK_SITL_SPEEDUP`` says (the
measurements in docs/sitl-measurements.md were all made at 8)."""

Msg = Any
"""A pymavlink message (pymavlink has no type information)."""

Streams = Sequence[tuple[str, float]]
"""Messages to ask for (SET_MESSAGE_INTERVAL) and their rates in Hz."""

MODES: dict[str, dict[str, int]] = {
    "rover": {
        "MANUAL": 0,
        "HOLD": 4,
        "LOITER": 5,
        "AUTO": 10,
        "RTL": 11,
        "SMART_RTL": 12,
        "GUIDED": 15,
    },
    "copter": {
        "STABILIZE": 0,
        "ALT_HOLD": 2,
        "AUTO": 3,
        "GUIDED": 4,
        "LOITER": 5,
        "RTL": 6,
        "LAND": 9,
        "BRAKE": 17,
        "SMART_RTL": 21,
    },
    "plane": {
        "MANUAL": 0,
        "CIRCLE": 1,
        "FBWA": 5,
        "AUTO": 10,
        "RTL": 11,
        "LOITER": 12,
        "TAKEOFF": 13,
        "GUIDED": 15,
        "QRTL": 21,
    },
}
"""The custom_mode numbers of the modes the scripts use, per vehicle."""

DEFAULT_STREAMS: Streams = (
    ("GLOBAL_POSITION_INT", 5),
    ("GPS_RAW_INT", 2),
    ("SYS_STATUS", 2),
    ("EKF_STATUS_REPORT", 1),
    ("HOME_POSITION", 1),
)


@dataclass(frozen=True)
class Options:
    """What a script was told on its command line."""

    install: SitlInstall
    """The SITL launcher (``--sitl PATH`` or ``$CLARK_SITL``)."""
    out: Path
    """The folder the script writes its logs and results to (made if missing)."""
    speedup: float
    """SITL's speed-up: times are the autopilot's own whatever it is."""
    vehicle: str
    """The vehicle to measure (the script's only one when it takes no argument)."""


def parse_args(
    doc: str | None, argv: Sequence[str] | None, vehicles: Sequence[str] = VEHICLES
) -> Options:
    """Read a script's command line: ``[VEHICLE] [--out DIR] [--sitl PATH] [--speedup X]``.

    The output folder defaults to a new ``sitl-measurements-<date>-<time>`` folder under
    the current directory, so that a run never writes into the project's sources or an
    installed package; an ``--out`` inside the installed ``clark_engine`` is refused.

    Args:
        doc: The script's docstring: its first paragraph is the help's description, the
            rest its epilog.
        argv: The arguments (``sys.argv[1:]`` when None).
        vehicles: The vehicles the script measures; with one, it takes no VEHICLE argument.

    Returns:
        The options, with the output folder made.

    Raises:
        SystemExit: A usage error, an output folder inside the package, or no SITL found
            (argparse's exit code 2, with the reason).
    """
    head, _, tail = (doc or "").strip().partition("\n\n")
    parser = argparse.ArgumentParser(
        description=head,
        epilog=tail,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    if len(vehicles) > 1:
        parser.add_argument("vehicle", choices=list(vehicles), help="the SITL vehicle to boot")
    parser.add_argument(
        "--out",
        type=Path,
        default=None,
        help="folder for the logs and results (default: a new sitl-measurements-<time> "
        "folder under the current directory)",
    )
    parser.add_argument(
        "--sitl",
        default=None,
        help="the ArduPilot SITL folder (with its `sitl` launcher), or the launcher; "
        "default $CLARK_SITL",
    )
    parser.add_argument(
        "--speedup",
        type=float,
        default=float(os.environ.get(ENV_SPEEDUP) or DEFAULT_SPEEDUP),
        help=f"SITL's speed-up (default ${ENV_SPEEDUP}, else {DEFAULT_SPEEDUP:g})",
    )
    args = parser.parse_args(argv)
    try:
        install = SitlInstall.find(args.sitl)
    except SitlNotFound as exc:
        parser.error(str(exc))
    if args.out is None:
        out = Path.cwd() / time.strftime("sitl-measurements-%Y%m%d-%H%M%S")
        out.mkdir(parents=True)
    else:
        out = args.out
        package = Path(clark_engine.__file__).resolve().parent
        if out.resolve().is_relative_to(package):
            parser.error(f"--out {out} is inside the clark_engine package; write elsewhere")
        out.mkdir(parents=True, exist_ok=True)
    if not args.speedup > 0:
        parser.error(f"--speedup must be above 0, not {args.speedup:g}")
    vehicle = args.vehicle if len(vehicles) > 1 else vehicles[0]
    return Options(install=install, out=out, speedup=args.speedup, vehicle=vehicle)


def mode_name(vehicle: str, number: int) -> str:
    """The name of ``vehicle``'s mode ``number`` (the number itself when not in MODES)."""
    for name, n in MODES[vehicle].items():
        if n == number:
            return name
    return str(number)


def write_json(path: Path, data: object) -> None:
    """Write a script's results (``str`` for whatever JSON does not know, e.g. messages)."""
    with path.open("w", encoding="utf-8") as f:
        json.dump(data, f, indent=1, default=str)


class Gcs:
    """One fresh SITL vehicle and a ground station connected to it.

    Creating it boots the vehicle and connects (SITL's clock starts then); use it as a
    context manager, or call :meth:`close`, so that SITL always stops. Nothing is sent
    until :meth:`pump` runs (every wait below pumps), except by :meth:`send`.

    Args:
        options: The command line's options (SITL, speed-up, output folder).
        vehicle: ``rover``, ``copter`` or ``plane``.
        tag: The log's name: ``<out>/<tag>.jsonl``.
        sysid: The ground station's system id (the autopilot's MAV_GCS_SYSID is 255).
        compid: Its component id.
        home: Where the vehicle boots.
        extra_args: More ArduPilot command-line arguments.
    """

    def __init__(
        self,
        options: Options,
        vehicle: str,
        tag: str,
        *,
        sysid: int = 255,
        compid: int = 190,
        home: Home = ORIGIN,
        extra_args: Iterable[str] = (),
    ) -> None:
        self.vehicle = vehicle
        self.out = options.out
        self.sitl = SitlProcess(
            options.install,
            vehicle,
            home,
            speedup=options.speedup,
            extra_args=tuple(extra_args),
            keep_work=False,
        )
        self.sitl.start()
        try:
            self.sock = self.sitl.connect(timeout_s=30)
        except BaseException:
            self.sitl.stop()
            raise
        self.sock.setblocking(False)
        self.sysid = sysid
        self.mavs: dict[tuple[int, int], Any] = {}
        self.mav = self._enc(sysid, compid)
        self.parser = mav.MAVLink(None)
        self.parser.robust_parsing = True
        self.now = 0.0
        """The autopilot's time in seconds: the latest time_boot_ms received."""
        self.hb_sysids = [sysid]
        """The system ids a GCS HEARTBEAT is sent as, once a second of autopilot time."""
        self.hb_due = 0.0
        self.last_hb_sent: dict[int, float] = {}
        """System id -> autopilot time its last heartbeat was sent at."""
        self.last: dict[str, Msg] = {}
        """Message type -> the latest one received."""
        self.texts: list[tuple[float, int, str]] = []
        """Every STATUSTEXT: (time, severity, text)."""
        self.history: list[tuple[float, Msg]] = []
        self.log: IO[str] = (self.out / f"{tag}.jsonl").open("w", encoding="utf-8")
        self.target = 1
        self.echo_text = True
        """Print each STATUSTEXT as it arrives."""
        self.on_msg: list[Callable[[float, Msg], None]] = []
        """Called with (time, message) for each message received."""

    def __enter__(self) -> Gcs:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _enc(self, sysid: int, compid: int = 190) -> Any:
        """The encoder that sends as ``sysid``/``compid`` (one per pair, for its sequence)."""
        key = (sysid, compid)
        if key not in self.mavs:
            self.mavs[key] = mav.MAVLink(None, srcSystem=sysid, srcComponent=compid)
        return self.mavs[key]

    # --- io

    def send(self, msg: Msg, sysid: int | None = None) -> None:
        """Send one message, as the ground station or as another system id."""
        enc = self.mav if sysid is None else self._enc(sysid)
        data = msg.pack(enc)
        self.sock.setblocking(True)
        self.sock.sendall(data)
        self.sock.setblocking(False)

    def pump(self, wait_s: float = 0.05) -> list[Msg]:
        """Send the heartbeats that are due, then read what arrives within ``wait_s``.

        Only messages from the autopilot (system :attr:`target`) are kept; each is logged,
        remembered in :attr:`last` and :attr:`history`, and given to :attr:`on_msg`.

        Returns:
            The messages read.
        """
        if self.now >= self.hb_due:
            for s in self.hb_sysids:
                self.last_hb_sent[s] = self.now
                self.send(
                    mav.MAVLink_heartbeat_message(
                        mav.MAV_TYPE_GCS, mav.MAV_AUTOPILOT_INVALID, 0, 0, mav.MAV_STATE_ACTIVE, 3
                    ),
                    sysid=s,
                )
            self.hb_due = self.now + 1.0
        r, _, _ = select.select([self.sock], [], [], wait_s)
        if not r:
            self.sitl.raise_if_exited()
            return []
        try:
            data = self.sock.recv(1 << 16)
        except BlockingIOError:
            return []
        if not data:
            self.sitl.raise_if_exited()
            raise RuntimeError("SITL closed the connection")
        out = []
        for m in self.parser.parse_buffer(data) or []:
            if m.get_type() == "BAD_DATA" or m.get_srcSystem() != self.target:
                continue
            tb = getattr(m, "time_boot_ms", None)
            if tb is not None and tb / 1000.0 > self.now:
                self.now = tb / 1000.0
            t = m.get_type()
            self.last[t] = m
            self.history.append((self.now, m))
            d = m.to_dict()
            d["_t"] = round(self.now, 3)
            self.log.write(json.dumps(d, default=str) + "\n")
            if t == "STATUSTEXT":
                self.texts.append((self.now, m.severity, m.text))
                if self.echo_text:
                    print(f"  [{self.now:8.2f}] STATUSTEXT sev={m.severity} {m.text!r}", flush=True)
            for cb in self.on_msg:
                cb(self.now, m)
            out.append(m)
        return out

    def run_for(self, seconds: float) -> list[Msg]:
        """Pump for ``seconds`` of autopilot time; the messages read.

        Raises:
            TimeoutError: The autopilot's clock stopped (far longer in wall time than the
                speed-up allows).
        """
        end = self.now + seconds
        seen = []
        wall = time.monotonic() + seconds / self.sitl.speedup * 4 + 30
        while self.now < end:
            seen += self.pump()
            if time.monotonic() > wall:
                raise TimeoutError(f"clock stuck at {self.now}")
        return seen

    def wait_for(
        self,
        typ: str | None,
        within_s: float,
        where: Callable[[Msg], bool] | None = None,
        raise_: bool = True,
    ) -> Msg:
        """The first message of type ``typ`` (any when None) that ``where`` accepts.

        Args:
            typ: The message type, e.g. ``"STATUSTEXT"``.
            within_s: Autopilot seconds to wait.
            where: A test on the message; None accepts any.
            raise_: Raise when none came; False returns None instead.

        Raises:
            TimeoutError: None came within ``within_s`` (and ``raise_``).
        """
        end = self.now + within_s
        wall = time.monotonic() + within_s / self.sitl.speedup * 4 + 30
        while self.now <= end:
            for m in self.pump():
                if (typ is None or m.get_type() == typ) and (where is None or where(m)):
                    return m
            if time.monotonic() > wall:
                break
        if raise_:
            raise TimeoutError(f"no {typ} within {within_s}s (t={self.now:.2f})")
        return None

    def texts_since(self, t0: float) -> list[tuple[float, int, str]]:
        """The STATUSTEXTs received at or after autopilot time ``t0``."""
        return [t for t in self.texts if t[0] >= t0]

    # --- requests

    def command_long(self, cmd: int, *p: float, within_s: float = 5.0, raise_: bool = True) -> Msg:
        """Send COMMAND_LONG ``cmd`` with params ``p`` (the rest 0); its COMMAND_ACK."""
        v = [float(x) for x in p] + [0.0] * (7 - len(p))
        self.send(mav.MAVLink_command_long_message(self.target, 1, cmd, 0, *v[:7]))
        return self.wait_for("COMMAND_ACK", within_s, lambda m: m.command == cmd, raise_=raise_)

    def command_int(
        self,
        cmd: int,
        frame: int,
        p1: float = 0.0,
        p2: float = 0.0,
        p3: float = 0.0,
        p4: float = 0.0,
        x: float = 0,
        y: float = 0,
        z: float = 0.0,
        within_s: float = 5.0,
    ) -> Msg:
        """Send COMMAND_INT ``cmd`` in ``frame``; its COMMAND_ACK, or None when none came."""
        self.send(
            mav.MAVLink_command_int_message(
                self.target, 1, frame, cmd, 0, 0, p1, p2, p3, p4, int(x), int(y), float(z)
            )
        )
        return self.wait_for("COMMAND_ACK", within_s, lambda m: m.command == cmd, raise_=False)

    def interval(self, name: str, hz: float) -> int | None:
        """Ask for message ``name`` at ``hz``; the ack's result, None when none came."""
        msg_id = getattr(mav, f"MAVLINK_MSG_ID_{name}")
        ack = self.command_long(mav.MAV_CMD_SET_MESSAGE_INTERVAL, msg_id, 1e6 / hz, raise_=False)
        return None if ack is None else int(ack.result)

    def start(self, streams: Streams = DEFAULT_STREAMS) -> None:
        """Wait for the first HEARTBEAT, take its sender as the autopilot, ask for streams.

        SYSTEM_TIME is asked for at 10 Hz first: it is the clock. The acks' results go to
        :attr:`stream_results`.
        """
        hb = self.wait_for("HEARTBEAT", 30)
        self.target = hb.get_srcSystem()
        self.interval("SYSTEM_TIME", 10)
        self.wait_for("SYSTEM_TIME", 30)
        self.stream_results = {n: self.interval(n, hz) for n, hz in streams}

    def param_set(
        self,
        name: str,
        value: float,
        ptype: int = mav.MAV_PARAM_TYPE_REAL32,
        within_s: float = 3.0,
    ) -> Msg:
        """PARAM_SET; the first PARAM_VALUE of that name after it, or None."""
        self.send(mav.MAVLink_param_set_message(self.target, 1, name.encode(), float(value), ptype))
        return self.wait_for("PARAM_VALUE", within_s, lambda m: m.param_id == name, raise_=False)

    def param_get(self, name: str, within_s: float = 3.0) -> Msg:
        """PARAM_REQUEST_READ by name; the PARAM_VALUE, or None."""
        self.send(mav.MAVLink_param_request_read_message(self.target, 1, name.encode(), -1))
        return self.wait_for("PARAM_VALUE", within_s, lambda m: m.param_id == name, raise_=False)

    def param_list(self, within_s: float = 60.0) -> dict[str, Msg]:
        """Every parameter (PARAM_REQUEST_LIST; the missing ones asked for by index)."""
        self.send(mav.MAVLink_param_request_list_message(self.target, 1))
        params: dict[str, Msg] = {}
        count = None
        end = self.now + within_s
        quiet_since = self.now
        while self.now < end:
            got = False
            for m in self.pump():
                if m.get_type() == "PARAM_VALUE":
                    params[m.param_id] = m
                    count = m.param_count
                    got = True
            if got:
                quiet_since = self.now
            if count is not None and len(params) >= count:
                break
            if count is not None and self.now - quiet_since > 5:
                # ask for the missing ones by index
                have = {m.param_index for m in params.values()}
                missing = [i for i in range(count) if i not in have]
                for i in missing[:50]:
                    self.send(mav.MAVLink_param_request_read_message(self.target, 1, b"", i))
                quiet_since = self.now
        return params

    def set_mode(self, name: str) -> Msg:
        """DO_SET_MODE to the mode called ``name``; the ack."""
        return self.command_long(
            mav.MAV_CMD_DO_SET_MODE,
            mav.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED,
            MODES[self.vehicle][name],
        )

    def arm(self, force: bool = False) -> Msg:
        """Ask to arm (``force``: skip the checks); the ack."""
        return self.command_long(mav.MAV_CMD_COMPONENT_ARM_DISARM, 1, 21196 if force else 0)

    def mode(self) -> str:
        """The mode the latest HEARTBEAT reports ("?" before one)."""
        hb = self.last.get("HEARTBEAT")
        return "?" if hb is None else mode_name(self.vehicle, hb.custom_mode)

    def armed(self) -> bool:
        """Whether the latest HEARTBEAT reports the vehicle armed."""
        hb = self.last.get("HEARTBEAT")
        return bool(hb and hb.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED)

    def wait_ready(self, within_s: float = 120.0) -> None:
        """Wait for an absolute EKF position, then for the pre-arm checks to pass."""
        self.wait_for("EKF_STATUS_REPORT", within_s, lambda m: m.flags & mav.EKF_POS_HORIZ_ABS)
        self.wait_for(
            "SYS_STATUS",
            within_s,
            lambda m: m.onboard_control_sensors_health & mav.MAV_SYS_STATUS_PREARM_CHECK,
        )

    def arm_when_ready(self, within_s: float = 120.0, force: bool = False) -> None:
        """Ask to arm every 2 s until it is accepted, then wait for the armed HEARTBEAT.

        Raises:
            TimeoutError: Not armed within ``within_s``.
        """
        end = self.now + within_s
        while self.now < end:
            ack = self.arm(force)
            if ack.result == 0:
                self.wait_for(
                    "HEARTBEAT", 3, lambda m: m.base_mode & mav.MAV_MODE_FLAG_SAFETY_ARMED
                )
                return
            self.run_for(2)
        raise TimeoutError("could not arm")

    def goto(
        self,
        lat: float,
        lon: float,
        alt: float,
        frame: int = mav.MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        mask: int = 0x0FF8,
    ) -> None:
        """SET_POSITION_TARGET_GLOBAL_INT to a position (degrees, metres in ``frame``)."""
        self.send(
            mav.MAVLink_set_position_target_global_int_message(
                0,
                self.target,
                1,
                frame,
                mask,
                int(lat * 1e7),
                int(lon * 1e7),
                alt,
                0,
                0,
                0,
                0,
                0,
                0,
                0,
                0,
            )
        )

    def pos(self) -> tuple[float, float, float, float]:
        """The latest GLOBAL_POSITION_INT: lat, lon (deg), alt AMSL, relative_alt (m)."""
        g = self.last.get("GLOBAL_POSITION_INT")
        if g is None:
            return (math.nan,) * 4
        return g.lat / 1e7, g.lon / 1e7, g.alt / 1000.0, g.relative_alt / 1000.0

    def upload(self, items: list[Msg], mission_type: int, within_s: float = 10.0) -> Msg:
        """Mission protocol upload; items are MISSION_ITEM_INT messages (seq set here).

        Returns:
            The MISSION_ACK.

        Raises:
            TimeoutError: No MISSION_ACK within ``within_s``.
        """
        self.send(mav.MAVLink_mission_count_message(self.target, 1, len(items), mission_type))
        end = self.now + within_s
        while self.now < end:
            for m in self.pump():
                t = m.get_type()
                if (
                    t in ("MISSION_REQUEST_INT", "MISSION_REQUEST")
                    and m.mission_type == mission_type
                ):
                    it = items[m.seq]
                    it.seq = m.seq
                    it.mission_type = mission_type
                    self.send(it)
                elif t == "MISSION_ACK" and m.mission_type == mission_type:
                    return m
        raise TimeoutError("no MISSION_ACK")

    def close(self) -> None:
        """Close the connection, stop SITL and close the log."""
        try:
            self.sock.close()
        finally:
            self.sitl.stop()
            self.log.close()


def offset(lat: float, lon: float, north_m: float, east_m: float) -> tuple[float, float]:
    """The point ``north_m`` north and ``east_m`` east of (lat, lon), in degrees."""
    dlat = north_m / 6378137.0
    dlon = east_m / (6378137.0 * math.cos(math.radians(lat)))
    return lat + math.degrees(dlat), lon + math.degrees(dlon)


def dist_m(lat1: float, lon1: float, lat2: float, lon2: float) -> float:
    """Horizontal distance in metres between two points (flat earth; fine at these ranges)."""
    n = math.radians(lat2 - lat1) * 6378137.0
    e = math.radians(lon2 - lon1) * 6378137.0 * math.cos(math.radians(lat1))
    return math.hypot(n, e)
