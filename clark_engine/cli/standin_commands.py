"""``clark payload-sim``, ``autopilot-sim``, ``radio-sim``: the bench's stand-ins for ``clark run``.

Separate because they play the hardware an agent meets (:mod:`clark_engine.standins`),
not the engine; each imports its stand-in inside its command.
"""

from __future__ import annotations

import argparse


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


__all__ = ["cmd_autopilot_sim", "cmd_payload_sim", "cmd_radio_sim"]
