"""Outputs (paper §V-A) as small task classes, mink style.

Each output evaluates, from an updated :class:`~tsc_controller.dynamics.Dynamics`, its actual value
``y(q, v)``, its Jacobian ``J`` w.r.t. v (so d/dt of the relative-degree quantity is ``J vdot + drift``),
the drift ``Jdot v`` and, for relative degree 2, its velocity ``J v``:

* relative degree 1 (momenta, eq. Y_1):   y = J v,        ydot  = J vdot + drift
* relative degree 2 (positions, eq. Y_2): y = h(q),  ydot = J v,  yddot = J vdot + drift

The desired values come from the reference (``value, d_value, dd_value``); the TSC forms
Y = y - y_des and the commanded derivative of eq. (Ydes): Ydot1_des = -K1p Y1, Ydd2_des = -K2p Y2 - K2d Ydot2.

Point-based outputs do their 3-vector arithmetic on Python floats (the tick's point table as lists) and
form their Jacobian as one combination of point Jacobian rows.

``native_spec(dyn)`` describes an output to the compiled task rows (``tsc_controller._native.TaskRows``,
native/task.cpp, used by the TSC with the native backend): (kind, integer parameters, float parameters,
dim); None = no compiled form (the TSC then evaluates the list in Python).  ``evaluate`` stays the
reference (tests/unit/test_tsc_native.py).
"""
from __future__ import annotations

import math

import numpy as np

from .dynamics import SIDES, Dynamics


class Output:
    """Base class: ``name``, ``dim``, relative ``degree`` (1 or 2), per-output ``weight``, gains."""
    degree = 2
    dim = 1

    def __init__(self, name: str, weight=1.0, kp=100.0, kd=20.0):
        self.name = name
        self.weight = weight
        self.kp = kp
        self.kd = kd

    def evaluate(self, dyn: Dynamics):
        """Return (y, J, drift, ydot_or_None) with y (dim,), J (dim, nv), drift (dim,)."""
        raise NotImplementedError

    def native_spec(self, dyn: Dynamics):
        """(kind, ints, floats, dim) of the compiled task rows, or None (module doc)."""
        return None


def _point_rows(dyn, names):
    """Indices of the x, y, z rows of points in the stacked point Jacobians ``dyn.Jp.reshape(-1, nv)``."""
    return np.array([3 * dyn.point_index(n) + i for n in names for i in range(3)])


def _rows_jacobian(dyn, rows, coef):
    """sum_i coef_i * (row rows_i of the stacked point Jacobians), as a 1 x nv array."""
    return np.array([coef]) @ dyn.Jp.reshape(-1, dyn.nv)[rows]


def _atan2_rates(u, w, ud, wd):
    """Angle atan2(u, w) of a planar vector (u, w) moving at (ud, wd), with what an angle output needs:
    the gradient (gu, gw) = d angle / d(u, w), the rate gu ud + gw wd, and the velocity part of its
    second derivative, d/dt(gu) ud + d/dt(gw) wd (the drift adds gu, gw times the (u, w) drifts)."""
    rho2 = u * u + w * w
    gu, gw = w / rho2, -u / rho2
    s2 = 2.0 * (u * ud + w * wd)
    dgu, dgw = (wd * rho2 - w * s2) / rho2 ** 2, (-ud * rho2 + u * s2) / rho2 ** 2
    return math.atan2(u, w), gu, gw, gu * ud + gw * wd, dgu * ud + dgw * wd


def _scalars(y, drift, ydot):
    """(y, drift, ydot) of a 1-dim output as (1,) arrays (views of one array)."""
    a = np.array([y, drift, ydot])
    return a[0:1], a[1:2], a[2:3]


class CentroidalPitchMomentum(Output):
    """H_pitch(q, v): centroidal angular momentum about the COM, world y (eq. Y_1^{J/L}); degree 1."""
    degree = 1

    def evaluate(self, dyn):
        return dyn.hg[4:5], dyn.Ag[4:5], dyn.dAg_v[4:5], None

    def native_spec(self, dyn):
        return "centroidal", [4], [], 1


class FlywheelMomentum(Output):
    """H_flywheel(q, v) = I_axis * (world-y angular velocity of the flywheel) (eq. Y_1^F); degree 1.

    omega_fw = R_pelvis (omega_pelvis_local + a qdot_fw), a the wheel axis in the pelvis frame;
    d/dt(e_y^T omega_fw) = e_y^T R (omega_l_dot + a qddot_fw) + e_y^T R (omega_l x a qdot_fw).
    """
    degree = 1

    def __init__(self, name="H_flywheel", **kw):
        super().__init__(name, **kw)

    def _setup(self, dyn):
        m = dyn.model
        jid = dyn._jid["flywheel"]
        jm = m.joints[jid]
        # hinge axis of the flywheel in its parent (pelvis) frame
        ax = {"JointModelRX": [1, 0, 0], "JointModelRY": [0, 1, 0], "JointModelRZ": [0, 0, 1]}.get(jm.shortname())
        if ax is None:
            ax = list(jm.axis) if hasattr(jm, "axis") else [0, 1, 0]
        ax_local = np.array(ax, float)
        self._a = m.jointPlacements[jid].rotation @ ax_local
        self._I = float(ax_local @ m.inertias[jid].inertia @ ax_local)
        self._iv = m.idx_vs[jid]
        self._base_v = m.idx_vs[dyn.base_jid]

    def evaluate(self, dyn):
        if not hasattr(self, "_I"):
            self._setup(dyn)
        b, iv, I = self._base_v, self._iv, self._I
        ey_R = dyn.R_base[1]                 # e_y^T R
        J = np.zeros((1, dyn.nv))
        J[0, b + 3:b + 6] = I * ey_R
        J[0, iv] = I * (ey_R @ self._a)
        (w0, w1, w2), (a0, a1, a2), e = dyn.v[b + 3:b + 6].tolist(), (self._a * dyn.v[iv]).tolist(), ey_R.tolist()
        drift = I * (e[0] * (w1 * a2 - w2 * a1) + e[1] * (w2 * a0 - w0 * a2) + e[2] * (w0 * a1 - w1 * a0))
        return J @ dyn.v, J, np.array([drift]), None

    def native_spec(self, dyn):
        if not hasattr(self, "_I"):
            self._setup(dyn)
        return "flywheel", [self._base_v, self._iv], [self._I, *self._a.tolist()], 1


class LegLength(Output):
    """L_robot(q): hip-pitch-joint-to-foot-joint distance, mean of both legs (or one ``side``)."""

    def __init__(self, name="L", sides=SIDES, **kw):
        super().__init__(name, **kw)
        self.sides = tuple(sides)
        self._idx = None

    def evaluate(self, dyn):
        if self._idx is None:
            pi = dyn.point_index
            self._idx = [(pi(f"{s}_foot"), pi(f"{s}_hip")) for s in self.sides]
            self._rows = _point_rows(dyn, [f"{s}_{p}" for s in self.sides for p in ("foot", "hip")])
        P, V, A = dyn.point_lists()
        k = 1.0 / len(self.sides)
        L = Ld = dd = 0.0
        coef = []
        for f, h in self._idx:
            (f0, f1, f2), (h0, h1, h2) = P[f], P[h]
            r0, r1, r2 = f0 - h0, f1 - h1, f2 - h2                    # hip -> foot
            Li = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
            n0, n1, n2 = r0 / Li, r1 / Li, r2 / Li
            (f0, f1, f2), (h0, h1, h2) = V[f], V[h]
            v0, v1, v2 = f0 - h0, f1 - h1, f2 - h2
            Ldi = n0 * v0 + n1 * v1 + n2 * v2
            (f0, f1, f2), (h0, h1, h2) = A[f], A[h]
            # d^2|r|/dt^2 = n . a_r + (|v_r|^2 - Ldot^2) / L
            dd += n0 * (f0 - h0) + n1 * (f1 - h1) + n2 * (f2 - h2) + (v0 * v0 + v1 * v1 + v2 * v2 - Ldi * Ldi) / Li
            L += Li
            Ld += Ldi
            coef += [k * n0, k * n1, k * n2, -k * n0, -k * n1, -k * n2]
        y, drift, ydot = _scalars(k * L, k * dd, k * Ld)
        return y, _rows_jacobian(dyn, self._rows, coef), drift, ydot

    def native_spec(self, dyn):
        pi = dyn.point_index
        return "leg_length", [pi(f"{s}_{p}") for s in self.sides for p in ("foot", "hip")], [], 1


class LegAngle(Output):
    """beta_leg(q): sagittal angle of the hip->foot vector from the downward vertical, atan2(r_x, -r_z)."""

    def __init__(self, name="beta_leg", sides=SIDES, **kw):
        super().__init__(name, **kw)
        self.sides = tuple(sides)
        self._idx = None

    def evaluate(self, dyn):
        if self._idx is None:
            pi = dyn.point_index
            self._idx = [(pi(f"{s}_foot"), pi(f"{s}_hip")) for s in self.sides]
            self._rows = np.array([3 * k + i for f, h in self._idx for k in (f, h) for i in (0, 2)])
        P, V, A = dyn.point_lists()
        k = 1.0 / len(self.sides)
        beta = bdot = drift = 0.0
        coef = []
        for f, h in self._idx:
            # (x, z) = hip->foot, z measured downwards
            ang, gx, gz, rate, curv = _atan2_rates(P[f][0] - P[h][0], -(P[f][2] - P[h][2]),
                                                   V[f][0] - V[h][0], -(V[f][2] - V[h][2]))
            beta += ang
            bdot += rate
            drift += gx * (A[f][0] - A[h][0]) - gz * (A[f][2] - A[h][2]) + curv
            coef += [k * gx, -k * gz, -k * gx, k * gz]     # J = gx J_rx - gz J_rz
        y, drift, ydot = _scalars(k * beta, k * drift, k * bdot)
        return y, _rows_jacobian(dyn, self._rows, coef), drift, ydot

    def native_spec(self, dyn):
        pi = dyn.point_index
        return "leg_angle", [pi(f"{s}_{p}") for s in self.sides for p in ("foot", "hip")], [], 1


class ComPosition(Output):
    """x_com(q), y_com(q) (world) from the centroidal map: J = A_g[:3]/m, drift = (dA_g v)[:3]/m."""

    def __init__(self, name="com", axes=(0, 1), **kw):
        super().__init__(name, **kw)
        self.axes = list(axes)
        self.dim = len(self.axes)
        a0 = self.axes[0]
        contiguous = self.axes == list(range(a0, a0 + self.dim))
        self._sel = slice(a0, a0 + self.dim) if contiguous else np.array(self.axes)

    def evaluate(self, dyn):
        s = self._sel
        im = 1.0 / dyn.mass
        y, drift, ydot = np.array((dyn.com[s], dyn.dAg_v[s], dyn.hg_lin[s]))
        drift *= im
        ydot *= im
        return y, dyn.Ag[s] * im, drift, ydot

    def native_spec(self, dyn):
        return "com", list(self.axes), [], self.dim


class PelvisOrientation(Output):
    """ZYX Euler angles (roll phi, pitch theta, yaw psi) of the pelvis; ``axes`` picks among 'roll','pitch','yaw'.

    omega_world = R v[3:6] and omega_world_dot = R vdot[3:6] for the free flyer (omega x omega = 0).
    """
    ORDER = ("roll", "pitch", "yaw")

    def __init__(self, name="pelvis", axes=("pitch", "yaw"), **kw):
        super().__init__(name, **kw)
        self.axes = [self.ORDER.index(a) for a in axes]
        self.dim = len(self.axes)
        self._b = None

    def evaluate(self, dyn):
        if self._b is None:
            self._b = dyn.model.idx_vs[dyn.base_jid]
        b, R = self._b, dyn.R_base
        (r00, r01, r02), (r10, r11, r12), (r20, r21, r22) = R.tolist()
        x, y, z = dyn.v[b + 3:b + 6].tolist()
        w0, w1, w2 = r00 * x + r01 * y + r02 * z, r10 * x + r11 * y + r12 * z, r20 * x + r21 * y + r22 * z
        psi = math.atan2(r10, r00)
        th = math.asin(max(-1.0, min(1.0, -r20)))
        phi = math.atan2(r21, r22)
        cp, sp, ct, st = math.cos(psi), math.sin(psi), math.cos(th), math.sin(th)
        g = cp * w0 + sp * w1
        hh = -sp * w0 + cp * w1
        thd, phid = hh, g / ct
        psid = w2 + st * phid
        d_th = -psid * g
        d_phi = psid * hh / ct + g * st * thd / (ct * ct)
        d_psi = ct * thd * phid + st * d_phi
        E = np.array([[cp / ct, sp / ct, 0.0],            # roll rate  from omega_world
                      [-sp, cp, 0.0],                      # pitch rate
                      [st * cp / ct, st * sp / ct, 1.0]])  # yaw rate
        J = np.zeros((3, dyn.nv))
        np.matmul(E, R, out=J[:, b + 3:b + 6])
        ang, vel, drift = np.array([[phi, th, psi], [phid, thd, psid], [d_phi, d_th, d_psi]])
        if self.dim == 3:
            return ang, J, drift, vel
        a = self.axes
        return ang[a], J[a], drift[a], vel[a]

    def native_spec(self, dyn):
        return "pelvis", [dyn.model.idx_vs[dyn.base_jid], *self.axes], [], self.dim


class JointPositions(Output):
    """Joint angles (hinges) held: q_j - q_j^des; J = selection, drift = 0."""

    def __init__(self, name="joints", joints=(), **kw):
        super().__init__(name, **kw)
        self.joints = list(joints)
        self.dim = len(self.joints)
        self._idx = None

    def evaluate(self, dyn):
        if self._idx is None:
            self._idx = (np.array([dyn.q_index(j) for j in self.joints]), np.array([dyn.v_index(j) for j in self.joints]))
        iq, iv = self._idx
        J = np.zeros((self.dim, dyn.nv))
        J[np.arange(self.dim), iv] = 1.0
        return dyn.q[iq], J, np.zeros(self.dim), dyn.v[iv]

    def native_spec(self, dyn):
        ij = [i for j in self.joints for i in (dyn.q_index(j), dyn.v_index(j))]
        return "joints", ij, [], self.dim


class LegAsymmetry(Output):
    """The legs' departure from mirror symmetry in the sagittal plane: left minus right of hip pitch and
    knee (one leg ahead of, or longer than, the other).  Hip roll and yaw are left out: the pelvis-axis
    hold turns the pelvis with them.  Linear in q: J is constant, the drift 0.  A somersault's FLIGHT
    output (config.DEFAULT_GAINS["leg_symmetry"]; not in the paper)."""

    JOINTS = ("hip_pitch", "knee")
    dim = len(JOINTS)

    def __init__(self, name="leg_symmetry", **kw):
        super().__init__(name, **kw)
        self._idx = None

    def _indices(self, dyn):
        """Per row: (q, v index of the left joint, q, v index of the right one)."""
        if self._idx is None:
            self._idx = [(dyn.q_index(f"left_{j}"), dyn.v_index(f"left_{j}"),
                          dyn.q_index(f"right_{j}"), dyn.v_index(f"right_{j}")) for j in self.JOINTS]
        return self._idx

    def evaluate(self, dyn):
        J = np.zeros((self.dim, dyn.nv))
        y = np.zeros(self.dim)
        for k, (ql, vl, qr, vr) in enumerate(self._indices(dyn)):
            J[k, vl], J[k, vr] = 1.0, -1.0
            y[k] = dyn.q[ql] - dyn.q[qr]
        return y, J, np.zeros(self.dim), J @ dyn.v

    def native_spec(self, dyn):
        return "joint_differences", [i for row in self._indices(dyn) for i in row], [], self.dim


class FootPitch(Output):
    """Toe pitch: angle of the heel->toe line above the horizontal, atan2(z_toe - z_heel, x_toe - x_heel)
    (0 = flat, + = toe up), mean of the feet.  An angle, not its sine (z_toe - z_heel)/l: the sine's
    gradient vanishes as the foot nears vertical, where a frontflip's held foot is at T1
    (docs/tuning.md, Outputs)."""

    def __init__(self, name="toe_pitch", sides=SIDES, **kw):
        super().__init__(name, **kw)
        self.sides = tuple(sides)
        self._idx = None

    def evaluate(self, dyn):
        if self._idx is None:
            pi = dyn.point_index
            self._idx = [(pi(f"{s}_toe"), pi(f"{s}_heel")) for s in self.sides]
            self._rows = np.array([3 * k + i for t, h in self._idx for k in (t, h) for i in (0, 2)])
        P, V, A = dyn.point_lists()
        k = 1.0 / len(self.sides)
        y = drift = vel = 0.0
        coef = []
        for t, h in self._idx:
            # (rise, run) of the heel->toe line
            ang, ga, gb, rate, curv = _atan2_rates(P[t][2] - P[h][2], P[t][0] - P[h][0],
                                                   V[t][2] - V[h][2], V[t][0] - V[h][0])
            y += ang
            vel += rate
            drift += ga * (A[t][2] - A[h][2]) + gb * (A[t][0] - A[h][0]) + curv
            coef += [k * gb, k * ga, -k * gb, -k * ga]            # rows: toe x, toe z, heel x, heel z
        y, drift, ydot = _scalars(k * y, k * drift, k * vel)
        return y, _rows_jacobian(dyn, self._rows, coef), drift, ydot

    def native_spec(self, dyn):
        self.evaluate(dyn)            # point indices (set up on first use)
        return "foot_pitch", [i for t, h in self._idx for i in (t, h)], [], 1


class FootPoints(Output):
    """Swing foot on the ground: world positions of the toe and heel ends of one foot (6 rows).

    Used while a foot that should be on the ground has come off it (``Controller`` per-foot contact):
    it is driven back to where it stood, flat, instead of being modelled as still in contact."""

    dim = 6

    def __init__(self, name="foot", side="left", **kw):
        super().__init__(name, **kw)
        self.side = side
        self._idx = None

    def evaluate(self, dyn):
        if self._idx is None:
            self._idx = np.array([dyn.point_index(f"{self.side}_{k}") for k in ("toe", "heel")])
        i = self._idx
        return dyn.P[i].ravel(), dyn.Jp[i].reshape(6, dyn.nv), dyn.drift[i].ravel(), dyn.pdot[i].ravel()

    def native_spec(self, dyn):
        return "foot_points", [dyn.point_index(f"{self.side}_{k}") for k in ("toe", "heel")], [], 6


class SagittalPitch(Output):
    """Unwrapped sagittal pelvis pitch theta from ``source()`` (the controller's, continued across
    +-pi), degree 2: theta_dot = e_y^T R omega_local (world-y angular velocity), drift 0 (omega x omega = 0)."""

    def __init__(self, name="pitch", source=None, **kw):
        super().__init__(name, **kw)
        self._source = source

    def evaluate(self, dyn):
        b = dyn.model.idx_vs[dyn.base_jid]
        J = np.zeros((1, dyn.nv))
        J[0, b + 3:b + 6] = dyn.data.oMi[dyn.base_jid].rotation[1]
        return np.array([self._source()]), J, np.zeros(1), J @ dyn.v

    def native_spec(self, dyn):
        return "pitch", [dyn.model.idx_vs[dyn.base_jid]], [], 1

    def value(self):
        """The pitch of this tick (``source()``), the compiled task's input."""
        return self._source()


class PelvisAxisTilt(Output):
    """Tilt of the pelvis y axis (the flywheel's axis) out of the world y direction, degree 2:
    y = the world x and z components of r = R e_y (0 when the pelvis turns only about world y, as in
    a somersault).  ydot = (omega x r)_{x,z} = -[r]x R omega_local, yddot = J vdot + (omega x (omega x r))_{x,z}
    with omega = R omega_local (world).  Defined at every pitch, unlike roll and yaw Euler angles."""

    dim = 2

    def evaluate(self, dyn):
        b = dyn.model.idx_vs[dyn.base_jid]
        R = dyn.R_base
        r = R[:, 1]
        w = R @ dyn.v[b + 3:b + 6]
        rx = np.array([[0.0, -r[2], r[1]], [r[2], 0.0, -r[0]], [-r[1], r[0], 0.0]])
        J = np.zeros((2, dyn.nv))
        J[:, b + 3:b + 6] = (-rx @ R)[[0, 2]]
        ydot = np.cross(w, r)
        drift = np.cross(w, ydot)
        return r[[0, 2]].copy(), J, drift[[0, 2]], ydot[[0, 2]]

    def native_spec(self, dyn):
        return "axis", [dyn.model.idx_vs[dyn.base_jid]], [], 2
