"""Momentum-included task space control with the motor torques as the only variables (paper §V-B).

Constraint forces eliminated (eq. (utoF)):   F_v = A_v u + b_v,
    A_v = -(J M^-1 J^T)^-1 J M^-1 B,   b_v = (J M^-1 J^T)^-1 (J M^-1 H - Jdot v),
with H = Coriolis + gravity - J_s^T tau_s - damping (springs moved into H), and J = J_{h,v} the
domain's holonomic constraints (loop closures always, foot contact on the ground).  Then
    qddot = Abar u + bbar,  Abar = M^-1 (B + J^T A_v),  bbar = -M^-1 (H - J^T b_v),
each output's derivative is affine in u (Ydot = cA u + cB) and the QP is
    min_u || W^1/2 (cA u + cB - Ydot_des) ||^2 + reg ||u||^2
    s.t.  C_v A_v u <= c_v - C_v b_v   (GRF, ground domains),   u_lb(qdot) <= u <= u_ub(qdot).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np
from scipy.linalg.lapack import dpotrf, dpotrs

from .limits import grf_constraints


@dataclass
class Desired:
    """Reference of one output: value, first and second time derivatives (arrays of the output's dim)."""
    value: np.ndarray
    d_value: np.ndarray = None
    dd_value: np.ndarray = None


@dataclass
class QPResult:
    u: np.ndarray
    status: str
    forces: np.ndarray          # predicted constraint forces (contact rows first when on the ground)
    qdd: np.ndarray
    solve_time: float
    iterations: int = 0
    y: dict = field(default_factory=dict)   # output errors (name -> Y)


class ConstrainedDynamics:
    """The affine maps F = A u + b and qddot = Abar u + bbar of one tick (paper eq. (utoF) ff.)."""

    def __init__(self, dyn, ground: bool, feet=(True, True)):
        self.ground = ground
        J, dJv = dyn.constraints(ground, feet)
        Minv = dyn.Minv
        nu = dyn.nu
        MiJ = Minv @ J.T                              # M^-1 J^T
        MiB = Minv[:, dyn.motor_v]                    # M^-1 B
        MiH = Minv @ dyn.H
        c, info = dpotrf(J @ MiJ, lower=0, clean=0)   # J M^-1 J^T (full row rank by construction)
        if info != 0:
            raise np.linalg.LinAlgError(f"J M^-1 J^T not positive definite (dpotrf info {info})")
        JMi = MiJ.T
        r = np.empty((J.shape[0], nu + 1))
        r[:, :nu] = JMi[:, dyn.motor_v]               # J M^-1 B
        r[:, nu] = JMi @ dyn.H - dJv                  # J M^-1 H - Jdot v
        Y, info = dpotrs(c, r, lower=0)
        self.A = -Y[:, :nu]
        self.b = Y[:, nu]
        self.Abar = MiB + MiJ @ self.A                # M^-1 (B + J^T A_v)
        self.bbar = MiJ @ self.b - MiH                # -M^-1 (H - J^T b_v)
        self.J, self.dJv, self.nc = J, dJv, J.shape[0]


class _ProxQP:
    """proxsuite dense ProxQP, warm-started from the previous tick (one instance per problem size).

    A warm start from a dissimilar previous problem can make ProxQP report primal infeasibility
    falsely; any non-solved warm-started answer is retried cold."""

    def __init__(self, n, n_in):
        import proxsuite
        self.pq = proxsuite.proxqp
        self.n, self.n_in = n, n_in
        self.qp = None

    def _cold(self, H, g, C, lo, up, lb, ub):
        qp = self.qp = self.pq.dense.QP(self.n, 0, self.n_in, True)
        qp.settings.eps_abs = 1e-7
        qp.settings.eps_rel = 0.0
        qp.settings.verbose = False
        qp.init(H, g, None, None, C, lo, up, lb, ub)
        qp.solve()
        # warm start only once a previous result exists (setting it before the first solve segfaults)
        qp.settings.initial_guess = self.pq.InitialGuess.WARM_START_WITH_PREVIOUS_RESULT

    def solve(self, H, g, C, lo, up, lb, ub):
        solved = self.pq.QPSolverOutput.PROXQP_SOLVED
        if self.qp is None:
            self._cold(H, g, C, lo, up, lb, ub)
        else:
            self.qp.update(H, g, None, None, C, lo, up, lb, ub, update_preconditioner=True)
            self.qp.solve()
            if self.qp.results.info.status != solved:
                self._cold(H, g, C, lo, up, lb, ub)
        r = self.qp.results
        st = r.info.status
        return r.x.copy(), ("solved" if st == solved else str(st).split(".")[-1]), r.info.iter


class _DAQP:
    """DAQP dual active-set (bounds passed as simple bounds)."""

    def __init__(self, n, n_in):
        import daqp
        self.daqp = daqp
        self.n, self.n_in = n, n_in

    def solve(self, H, g, C, lo, up, lb, ub):
        n = self.n
        if C is None or C.shape[0] == 0:
            A = np.zeros((0, n))
            bu, bl = ub, lb
        else:
            A = np.ascontiguousarray(C)
            bu = np.concatenate([ub, up])
            bl = np.concatenate([lb, lo])
        sense = np.zeros(len(bu), dtype=np.int32)
        x, _, flag, info = self.daqp.solve(np.ascontiguousarray(H), g, A, bu, bl, sense)
        return np.asarray(x), ("solved" if flag == 1 else f"daqp_exit_{flag}"), int(info.get("iterations", 0))


SOLVERS = {"proxqp": _ProxQP, "daqp": _DAQP}


class TSC:
    """The torque-only QP of eq. (QP) over a list of outputs."""

    def __init__(self, dyn, solver: str = "daqp", reg: float = 1e-4, mu: float = 0.6, f_min: float = 1.0,
                 cop_margin: float = 0.0):
        self.dyn = dyn
        self.reg = reg
        self.solver_name = solver
        self._solvers = {}
        self.C, self.c = grf_constraints(2, mu, f_min, cop_margin)
        self.C1, self.c1 = grf_constraints(1, mu, f_min, cop_margin)     # one foot in contact
        self._lo = np.full(len(self.c), -1e20)
        self._lo1 = np.full(len(self.c1), -1e20)
        self._w = {}

    def _solver(self, n_in):
        s = self._solvers.get(n_in)
        if s is None:
            s = self._solvers[n_in] = SOLVERS[self.solver_name](self.dyn.nu, n_in)
        return s

    def solve(self, outputs, desired, ground: bool, u_lb, u_ub, feet=(True, True), u_prev=None,
              w_du: float = 0.0) -> QPResult:
        """One QP: outputs (list of Output), desired (list of Desired, same order); ``feet`` (left,
        right): which feet are in contact on the ground (both by default); ``w_du`` > 0 adds
        w_du ||u - u_prev||^2 (torque smoothing)."""
        dyn = self.dyn
        t_a = time.perf_counter()
        n_feet = sum(bool(f) for f in feet) if ground else 0
        ground = ground and n_feet > 0
        dyn.constraints(ground, feet)
        t_b = time.perf_counter()
        cd = ConstrainedDynamics(dyn, ground, feet)
        Js, rhs, errs = [], [], {}
        for out, des in zip(outputs, desired):
            y, Jy, drift, ydot = out.evaluate(dyn)
            e = y - des.value
            dv = 0.0 if des.d_value is None else des.d_value
            if out.degree == 1:
                cmd = dv - out.kp * e                       # Ydot1_des = -K1p Y1
            else:
                ddv = 0.0 if des.dd_value is None else des.dd_value
                cmd = ddv - out.kp * e - out.kd * (ydot - dv)   # Ydd2_des = -K2p Y2 - K2d Ydot2
            errs[out.name] = e
            Js.append(Jy)
            rhs.append(drift - cmd)
        key = tuple(map(id, outputs))
        w = self._w.get(key)
        if w is None:
            w = self._w[key] = np.concatenate([np.broadcast_to(np.asarray(o.weight, float), (j.shape[0],))
                                               for o, j in zip(outputs, Js)])
        Jy = np.concatenate(Js)
        cA = Jy @ cd.Abar                                   # Ydot = cA u + cB
        cB = Jy @ cd.bbar + np.concatenate(rhs)             # cB here already minus Ydot_des
        t_c = time.perf_counter()
        WAt = cA.T * w                                      # A^T W
        H = WAt @ cA
        H.flat[::H.shape[0] + 1] += self.reg + w_du
        g = WAt @ cB
        if w_du > 0.0 and u_prev is not None:
            g = g - w_du * np.asarray(u_prev, float)
        if ground:
            Cg, cg, lo = (self.C, self.c, self._lo) if n_feet == 2 else (self.C1, self.c1, self._lo1)
            nf = Cg.shape[1]
            C = Cg @ cd.A[:nf]
            up = cg - Cg @ cd.b[:nf]
        else:
            C, lo, up = None, None, None
        t0 = time.perf_counter()
        u, status, it = self._solver(0 if C is None else C.shape[0]).solve(H, g, C, lo, up, u_lb, u_ub)
        if status != "solved" or not math.isfinite(u @ u):
            # infeasible GRF set (e.g. at lift-off): keep the torque limits, drop the GRF rows
            u2, st2, it2 = self._solver(0).solve(H, g, None, None, None, u_lb, u_ub)
            if st2 == "solved" and math.isfinite(u2 @ u2):
                u, status, it = u2, status + "->box_only", it + it2
            else:
                u, status = np.clip(np.zeros(dyn.nu), u_lb, u_ub), status + "->zero"
        ts = time.perf_counter() - t0
        F = cd.A @ u + cd.b
        self.last = cd
        res = QPResult(u=u, status=status, forces=F, qdd=cd.Abar @ u + cd.bbar, solve_time=ts, iterations=it, y=errs)
        res.timing = dict(constraints=t_b - t_a, elimination_outputs=t_c - t_b, qp=time.perf_counter() - t_c)
        return res
