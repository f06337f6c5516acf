"""ArduPilot's control maths, as the models fly it (AP_Math control.cpp).

Apart from the models because it is ArduPilot's library code, not an airframe's: the
square-root controller the copter and the rover brake with, and the jerk-limited shaping
of a position target that ArduRover's GUIDED follows, with the small vector and angle
helpers they share.
"""

from __future__ import annotations

import math
from typing import Final

ROVER_CORNER_ACCEL_RATIO: Final = 1.0 / math.sqrt(2.0)
"""AP_Math control.cpp's CORNER_ACCELERATION_RATIO: where the shaped velocity's change along
its command dominates, the part across it keeps this share of the acceleration limit
(``limit_accel_corner_xy`` of the SITL build, 2025-07)."""

TAU = 2.0 * math.pi
HALF_PI = 0.5 * math.pi
INF = math.inf


def clamp(value: float, low: float, high: float) -> float:
    """``value`` within [``low``, ``high``]."""
    return low if value < low else (high if value > high else value)


def wrap_pi(angle_rad: float) -> float:
    """An angle in [-pi, pi)."""
    return (angle_rad + math.pi) % TAU - math.pi


def sqrt_controller(error: float, p_gain: float, accel_max: float, dt_s: float) -> float:
    """ArduPilot's square-root controller: the speed that brakes to a stop at ``error``.

    Linear (``p_gain * error``) near the target, ``sqrt(2 * accel_max * distance)``
    farther out, so that decelerating at ``accel_max`` arrives with zero speed; and
    never more than covers the error in one step, so a discrete step cannot overshoot.
    """
    linear_m = accel_max / (p_gain * p_gain)
    if error > linear_m:
        speed = math.sqrt(2.0 * accel_max * (error - 0.5 * linear_m))
    elif error < -linear_m:
        speed = -math.sqrt(2.0 * accel_max * (-error - 0.5 * linear_m))
    else:
        speed = p_gain * error
    limit = abs(error) / dt_s
    return clamp(speed, -limit, limit)


def limit_length(x: float, y: float, limit: float) -> tuple[float, float]:
    """The vector (x, y) shortened to ``limit`` if longer (ArduPilot's Vector2f::limit_length)."""
    length = math.hypot(x, y)
    if length > limit:
        scale = limit / length
        return x * scale, y * scale
    return x, y


def sqrt_controller_xy(
    x: float, y: float, p_gain: float, accel_max: float, dt_s: float
) -> tuple[float, float]:
    """:func:`sqrt_controller` of a 2-D error, along the error (control.cpp's vector form)."""
    length = math.hypot(x, y)
    if length <= 0.0:
        return 0.0, 0.0
    scale = sqrt_controller(length, p_gain, accel_max, dt_s) / length
    return x * scale, y * scale


def limit_accel_corner_xy(
    vn: float, ve: float, an: float, ae: float, accel_max: float
) -> tuple[float, float]:
    """An acceleration limited to ``accel_max``, keeping a share for the turn.

    AP_Math control.cpp's ``limit_accel_corner_xy`` as the SITL build (ArduPilot master of
    2025-07) has it, about the velocity (vn, ve) the target is asked for: where the part
    across that velocity is at least the part along it, the vector is simply shortened;
    where the part along dominates, the part across keeps
    :data:`ROVER_CORNER_ACCEL_RATIO` of the limit and the part along has what is left.
    (Later ArduPilot splits about the current velocity and gives braking priority: SITL's
    logged shaped target follows this one, to 0.2 m over 5 s after a redirect.)
    """
    speed = math.hypot(vn, ve)
    if speed <= 0.0:
        return limit_length(an, ae, accel_max)
    un, ue = vn / speed, ve / speed
    along = an * un + ae * ue
    cn, ce = an - un * along, ae - ue * along
    if along * along <= cn * cn + ce * ce:
        return limit_length(an, ae, accel_max)
    cn, ce = limit_length(cn, ce, ROVER_CORNER_ACCEL_RATIO * accel_max)
    along_max = math.sqrt(max(accel_max * accel_max - (cn * cn + ce * ce), 0.0))
    along = clamp(along, -along_max, along_max)
    return cn + un * along, ce + ue * along


def shape_pos_vel_accel_xy(
    error_n_m: float,
    error_e_m: float,
    vn: float,
    ve: float,
    an: float,
    ae: float,
    speed_max: float,
    accel_max: float,
    jerk_max: float,
    dt_s: float,
) -> tuple[float, float]:
    """The next acceleration of a shaped target ``error`` short of a destination at rest.

    AP_Math control.cpp's ``shape_pos_vel_accel_xy`` with ``shape_vel_accel_xy`` as the
    SITL build has them: a velocity toward the destination from a square-root law (gain
    ``0.5 jerk/accel``, braking at half ``accel_max``), capped at ``speed_max``; the
    acceleration toward that velocity from a square-root law on the velocity error (gain
    ``jerk/accel``, limited at ``jerk_max``), held by :func:`limit_accel_corner_xy` about
    the velocity asked, and approached at ``jerk_max``. One 2-D limit for the velocity
    vector: turning 3 m/s through 90 degrees is a 4.2 m/s change, seconds at 1 m/s^2, the
    target slowing on the way. Checked against SITL's own log (PSCN/PSCE): from the same
    state, this target stays within 0.1 m of SITL's over a 40 m leg from rest and within
    0.2-0.3 m over 5 s after a redirect.

    Args:
        error_n_m: Destination minus the shaped position, north.
        error_e_m: The same, east.
        vn: The shaped velocity, north (m/s).
        ve: The same, east.
        an: The shaped acceleration, north (m/s^2).
        ae: The same, east.
        speed_max: The leg speed (m/s).
        accel_max: The acceleration limit (m/s^2).
        jerk_max: The jerk limit (m/s^3).
        dt_s: The step.

    Returns:
        The shaped acceleration (north, east) for the next step.
    """
    tn, te = sqrt_controller_xy(
        error_n_m, error_e_m, 0.5 * jerk_max / accel_max, 0.5 * accel_max, dt_s
    )
    tn, te = limit_length(tn, te, speed_max)
    wn, we = sqrt_controller_xy(tn - vn, te - ve, jerk_max / accel_max, jerk_max, dt_s)
    wn, we = limit_accel_corner_xy(tn, te, wn, we, accel_max)
    dn, de = limit_length(wn - an, we - ae, jerk_max * dt_s)
    return an + dn, ae + de
