"""Time profiles of the controller's targets (no ROS): the quintic (min-jerk) blend and the leg catch
of a landing.  The compiled ground targets (native/ground.cpp) compute the same numbers, to the bit."""
from __future__ import annotations

import numpy as np


def quintic(y0, y1, T, s, v0=None):
    """Quintic from (y0, v0, 0) to (y1, 0, 0) over T (min-jerk when v0 = 0), at time s: (y, ydot, yddot).

    y = y0 + (y1 - y0) p(x) + v0 (s + T r(x)),  x = s/T,  p = 10x^3 - 15x^4 + 6x^5,  r = -6x^3 + 8x^4 - 3x^5."""
    if T <= 0 or s >= T:
        y1 = np.asarray(y1, float)
        z = np.zeros(y1.shape)
        return y1, z, z
    x = max(s, 0.0) / T
    x2 = x * x
    x3 = x2 * x
    p, dp, ddp = x3 * (10 - 15 * x + 6 * x2), x2 * (30 - 60 * x + 30 * x2) / T, x * (60 - 180 * x + 120 * x2) / T ** 2
    r, dr, ddr = x3 * (-6 + 8 * x - 3 * x2), x2 * (-18 + 32 * x - 15 * x2) / T, x * (-36 + 96 * x - 60 * x2) / T ** 2
    if (type(y0) is np.ndarray and type(y1) is np.ndarray and y0.dtype == y1.dtype == np.float64
            and y0.ndim == 1 and y0.shape == y1.shape
            and (v0 is None or (type(v0) is np.ndarray and v0.dtype == np.float64 and v0.shape == y0.shape))):
        # the expressions below element by element in Python floats (the same operations in the same
        # order: the same numbers), for the 1-3 element outputs of a tick, where numpy's per-call cost
        # is most of the time
        a, b = y0.tolist(), y1.tolist()
        d = [bi - ai for ai, bi in zip(a, b)]
        if v0 is None:
            return (np.array([ai + p * di for ai, di in zip(a, d)]), np.array([dp * di for di in d]),
                    np.array([ddp * di for di in d]))
        c0, c1, c2 = max(s, 0.0) + T * r, 1.0 + T * dr, T * ddr
        v = v0.tolist()
        return (np.array([ai + p * di + c0 * vi for ai, di, vi in zip(a, d, v)]),
                np.array([dp * di + c1 * vi for di, vi in zip(d, v)]),
                np.array([ddp * di + c2 * vi for di, vi in zip(d, v)]))
    y1 = np.asarray(y1, float)
    d = y1 - y0
    if v0 is None:
        return y0 + p * d, dp * d, ddp * d
    return y0 + p * d + (max(s, 0.0) + T * r) * v0, dp * d + (1.0 + T * dr) * v0, ddp * d + T * ddr * v0


#: s, the leg's min-jerk rise to the standing length after the catch (leg_catch)
LEG_RISE_TIME = 1.5


def leg_catch(L0, v0, L1, t, decel=15.0, L_min=0.50, rise_time=LEG_RISE_TIME):
    """Leg length after a touch-down at speed v0 < 0: constant deceleration a over the stroke
    d = v0^2 / (2 a) (d capped at L0 - L_min, a raised to match), then a min-jerk rise to L1 over
    ``rise_time``.  Returns (L, Ldot, Lddot) at time t after touch-down.  A quintic that starts with
    the touch-down velocity either overshoots the leg stroke or ends with a deceleration above g
    that throws the robot off the ground again; this profile does neither."""
    if v0 >= 0.0:      # already rising (a re-anchor mid-landing): keep that velocity, do not stop the leg
        return quintic(np.array([L0]), np.array([L1]), rise_time, t, np.array([v0]))
    d = min(v0 * v0 / (2.0 * decel), max(L0 - L_min, 0.02))
    a = v0 * v0 / (2.0 * d)
    tc = -v0 / a
    if t < tc:
        return np.array([L0 + v0 * t + 0.5 * a * t * t]), np.array([v0 + a * t]), np.array([a])
    return quintic(np.array([L0 - d]), np.array([L1]), rise_time, t - tc)


def leg_catch_duration(L0, v0, decel=15.0, L_min=0.50, rise_time=LEG_RISE_TIME):
    """Time after which :func:`leg_catch` has reached its final value."""
    if v0 >= 0.0:
        return rise_time
    d = min(v0 * v0 / (2.0 * decel), max(L0 - L_min, 0.02))
    return -v0 / (v0 * v0 / (2.0 * d)) + rise_time
