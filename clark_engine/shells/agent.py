"""One agent on its real interfaces, from its compiled config and the command line's options.

:func:`open_agent` is what ``clark run`` does before the loop starts: it opens the
logbook in the logs folder, the counter and replay stores in the state folder, the
radio the hardware profile names (``link: xbee_digimesh`` or ``udp``), the payloads and
the autopilot link, builds the runtime with the shell's clock origin, and returns the
:class:`~clark_engine.shells.realtime.RealtimeShell` ready to :meth:`run`. Options
disable any interface (testing mode, thesis 7.2.9) or override where it is
(``--autopilot-connection tcp:127.0.0.1:5760`` for SITL, a UDP radio on loopback with
the peers' ports for rehearsals on one machine).

The state folder: the packet counter store (``<mission>.<agent>.counter``) and the
replay store (``<mission>.<agent>.replay`` and its ``.live`` beside it) of an
authenticated mission must outlive every run (a restarted agent must never reuse a
counter, nor accept a packet again), so they live in one folder beside the run's logs
folder, ``<logs>/../state`` by default, not in the logs folder a new run replaces.
"""

from __future__ import annotations

import contextlib
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from clark_engine.errors import UsageError
from clark_engine.io.autopilot import AutopilotAdapter
from clark_engine.io.autopilot_settings import AutopilotSettings
from clark_engine.io.payload import PayloadAdapter, PayloadError, open_payload
from clark_engine.io.radio import Radio
from clark_engine.io.transports import (
    SerialTransport,
    TcpTransport,
    Transport,
    TransportError,
    UdpTransport,
    open_transport,
    parse_address,
)
from clark_engine.link.auth import CounterStore, ReplayStore
from clark_engine.runtime.config import AgentConfig
from clark_engine.runtime.logbook import Logbook
from clark_engine.runtime.runtime import AgentRuntime
from clark_engine.shells.links import AutopilotLink, RadioLink
from clark_engine.shells.realtime import Clock, RealtimeShell, gps_epoch_ms

RECONNECT_TIMEOUT_S = 1.0
"""Longest a TCP connect to the autopilot may hold the loop (counted as an overrun)."""


@dataclass
class RunOptions:
    """How ``clark run`` puts one agent on its interfaces.

    Attributes:
        logs: The run's logs folder (the agent's four log files go there).
        state: The state folder (counter and replay stores); ``<logs>/../state`` when None.
        autopilot: False disables the autopilot (testing mode).
        radio: False disables the radio.
        payloads: False disables every payload.
        autopilot_connection: Overrides the profile's connection (``tcp:HOST:PORT``,
            ``udp:HOST:PORT`` to listen, ``udpout:HOST:PORT`` to send first,
            ``serial:DEVICE[:BAUD]``).
        radio_link: Overrides the profile's radio kind: ``udp`` or ``xbee``.
        radio_address: This agent's radio address (``127.0.0.1:15001`` for UDP).
        radio_device: An XBee's serial device, over the profile's ``connection.device``
            (``/dev/ttyUSB0``, or an emulated radio's pty from ``clark radio-sim xbee``).
        peers: Peer name -> radio address, over the mission's.
        key: The mission key, for an authenticated mission.
        loop_hz: Overrides the mission's loop rate (benchmarks).
        overwrite_logs: Replace this agent's log files of an earlier run.
    """

    logs: Path
    state: Path | None = None
    autopilot: bool = True
    radio: bool = True
    payloads: bool = True
    autopilot_connection: str | None = None
    radio_link: str | None = None
    radio_address: str | None = None
    radio_device: str | None = None
    peers: dict[str, str] = field(default_factory=dict)
    key: bytes | None = None
    loop_hz: float | None = None
    overwrite_logs: bool = False

    @property
    def state_folder(self) -> Path:
        """Where the counter and replay stores live."""
        return self.state if self.state is not None else self.logs.parent / "state"


def connection_from_text(text: str) -> tuple[Callable[[], Transport], str]:
    """A transport factory from ``KIND:WHERE`` (see :class:`RunOptions`), and its description.

    Raises:
        UsageError: Not one of the forms.
    """
    kind, sep, where = text.partition(":")
    try:
        if sep and kind == "tcp":
            address = parse_address(where)
            return (
                lambda: TcpTransport(address, connect_timeout_s=RECONNECT_TIMEOUT_S),
                f"tcp {where}",
            )
        if sep and kind in ("udp", "udpin"):
            address = parse_address(where)
            return (lambda: UdpTransport(bind=address)), f"udp listen {where}"
        if sep and kind == "udpout":
            address = parse_address(where)
            return (lambda: UdpTransport(remote=address)), f"udp to {where}"
        if sep and kind == "serial" and where:
            device, _, baud = where.partition(":")
            if baud and not baud.isdigit():
                raise TransportError(f"{baud!r} is not a baud rate")
            rate = int(baud) if baud else 115200
            return (lambda: SerialTransport(device, rate)), f"serial {device}"
    except TransportError as exc:
        raise UsageError(f"--autopilot-connection {text}: {exc}") from None
    raise UsageError(
        f"--autopilot-connection {text!r}: use tcp:HOST:PORT, udp:HOST:PORT (listen), "
        "udpout:HOST:PORT or serial:DEVICE[:BAUD] (e.g. tcp:127.0.0.1:5760 for SITL)"
    )


def _profile_connection(connection: Mapping[str, Any]) -> tuple[Callable[[], Transport], str]:
    kind = connection.get("kind")
    where = connection.get("device") or connection.get("address") or "?"
    if kind == "tcp":
        return connection_from_text(f"tcp:{where}")
    return (lambda: open_transport(connection)), f"{kind} {where}"


def radio_kind(profile: Mapping[str, Any], override: str | None) -> str:
    """``udp`` or ``xbee``: the override, else the profile's ``link``."""
    if override is not None:
        return override
    link = str(profile.get("link", ""))
    return "xbee" if link.startswith("xbee") else "udp" if link == "udp" else link


def radio_factory(
    config: AgentConfig, options: RunOptions
) -> tuple[Callable[[], Radio], str] | None:
    """Builds, opens and verifies the agent's radio; None when it has none.

    Raises:
        UsageError: The profile names a radio this engine does not drive, or an
            address that does not fit it.
    """
    profile = config.raw["agent"]["hardware"].get("radio")
    if not profile:
        return None
    kind = radio_kind(profile, options.radio_link)
    peers = {p.name: p.radio_address for p in config.peers if p.radio_address}
    peers.update(options.peers)
    if kind == "udp":
        from clark_engine.io.udp_radio import UdpRadio

        own = options.radio_address
        if own is None and options.radio_link is None:
            own = profile.get("address")
        addresses = [a for a in peers.values() if is_host_port(a)]
        if own is not None and not is_host_port(own):
            raise UsageError(
                f"radio address {own!r} is not host:port; give --radio-address for a UDP radio"
            )

        def open_udp() -> Radio:
            radio = UdpRadio.from_profile(profile, own, addresses)
            radio.open()
            radio.verify()
            return radio

        return open_udp, f"udp {own or 'profile port'}"
    if kind == "xbee":
        from clark_engine.io.xbee import XBeeRadio

        connection = profile.get("connection") or {}
        port = options.radio_device or connection.get("device")
        if not port:
            raise UsageError(
                "the radio profile's connection has no serial device; give --radio-device "
                "(e.g. /dev/ttyUSB0)"
            )

        def open_xbee() -> Radio:
            radio = XBeeRadio(
                str(port),
                baud_bps=int(connection.get("baud_bps", 115200)),
                network_id=profile.get("network_id"),
                api_mode=int(profile.get("api_mode", 1)),
            )
            radio.open()
            try:
                radio.verify()
            except Exception:
                radio.close()
                raise
            return radio

        return open_xbee, f"xbee {port}"
    raise UsageError(f"radio link {kind!r} is not one this engine drives; use udp or xbee")


def is_host_port(text: str) -> bool:
    """True when ``text`` is a ``host:port`` address (a UDP radio's kind of address)."""
    try:
        parse_address(text)
    except TransportError:
        return False
    return True


def autopilot_link(config: AgentConfig, options: RunOptions, logbook: Logbook) -> AutopilotLink:
    """The autopilot's adapter and its transport factory (the override, else the profile's)."""
    adapter = AutopilotAdapter(AutopilotSettings.from_config(config), logger=logbook.interface)
    if options.autopilot_connection is not None:
        factory, describe = connection_from_text(options.autopilot_connection)
    else:
        autopilot = config.raw["agent"]["hardware"].get("autopilot") or {}
        factory, describe = _profile_connection(autopilot.get("connection") or {})
    return AutopilotLink(adapter, factory, describe)


def open_payloads(config: AgentConfig) -> dict[str, PayloadAdapter]:
    """Every payload of the agent, open (listening).

    Raises:
        PayloadError: One cannot be opened; the others are closed.
    """
    opened: dict[str, PayloadAdapter] = {}
    try:
        for name, profile in (config.raw["agent"]["hardware"].get("payloads") or {}).items():
            opened[name] = open_payload(name, profile)
    except PayloadError:
        for adapter in opened.values():
            adapter.close()
        raise
    return opened


def open_agent(
    config: AgentConfig,
    options: RunOptions,
    *,
    clock: Clock = time.monotonic,
) -> RealtimeShell:
    """The agent's runtime and links in a shell, ready to run.

    The radio is opened here (a radio that cannot open is an error at the start,
    exit 2, never a silent retry); the autopilot is opened by the loop, which retries
    it with back-off (a mission computer may boot before its autopilot).

    Raises:
        ClarkError: The logs, the state folder, the radio or a payload cannot be opened.
    """
    radio_link: RadioLink | None = None
    first_radio: Radio | None = None
    if options.radio:
        made = radio_factory(config, options)
        if made is not None:
            factory, describe = made
            first_radio = factory()
            radio_link = RadioLink(factory, describe)
            radio_link.radio = first_radio
    payloads: dict[str, PayloadAdapter] = {}
    logbook: Logbook | None = None
    try:
        payloads = open_payloads(config) if options.payloads else {}
        logbook = Logbook.to_folder(options.logs, config, overwrite=options.overwrite_logs)
        counter_store = replay_store = None
        if config.authenticated:
            state = options.state_folder
            try:
                state.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise UsageError(
                    f"cannot create the state folder {state}: {exc.strerror or exc}"
                ) from None
            stem = f"{config.mission_name}.{config.agent}"
            counter_store = CounterStore(state / f"{stem}.counter")
            replay_store = ReplayStore(state / f"{stem}.replay")
        has_autopilot = config.is_vehicle and options.autopilot
        origin = clock()
        runtime = AgentRuntime(
            config,
            key=options.key,
            counter_store=counter_store,
            replay_store=replay_store,
            logbook=logbook,
            # Stations (and vehicles with the autopilot disabled) stamp GPS time from the
            # system clock; a vehicle's autopilot time takes over once it reports one.
            gps_epoch_ms=None if has_autopilot else gps_epoch_ms(time.time()),
            autopilot_connected=options.autopilot or not config.is_vehicle,
        )
        autopilot = autopilot_link(config, options, logbook) if has_autopilot else None
        peer_addresses = {p.name: p.radio_address for p in config.peers if p.radio_address}
        peer_addresses.update(options.peers)
        shell = RealtimeShell(
            runtime,
            autopilot=autopilot,
            radio=None,
            payloads=payloads,
            peer_addresses=peer_addresses,
            loop_hz=options.loop_hz,
            clock=clock,
            origin_s=origin,
        )
    except BaseException:
        if logbook is not None:
            logbook.close()
        for adapter in payloads.values():
            adapter.close()
        if first_radio is not None:
            with contextlib.suppress(Exception):
                first_radio.close()
        raise
    shell.radio = radio_link
    return shell
