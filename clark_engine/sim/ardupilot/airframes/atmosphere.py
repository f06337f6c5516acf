"""The standard atmosphere and SITL's airspeed sensor: an equivalent airspeed made true.

Apart from the fixed-wing model because it is physics and a sensor, not ArduPlane's
flying: ArduPlane holds what its pitot reads (an equivalent airspeed), and the aircraft
flies :func:`eas2tas` times that through the air, read low by SITL's sensor.
"""

from __future__ import annotations

from typing import Final

from clark_engine.sim.ardupilot.airframes.base import G_M_S2

ISA_SEA_LEVEL_K: Final = 288.15
"""The 1976 standard atmosphere's sea-level temperature, K (15 C)."""
ISA_LAPSE_K_M: Final = 0.0065
"""Its tropospheric lapse rate, K per metre."""
ISA_DENSITY_EXPONENT: Final = G_M_S2 / (ISA_LAPSE_K_M * 287.053) - 1.0
"""rho / rho0 = (T / T0) ** this in the troposphere (g / (L R) - 1, R of dry air)."""


PLANE_AIRSPEED_SENSOR_SCALE: Final = 0.9937
"""What ArduPlane SITL's airspeed sensor reads per m/s of the equivalent airspeed its
simulator flies at (fitted): holding AIRSPEED_CRUISE 18 m/s by it (VFR_HUD airspeed 17.99-
18.01) at 150 m above sea level in still air, SITL's plane flew 18.24-18.25 m/s over the
ground, straight and circling alike (1.0134-1.0138 in two runs, 2026-11-28), where the
standard atmosphere's :func:`eas2tas` gives 1.0072: its simulated analog pitot reads 0.63 %
low. A real aircraft's sensor has its own error (ARSPD_RATIO); this is SITL's."""


def eas2tas(alt_amsl_m: float) -> float:
    """True over equivalent airspeed at ``alt_amsl_m`` in the 1976 standard atmosphere.

    ``sqrt(rho0 / rho)``: the factor ArduPilot SITL's simulator converts its aircraft's
    true airspeed to what the pitot measures with (AP_Baro::get_EAS2TAS_for_alt_amsl,
    called from SITL_State::_update_airspeed), so the EAS ArduPlane holds is flown at
    this times it through the air: 1.0072 at 150 m above sea level. The troposphere's
    law (below 11 km); an altitude below sea level is taken as sea level's density.
    """
    temperature_k = ISA_SEA_LEVEL_K - ISA_LAPSE_K_M * max(alt_amsl_m, 0.0)
    return float((temperature_k / ISA_SEA_LEVEL_K) ** (-0.5 * ISA_DENSITY_EXPONENT))
