"""A noisy GPS: what the autopilot reports of it, raw and as its estimate.

ArduPilot reports two positions: GPS_RAW_INT is the receiver's fix as it is, and
GLOBAL_POSITION_INT is its EKF's estimate, which fuses the fixes with the IMU and so
passes on only a smoothed share of the receiver's white noise. Measured on ArduRover
SITL at rest, fed 0.5 m of fresh Gaussian noise per axis at every 5 Hz fix
(benchmarks/probe_gps_noise_ekf.py, docs/performance.md): GPS_RAW_INT spreads 0.47-0.56 m
per axis and is white; GLOBAL_POSITION_INT spreads 0.16-0.19 m and wanders slowly
(autocorrelation 0.76-0.79 after 0.5 s, 0.03-0.07 after 3 s). The engine's follow and
distance checks read GLOBAL_POSITION_INT: a simulation that put the raw noise there
would cross a distance threshold on the first noisy dip, sooner than in flight.

SITL's GPS has no horizontal noise of its own, so the scenario plays the noise through
its GPS offset (flight.run_with_gps_noise); the simulated vehicle gets the dry run's
``sim.gps_noise_m``.
"""

from __future__ import annotations

import math
import statistics

from flight import autocorrelation, here, offset_m, run_with_gps_noise, streaming
from harness import Peer, backends

NOISE_M = 0.5
"""The dry run's default ``sim.gps_noise_m``: per horizontal axis, fresh at every fix."""
SETTLE_S = 3.0
"""Noise before the recording: the estimate settles into it (SITL's EKF first)."""
RECORD_S = 15.0
"""Noise recorded: about fifteen of the estimate's correlation times."""
REPORT_S = 0.1
"""Both positions stream at 10 Hz."""


def spreads(points: list[tuple[float, float]]) -> tuple[float, float, float, float]:
    """Figures of (north, east) offsets (m) from the still position, one per :data:`REPORT_S`.

    Returns:
        The spread (RMS of the two axes' standard deviations, m), the autocorrelation
        after 0.5 s and after 3 s (mean of the two axes), and how far the mean is off (m).
    """
    north = [n for n, _ in points]
    east = [e for _, e in points]
    spread = math.sqrt((statistics.pvariance(north) + statistics.pvariance(east)) / 2.0)
    lag_half, lag_three = round(0.5 / REPORT_S), round(3.0 / REPORT_S)
    ac_half = (autocorrelation(north, lag_half) + autocorrelation(east, lag_half)) / 2.0
    ac_three = (autocorrelation(north, lag_three) + autocorrelation(east, lag_three)) / 2.0
    return spread, ac_half, ac_three, math.hypot(statistics.fmean(north), statistics.fmean(east))


@backends(kinds=("rover",))
def test_a_noisy_gps_is_reported_raw_and_smoothed_as_ardupilot_reports_it(rover: Peer) -> None:
    """A rover at rest, 0.5 m of white GPS noise: GPS_RAW_INT spreads it all, white;
    GLOBAL_POSITION_INT about a third of it, and slowly (ArduRover SITL's EKF)."""
    with streaming(rover, {"GPS_RAW_INT": round(REPORT_S * 1e6)}):
        rover.run_for(1.0)
        still = here(rover)
        run_with_gps_noise(rover, SETTLE_S, NOISE_M, seed=19)
        mark = rover.mark()
        run_with_gps_noise(rover, RECORD_S, NOISE_M, seed=20)
        figures = {}
        for kind in ("GLOBAL_POSITION_INT", "GPS_RAW_INT"):
            points = [
                offset_m(still.lat_deg, still.lon_deg, m.lat / 1e7, m.lon / 1e7)
                for _, m in rover.history[mark:]
                if m.get_type() == kind
            ]
            assert len(points) >= RECORD_S / REPORT_S * 0.8, (kind, len(points))
            figures[kind] = spreads(points)
        rover.run_for(2.0)  # the estimate settles back before the next scenario
    raw, ac_half, ac_three, off_m = figures["GPS_RAW_INT"]
    # The noise was fed: SITL 0.47-0.56 m. Less when the machine is busy: the harness
    # feeds SITL a fresh offset per fix by a parameter, and a late one repeats the last
    # (0.36 m in a loaded suite run), so the estimate is judged against the raw spread.
    assert 0.3 <= raw <= 0.65, figures
    assert ac_half <= 0.3, figures  # white: a fresh error at every fix
    assert off_m <= 0.25, figures
    spread, ac_half, ac_three, off_m = figures["GLOBAL_POSITION_INT"]
    assert 0.09 <= spread <= 0.27, figures  # SITL 0.16-0.19 (0.5 m fed)
    # About a third of the raw spread (SITL about 0.3-0.4, 0.49 with the late offsets of a
    # loaded run; the simulation 0.26); a position that reported the raw fix would be 1.
    assert 0.18 <= spread / raw <= 0.6, figures
    assert ac_half >= 0.45, figures  # SITL 0.76-0.79: it remembers
    assert ac_three <= 0.45, figures  # SITL 0.03-0.07: but not for long
    assert off_m <= 0.25, figures
