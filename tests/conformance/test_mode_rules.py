"""Every mode of the three autopilot profiles: setting it and arming in it, as ArduPilot does.

Four sweeps per vehicle (tests/conformance/modesweep.py): every mode set from the
manual mode while disarmed and while armed (forced), in the first seconds after
boot (before the GPS has a fix, so before home, the EKF origin and a position),
and again once the vehicle is ready, where arming in every mode that can be
entered is tried too. What ArduPilot SITL did is the table in mode_rules_table.py;
every backend must do exactly that: the result, the mode and armed state that
follow, and the texts, in order.

Left out: arming ArduPlane in TAKEOFF (it launches; test_plane.py) and setting
ArduPlane's AUTO or TAKEOFF armed on the ground (TAKEOFF launches it; AUTO without a
mission turns into RTL, which may).
"""

from __future__ import annotations

from harness import Peer, backends
from mode_rules_table import TABLE
from modesweep import Step, Sweep, arm, fast_heartbeats, set_mode, sweep_arm, sweep_set

NOT_ARMED_HERE = {"plane": ("TAKEOFF",)}
"""Modes not armed in by the sweep (ArduPlane launches in TAKEOFF)."""
NOT_SET_ARMED = {"plane": ("TAKEOFF", "AUTO")}
"""Modes not set while armed on the ground (automatic modes may launch a plane)."""
SWEEP_BY_S = {"rover": 19.0, "copter": 20.0, "plane": 19.0}
"""When the disarmed sweep before ready must have ended: the next change of the rules,
the EKF origin (19.3-20 s). ArduRover's RTL and SMART_RTL, whose rules change when home
is set at the first GPS fix (10.05 s), are tried first, at about 3 s."""


HOME_AT_S = 10.0
"""Every firmware but ArduCopter sets home at its first GPS fix (10.05-10.1 s)."""
MODE_SWITCH_READ_S = 3.0
"""ArduCopter reads its mode switch when its RC input starts (2.74 s after boot), which
puts it back in the switch's mode (STABILIZE in SITL): the sweep starts after that."""


def observe_before_ready(peer: Peer) -> dict[str, Sweep]:
    """The sweeps of a vehicle just booted: disarmed before its home is set, then armed."""
    peer.run_for(max(0.0, MODE_SWITCH_READ_S - peer.now_s))
    fast_heartbeats(peer, True)
    # RTL first: ArduRover's RTL must be tried before home is set.
    modes = sorted(peer.spec.modes, key=lambda name: name not in ("RTL", "SMART_RTL"))
    disarmed = sweep_set(peer, modes[:2], armed=False)
    assert peer.now_s < HOME_AT_S, f"RTL and SMART_RTL were tried at t={peer.now_s:.1f} s"
    disarmed.update(sweep_set(peer, modes[2:], armed=False))
    assert peer.now_s < SWEEP_BY_S[peer.kind], f"the sweep ended at t={peer.now_s:.1f} s"
    not_armed = NOT_SET_ARMED.get(peer.kind, ())
    armed = sweep_set(peer, [m for m in modes if m not in not_armed], armed=True, force=True)
    fast_heartbeats(peer, False)
    return {"set_before_ready": disarmed, "set_armed_before_ready": armed}


def observe_ready(peer: Peer) -> dict[str, Sweep]:
    """The sweeps of a ready vehicle: every mode set disarmed, armed in, and set armed."""
    peer.wait_ready()
    fast_heartbeats(peer, True)
    try:
        # In the profile's order, so that ArduCopter arms between entering SMART_RTL twice
        # disarmed (the second entry is an internal error that blocks arming, test_traps.py).
        modes = list(peer.spec.modes)
        disarmed = sweep_set(peer, modes, armed=False)
        armed_in = sweep_arm(peer, [m for m in modes if m not in NOT_ARMED_HERE.get(peer.kind, ())])
        armed = sweep_set(
            peer, [m for m in modes if m not in NOT_SET_ARMED.get(peer.kind, ())], armed=True
        )
    finally:
        fast_heartbeats(peer, False)
    return {"set_ready": disarmed, "arm_ready": armed_in, "set_armed_ready": armed}


def differences(kind: str, observed: dict[str, Sweep]) -> list[str]:
    """Every place where ``observed`` differs from SITL's table, one line each."""
    lines = []
    for phase, sweep in observed.items():
        expected: dict[str, Step] = TABLE[kind][phase]
        for name in sorted(set(sweep) | set(expected)):
            got, want = sweep.get(name), expected.get(name)
            if got != want:
                lines.append(f"{phase} {name}: {got} where ArduPilot gave {want}")
    return lines


@backends("fresh_peer")
def test_every_mode_before_ready(fresh_peer: Peer) -> None:
    problems = differences(fresh_peer.kind, observe_before_ready(fresh_peer))
    assert not problems, "\n".join(problems)


def test_every_mode_when_ready(peer: Peer) -> None:
    problems = differences(peer.kind, observe_ready(peer))
    assert not problems, "\n".join(problems)


MANUAL_ARMABLE_S = 25.0
"""Every firmware passes its pre-arm checks in its manual mode by 24 s (test_readiness.py)."""


@backends("fresh_peer", kinds=("rover",))
def test_rover_rtl_before_the_ekf_origin_blocks_arming_until_reboot(fresh_peer: Peer) -> None:
    # Between home (the first GPS fix, 10 s) and the EKF origin (20 s), ArduRover's RTL fails
    # an internal check: refused, and the internal error refuses every arming after it.
    peer = fresh_peer
    peer.wait_for("HOME_POSITION", 15.0, since=0)
    peer.run_for(1.0)
    step = set_mode(peer, "RTL")
    assert step == Step(
        4, "MANUAL", False, ("4:Flight mode change failed", "2:Internal Errors 0x100000")
    )
    peer.run_for(MANUAL_ARMABLE_S - peer.now_s)
    blocked = arm(peer)
    assert blocked == Step(
        4, "MANUAL", False, ("2:Arm: Internal errors 0x100000 l:239 flow_of_ctrl",)
    )


@backends("fresh_peer", kinds=("copter",))
def test_copter_smart_rtl_twice_disarmed_blocks_arming_until_reboot(fresh_peer: Peer) -> None:
    # Entering SMART_RTL disarmed a second time without arming in between is an internal
    # error in ArduCopter: the mode is entered, and every arming after it refused.
    peer = fresh_peer
    peer.wait_ready()
    fast_heartbeats(peer, True)
    assert set_mode(peer, "SMART_RTL") == Step(0, "SMART_RTL", False, ())
    assert set_mode(peer, "STABILIZE") == Step(0, "STABILIZE", False, ())
    assert set_mode(peer, "SMART_RTL") == Step(
        0, "SMART_RTL", False, ("2:Internal Errors 0x100000",)
    )
    assert set_mode(peer, "STABILIZE").result == 0
    blocked = arm(peer)
    assert blocked == Step(
        4, "STABILIZE", False, ("2:Arm: Internal errors 0x100000 l:130 flow_of_ctrl",)
    )
