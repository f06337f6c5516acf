"""The simulated autopilot's parameter list (sim/ardupilot/params.py) and SYS_STATUS bits.

The list itself is asserted against SITL by tests/conformance/test_params.py; here: the
shipped data is sound and agrees with the parameters the simulation acts on, it is shared
between vehicles, and which value wins where SITL's parameter file and the simulated
firmware differ.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest
from pymavlink.dialects.v20 import ardupilotmega as mavlink2
from test_sim_autopilot import Gcs, ask, download, make_sim

from clark_engine.sim.ardupilot import params as ap_params
from clark_engine.sim.ardupilot import sys_status as ap_sys_status
from clark_engine.sim.ardupilot.firmware import COMMON_PARAMS, FIRMWARES
from clark_engine.sim.ardupilot.params import ParamStore, sitl_table
from clark_engine.sim.ardupilot.streams import STREAM_RATES

ROOT = Path(__file__).resolve().parent.parent

FIRMWARE_WINS: dict[str, dict[str, tuple[float, float]]] = {
    "ardurover": {
        "CRUISE_SPEED": (2.0, 5.0),
        "CRUISE_THROTTLE": (50.0, 30.0),
        "WP_SPEED": (2.0, 5.0),
        "WP_RADIUS": (2.0, 3.0),
    },
    "arducopter": {"FENCE_RADIUS": (300.0, 150.0)},
    "arduplane": {
        "AIRSPEED_CRUISE": (15.0, 22.0),
        "AIRSPEED_MIN": (9.0, 10.0),
        "AIRSPEED_MAX": (22.0, 30.0),
        "WP_RADIUS": (90.0, 50.0),
        "WP_LOITER_RAD": (60.0, 80.0),
        "NAVL1_PERIOD": (17.0, 15.0),
        "ROLL_LIMIT_DEG": (45.0, 65.0),
        "PTCH_LIM_MAX_DEG": (20.0, 25.0),
        "PTCH_LIM_MIN_DEG": (-25.0, -20.0),
    },
}
"""Where SITL's default-parameter file (rover.parm, copter.parm, plane.parm) gives a
parameter the simulation acts on another value than the firmware's own default:
(the simulation's, SITL's). The firmware's wins (docs/autopilot-fidelity.md); this list
is the one that page gives."""


def acting(firmware: str) -> dict[str, tuple[float, int]]:
    """The parameters the simulation acts on, with their start values and types."""
    fw = FIRMWARES[firmware]
    table: dict[str, tuple[float, int]] = {"MAV_SYSID": (1.0, ap_params.INT16)}
    for name, (value, kind) in {**COMMON_PARAMS, **fw.params}.items():
        table[name] = (
            (fw.default_stream_hz if value else 0.0, kind)
            if name in STREAM_RATES
            else (
                float(value),
                kind,
            )
        )
    return table


@pytest.mark.parametrize("firmware", sorted(FIRMWARES))
def test_the_parameters_acted_on_are_listed_with_sitls_types(firmware: str) -> None:
    table = sitl_table(firmware)
    hidden = FIRMWARES[firmware].hidden_params
    differ: dict[str, tuple[float, float]] = {}
    for name, (value, kind) in acting(firmware).items():
        if name in hidden:
            assert name not in table.types, f"{name} is hidden by {firmware} but listed"
            continue
        assert table.types.get(name) == kind, f"{firmware} {name}: type or absence"
        if ap_params.stored(value, kind) != table.values[name] and name != "MAV_SYSID":
            differ[name] = (value, table.values[name])
    assert differ == FIRMWARE_WINS[firmware]


@pytest.mark.parametrize("firmware", sorted(FIRMWARES))
def test_the_firmwares_value_wins_and_a_profiles_over_both(firmware: str) -> None:
    sim, _ = make_sim(firmware=firmware, params={"ARMING_CHECK": 0})
    for name, (ours, _sitl) in FIRMWARE_WINS[firmware].items():
        assert sim.param(name) == pytest.approx(ours)
    assert sim.param("ARMING_CHECK") == 0  # listed only: the profile's value is kept
    assert make_sim(firmware=firmware)[0].param("ARMING_CHECK") == 1  # SITL's


def test_the_list_is_loaded_once_and_shared_and_values_are_per_vehicle() -> None:
    a, _ = make_sim(firmware="ardurover")
    b, _ = make_sim(firmware="ardurover")
    assert a.params.table is b.params.table is sitl_table("ardurover")
    gcs = Gcs()
    ask(a, gcs, gcs.frame(gcs.mav.param_set_encode(1, 1, b"LOG_BITMASK", 7.0, 6)))
    assert (a.param("LOG_BITMASK"), b.param("LOG_BITMASK")) == (7.0, 65535.0)


def test_the_store_clamps_an_integer_it_does_not_act_on() -> None:
    store = ParamStore("arducopter", {})
    assert store.set("ANGLE_MAX", 1e9) is False  # int16
    assert store.get("ANGLE_MAX") == (32767.0, ap_params.INT16)
    assert store.get("NO_SUCH_PARAM") is None
    assert store.name_at(store.count) is None and store.name_at(-1) is None


def test_a_list_is_paced_and_a_second_request_starts_it_again() -> None:
    sim, _ = make_sim(firmware="arducopter")
    gcs = Gcs()
    first = ask(sim, gcs, gcs.frame(gcs.mav.param_request_list_encode(1, 1)))
    assert 0 < len(first) < 50  # not 50 kB at once
    half = ask(sim, gcs, b"", 1.5)  # (nothing sent: the list goes on)
    assert [m.param_index for m in first + half] == list(range(len(first) + len(half)))
    values = download(sim, gcs, now_s=2.0)  # asked again: from index 0, all of it
    assert [m.param_index for m in values] == list(range(1354))


def test_the_generator_checks_the_shipped_lists() -> None:
    done = subprocess.run(
        [sys.executable, str(ROOT / "tools" / "gen_sitl_params.py"), "--check"],
        capture_output=True,
        text=True,
        timeout=60,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert "ardurover: 1240 parameters, FORMAT_VERSION .. MAV3_OPTIONS" in done.stdout


@pytest.mark.parametrize(
    ("firmware", "mode", "controllers"),
    [
        ("ardurover", "MANUAL", 0),
        ("ardurover", "HOLD", 0),
        ("ardurover", "GUIDED", 0x400 | 0x800 | 0x1000 | 0x4000),
        ("arducopter", "STABILIZE", 0),
        ("arducopter", "ALT_HOLD", 0x2000),
        ("arducopter", "GUIDED", 0x2000 | 0x4000),
        ("arduplane", "MANUAL", 0),
        ("arduplane", "FBWA", 0x400 | 0x800),
        ("arduplane", "AUTO", 0x400 | 0x800 | 0x1000 | 0x2000 | 0x4000),
    ],
)
def test_the_controllers_a_mode_uses_are_enabled(
    firmware: str, mode: str, controllers: int
) -> None:
    assert ap_sys_status.mode_bits(firmware, mode) == controllers


def test_the_logger_runs_armed_and_15_s_after() -> None:
    inputs = dict(
        since_boot_s=60.0,
        mode="MANUAL",
        gps_fixed=True,
        ekf_origin=True,
        ekf_position=True,
        prearm_ok=True,
        fence=(True, False, True),
    )
    on = ap_sys_status.sensor_bits("ardurover", ap_sys_status.Inputs(logging=True, **inputs))
    off = ap_sys_status.sensor_bits("ardurover", ap_sys_status.Inputs(logging=False, **inputs))
    assert on[1] & ~off[1] == mavlink2.MAV_SYS_STATUS_LOGGING
    assert on[0] == off[0] and on[2] == off[2]  # present and healthy either way
