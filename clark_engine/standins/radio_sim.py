"""A mission's XBee network, emulated for ``clark run``: ``clark radio-sim xbee``.

A rehearsal on one machine without radios can use UDP (``clark run --radio
udp``), but then the path the mission flies with (digi-xbee, the serial line,
API frames, transmit status, the 900HP's shared 33 kbit/s channel) is not the
one rehearsed. This command puts one emulated XBee 900HP per agent of the mission
on a pseudo-terminal (:class:`~clark_engine.sim.xbee_emulator.XBeeEmulator`),
each at the 64-bit address the mission gives that agent, and names each
``DIR/<agent>`` (a symbolic link, as ``/dev/serial/by-id`` names a USB radio), so
that each ``clark run`` opens its agent's radio with ``--radio xbee --radio-device
DIR/<agent>`` exactly as it would open ``/dev/ttyUSB0``. The channel's
throughput is the radio profile's ``throughput_bps`` (the thesis's 33 kbit/s for
the 900HP); loss and latency are options.

Only agents whose radio address is an XBee's (16 hex digits) get a radio; the
others are listed as left out.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any, Final

from clark_engine.dryrun.rehearsal import StopFlag
from clark_engine.errors import ClarkError, UsageError
from clark_engine.mission.model import Mission
from clark_engine.sim.xbee_emulator import THROUGHPUT_BPS, XBeeEmulator
from clark_engine.validation import load_mission

XBEE_ADDRESS: Final = re.compile(r"^[0-9A-Fa-f]{16}$")


def xbee_agents(mission: Mission) -> tuple[dict[str, str], list[str]]:
    """The agents with an XBee address (name -> 16 hex digits), and those without."""
    radios: dict[str, str] = {}
    others: list[str] = []
    for name, agent in mission.agents.items():
        radio = (agent.raw.get("hardware") or {}).get("radio")
        address = radio.get("address") if isinstance(radio, dict) else None
        if isinstance(address, str) and XBEE_ADDRESS.match(address):
            radios[name] = address.upper()
        else:
            others.append(name)
    return radios, others


def _throughput_bps(mission: Mission, agents: list[str]) -> float:
    """The slowest of the agents' radio profiles' ``throughput_bps`` (the 900HP's by default)."""
    figures = []
    for name in agents:
        profile = mission.agents[name].hardware.part("radio") or {}
        if profile.get("throughput_bps"):
            figures.append(float(profile["throughput_bps"]))
    return min(figures) if figures else float(THROUGHPUT_BPS)


def serve_network(args: Any) -> int:
    """``clark radio-sim xbee MISSION --dir DIR``: the emulated radios until stopped.

    Returns:
        0 after a clean stop.

    Raises:
        UsageError: A bad option, or DIR holds something that is not one of our links.
        ClarkError: An invalid mission, or no agent with an XBee address.
    """
    if not 0.0 <= args.loss <= 1.0:
        raise UsageError(f"--loss {args.loss:g}: give a share from 0 to 1")
    if args.latency_s < 0:
        raise UsageError(f"--latency-s {args.latency_s:g}: give 0 or more")
    mission = load_mission(args.mission)
    radios, others = xbee_agents(mission)
    if not radios:
        raise ClarkError(
            f"{args.mission}: no agent has an XBee address (16 hex digits in "
            "hardware.radio.address); nothing to emulate"
        )
    folder = Path(args.dir)
    links = {name: folder / name for name in radios}
    for link in links.values():
        if link.exists() and not link.is_symlink():
            raise UsageError(f"{link} exists and is not a radio's link; choose another --dir")
    throughput = args.throughput_bps or _throughput_bps(mission, list(radios))
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UsageError(f"--dir {folder}: {exc.strerror or exc}") from None
    emulator = XBeeEmulator(
        loss=args.loss, latency_s=args.latency_s, throughput_bps=throughput, seed=args.seed
    )
    made: list[Path] = []
    try:
        for name, address in radios.items():
            radio = emulator.add_radio(address, node_id=name[:20])
            link = links[name]
            link.unlink(missing_ok=True)
            link.symlink_to(radio.port)
            made.append(link)
        emulator.start()
        print(
            f"clark radio-sim: {len(radios)} emulated XBee 900HP radios, one channel at "
            f"{throughput:g} bit/s, loss {args.loss:g}, latency {args.latency_s:g} s",
            flush=True,
        )
        for name, link in links.items():
            print(f"{name}: clark run ... --radio xbee --radio-device {link}", flush=True)
        if others:
            print(f"left out (no XBee address): {', '.join(others)}", flush=True)
        stop = StopFlag(args.until)
        with stop.on_signals():
            stop.wait()
    finally:
        emulator.stop()
        for link in made:
            link.unlink(missing_ok=True)
    print("clark radio-sim: stopped", flush=True)
    return 0
