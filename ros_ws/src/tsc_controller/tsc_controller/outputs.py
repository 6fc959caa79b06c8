"""Outputs (paper §V-A) as small task classes, mink style.

Each output evaluates, from an updated :class:`~tsc_controller.dynamics.Dynamics`, its actual value
``y(q, v)``, its Jacobian ``J`` w.r.t. v (so d/dt of the relative-degree quantity is ``J vdot + drift``),
the drift ``Jdot v`` and, for relative degree 2, its velocity ``J v``:

* relative degree 1 (momenta, eq. Y_1):   y = J v,        ydot  = J vdot + drift
* relative degree 2 (positions, eq. Y_2): y = h(q),  ydot = J v,  yddot = J vdot + drift

The desired values come from the reference (``value, d_value, dd_value``); the TSC forms
Y = y - y_des and the commanded derivative of eq. (Ydes): Ydot1_des = -K1p Y1, Ydd2_des = -K2p Y2 - K2d Ydot2.
"""
from __future__ import annotations

import math

import numpy as np

from .dynamics import SIDES, Dynamics, cross3


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


class CentroidalPitchMomentum(Output):
    """H_pitch(q, v): centroidal angular momentum about the COM, world y (eq. Y_1^{J/L}); degree 1."""
    degree = 1

    def evaluate(self, dyn):
        J = dyn.Ag[4:5]
        return J @ dyn.v, J, dyn.dAg_v[4:5], None


class FlywheelMomentum(Output):
    """H_flywheel(q, v) = I_axis * (world-y angular velocity of the flywheel) (eq. Y_1^F); degree 1.

    omega_fw = R_pelvis (omega_pelvis_local + a qdot_fw), a the wheel axis in the pelvis frame;
    d/dt(e_y^T omega_fw) = e_y^T R (omega_l_dot + a qddot_fw) + e_y^T R (omega_l x a qdot_fw).
    """
    degree = 1

    def __init__(self, name="H_flywheel", **kw):
        super().__init__(name, **kw)

    def evaluate(self, dyn):
        m = dyn.model
        jid = dyn._jid["flywheel"]
        if not hasattr(self, "_I"):
            jm = m.joints[jid]
            # hinge axis of the flywheel in its parent (pelvis) frame
            S = jm.shortname()
            ax = {"JointModelRX": [1, 0, 0], "JointModelRY": [0, 1, 0], "JointModelRZ": [0, 0, 1]}.get(S)
            if ax is None:
                ax = list(jm.axis) if hasattr(jm, "axis") else [0, 1, 0]
            ax_local = np.array(ax, float)
            self._a = m.jointPlacements[jid].rotation @ ax_local
            self._I = float(ax_local @ m.inertias[jid].inertia @ ax_local)
            self._iv = m.idx_vs[jid]
            self._base_v = m.idx_vs[dyn.base_jid]
        R = dyn.data.oMi[dyn.base_jid].rotation
        b = self._base_v
        ey_R = R[1]                          # e_y^T R
        J = np.zeros((1, dyn.nv))
        J[0, b + 3:b + 6] = self._I * ey_R
        J[0, self._iv] = self._I * (ey_R @ self._a)
        wl = dyn.v[b + 3:b + 6]
        drift = self._I * (ey_R @ cross3(wl, self._a * dyn.v[self._iv]))
        return J @ dyn.v, J, np.array([drift]), None


def leg_vector(dyn, side):
    """hip (hip-pitch joint origin) -> foot (foot joint origin) vector, its J, drift, velocity."""
    ph, Jh, dh, vh, _ = dyn.point(f"{side}_hip")
    pf, Jf, df, vf, _ = dyn.point(f"{side}_foot")
    return pf - ph, Jf - Jh, df - dh, vf - vh


def _leg_length(dyn, side):
    r, Jr, dr, vr = leg_vector(dyn, side)
    L = math.sqrt(r @ r)
    n = r / L
    J = n @ Jr
    Ldot = n @ vr
    drift = n @ dr + (vr @ vr - Ldot * Ldot) / L
    return L, J, drift, Ldot


class LegLength(Output):
    """L_robot(q): hip-pitch-joint-to-foot-joint distance, mean of both legs (or one ``side``)."""

    def __init__(self, name="L", sides=SIDES, **kw):
        super().__init__(name, **kw)
        self.sides = tuple(sides)
        self._idx = None

    def evaluate(self, dyn):
        if self._idx is None:
            ix = dyn._pt_index
            self._idx = ([ix[f"{s}_foot"] for s in self.sides], [ix[f"{s}_hip"] for s in self.sides])
        if dyn._tab is None:
            dyn._point_table()
        P, Jp, drift, pdot, _ = dyn._tab
        k = 1.0 / len(self.sides)
        L = Ld = dd = 0.0
        J = 0.0
        for f, h in zip(*self._idx):
            r = P[f] - P[h]                              # hip -> foot
            Li = math.sqrt(r @ r)
            n = r / Li
            vr = pdot[f] - pdot[h]
            Ldi = n @ vr
            J = J + n @ (Jp[f] - Jp[h])
            # d^2|r|/dt^2 = n . a_r + (|v_r|^2 - Ldot^2) / L
            dd += n @ (drift[f] - drift[h]) + (vr @ vr - Ldi * Ldi) / Li
            L += Li
            Ld += Ldi
        return np.array([k * L]), (k * J)[None], np.array([k * dd]), np.array([k * Ld])


class LegAngle(Output):
    """beta_leg(q): sagittal angle of the hip->foot vector from the downward vertical, atan2(r_x, -r_z)."""

    def __init__(self, name="beta_leg", sides=SIDES, **kw):
        super().__init__(name, **kw)
        self.sides = tuple(sides)

    def evaluate(self, dyn):
        acc = [0.0, 0.0, 0.0, 0.0]
        for s in self.sides:
            r, Jr, dr, vr = leg_vector(dyn, s)
            x, z = r[0], -r[2]
            rho2 = x * x + z * z
            gx, gz = z / rho2, -x / rho2             # d beta / d(x, z)
            J = gx * Jr[0] - gz * Jr[2]
            xd, zd = vr[0], -vr[2]
            bd = gx * xd + gz * zd
            # second-order term: d/dt(gx) xd + d/dt(gz) zd
            dgx = (zd * rho2 - z * 2 * (x * xd + z * zd)) / rho2 ** 2
            dgz = (-xd * rho2 + x * 2 * (x * xd + z * zd)) / rho2 ** 2
            drift = gx * dr[0] - gz * dr[2] + dgx * xd + dgz * zd
            acc[0] += math.atan2(x, z)
            acc[1] = acc[1] + J
            acc[2] += drift
            acc[3] += bd
        k = 1.0 / len(self.sides)
        return np.array([k * acc[0]]), (k * acc[1])[None], np.array([k * acc[2]]), np.array([k * acc[3]])


class ComPosition(Output):
    """x_com(q), y_com(q) (world) from the centroidal map: J = A_g[:3]/m, drift = (dA_g v)[:3]/m."""

    def __init__(self, name="com", axes=(0, 1), **kw):
        super().__init__(name, **kw)
        self.axes = list(axes)
        self.dim = len(self.axes)

    def evaluate(self, dyn):
        a0, a1 = self.axes[0], self.axes[-1] + 1
        if a1 - a0 != self.dim:
            c, J, d = dyn.com_terms()
            J = J[self.axes]
            return c[self.axes].copy(), J, d[self.axes], J @ dyn.v
        im = 1.0 / dyn.mass
        J = dyn.Ag[a0:a1] * im
        return dyn.data.com[0][a0:a1].copy(), J, dyn.dAg_v[a0:a1] * im, dyn.hg_lin[a0:a1] * im


class PelvisOrientation(Output):
    """ZYX Euler angles (roll phi, pitch theta, yaw psi) of the pelvis; ``axes`` picks among 'roll','pitch','yaw'.

    omega_world = R v[3:6] and omega_world_dot = R vdot[3:6] for the free flyer (omega x omega = 0).
    """
    ORDER = ("roll", "pitch", "yaw")

    def __init__(self, name="pelvis", axes=("pitch", "yaw"), **kw):
        super().__init__(name, **kw)
        self.axes = [self.ORDER.index(a) for a in axes]
        self.dim = len(self.axes)

    def evaluate(self, dyn):
        b = dyn.model.idx_vs[dyn.base_jid]
        R = dyn.data.oMi[dyn.base_jid].rotation
        w0, w1, w2 = (R @ dyn.v[b + 3:b + 6]).tolist()
        (r00, _, _), (r10, _, _), (r20, r21, r22) = R.tolist()
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
        J[:, b + 3:b + 6] = E @ R
        ang = np.array([phi, th, psi])
        vel = np.array([phid, thd, psid])
        drift = np.array([d_phi, d_th, d_psi])
        if self.dim == 3:
            return ang, J, drift, vel
        a = self.axes
        return ang[a], J[a], drift[a], vel[a]


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
        return dyn.q[iq].copy(), J, np.zeros(self.dim), dyn.v[iv].copy()


class FootPitch(Output):
    """Toe pitch: (z_toe - z_heel)/l_foot (sine of the foot-line pitch, 0 = flat), mean of both feet."""

    def __init__(self, name="toe_pitch", sides=SIDES, **kw):
        super().__init__(name, **kw)
        self.sides = tuple(sides)

    def evaluate(self, dyn):
        y = J = dr = vel = 0.0
        for s in self.sides:
            pt, Jt, dt_, vt, _ = dyn.point(f"{s}_toe")
            ph, Jh, dh, vh, _ = dyn.point(f"{s}_heel")
            ell = float(np.linalg.norm(dyn.model.frames[dyn.points[f"{s}_toe"].frame_id].placement.translation
                                       - dyn.model.frames[dyn.points[f"{s}_heel"].frame_id].placement.translation))
            y += (pt[2] - ph[2]) / ell
            J = J + (Jt[2] - Jh[2]) / ell
            dr += (dt_[2] - dh[2]) / ell
            vel += (vt[2] - vh[2]) / ell
        k = 1.0 / len(self.sides)
        return np.array([k * y]), (k * J)[None], np.array([k * dr]), np.array([k * vel])


class FootPoints(Output):
    """Swing foot on the ground: world positions of the toe and heel ends of one foot (6 rows).

    Used while a foot that should be on the ground has come off it (``Controller`` per-foot contact):
    it is driven back to where it stood, flat, instead of being modelled as still in contact."""

    dim = 6

    def __init__(self, name="foot", side="left", **kw):
        super().__init__(name, **kw)
        self.side = side

    def evaluate(self, dyn):
        ys, Js, ds, vs = [], [], [], []
        for k in ("toe", "heel"):
            p, J, d, v, _ = dyn.point(f"{self.side}_{k}")
            ys.append(p)
            Js.append(J)
            ds.append(d)
            vs.append(v)
        return np.concatenate(ys), np.vstack(Js), np.concatenate(ds), np.concatenate(vs)
