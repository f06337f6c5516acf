"""Sweeps of every mode of a profile: what setting it and arming in it do.

The scenarios in test_mode_rules.py compare these observations with the table
measured on ArduPilot SITL (mode_rules_table.py); ``python modesweep.py
test_mode_rules KIND [sim|sitl]`` prints a backend's observations in that table's
form, which is how the table was made (and how to remake it for a new SITL build).
Other scenario modules with ``observe_*`` functions (test_commands.py) are printed
the same way.

An observation is what a ground station can tell: the COMMAND_ACK result, the mode
and armed state in the next HEARTBEAT, and the STATUSTEXTs the command caused
(texts about something else, such as the EKF's progress, are left out).
"""

from __future__ import annotations

import re
import sys
from collections.abc import Iterable
from typing import NamedTuple

from harness import Peer, StatusText
from pymavlink.dialects.v20 import ardupilotmega as mavlink2

SETTLE_S = 0.2
"""Vehicle seconds to collect the texts a command causes (ArduPilot sends them at once)."""
HEARTBEAT_US = 100_000
"""HEARTBEAT interval during a sweep, so the mode after each command is known at once."""

UNRELATED = (
    "EKF",
    "GPS 1:",
    "Field Elevation",
    "AHRS:",
    "PreArm:",
    "RC7:",
    "Barometer",
    "Airspeed",
    "Throttle failsafe",
    "Calibrating",
    "Reached destination",
)
"""Texts about the vehicle's own progress, not about a command (prefixes). ArduRover's
"Reached destination" on entering RTL depends on where the sweep's earlier modes (CIRCLE
drives) left it; test_rtl.py asserts it."""


class Step(NamedTuple):
    """What one command did: result, then mode, armed and the texts it caused."""

    result: int
    mode: str
    armed: bool
    texts: tuple[str, ...]


def command_texts(texts: Iterable[StatusText]) -> tuple[str, ...]:
    """``severity:text`` of the texts a command caused (numbers that vary blanked)."""
    out = []
    for s in texts:
        if s.text.startswith(UNRELATED):
            continue
        text = re.sub(r"xaccel = -?[\d.]+", "xaccel = *", s.text)
        out.append(f"{s.severity}:{text}")
    return tuple(out)


def _after(peer: Peer, mark: int, result: int) -> Step:
    peer.run_for(SETTLE_S)
    hb = peer.heartbeat()
    mode = peer.mode_name(int(hb.custom_mode))
    texts = command_texts(peer.texts_since(mark))
    if mode == "LOITERALTQLAND":
        # ArduPlane without VTOL motors says "Q_ENABLE 0" now and then while in this
        # mode, at no time a sweep can pin down.
        texts = tuple(t for t in texts if t != "6:Q_ENABLE 0")
    return Step(int(result), mode, bool(hb.base_mode & mavlink2.MAV_MODE_FLAG_SAFETY_ARMED), texts)


def set_mode(peer: Peer, name: str) -> Step:
    """MAV_CMD_DO_SET_MODE to ``name``, and what it did."""
    mark = peer.mark()
    return _after(peer, mark, peer.set_mode(name).result)


def arm(peer: Peer, force: bool = False) -> Step:
    """Arm, and what it did."""
    mark = peer.mark()
    return _after(peer, mark, peer.arm(force).result)


def back_to(peer: Peer, mode: str, armed: bool, force: bool = False) -> None:
    """Put the vehicle in ``mode``, disarmed or armed (forced where asked)."""
    if peer.is_armed() and not armed:
        peer.disarm(force=True)
    if peer.set_mode(mode).result != mavlink2.MAV_RESULT_ACCEPTED:
        raise AssertionError(f"{peer.backend}: cannot go back to {mode}")
    if armed and not peer.is_armed():
        mark = peer.mark()
        ack = peer.arm(force)
        if ack.result != mavlink2.MAV_RESULT_ACCEPTED:
            peer.run_for(SETTLE_S)
            raise AssertionError(
                f"{peer.backend}: cannot arm in {mode} at t={peer.now_s:.1f} s: "
                f"{command_texts(peer.texts_since(mark))}"
            )
        peer.run_for(SETTLE_S)


Sweep = dict[str, Step]


def sweep_set(peer: Peer, modes: Iterable[str], *, armed: bool, force: bool = False) -> Sweep:
    """Set each mode from the manual mode, disarmed or armed (forced where asked)."""
    manual = str(peer.spec.autopilot["manual_mode"])
    observed = {}
    for name in modes:
        back_to(peer, manual, armed, force)
        observed[name] = set_mode(peer, name)
    back_to(peer, manual, armed=False)
    return observed


def sweep_arm(peer: Peer, modes: Iterable[str]) -> Sweep:
    """Arm in each mode that can be entered disarmed (from the manual mode), then disarm."""
    manual = str(peer.spec.autopilot["manual_mode"])
    observed = {}
    for name in modes:
        back_to(peer, manual, armed=False)
        if peer.set_mode(name).result != mavlink2.MAV_RESULT_ACCEPTED:
            continue
        peer.run_for(SETTLE_S)
        if peer.mode_name(int(peer.heartbeat().custom_mode)) != name:
            continue  # entered, and left at once (ArduPlane's AUTO without a mission)
        observed[name] = arm(peer)
    back_to(peer, manual, armed=False)
    return observed


def fast_heartbeats(peer: Peer, on: bool) -> None:
    """HEARTBEAT at 10 Hz (on) or at the default 1 Hz."""
    ack = peer.message_interval("HEARTBEAT", HEARTBEAT_US if on else 0)
    assert ack.result == mavlink2.MAV_RESULT_ACCEPTED, ack


def render(sweep: Sweep, indent: str = "        ") -> str:
    """A sweep as Python source for mode_rules_table.py."""
    lines = [
        f"{indent}{name!r}: Step({s.result}, {s.mode!r}, {s.armed}, {s.texts!r}),"
        for name, s in sweep.items()
    ]
    return "\n".join(lines)


def main(module: str, kind: str, source: str) -> None:
    """Print what every ``observe_*`` function of a scenario module sees on one backend.

    Each is given a new vehicle of ``kind`` (``python modesweep.py test_mode_rules rover``).
    """
    import importlib

    from harness import open_peer

    scenarios = importlib.import_module(module)
    for name in sorted(dir(scenarios)):
        if not name.startswith("observe_"):
            continue
        peer = open_peer(f"{source}-{kind}")
        try:
            for phase, sweep in getattr(scenarios, name)(peer).items():
                print(f"    {phase!r}: {{\n{render(sweep)}\n    }},")
        finally:
            peer.close()


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else "sitl")
