"""Ground-phase references (JUMPING, LANDING) from FSLIP knots.

FSLIP knots → robot outputs (paper §V-A, eq. Y^{J/L}): ``H_pitch`` = H (the FSLIP flywheel
momentum I(L)θ̇ = whole-robot centroidal pitch momentum; d = τ, dd = τ̇), ``L`` = r + F^s/K
(d = ṙ + ṡ, dd = r̈ + s̈ with ṙ, r̈ from the states and the dynamics, ṡ, s̈ by differences of the
knot values), ``x_com`` = x + (the standing COM x measured when the flip is requested: the foot
sits under the standing COM; d = ẋ, dd = ẍ from the dynamics), ``phi_pitch`` = β (the pelvis tracks the leg angle on the ground, §IV-A;
β̇, β̈ analytic).  Knots are resampled every 2 ms (cubic Hermite on value/derivative pairs).
"""
from __future__ import annotations

import numpy as np

from . import fslip as F
from . import jumping as Jm
from .plan_types import Reference

#: sample step of every reference (s)
DT_SAMPLE = 0.002


def knot_outputs(sol: Jm.Solution):
    """Per-knot (value, d, dd) of x, H, L, β from a solution (see module doc)."""
    p, X, U, t = sol.params, sol.X, sol.U, sol.t
    acc = np.array([F.dynamics_np(X[k], U[k], p) for k in range(len(t))])
    x, z, xd, zd, H = X.T
    xdd, zdd = acc[:, 2], acc[:, 3]
    r = np.hypot(x, z)
    rd = (x * xd + z * zd) / r
    rdd = (xd ** 2 + zd ** 2 + x * xdd + z * zdd) / r - rd ** 2 / r
    s = sol.L - r
    sd = np.gradient(s, t)
    sdd = np.gradient(sd, t)
    tau = U[:, 1]
    w = z * xd - x * zd
    bd = w / r ** 2
    bdd = (z * xdd - x * zdd) / r ** 2 - 2 * w * (x * xd + z * zd) / r ** 4
    return {"x": (x, xd, xdd), "H": (H, tau, np.gradient(tau, t)), "L": (sol.L, rd + sd, rdd + sdd), "r_dot": (rd, rdd),
            "beta": (np.arctan2(x, z), bd, bdd), "s": s, "acc": acc}


def _resample(t, cols, dt=DT_SAMPLE):
    """cols: list of (v, d, dd) on knots t → (tt, V, D, DD) sampled every dt: V and D from one
    cubic Hermite spline through (v, d) (D is exactly V'), DD = derivative of the (d, dd) spline."""
    from scipy.interpolate import CubicHermiteSpline
    n = max(int(round(t[-1] / dt)), 1) + 1
    tt = np.linspace(0.0, t[-1], n)
    V, D, DD = (np.zeros((n, len(cols))) for _ in range(3))
    for j, (v, d, dd) in enumerate(cols):
        sv = CubicHermiteSpline(t, v, d)          # value and its exact derivative
        V[:, j] = sv(tt)
        D[:, j] = sv.derivative()(tt)
        DD[:, j] = CubicHermiteSpline(t, d, dd).derivative()(tt)
    return tt, V, D, DD


def leg_offset(p, L_stand: float) -> float:
    """A reference's leg length L minus the FSLIP's r: the robot's standing L minus the FSLIP's
    standing r (see ground_reference)."""
    return L_stand - float(F.static_state(p, L_stand)[0][1])


def ground_reference(domain, sol: Jm.Solution, x_offset: float, L_stand: float, figures=None, parameters=None):
    """JUMPING / LANDING reference (H_pitch, L, x_com, phi_pitch) from FSLIP knots.

    The robot's leg length (hip-pitch joint to foot joint, springs deflected as they are) hardly
    changes with the load it carries (0.861 m unloaded, 0.864 m standing, measured), so it follows
    the FSLIP's real leg length r, offset so that standing at rest maps to the robot's standing L;
    the actuated length L = r + F^s/K would ask the robot to shorten its leg whenever the FSLIP
    spring unloads.  Parameters ``leg_offset`` (that offset, m) and ``fslip_mass`` (kg) say how to
    turn it back into the FSLIP's motion and force (plan_geometry; the controller does not read them).
    ``L_stand``: the robot's standing leg length."""
    o = knot_outputs(sol)
    x, xd, xdd = o["x"]
    p = sol.params
    offset = leg_offset(p, L_stand)
    (r, rd, rdd) = (np.hypot(x, sol.X[:, 1]), ) + o["r_dot"]
    cols = [o["H"], (r + offset, rd, rdd), (x + x_offset, xd, xdd), o["beta"]]
    tt, V, D, DD = _resample(sol.t, cols)
    params = dict(parameters or {})
    params.update(leg_offset=offset, fslip_mass=float(p.m))
    return Reference(domain, tt, ["H_pitch", "L", "x_com", "phi_pitch"], V, D, DD,
                     params, dict(figures or {}))
