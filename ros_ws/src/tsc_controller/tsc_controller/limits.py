"""Constraints of the TSC QP (paper eq. (QP)): torque–speed envelope and ground-reaction limits.

* Torque Limit: u_lb(qdot) <= u <= u_ub(qdot) of ``cassie_model.motor_limits.MotorLimits``
  (the simulator's own envelope; the flywheel has a constant 195 N·m, or ``flywheel_torque``).
* A speed cap (the LANDING's flywheel, :func:`speed_cap_row`): one row on all the motor torques that keeps a
  joint's predicted speed at the next tick, w + drift + dt m.u, within w_cap.
* GRF: C_v F_v <= c_v, with F_v in the contact basis of :meth:`Dynamics.contact_constraints`
  (per foot: toe (f_d, f_t, f_n), heel (f_t, f_n)):  f_n >= f_min at toe and heel (unilateral and
  centre of pressure inside the foot), |f_t| <= mu f_n at each point, and the foot's along-foot
  force (carried by the toe row only, see dynamics) |f_d| <= mu (f_n,toe + f_n,heel) — a friction pyramid.
"""
from __future__ import annotations

import numpy as np
from cassie_model.description import motor_torque_limits
from cassie_model.motor_limits import MotorLimits

from . import _native

ROWS_PER_FOOT = 5


def grf_constraints(n_feet: int = 2, mu: float = 0.6, f_min: float = 1.0, cop_margin: float = 0.0):
    """(C, c) with C F <= c for the stacked foot forces (5 per foot, ordered as the contact rows).

    ``cop_margin`` in [0, 0.5) keeps the centre of pressure that fraction of the foot length away
    from the toe and the heel (the flat-foot contact model stops being true once a compliant foot
    rocks onto one edge under a landing load)."""
    rows, rhs = [], []
    for k in range(n_feet):
        o = ROWS_PER_FOOT * k
        td, tt, tn, ht, hn = o, o + 1, o + 2, o + 3, o + 4

        def row(coefs):
            r = np.zeros(ROWS_PER_FOOT * n_feet)
            for i, cval in coefs:
                r[i] = cval
            return r
        rows += [row([(tn, -1.0)]), row([(hn, -1.0)])]
        rhs += [-f_min, -f_min]
        if cop_margin > 0.0:      # toe and heel each carry >= cop_margin of the foot's load
            rows += [row([(tn, cop_margin - 1.0), (hn, cop_margin)]), row([(hn, cop_margin - 1.0), (tn, cop_margin)])]
            rhs += [0.0, 0.0]
        for i, n in ((tt, tn), (ht, hn)):
            rows += [row([(i, 1.0), (n, -mu)]), row([(i, -1.0), (n, -mu)])]
            rhs += [0.0, 0.0]
        rows += [row([(td, 1.0), (tn, -mu), (hn, -mu)]), row([(td, -1.0), (tn, -mu), (hn, -mu)])]
        rhs += [0.0, 0.0]
    return np.array(rows), np.array(rhs)


def speed_cap_row(m, w: float, w_cap: float, dt: float, drift: float, lb, ub):
    """(row, upper) with row.u <= upper: a joint's speed at the next tick, predicted w + drift + dt m.u
    (m: the joint's row of M^-1 B, its acceleration per motor torque), at most ``w_cap`` in magnitude
    along its present sign; above the cap a brake.  ``upper`` is kept at or above the least row.u the
    torque bounds (lb, ub) allow: beyond them the row asks for the most brake there is, and the QP stays
    feasible."""
    sgn = 1.0 if w >= 0.0 else -1.0
    row = sgn * dt * np.asarray(m, float)
    upper = w_cap - sgn * (w + drift)
    least = float(np.minimum(row * np.asarray(lb, float), row * np.asarray(ub, float)).sum())
    return row, max(upper, least)


class TorqueLimits:
    """u_lb(qdot), u_ub(qdot) of the 11 motors (contract order): the envelope of ``limits`` (a
    :class:`~cassie_model.motor_limits.MotorLimits`, the simulator's), compiled from the same
    definition (cassie_model native/motor_envelope.h): Cassie's published curve, full torque up to half
    the no-load speed, none at it, whatever the torque's sign."""

    def __init__(self, limits: MotorLimits | None = None, speed_scale: float = 1.0,
                 flywheel_torque: float | None = None):
        self.limits = limits if limits is not None else MotorLimits.from_flywheel("I", speed_scale, flywheel_torque)
        self.tau_max = np.asarray(self.limits.torque_limit, float)
        self._inv_w0 = np.asarray(self.limits.inv_no_load_speed, float)

    @classmethod
    def for_description(cls, mjcf: str, speed_scale: float = 1.0, flywheel_torque: float | None = None):
        """The limits of the robot an MJCF describes: its flywheel motor's torque limit from the
        description (the flywheel actuator's ctrlrange, the simulator's); a ``flywheel_torque`` given
        as well must equal it (ValueError otherwise: the controller would plan torques the plant
        clips, or leave torque unused)."""
        described = motor_torque_limits(mjcf).get("flywheel")
        if not flywheel_torque:
            flywheel_torque = described
        elif described is not None and abs(flywheel_torque - described) > 1e-9 * described:
            raise ValueError(f"flywheel torque {flywheel_torque:g} N*m differs from the robot description's "
                             f"{described:g} N*m (its flywheel actuator's ctrlrange)")
        return cls(speed_scale=speed_scale, flywheel_torque=flywheel_torque)

    def bounds(self, motor_velocities):
        """(u_lb, u_ub): the bound a motor pushes against (the sign of its velocity) is
        tau_max clip(1 - |w|/w0, 0, 1), the other one tau_max.  Compiled (tsc_controller._native);
        ``limits.bounds`` (MotorLimits.bounds) is the Python reference it equals bit for bit."""
        return _native.torque_bounds(motor_velocities, self._inv_w0, self.tau_max)
