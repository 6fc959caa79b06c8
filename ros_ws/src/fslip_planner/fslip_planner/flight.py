"""Flight phase planning (paper §IV): momentum transmission and assistive components.

* θ_des(t), ω̄_des(t) (§IV-A): a cubic with θ(0) = θ₀ (measured pelvis pitch at lift-off, the
  paper's β^lift-off since the pelvis tracks β on the ground), ω̄(0) = measured pelvis pitch rate,
  θ(T) = ±2π − β^lift-off (frontflip +, backflip −, hop 0), ω̄(T) = 0; T = flight time recomputed
  from the measured vertical COM speed.  Output ``phi_pitch`` (unwrapped) with d = ω̄_des and
  dd = ω̄̇_des; the controller closes eq. (momentumTrans) with it.
* Leg retraction / tucking (§IV-B): L_des(t) retracts from the lift-off length to ``L_tuck`` by
  T1/2 and extends back to the landing length (= planned lift-off length) by T1 = ¾ T (quintic
  segments, zero end velocities/accelerations), then stays.
* Foot placement (§IV-B): parameter ``beta_liftoff`` in the controller's ``beta_leg`` convention
  (atan2(r_x, −r_z) of the hip→foot vector, world frame) = −β_FSLIP; the controller drives the
  leg to −beta_liftoff = +β_FSLIP (foot ahead of the COM, mirroring lift-off) after T1.
"""
from __future__ import annotations

import math

import numpy as np

from . import fslip as F

SIGN = {"backflip": -1.0, "frontflip": 1.0, "hop": 0.0}
TUCK_MAX_ACC = 30.0   # m/s^2, peak leg-length acceleration of the tuck
TUCK_LENGTH = 0.6     # m, leg length of the deepest tuck


def cubic(y0, v0, y1, v1, T, t):
    """Cubic Hermite y(t) on [0, T] with y(0)=y0, ẏ(0)=v0, y(T)=y1, ẏ(T)=v1: (y, ẏ, ÿ)."""
    t = np.clip(np.asarray(t, float), 0.0, T)
    a0, a1 = y0, v0
    a2 = (3 * (y1 - y0) - (2 * v0 + v1) * T) / T ** 2
    a3 = (2 * (y0 - y1) + (v0 + v1) * T) / T ** 3
    return (a0 + a1 * t + a2 * t ** 2 + a3 * t ** 3, a1 + 2 * a2 * t + 3 * a3 * t ** 2, 2 * a2 + 6 * a3 * t)


def min_jerk(y0, y1, T, t):
    """Quintic rest-to-rest from y0 to y1 over [0, T]: (y, ẏ, ÿ)."""
    x = np.clip(np.asarray(t, float) / T, 0.0, 1.0)
    p = x ** 3 * (10 - 15 * x + 6 * x ** 2)
    dp = 30 * x ** 2 * (1 - x) ** 2 / T
    ddp = 60 * x * (1 - x) * (1 - 2 * x) / T ** 2
    d = y1 - y0
    return y0 + d * p, d * dp, d * ddp


def tuck_profile(L_lo, L_tuck, L_land, T1, t):
    """L_des(t): retract L_lo → L_tuck on [0, T1/2], extend L_tuck → L_land on [T1/2, T1], then hold."""
    t = np.asarray(t, float)
    h = 0.5 * T1
    a = min_jerk(L_lo, L_tuck, h, t)
    b = min_jerk(L_tuck, L_land, h, t - h)
    first = t < h
    return tuple(np.where(first, ai, bi) for ai, bi in zip(a, b))


def trapezoid(y0, v0, y1, T, a, t):
    """Rotation profile limited to |ÿ| ≤ a: from (y0, v0) to (y1, 0) in T — ramp to a cruise rate,
    hold it, ramp to rest (the cruise rate found by bisection).  None if no such profile exists.
    The flywheel turns the rest of the body at most at τ_max / I_rest; a cubic asks for its peak
    acceleration 6 Δθ / T² at both ends and saturates the flywheel motor (docs/measurements.md,
    Planner and robot-model values)."""
    d = y1 - y0

    def area(w):
        t1 = abs(w - v0) / a
        t3 = abs(w) / a
        if t1 + t3 > T:
            return None
        return 0.5 * (v0 + w) * t1 + w * (T - t1 - t3) + 0.5 * w * t3
    span = 4.0 * abs(d) / T + abs(v0) + 1.0
    grid = np.linspace(-span, span, 4001)
    # area(w) - d over the grid at once (the same operations element by element; NaN where no
    # profile exists), then the first bracket of a root of area(w) = d, refined by bisection.  The
    # grid in Python took ~3 ms a call, and a flight plan that searches the acceleration makes ~20
    # (the planner node's lift-off answer: ~80 ms, for which the lockstep simulator held)
    t1g, t3g = np.abs(grid - v0) / a, np.abs(grid) / a
    f = 0.5 * (v0 + grid) * t1g + grid * (T - t1g - t3g) + 0.5 * grid * t3g - d
    f[t1g + t3g > T] = np.nan
    fa_all, fb_all = f[:-1], f[1:]
    with np.errstate(invalid="ignore"):
        hits = np.flatnonzero(fa_all * fb_all <= 0.0)        # NaN (no profile) compares False
    if hits.size == 0:
        return None
    i = int(hits[0])
    fa = float(f[i])
    a_lo, a_hi = float(grid[i]), float(grid[i + 1])
    for _ in range(60):
        m = 0.5 * (a_lo + a_hi)
        if (area(m) - d) * fa <= 0.0:
            a_hi = m
        else:
            a_lo, fa = m, area(m) - d
    w = 0.5 * (a_lo + a_hi)
    t1, t3 = abs(w - v0) / a, abs(w) / a
    s1, s3 = np.sign(w - v0) * a, -np.sign(w) * a
    t = np.clip(np.asarray(t, float), 0.0, T)
    y, yd, ydd = np.empty_like(t), np.empty_like(t), np.empty_like(t)
    y_t1 = y0 + v0 * t1 + 0.5 * s1 * t1 ** 2
    t2 = T - t3
    y_t2 = y_t1 + w * (t2 - t1)
    for k, tk in enumerate(t):
        if tk < t1:
            y[k], yd[k], ydd[k] = y0 + v0 * tk + 0.5 * s1 * tk ** 2, v0 + s1 * tk, s1
        elif tk < t2:
            y[k], yd[k], ydd[k] = y_t1 + w * (tk - t1), w, 0.0
        else:
            u = tk - t2
            y[k], yd[k], ydd[k] = y_t2 + w * u + 0.5 * s3 * u ** 2, w + s3 * u, s3
    return y, yd, ydd


def tuck_timing(kind, T, L_lo, L_tuck=TUCK_LENGTH, t1_fraction=0.75):
    """(T1, L_tuck) of the tuck (§IV-B) in a flight of T s: retracted by T1/2, extended by T1; none
    for a hop (a hop turns nothing: feet placed and flat from lift-off on, T1 = 0)."""
    if SIGN[kind] == 0.0:
        return 0.0, L_lo
    T1 = t1_fraction * T
    # the tuck must fit its time: a min-jerk retraction by d over T1/2 peaks at 5.77 d/(T1/2)^2;
    # keep it within TUCK_MAX_ACC (a 0.33 s flight would otherwise ask for ~100 m/s^2)
    return T1, max(L_tuck, L_lo - TUCK_MAX_ACC * (0.5 * T1) ** 2 / 5.77)


def leg_profile(L_lo, L_tuck, L_land, T1, t):
    """(L, L̇, L̈) of the flight: the tuck of :func:`tuck_profile` (none for T1 = 0); ``L_land``
    None: the lift-off length."""
    L_land = L_lo if L_land is None else min(L_lo, L_land)
    if T1 <= 0.0:
        return np.full_like(t, L_lo), np.zeros_like(t), np.zeros_like(t)
    return tuck_profile(L_lo, min(L_tuck, L_lo), L_land, T1, t)


def flight_plan(kind, theta0, omega0, zdot, beta_lo, L_lo, platform=0.0, L_tuck=TUCK_LENGTH,
                t1_fraction=0.75, dt=0.002, g=F.G, max_body_acc=None, hard_body_acc=None, L_land=None):
    """Flight reference samples.  Returns dict(t, theta(3×n), L(3×n), T, T1, theta_T).
    ``max_body_acc`` (rad/s², the flywheel torque limit over the rest of the body's inertia): the
    pitch profile is a :func:`trapezoid` within it when one exists; else, with ``hard_body_acc`` (the
    full torque limit over that inertia), the trapezoid of the least acceleration up to it that turns
    the body in T (a bang-bang turn needs 4 Δθ / T², the cubic 6 Δθ / T² at both ends: it
    over-rotates, docs/measurements.md, Planner and robot-model values); else the paper's cubic.  ``L_land``: leg length at
    touch-down (default: the lift-off length)."""
    if kind not in SIGN:
        raise ValueError(f"unknown kind {kind!r}")
    T = float(F.flight_time(max(zdot, 0.05), platform, g))
    T1, L_tuck = tuck_timing(kind, T, L_lo, L_tuck, t1_fraction)
    theta_T = SIGN[kind] * 2 * math.pi - beta_lo
    n = max(int(math.ceil(T / dt)), 2) + 1
    t = np.linspace(0.0, T, n)
    th = None
    if max_body_acc is not None and SIGN[kind] != 0.0:
        th = trapezoid(theta0, omega0, theta_T, T, max_body_acc, t)
        if th is None and hard_body_acc is not None and hard_body_acc > max_body_acc:
            t_chk = np.array([0.0])
            if trapezoid(theta0, omega0, theta_T, T, hard_body_acc, t_chk) is not None:
                lo, hi = max_body_acc, hard_body_acc
                for _ in range(20):
                    mid = 0.5 * (lo + hi)
                    if trapezoid(theta0, omega0, theta_T, T, mid, t_chk) is None:
                        lo = mid
                    else:
                        hi = mid
                th = trapezoid(theta0, omega0, theta_T, T, min(1.02 * hi, hard_body_acc), t)
    if th is None:
        th = cubic(theta0, omega0, theta_T, 0.0, T, t)
    L = leg_profile(L_lo, L_tuck, L_land, T1, t)
    return dict(t=t, theta=np.array(th), L=np.array(L), T=T, T1=T1, theta_T=theta_T)


def max_body_turn(h0, t, inertia, tau_max):
    """Largest rotation (rad, in the direction of ``h0``'s sign convention: positive) that the body
    without the flywheel can make in a flight sampled at ``t`` (from 0 to T) and end at rest, when
    only the flywheel motor (|torque| ≤ ``tau_max``) changes its momentum (momentum transmission,
    eq. momentumTrans).

    The body's own pitch momentum h = I_rest(t) ω̄ starts at ``h0`` (the lift-off rate times the
    lift-off inertia) and must end at 0; |ḣ| ≤ τ_max, and ω̄ = h / I_rest(t) with ``inertia`` the
    body's inertia at ``t`` along the planned tuck.  The most rotation comes from the bang-bang
    momentum h(t) = min(h0 + τ t, τ (T − t)), integrated over the flight."""
    h = np.minimum(h0 + tau_max * t, tau_max * (t[-1] - t))
    w = h / inertia
    return float(np.sum(0.5 * (w[1:] + w[:-1]) * np.diff(t)))


def flight_torque_needed(turn, omega0, T, inertia, tau_hi=1e4, n=400):
    """Least flywheel torque (N·m) that turns the body by ``turn`` rad (sign = direction) in a flight
    of ``T`` s from the lift-off rate ``omega0`` and brings it to rest (:func:`max_body_turn`
    bisected on the torque, ``inertia(t)`` sampled once at ``n`` times); ``inf`` where even
    ``tau_hi`` cannot (a flight too short)."""
    t = np.linspace(0.0, T, n)
    I = inertia(t)
    h0 = (1.0 if turn >= 0 else -1.0) * omega0 * float(I[0])
    D = abs(turn)
    if max_body_turn(h0, t, I, tau_hi) < D:
        return math.inf
    lo, hi = 0.0, tau_hi
    for _ in range(50):
        m = 0.5 * (lo + hi)
        if max_body_turn(h0, t, I, m) >= D:
            hi = m
        else:
            lo = m
    return hi
