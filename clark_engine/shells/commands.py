"""``clark run`` and ``clark check``: what the command line does, apart from parsing it.

``clark run MISSION --agent NAME`` (or ``clark run COMPILED.json``) puts one agent on
its real interfaces (:func:`~clark_engine.shells.agent.open_agent`) and runs the
real-time loop until SIGINT or SIGTERM, a terminate, or ``--until``. ``clark check
autopilot|radio|payload`` are the module test tools of thesis 2.3.1-2.3.3: connect,
verify, print what is seen for a few seconds; exit 0 when it works, 1 when it does not.
"""

from __future__ import annotations

import contextlib
import selectors
import sys
import time
from collections.abc import Mapping
from pathlib import Path
from typing import Any, TextIO

from clark_engine.errors import ClarkError, UsageError
from clark_engine.runtime.config import AgentConfig, config_from_dict, load_config
from clark_engine.shells.agent import (
    RunOptions,
    autopilot_link,
    connection_from_text,
    is_host_port,
    open_agent,
    radio_factory,
    radio_kind,
)
from clark_engine.shells.realtime import EXIT_ABORTED

EXIT_OK = 0
EXIT_FAILED = 1
EXIT_USAGE = 2
EXIT_SHORTENED = EXIT_ABORTED
"""A second signal shortened the stop (130, as a shell's Ctrl-C; docs/run.md)."""


def load_agent(path_text: str, agent: str | None) -> tuple[AgentConfig, list[dict[str, Any]], Path]:
    """The agent's compiled config, the mission's operator script, and the key's folder.

    Raises:
        UsageError: The file cannot be read, or the agent is missing or not named when
            a mission is given.
        ClarkError: The mission is invalid.
    """
    path = Path(path_text)
    if not path.exists():
        raise UsageError(f"{path_text}: no such file")
    if path.suffix == ".json":
        config = load_config(path)
        if agent is not None and agent != config.agent:
            raise UsageError(f"{path_text} is {config.agent}'s config, not {agent}'s")
        source = (config.raw.get("source") or {}).get("file")
        folder = Path(source).parent if source and Path(source).parent.exists() else path.parent
        return config, [], folder
    from clark_engine.mission.compiler import agent_config
    from clark_engine.validation import load_mission

    mission = load_mission(path_text)
    if agent is None:
        raise UsageError(
            f"--agent NAME is required with a mission; agents: {', '.join(mission.agents)}"
        )
    if agent not in mission.agents:
        raise UsageError(
            f"{path_text}: there is no agent {agent!r}; agents: {', '.join(mission.agents)}"
        )
    config = config_from_dict(agent_config(mission, mission.agents[agent]))
    return config, list(mission.operator), path.parent


def _peers(items: list[str] | None) -> dict[str, str]:
    peers: dict[str, str] = {}
    for item in items or []:
        name, sep, address = item.partition("=")
        if not sep or not name or not address:
            raise UsageError(f"--peer {item!r}: use NAME=ADDRESS (e.g. mcs=127.0.0.1:15001)")
        peers[name] = address
    return peers


def run_options(args: Any, config: AgentConfig, key_folder: Path) -> RunOptions:
    """RunOptions from ``clark run``'s (or ``clark check``'s) arguments."""
    logs = (
        Path(args.logs)
        if getattr(args, "logs", None)
        else Path("logs") / (f"{config.mission_name}-{time.strftime('%Y%m%d-%H%M%S')}")
    )
    unknown = [name for name in _peers(args.peer) if config.peer(name) is None]
    if unknown:
        raise UsageError(
            f"--peer: no agent {', '.join(unknown)} in the mission; "
            f"peers: {', '.join(p.name for p in config.peers)}"
        )
    if args.autopilot_connection is not None:
        connection_from_text(args.autopilot_connection)  # a usage error before anything opens
    radio_device = getattr(args, "radio_device", None)
    if radio_device is not None:
        profile = config.raw["agent"]["hardware"].get("radio")
        if not profile:
            raise UsageError(f"--radio-device: {config.agent} has no radio")
        if radio_kind(profile, args.radio) != "xbee":
            raise UsageError(
                "--radio-device names an XBee's serial device: use it with --radio xbee"
            )
    key = None
    if config.authenticated:
        from clark_engine.link.auth import KeyFileError, load_key

        key_path = (
            Path(args.key) if getattr(args, "key", None) else key_folder / str(config.key_file)
        )
        try:
            key = load_key(key_path)
        except KeyFileError as exc:
            raise UsageError(str(exc)) from None
    return RunOptions(
        logs=logs,
        state=Path(args.state) if getattr(args, "state", None) else None,
        autopilot=not getattr(args, "no_autopilot", False),
        radio=not getattr(args, "no_radio", False),
        payloads=not getattr(args, "no_payload", False),
        autopilot_connection=args.autopilot_connection,
        radio_link=args.radio,
        radio_address=args.radio_address,
        radio_device=getattr(args, "radio_device", None),
        peers=_peers(args.peer),
        key=key,
        loop_hz=getattr(args, "loop_hz", None),
        overwrite_logs=getattr(args, "overwrite", False),
    )


def run(args: Any, out: TextIO | None = None) -> int:
    """``clark run``: the agent on its interfaces until stopped.

    With ``--view`` (a station only), the station's live web view is served alongside
    (:mod:`clark_engine.station`, docs/station-view.md): its server starts before any link
    opens and stops after the loop, its clients sent the last state.
    """
    out = out if out is not None else sys.stdout
    from clark_engine.shells.console import OperatorConsole, OperatorScript, StatusView

    config, script, key_folder = load_agent(args.mission, args.agent)
    if args.script and not script:
        raise UsageError("--script: the mission has no operator script (give the mission file)")
    if args.script and config.role != "mcs":
        raise UsageError("--script plays the station's operator script: run it on the station")
    options = run_options(args, config, key_folder)
    from clark_engine.io.radio import RadioError
    from clark_engine.station.live_view import fleet_configs, open_view, view_settings

    settings = view_settings(
        getattr(args, "view", None),
        getattr(args, "view_token", None),
        getattr(args, "view_token_file", None),
        getattr(args, "view_hz", None),
        config,
    )
    # The view's server starts first: a port in use ends the run before any link opens.
    served = open_view(settings, config, *fleet_configs(args.mission, config)) if settings else None
    try:
        shell = open_agent(config, options)
    except BaseException as exc:
        if served is not None:
            served.stop()
        if isinstance(exc, RadioError):  # an I/O error at the start: exit 2, no silent retry
            raise UsageError(
                f"cannot open {config.agent}'s radio: {exc}; check its connection and address "
                "(`clark check radio`), or run without it (--no-radio, testing mode)"
            ) from None
        raise
    screen = out.isatty() and not args.plain
    view = StatusView(out, screen=screen)
    link = served.attach(shell) if served is not None else None
    shell.on_tick.append(view)
    if args.script:
        shell.on_tick.append(OperatorScript(script, view))
    if config.role == "mcs" and not args.no_console and sys.stdin is not None:
        try:
            fd = sys.stdin.fileno()
        except (OSError, ValueError):
            fd = -1
        if fd >= 0:
            # stdin that a selector cannot watch (/dev/null, a file): no console, no crash
            with contextlib.suppress(OSError):
                OperatorConsole(shell, fd, view)
    print(
        f"clark run: {config.agent} of {config.mission_name} at {shell.loop_hz:g} Hz; "
        f"logs in {options.logs}; Ctrl-C stops",
        file=out,
        flush=True,
    )
    if served is not None:
        where = f"clark run: station view at {served.server.url}"  # with the token, if any
        print(where, file=out, flush=True)
        if screen:
            view.messages.append(where)  # kept on the redrawn screen
    shell.announce = lambda line: print(f"clark run: {line}", file=out, flush=True)
    # The handlers stay until the last line: a second Ctrl-C while the view closes, or
    # as the summary prints, shortens what is left rather than raising out of it.
    with shell.signals():
        try:
            code = shell.run(until_s=args.until)
        finally:
            if served is not None and link is not None:
                link.close(shell.now())  # the last state (terminated, stopped) to the page
                served.stop()
        print(f"clark run: stopped ({shell.stopped_by}): {shell.summary()}", file=out, flush=True)
    return EXIT_SHORTENED if shell.hurried_by is not None else code


# -- clark check ------------------------------------------------------------------------------


def _say(out: TextIO, text: str) -> None:
    print(text, file=out, flush=True)


def check(args: Any, out: TextIO | None = None) -> int:
    """``clark check autopilot|radio|payload``: exit 0 when it works, 1 when it does not."""
    out = out if out is not None else sys.stdout
    config, _script, key_folder = load_agent(args.mission, args.agent)
    args.logs = None
    options = run_options(args, config, key_folder)
    if args.what == "autopilot":
        return _check_autopilot(config, options, args.seconds, out)
    if args.what == "radio":
        return _check_radio(config, options, args.seconds, out)
    return _check_payload(config, args.seconds, out)


def _check_autopilot(config: AgentConfig, options: RunOptions, seconds: float, out: TextIO) -> int:
    from clark_engine.io.transports import TransportError
    from clark_engine.runtime.events import AutopilotText, VehicleState
    from clark_engine.runtime.logbook import Logbook

    if not config.is_vehicle:
        raise UsageError(f"{config.agent} is a station: it has no autopilot to check")
    logbook = Logbook.in_memory(config, tables=False)
    link = autopilot_link(config, options, logbook)
    _say(out, f"autopilot: connecting to {link.describe}")
    try:
        transport = link.open_transport()
    except TransportError as exc:
        _say(out, f"autopilot: FAILED: cannot open {link.describe}: {exc}")
        return EXIT_FAILED
    adapter = link.adapter
    heartbeat_seen = False
    last_mode: str | None = None
    try:
        with selectors.DefaultSelector() as selector:
            fd = transport.fileno()
            if fd is not None:
                selector.register(fd, selectors.EVENT_READ)
            start = time.monotonic()
            transport.send(adapter.start(0.0))
            while (now := time.monotonic() - start) < seconds:
                selector.select(0.1)
                now = time.monotonic() - start
                for event in adapter.receive(transport.receive(), now):
                    if isinstance(event, VehicleState):
                        if event.mode != last_mode:
                            last_mode = event.mode
                            _say(
                                out,
                                f"  {now:5.1f} s state: mode {event.mode} "
                                f"{'armed' if event.armed else 'disarmed'} lat {event.lat_deg:.6f} "
                                f"lon {event.lon_deg:.6f} alt {event.alt_m:.1f} m "
                                f"gps_time_ms {event.gps_time_ms}",
                            )
                    elif isinstance(event, AutopilotText):
                        _say(out, f"  {now:5.1f} s says: {event.text[:120]!r}")
                    elif type(event).__name__ == "AutopilotHeartbeat" and not heartbeat_seen:
                        heartbeat_seen = True
                        _say(out, f"  {now:5.1f} s heartbeat: {event}")
                transport.send(adapter.poll(now))
            status = adapter.status
            _say(
                out,
                f"autopilot: heartbeat {'yes' if heartbeat_seen else 'NO'}; verified "
                f"{'yes' if adapter.verified else 'NO'}; firmware {adapter.flight_sw_version}; "
                f"GPS fix type {status.gps_fix_type}; ready "
                + ("yes" if status.ready else f"no (waiting for {', '.join(status.waiting_for)})"),
            )
            if adapter.problem:
                _say(out, f"autopilot: problem: {adapter.problem}")
            transport.send(adapter.close(now))
    except TransportError as exc:
        _say(out, f"autopilot: FAILED: {exc}")
        return EXIT_FAILED
    finally:
        transport.close()
        logbook.close()
    ok = heartbeat_seen and adapter.verified
    _say(out, f"autopilot: {'OK' if ok else 'FAILED'}")
    return EXIT_OK if ok else EXIT_FAILED


def _check_radio(config: AgentConfig, options: RunOptions, seconds: float, out: TextIO) -> int:
    from clark_engine.io.radio import RadioError
    from clark_engine.link.codec import Codec
    from clark_engine.link.errors import ClarkLinkError

    made = radio_factory(config, options)
    if made is None:
        raise UsageError(f"{config.agent} has no radio in its profile")
    factory, describe = made
    expected = expected_peers(config, options)
    _say(out, f"radio: opening {describe}")
    try:
        radio = factory()
    except RadioError as exc:
        _say(out, f"radio: FAILED: {exc}")
        return EXIT_FAILED
    codec = Codec(config.mission_id, config.agent_id, options.key, max_packet_bytes=1400)
    heard = 0
    try:
        _say(out, f"radio: own address {radio.address}; verified")
        with selectors.DefaultSelector() as selector:
            fd = radio.fileno()
            if fd is not None:
                selector.register(fd, selectors.EVENT_READ)
            start = time.monotonic()
            while time.monotonic() - start < seconds:
                selector.select(0.2)
                now = time.monotonic() - start
                for frame in radio.receive():
                    heard += 1
                    try:
                        packet = codec.decode(frame.data)
                        what = (
                            f"agent {packet.sender_id} mission {packet.mission_id}: "
                            + ", ".join(type(m).__name__ for m in packet.messages)
                        )
                    except ClarkLinkError as exc:
                        what = f"not a ClarkLink packet of this mission ({type(exc).__name__})"
                    _say(
                        out, f"  {now:5.1f} s from {frame.source}: {len(frame.data)} bytes, {what}"
                    )
        stats = radio.stats
        _say(
            out,
            f"radio: {heard} frame(s) heard in {seconds:g} s; "
            f"dropped {sum(stats.dropped.values())}",
        )
    finally:
        radio.close()
    if heard == 0 and expected:
        _say(
            out,
            f"radio: FAILED: nothing heard in {seconds:g} s from {', '.join(expected)} "
            "(are they running, on this network, with these addresses?)",
        )
        return EXIT_FAILED
    if heard == 0:
        _say(
            out,
            "radio: OK (opened and verified), but NOTHING was heard: no peer address this "
            "radio can reach is known (give --peer NAME=ADDRESS to expect one)",
        )
        return EXIT_OK
    _say(out, "radio: OK")
    return EXIT_OK


def expected_peers(config: AgentConfig, options: RunOptions) -> list[str]:
    """The peers ``clark check radio`` expects to hear: those with an address its radio can use.

    A UDP radio reaches ``host:port`` addresses only (the mission's XBee addresses are
    not), an XBee radio the mission's (or ``--peer``'s) addresses; a peer is expected
    when it has one, since it is then meant to be on the air.
    """
    profile = config.raw["agent"]["hardware"].get("radio") or {}
    kind = radio_kind(profile, options.radio_link)
    addresses = {p.name: p.radio_address for p in config.peers if p.radio_address}
    addresses.update(options.peers)
    if kind == "udp":
        return sorted(name for name, address in addresses.items() if is_host_port(address))
    return sorted(addresses)


def _check_payload(config: AgentConfig, seconds: float, out: TextIO) -> int:
    from clark_engine.io.payload import PayloadError, open_payload

    payloads: Mapping[str, Any] = config.raw["agent"]["hardware"].get("payloads") or {}
    if not payloads:
        raise UsageError(f"{config.agent} has no payload in its profile")
    ok = True
    for name, profile in payloads.items():
        try:
            adapter = open_payload(name, profile)
        except PayloadError as exc:
            _say(out, f"payload {name}: FAILED: {exc}")
            ok = False
            continue
        try:
            _say(out, f"payload {name}: listening on {adapter.address}; waiting {seconds:g} s")
            with selectors.DefaultSelector() as selector:
                fd = adapter.fileno()
                if fd is not None:
                    selector.register(fd, selectors.EVENT_READ)
                start = time.monotonic()
                was = False
                while time.monotonic() - start < seconds:
                    selector.select(0.2)
                    for event in adapter.receive():
                        _say(
                            out, f"  {name}: {event.kind} request {event.request_id} {event.detail}"
                        )
                    if adapter.connected and not was:
                        was = True
                        _say(out, f"  {name}: connected")
            stats = adapter.stats
            _say(out, f"payload {name}: connected {'yes' if adapter.connected else 'NO'}; {stats}")
            ok = ok and adapter.connected
        finally:
            adapter.close()
    _say(out, f"payload: {'OK' if ok else 'FAILED'}")
    return EXIT_OK if ok else EXIT_FAILED


__all__ = ["ClarkError", "check", "load_agent", "run"]
