"""The per-tick terms of :class:`dynamics.Dynamics` in numpy (``backend="python"``): the reference the
compiled tick (``tsc_controller._native``) is tested against; the formulas are in :mod:`dynamics`'s
module doc."""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin

# p @ _SKEW -> [p]x, row-major: [[0, -p2, p1], [p2, 0, -p0], [-p1, p0, 0]]
_SKEW = np.zeros((3, 9))
_SKEW[2, 1] = _SKEW[0, 5] = _SKEW[1, 6] = -1.0
_SKEW[1, 2] = _SKEW[2, 3] = _SKEW[0, 7] = 1.0


def skew(p):
    """[p]x of each row of a k x 3 array, k x 3 x 3."""
    return (p @ _SKEW).reshape(-1, 3, 3)


class PythonTick:
    """Dynamics's numpy tick: :meth:`_update_python` (its :meth:`update` without the native backend) and
    the constraint rows it builds on demand (:meth:`_constraint_rows`)."""

    def _update_python(self, q, v):
        """:meth:`update` in numpy (the reference implementation)."""
        model, data = self.model, self.data
        self.q, self.v = q, v
        self.Minv = pin.computeMinverse(model, data, q)     # full symmetric M^-1 (pin >= 3)
        h = pin.nonLinearEffects(model, data, q, v)
        tau_p = self._neg_D * v + self._Kq @ (q - self.q_spring)
        self.tau_passive = tau_p                 # J_s^T tau_s (springs) and joint damping
        np.subtract(tau_p, h, out=self.BH[:, -1])   # -H, H of eq. (1) with the passive torques moved in
        pin.dccrba(model, data, q, v)            # returns dA_g; sets data.Ag, data.J, data.dJ, data.oMi
        self.Ag = data.Ag
        self.dAg_v = data.dAg @ v
        self.hg = self.Ag @ v                    # centroidal momentum (linear = m * COM velocity)
        self.hg_lin = self.hg[:3]
        pin.updateFramePlacements(model, data)
        self._point_table(v)
        self._rows = None
        self._lists = None
        return self

    def _point_table(self, v):
        """Positions P, world-aligned Jacobians Jp (linear part), drifts and velocities pdot of every
        point (module doc; loop points' drifts relative to the loop's body 1); the joint placements."""
        data = self.data
        oMi = data.oMi.tolist()
        Hj = np.array([oMi[j].homogeneous for j in self._tj])                      # joints x 4 x 4
        self._Hj = Hj
        self.R_base = Hj[self._tj_base, :3, :3]
        P = np.take(Hj.reshape(-1, 4) @ self._pt_L, self._pt_take).reshape(-1, 3)
        Sk = skew(P)
        n, nv = len(P), self.nv
        self._pt_rows = rows = np.empty((3 * n, nv + 1))     # [stacked J_p, stacked drifts]
        Jp, drift = rows[:, :nv].reshape(n, 3, nv), rows[:, nv].reshape(n, 3)
        J = data.J
        np.matmul(Sk, J[3:], out=Jp)
        np.subtract(J[:3], Jp, out=Jp)
        Jp *= self._pt_mask
        pdot = Jp @ v
        acc = ((data.dJ * v) @ self._pt_support).T                                # (a_O, alpha) per point
        w = ((J[3:] * v) @ self._pt_support_w).T                                  # omega, omega - omega_1
        np.subtract(acc[:, :3], (Sk @ acc[:, 3:, None])[:, :, 0], out=drift)
        drift -= (skew(pdot) @ w[n:, :, None])[:, :, 0]
        self.P, self.Jp, self.drift, self.pdot, self.omega = P, Jp, drift, pdot, w[:n]

    def _constraint_rows(self):
        """[J, Jdot v] of all constraint rows of the tick: contact (both feet) | loops | springs."""
        T = self._T
        cs = []
        Pxy = self.P[self._contact_idx, :2].tolist()
        for f in range(2):
            (tx, ty), (hx, hy) = Pxy[2 * f], Pxy[2 * f + 1]
            dx, dy = tx - hx, ty - hy
            nrm = math.sqrt(dx * dx + dy * dy)
            c, s = dx / nrm, dy / nrm
            cs += [c, s, -s, c, -s, c]
        Tf = self._T_flat
        Tf[self._cs_idx] = cs
        R = self._Hj[self._loop_R, :3, :3]
        Tf[self._loop_put] = np.take(self._loop_S @ R.transpose(0, 2, 1), self._loop_take)
        nr = T.shape[0]
        Jd = np.empty((nr + self._spring_rows, self.nv + 1))
        np.matmul(T, self._pt_rows, out=Jd[:nr])
        Jd[nr:] = self._spring_Jd
        self._rows = Jd
        return Jd
