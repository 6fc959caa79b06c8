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
from scipy.linalg.lapack import dposv

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
    solve_time: float
    iterations: int = 0
    y: dict = field(default_factory=dict)   # output errors (name -> Y)
    dynamics: ConstrainedDynamics = None

    @property
    def forces(self):
        """Predicted constraint forces F = A u + b (contact rows first when on the ground); worked
        out when asked for (the controller node does not)."""
        return self.dynamics.forces(self.u)

    @property
    def qdd(self):
        """Predicted joint accelerations Abar u + bbar."""
        return self.dynamics.Abar @ self.u + self.dynamics.bbar


class ConstrainedDynamics:
    """The affine maps F = A u + b and qddot = Abar u + bbar of one tick (paper eq. (utoF) ff.).

    One pass over R = [J^T, B, -H]: Y = (J M^-1 J^T)^-1 (J M^-1 [B, -H] + [0, Jdot v]) = -[A, b] and
    X = M^-1 [B, -H] - M^-1 J^T Y = [Abar, bbar].  ``backend`` (default: the Dynamics' own) "native"
    runs it in the compiled tick (Cholesky of J M^-1 J^T as dposv's), "python" in numpy/LAPACK.
    ``arrays=False`` (native only) leaves Y, X, J, Jdot v in the compiled tick, for its task's QP
    terms, and none here: no forces, A, b, Abar or bbar from this object."""

    def __init__(self, dyn, ground: bool, feet=(True, True), backend: str | None = None, arrays: bool = True):
        self.ground = ground
        native = (backend or dyn.backend) == "native"
        if native and not arrays:
            ok = dyn.native.eliminate_in_place(dyn.row_set(ground, feet))
            self.Y = self.X = J = dJv = nc = None
        elif native:
            ok, self.Y, self.X, J, dJv = dyn.native.eliminate(dyn.row_set(ground, feet))
            nc = J.shape[0]
        if native:
            if not ok:
                raise np.linalg.LinAlgError("J M^-1 J^T not positive definite (native Cholesky)")
        else:
            J, dJv = dyn.constraints(ground, feet)
            nc = J.shape[0]
            MiR = dyn.Minv @ np.concatenate((J.T, dyn.BH), axis=1)     # [M^-1 J^T, M^-1 B, -M^-1 H]
            JMiR = J @ MiR
            JMiR[:, -1] += dJv
            _, self.Y, info = dposv(JMiR[:, :nc], JMiR[:, nc:], lower=0)   # J M^-1 J^T: full row rank by construction
            if info != 0:
                raise np.linalg.LinAlgError(f"J M^-1 J^T not positive definite (dposv info {info})")
            self.X = MiR[:, nc:] - MiR[:, :nc] @ self.Y
        self.J, self.dJv, self.nc, self.nu = J, dJv, nc, dyn.nu

    @property
    def A(self):
        return -self.Y[:, :self.nu]

    @property
    def b(self):
        return -self.Y[:, self.nu]

    @property
    def Abar(self):
        return self.X[:, :self.nu]

    @property
    def bbar(self):
        return self.X[:, self.nu]

    def forces(self, u):
        """F = A u + b."""
        if self.Y is None:
            raise ValueError("constraint forces not kept: eliminated with arrays=False (details=False)")
        F = self.Y[:, :self.nu] @ u
        F += self.Y[:, self.nu]
        return np.negative(F, out=F)


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
        self._bu = np.empty(n + n_in)
        self._bl = np.empty(n + n_in)
        self._sense = np.zeros(n + n_in, dtype=np.int32)
        self._A0 = np.zeros((0, n))

    def solve(self, H, g, C, lo, up, lb, ub):
        n, bu, bl = self.n, self._bu, self._bl
        if C is None or C.shape[0] == 0:
            A = self._A0
            bu, bl = ub, lb
        else:
            A = np.ascontiguousarray(C)
            bu[:n] = ub
            bu[n:] = up
            bl[:n] = lb
            bl[n:] = lo
        x, _, flag, info = self.daqp.solve(np.ascontiguousarray(H), g, A, bu, bl, self._sense[:len(bu)])
        return np.asarray(x), ("solved" if flag == 1 else f"daqp_exit_{flag}"), int(info.get("iterations", 0))


class _OSQP:
    """OSQP (ADMM, through its own API): H (dense, its upper triangle) and [C; I] keep the same
    pattern from tick to tick, so the solver is set up once per problem size and then updated and
    warm-started; tolerances 1e-8 (no polishing: it prints to stdout whatever the verbosity)."""

    def __init__(self, n, n_in):
        import osqp
        from scipy import sparse
        self.osqp, self.n, self.n_in = osqp, n, n_in
        self.prob = None
        rows, cols = np.triu_indices(n)
        self._P, self._Pidx = self._pattern(sparse, rows, cols, (n, n))
        ar, ac = np.divmod(np.arange((n_in + n) * n), n)
        self._A, self._Aidx = self._pattern(sparse, ar, ac, (n_in + n, n))
        self._Ad = np.zeros((n_in + n, n))
        self._Ad[n_in:] = np.eye(n)

    @staticmethod
    def _pattern(sparse, rows, cols, shape):
        """A CSC matrix with every (row, col) stored (zeros too) and, per stored entry, the flat
        row-major index of the dense matrix it comes from."""
        m = sparse.csc_matrix((np.arange(1, len(rows) + 1, dtype=float), (rows, cols)), shape=shape)
        order = m.data.astype(int) - 1
        return m, rows[order] * shape[1] + cols[order]

    def solve(self, H, g, C, lo, up, lb, ub):
        n_in = self.n_in
        if n_in:
            self._Ad[:n_in] = C
            lower, upper = np.concatenate([lo, lb]), np.concatenate([up, ub])
        else:
            lower, upper = np.asarray(lb, float), np.asarray(ub, float)
        Px, Ax = np.asarray(H, float).ravel()[self._Pidx], self._Ad.ravel()[self._Aidx]
        if self.prob is None:
            self._P.data[:], self._A.data[:] = Px, Ax
            self.prob = self.osqp.OSQP()
            self.prob.setup(self._P, np.asarray(g, float), self._A, lower, upper, eps_abs=1e-8,
                            eps_rel=1e-8, polishing=False, verbose=False, warm_starting=True, max_iter=20000)
        else:
            self.prob.update(q=np.asarray(g, float), l=lower, u=upper, Px=Px, Ax=Ax)
        r = self.prob.solve(raise_error=False)    # a failed solve is a status, as for the other solvers
        st = str(r.info.status)
        ok = st.startswith("solved") and r.x is not None
        # ADMM meets the bounds to its tolerance only (~1e-5 N·m over): the torques onto them exactly
        return (np.clip(np.asarray(r.x, float), lb, ub) if ok else np.full(self.n, np.nan),
                "solved" if ok else f"osqp_{st}", int(r.info.iter))


SOLVERS = {"proxqp": _ProxQP, "daqp": _DAQP, "osqp": _OSQP}


class _Task:
    """Per output list (cached): stacked weights and gains, row slices.  Gains are read when the list
    is first seen, weights whenever one has changed (a weight may vary in time); degree-1 rows get
    kd = 0 (their command has no velocity term)."""

    def __init__(self, outputs, evaluated):
        self.outputs = tuple(outputs)          # keeps the ids of the cache key alive
        self.dims = [ev[1].shape[0] for ev in evaluated]
        self.m = sum(self.dims)
        self.kp, self.kd = (
            np.concatenate([np.broadcast_to(np.asarray(g(o), float), (d,)) for o, d in zip(outputs, self.dims)])
            for g in (lambda o: o.kp, lambda o: o.kd if o.degree == 2 else 0.0))
        self._weights, self._w = None, None      # stacked by ``w`` on first use
        ends = np.cumsum(self.dims).tolist()
        self.slices = [(o.name, slice(e - d, e)) for o, d, e in zip(outputs, self.dims, ends)]
        self.deg1 = [o.degree == 1 for o in outputs]
        self.zeros = [np.zeros(d) for d in self.dims]
        self.native = None

    @property
    def w(self):
        """Row weights: re-read when an output's weight has changed (a weight may vary in time)."""
        ws = tuple(o.weight for o in self.outputs)
        if ws != self._weights:
            self._weights = ws
            self._w = np.concatenate([np.full(d, float(w_)) for w_, d in zip(ws, self.dims)])
        return self._w

    def compile(self, dyn):
        """The compiled task rows of this list (native backend, every output with a compiled form):
        ``native`` (tsc_controller._native.TaskRows), its buffers y, drift, ydot as attributes, and the
        outputs whose value the controller gives (SagittalPitch).  It keeps kp, kd of this list."""
        from . import _native

        def owner(cls, name):
            return next(c for c in cls.__mro__ if name in vars(c))
        # a subclass that re-defines evaluate but not native_spec has no compiled form
        if any(owner(type(o), "native_spec") is not owner(type(o), "evaluate") for o in self.outputs):
            return
        specs = [o.native_spec(dyn) for o in self.outputs]
        if any(sp is None for sp in specs):
            return
        assert [sp[3] for sp in specs] == self.dims, "native_spec dims differ from evaluate's"
        self.native = _native.TaskRows(specs, dyn.nv, dyn.nu, self.kp, self.kd)
        b = self.native.buffers()
        self.y, self.drift, self.ydot = b["y"], b["drift"], b["ydot"]
        self.valued = [o for o, sp in zip(self.outputs, specs) if sp[0] == "pitch"]

    def vectors(self, evaluated, desired):
        """y, value, feed-forward (d_value for degree 1, dd_value for 2), ydot, d_value, drift as the rows
        of one 6 x m array (missing derivatives are 0; scalars broadcast over their output)."""
        z = self.zeros
        parts = [e[0] for e in evaluated]
        parts += [d.value for d in desired]
        dv = [zk if d.d_value is None else d.d_value for d, zk in zip(desired, z)]
        parts += [v if deg1 else (zk if d.dd_value is None else d.dd_value)
                  for v, d, zk, deg1 in zip(dv, desired, z, self.deg1)]
        parts += [zk if deg1 else e[3] for e, zk, deg1 in zip(evaluated, z, self.deg1)]
        parts += dv
        parts += [e[2] for e in evaluated]
        try:
            return np.concatenate(parts).reshape(6, self.m)
        except ValueError:
            dims = self.dims * 6
            return np.concatenate([np.broadcast_to(np.asarray(p, float), (d,)) for p, d in zip(parts, dims)]
                                  ).reshape(6, self.m)


class TSC:
    """The torque-only QP of eq. (QP) over a list of outputs."""

    def __init__(self, dyn, solver: str = "daqp", reg: float = 1e-4, mu: float = 0.6, f_min: float = 1.0,
                 cop_margin: float = 0.0):
        self.dyn = dyn
        self.reg = reg
        self.solver_name = solver
        self._solvers = {}
        self.mu, self.f_min, self.cop_margin = mu, f_min, cop_margin
        self._grf = {}
        for n_feet in (1, 2):                     # built now, not on the first tick
            self._grf_rows(n_feet, cop_margin)
        self._tasks = {}

    def _grf_rows(self, n_feet, cop_margin, f_min=None):
        """(C, c, lower) of :func:`grf_constraints` for n_feet, a CoP margin and a least normal force
        (None: the constructor's), built once."""
        f_min = self.f_min if f_min is None else f_min
        key = (n_feet, cop_margin, f_min)
        if key not in self._grf:
            C, c = grf_constraints(n_feet, self.mu, f_min, cop_margin)
            self._grf[key] = (C, c, np.full(len(c), -1e20))
        return self._grf[key]

    def _solver(self, n_in):
        s = self._solvers.get(n_in)
        if s is None:
            s = self._solvers[n_in] = SOLVERS[self.solver_name](self.dyn.nu, n_in)
        return s

    def _task(self, outputs):
        """The cached :class:`_Task` of an output list (compiled with the native backend)."""
        key = tuple(map(id, outputs))
        task = self._tasks.get(key)
        if task is None:
            task = self._tasks[key] = _Task(outputs, [o.evaluate(self.dyn) for o in outputs])
            if self.dyn.backend == "native":
                task.compile(self.dyn)
        return task

    def _task_rows(self, outputs, desired):
        """Stacked output Jacobian Jy, rhs = drift - commanded derivative (eq. (Ydes)), errors by name:
        Ydot1_des = dv - K1p Y1,  Ydd2_des = ddv - K2p Y2 - K2d (ydot - dv)."""
        task = self._task(outputs)
        ev = [o.evaluate(self.dyn) for o in outputs]
        y, val, ff, ydot, dv, drift = task.vectors(ev, desired)
        e = y - val
        rhs = drift - (ff - task.kp * e - task.kd * (ydot - dv))
        errs = {name: e[sl] for name, sl in task.slices}
        return np.concatenate([x[1] for x in ev]), rhs, errs, task.w

    def _native_terms(self, task, desired, grf, w_du, u_prev, details=True):
        """The QP terms of :meth:`solve` from the compiled task rows: outputs evaluated at the tick,
        rhs and errors here (the errors by name only with ``details``), then H, g (and, with ``grf`` =
        (C_v, c_v, lower) on the ground, the GRF rows C, up) from the last elimination."""
        dyn = self.dyn
        task.native.evaluate(dyn.native, [o.value() for o in task.valued])
        e = task.native.errors(desired, task.deg1)         # the rhs stays in the compiled task
        errs = {name: e[sl] for name, sl in task.slices} if details else {}
        t_c = time.perf_counter()
        shift = w_du * np.asarray(u_prev, float) if w_du > 0.0 and u_prev is not None else None
        if grf is None:
            H, g = task.native.qp(dyn.native, None, task.w, self.reg + w_du, shift, None, None)
            return H, g, None, None, None, errs, t_c
        Cg, cg, lo = grf
        H, g, C, up = task.native.qp(dyn.native, None, task.w, self.reg + w_du, shift, Cg, cg)
        return H, g, C, lo, up, errs, t_c

    def solve(self, outputs, desired, ground: bool, u_lb, u_ub, feet=(True, True), u_prev=None,
              w_du: float = 0.0, cop_margin: float | None = None, details: bool = True,
              f_min: float | None = None, du_share=None, rows=None) -> QPResult:
        """One QP: outputs (list of Output), desired (list of Desired, same order); ``feet`` (left,
        right): which feet are in contact on the ground (both by default); ``w_du`` > 0 adds
        w_du ||u - u_prev||^2 (torque smoothing), each motor's term times its ``du_share`` (None: all 1);
        ``cop_margin`` and ``f_min`` override the constructor's; ``rows`` = (C_x, up_x): more rows
        C_x u <= up_x on the torques (the LANDING's flywheel cap, limits.speed_cap_row), kept when the GRF
        rows are dropped.
        ``details=False`` (compiled task rows only): the same u, without the output errors (``y``)
        and the elimination's arrays (no ``forces``, ``qdd``) in the result."""
        dyn = self.dyn
        nu = dyn.nu
        t_a = time.perf_counter()
        n_feet = sum(bool(f) for f in feet) if ground else 0
        ground = ground and n_feet > 0
        if dyn.native is None:                # (native: the rows came with the tick's update)
            dyn.constraints(ground, feet)
        t_b = time.perf_counter()
        task = self._task(outputs)
        lean = not details and task.native is not None
        cd = ConstrainedDynamics(dyn, ground, feet, arrays=not lean)
        grf = self._grf_rows(n_feet, self.cop_margin if cop_margin is None else cop_margin, f_min) if ground else None
        if task.native is not None:
            H, g, C, lo, up, errs, t_c = self._native_terms(task, desired, grf, w_du, u_prev, not lean)
        else:
            Jy, rhs, errs, w = self._task_rows(outputs, desired)
            G = Jy @ cd.X                                       # [cA, Jy bbar]: Ydot = cA u + Jy bbar + drift
            cA = G[:, :nu]
            cB = G[:, nu] + rhs                                 # cB here already minus Ydot_des
            t_c = time.perf_counter()
            WAt = cA.T * w                                      # A^T W
            H = WAt @ cA
            H.ravel()[::nu + 1] += self.reg + w_du
            g = WAt @ cB
            if w_du > 0.0 and u_prev is not None:
                g -= w_du * np.asarray(u_prev, float)
            if grf is not None:
                Cg, cg, lo = grf
                CY = Cg @ cd.Y[:Cg.shape[1]]                    # -[C_v A, C_v b]
                C = np.negative(CY[:, :nu])
                up = cg + CY[:, nu]
            else:
                C, lo, up = None, None, None
        if du_share is not None and w_du > 0.0 and u_prev is not None:
            d = w_du * (1.0 - np.asarray(du_share, float))     # the smoothing taken off again per motor
            H = np.array(H, float)
            H.ravel()[::nu + 1] -= d
            g = np.asarray(g, float) + d * np.asarray(u_prev, float)
        Cx = lox = upx = None
        if rows is not None:
            Cx, upx = np.atleast_2d(rows[0]), np.atleast_1d(rows[1])
            lox = np.full(len(upx), -1e20)
            if C is not None:
                C, lo, up = np.vstack((C, Cx)), np.concatenate((lo, lox)), np.concatenate((up, upx))
            else:
                C, lo, up = Cx, lox, upx
        t0 = time.perf_counter()
        u, status, it = self._solver(0 if C is None else C.shape[0]).solve(H, g, C, lo, up, u_lb, u_ub)
        if status != "solved" or not math.isfinite(u @ u):
            # infeasible GRF set (e.g. at lift-off): keep the torque limits (and ``rows``), drop the GRF rows
            n_x = 0 if Cx is None else Cx.shape[0]
            u2, st2, it2 = self._solver(n_x).solve(H, g, Cx, lox, upx, u_lb, u_ub)
            if st2 == "solved" and math.isfinite(u2 @ u2):
                u, status, it = u2, status + "->box_only", it + it2
            else:
                u, status = np.clip(np.zeros(nu), u_lb, u_ub), status + "->zero"
        ts = time.perf_counter() - t0
        self.last = cd
        res = QPResult(u=u, status=status, solve_time=ts, iterations=it, y=errs, dynamics=cd)
        res.timing = dict(constraints=t_b - t_a, elimination_outputs=t_c - t_b, qp=time.perf_counter() - t_c)
        return res
