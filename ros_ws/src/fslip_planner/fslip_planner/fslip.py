"""The Flywheel SLIP model (paper §III-A).

Stance dynamics with the foot fixed at the origin (x right/forward, z up; β = leg angle of the
mass about the foot, positive = mass ahead of the foot; θ, H about +y, positive = frontflip):

    m ẍ = −(τ+u)/r cosβ + F^s sinβ,   m z̈ = −m g + (τ+u)/r sinβ + F^s cosβ,   I θ̈ = τ,
    s = L − r,   F^s = K s + D ṡ,   r = √(x²+z²), sinβ = x/r, cosβ = z/r.

Formulation used for planning (fast convergence): state X = [x, z, ẋ, ż, H] with H = I θ̇ the
flywheel momentum (Ḣ = τ; with I = I(L) this is the whole-robot centroidal pitch momentum), control
U = [F^s, τ, u] (the leg's axial spring force, flywheel torque, foot torque).  The spring is massless
and its damping time constant D/K (< 1e-3 s, see the regression) is far below the knot spacing, so
its deflection is quasi-static, s = F^s/K(L), and the actuated leg length is *computed* from the
mass position: L = r + s (one fixed-point step for K(L)).  The GRF at the foot equals the force on
the mass (massless leg): F_x = m ẍ, F_z = m (z̈ + g).

All functions take numpy floats/arrays or CasADi symbols.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

G = 9.81


def _is_sym(v):
    return type(v).__module__.startswith("casadi")


def sqrt(v):
    if _is_sym(v):
        import casadi as ca
        return ca.sqrt(v)
    return np.sqrt(v)


def atan2(y, x):
    if _is_sym(y) or _is_sym(x):
        import casadi as ca
        return ca.atan2(y, x)
    return np.arctan2(y, x)


@dataclass
class FSLIPParams:
    """FSLIP parameters: point mass m, foot length l, friction μ, limits, and the regression
    (K(L), D(L), I(L), F_max(L), com_h(L)) of :mod:`fslip_planner.regression`."""
    m: float
    reg: object                     # regression.Regression
    foot_length: float
    mu: float = 0.6
    tau_max: float = 195.0          # |τ| bound (whole-body pitch torque), N·m
    L_min: float = 0.55
    L_max: float = 0.95
    knee_no_load_speed: float = math.inf   # rad/s; inf = no torque–speed envelope on the leg force
    #: the knee torque counts the tangential force too, (F^s + rho(L) f_t) dL/dq_knee (regression ``rho``);
    #: False: the axial force alone, F^s dL/dq_knee (docs/planner.md, "The knees' share")
    knee_tangential: bool = False
    I_flywheel: float = 0.1074      # spin inertia of the robot's pelvis flywheel
    g: float = G
    extra: dict = field(default_factory=dict)

    def K(self, L):
        return self.reg("K", L)

    def D(self, L):
        return self.reg("D", L)

    def I(self, L):
        return self.reg("I", L)

    def F_max(self, L):
        return self.reg("F_max", L)

    def knee_leg_force(self, X, U):
        """The axial leg force whose knee torque equals that of the foot force of (X, U): F^s, plus
        rho(L) f_t (f_t = (τ+u)/r, the tangential force) with ``knee_tangential``."""
        if not self.knee_tangential:
            return U[0]
        r = leg_geometry(X)[0]
        return U[0] + self.reg("rho", leg_length(X, U, self)) * (U[1] + U[2]) / r

    def dqknee_dL(self, L):
        return self.reg("F_max", L) / (2.0 * self.reg.info.get("knee_torque_limit", 195.2))


def leg_geometry(X):
    """(r, sinβ, cosβ, ṙ) of the state X = [x, z, ẋ, ż, H]."""
    x, z, xd, zd = X[0], X[1], X[2], X[3]
    r = sqrt(x * x + z * z)
    return r, x / r, z / r, (x * xd + z * zd) / r


def leg_length(X, U, p: FSLIPParams):
    """Actuated leg length L = r + s with the quasi-static spring s = F^s / K(L)."""
    r = leg_geometry(X)[0]
    F = U[0]
    s0 = F / p.K(r)
    s = F / p.K(r + s0)
    return r + s


def grf(X, U, p: FSLIPParams):
    """Ground reaction force (F_x, F_z) at the foot = force of the massless leg on the mass."""
    r, sb, cb, _ = leg_geometry(X)
    F, tau, u = U[0], U[1], U[2]
    ft = (tau + u) / r
    return -ft * cb + F * sb, ft * sb + F * cb


def dynamics(X, U, p: FSLIPParams):
    """Ẋ = f(X, U): [ẋ, ż, ẍ, z̈, Ḣ] (paper §III-A; Ḣ = τ)."""
    Fx, Fz = grf(X, U, p)
    return [X[2], X[3], Fx / p.m, Fz / p.m - p.g, U[1]]


def dynamics_np(X, U, p: FSLIPParams):
    return np.array([float(v) for v in dynamics(X, U, p)])


def pitch_rate(X, U, p: FSLIPParams):
    """θ̇ = H / I(L)."""
    return X[4] / p.I(leg_length(X, U, p))


def leg_angle(X):
    """β = atan2(x, z) (mass about the foot; + = mass ahead of the foot)."""
    return atan2(X[0], X[1])


def touchdown_zdot(zdot, platform_height, g=G):
    """Vertical speed at the touch-down of a ballistic flight from a lift-off at ż onto ground
    ``platform_height`` lower, the COM as high above the feet as at the lift-off (negative: falling)."""
    return -sqrt(zdot * zdot + 2.0 * g * platform_height)


def flight_time(zdot, platform_height, g=G):
    """Ballistic flight time from lift-off (vertical speed ż) to a touch-down ``platform_height``
    lower with the same COM height relative to the feet (paper: T = 2ż/g on flat ground)."""
    return (zdot + sqrt(zdot * zdot + 2.0 * g * platform_height)) / g


def static_state(p: FSLIPParams, L):
    """State and control standing at rest on a vertical leg of actuated length L: F^s = m g."""
    F = p.m * p.g
    # r + F/K(r + F/K(r)) = L  -> a few fixed-point steps
    r = L - F / float(p.K(L))
    for _ in range(50):
        X = np.array([0.0, r, 0.0, 0.0, 0.0])
        r = r + (L - float(leg_length(X, [F, 0, 0], p)))
    return np.array([0.0, r, 0.0, 0.0, 0.0]), np.array([F, 0.0, 0.0])


def params_for(flywheel="I", mu=0.6, knee_speed_envelope=True, motor_speed_scale=1.0,
               flywheel_torque=None, knee_tangential=False) -> FSLIPParams:
    """:class:`FSLIPParams` of the robot with a Table I flywheel: m = Cassie + flywheel mass, foot
    length l (toe–heel contact points), flywheel torque bound (``flywheel_torque`` N·m; None or 0:
    the flywheel's own), the regression, and (by default) the knee torque–speed envelope (the
    simulator clips motor torques with it), its no-load speed times ``motor_speed_scale`` as in
    ``cassie_model.motor_limits.MotorLimits``; ``knee_tangential`` as :class:`FSLIPParams`'."""
    from cassie_model import robot_params as P
    from cassie_model.motor_limits import with_flywheel_torque

    from . import regression
    reg = regression.load(flywheel)
    fw = with_flywheel_torque(P.flywheel(flywheel), flywheel_torque)
    reg.info.setdefault("knee_torque_limit", regression.knee_torque_limit())
    w0 = regression.knee_no_load_speed() * motor_speed_scale if knee_speed_envelope else math.inf
    return FSLIPParams(m=P.CASSIE_MASS + fw.mass, reg=reg, foot_length=P.FOOT_LENGTH, mu=mu,
                       tau_max=P.flywheel_motor(fw).torque_limit,
                       L_min=max(0.55, reg.L_min), L_max=min(0.95, reg.L_max),
                       knee_no_load_speed=w0, I_flywheel=fw.inertia_pitch, knee_tangential=bool(knee_tangential))
