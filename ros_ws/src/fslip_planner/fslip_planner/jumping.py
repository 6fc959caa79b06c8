"""Jumping optimisation on the FSLIP (paper §III-B): direct transcription, trapezoidal
integration, CasADi Opti + IPOPT, free final time.

Decision variables: X = [x, z, ẋ, ż, H] (5×N), U = [F^s, τ, u] (3×N), T (stance duration).
Constraints (every knot): trapezoidal dynamics; start standing at rest on the nominal leg length
(F^s = m g, τ = u = 0); L_min ≤ L ≤ L_max (L = r + F^s/K, computed); F^s ≥ 0; F_z ≥ 0; friction
cone |F_x| ≤ μ F_z; ZMP |u| ≤ F_z l/2; flywheel |τ| ≤ τ_max (see below); leg force
F^s ≤ F_max(L) = 2 τ_knee,max |dq_knee/dL| and, with the knee's torque–speed envelope
(:func:`cassie_model.motor_limits.planning_rows` at r = |dq_knee/dL| ṙ / ω₀; ṙ ≥ L̇ while the spring
unloads: conservative), F^s ≤ F_max(L) (1 − r) pushing and F^s ≤ 2 F_max(L) (1 + r) compressing;
with ``FSLIPParams.knee_tangential`` the knees' share F^s + ρ(L) f_t (f_t = (τ+u)/r) in place of F^s in
these rows (the knee torque of the tangential force too, regression ``rho``);
lift-off at the last knot: F_z = F_x = u = 0 (⇔ F^s = τ = u = 0); before that the feet stay loaded,
F_z ≥ ½ m g ramping to 0 over the last 3 knots (the robot's contact detector must not see an early
lift-off, e.g. in a free-fall crouch).
Task (lift-off state): T_flight = (ż + √(ż² + 2 g h_p))/g (= 2ż/g on flat ground);
θ̇·T_flight = ±2π − 2β (eq. taskEncoding; θ̇ = H/I(L)); COM apex z + ż²/2g + com_h = apex;
forward distance 2x + ẋ T_flight = d (foot-to-foot, the landing mirroring the lift-off).

Flywheel torque bound: τ is the whole-body pitch torque (Ḣ).  During stance the pelvis follows the
leg angle β (slowly), so nearly all of Ḣ is absorbed by the flywheel, whose motor gives at most
195 N·m; the two hip-pitch motors (2 × 195.2 N·m) that pass this torque from the legs to the pelvis
are not tighter.  Hence |τ| ≤ τ_fw,max.
Cost: Σ (c₁ L̈² + c₂ u² + c₃ τ²) ΔT (L̈ by second differences of the computed L).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Optional

import numpy as np
from cassie_model.motor_limits import planning_rows

from . import fslip as F

SIGN = {"backflip": -1.0, "frontflip": 1.0, "hop": 0.0}
COST = dict(c1=1e-3, c2=1e-2, c3=1e-4)
IPOPT_OPTS = {"expand": True, "ipopt.print_level": 0, "print_time": 0, "ipopt.sb": "yes", "ipopt.max_iter": 600,
              "ipopt.tol": 1e-6, "ipopt.acceptable_tol": 1e-4, "ipopt.mu_strategy": "adaptive"}


@dataclass
class Solution:
    """Knot trajectories of a solved FSLIP problem."""
    t: np.ndarray
    X: np.ndarray          # (N, 5)
    U: np.ndarray          # (N, 3)
    L: np.ndarray
    Fx: np.ndarray
    Fz: np.ndarray
    solve_time: float
    iterations: int
    status: str
    params: F.FSLIPParams = field(repr=False, default=None)
    extra: dict = field(default_factory=dict)

    @property
    def T(self):
        return float(self.t[-1])


def _collect(opti, sol, Xv, Uv, Tv, p, t0, stats):
    X = np.array(sol.value(Xv)).T
    U = np.array(sol.value(Uv)).T
    T = float(sol.value(Tv))
    N = X.shape[0]
    L = np.array([float(F.leg_length(X[k], U[k], p)) for k in range(N)])
    g = [F.grf(X[k], U[k], p) for k in range(N)]
    return Solution(np.linspace(0, T, N), X, U, L, np.array([float(a) for a, _ in g]),
                    np.array([float(b) for _, b in g]), time.perf_counter() - t0,
                    int(stats.get("iter_count", -1)), str(stats.get("return_status")), p)


_FUNCS = {}     # (id(params), N) -> (params, functions)


def row_scales(p: F.FSLIPParams):
    """Units of the path-constraint rows (m, N, N·m): each row is divided by its unit so that IPOPT
    sees O(1) constraint values and multipliers."""
    mg = p.m * p.g
    return np.array([0.1, 0.1, mg, mg, mg, mg, 10.0, 10.0, 100.0, 100.0, mg, mg, mg])


def knot_functions(p: F.FSLIPParams, N: int):
    """CasADi Functions (SX inside, mapped over N knots): dynamics f(X,U) (5×N), leg length L (1×N),
    and the stacked path-constraint expressions g(X,U) ≥ 0 divided by :func:`row_scales` (rows
    named in ``PATH_ROWS``)."""
    import casadi as ca
    key = (id(p), N)
    if key in _FUNCS:
        return _FUNCS[key][1]
    x = ca.SX.sym("x", 5)
    u = ca.SX.sym("u", 3)
    Fx, Fz = F.grf(x, u, p)
    L = F.leg_length(x, u, p)
    Fmax = p.F_max(L)
    Fk = p.knee_leg_force(x, u)            # the knees' share: F^s, or F^s + rho f_t (knee_tangential)
    rows = [L - p.L_min, p.L_max - L, u[0], Fz, p.mu * Fz - Fx, p.mu * Fz + Fx,
            0.5 * p.foot_length * Fz - u[2], 0.5 * p.foot_length * Fz + u[2],
            p.tau_max - u[1], p.tau_max + u[1], Fmax - Fk]
    if math.isfinite(p.knee_no_load_speed):
        rdot = F.leg_geometry(x)[3]
        rows += [Fmax * f - Fk for f in planning_rows(p.dqknee_dL(L) * rdot / p.knee_no_load_speed)]
    sc = row_scales(p)[:len(rows)]
    f = ca.Function("f", [x, u], [ca.vertcat(*F.dynamics(x, u, p))]).map(N)
    fl = ca.Function("L", [x, u], [L]).map(N)
    fg = ca.Function("g", [x, u], [ca.vertcat(*[r / s for r, s in zip(rows, sc)])]).map(N)
    _FUNCS[key] = (p, (f, fl, fg))      # p kept alive: its id is not reused by other parameters
    return f, fl, fg


#: names of the rows of the path constraints g(X, U) >= 0 (for failure diagnosis)
PATH_ROWS = ("leg length >= L_min", "leg length <= L_max", "leg force >= 0", "F_z >= 0",
             "friction cone (F_x <= mu F_z)", "friction cone (F_x >= -mu F_z)", "ZMP (u <= F_z l/2)",
             "ZMP (u >= -F_z l/2)", "flywheel torque <= tau_max", "flywheel torque >= -tau_max",
             "leg force limit (knee torque)", "knee torque-speed envelope",
             "knee torque-speed envelope (compressing)")
#: the rows that only involve the leg length (the rest constrain the controls)
LEG_ROWS = 2
#: state units (x, z in m; ẋ, ż in m/s; H in kg·m²/s): the dynamics defects are divided by them
STATE_SCALE = (0.1, 0.1, 1.0, 1.0, 10.0)


def transcribe(opti, X, U, T, p, N, free_controls=None, named=None):
    """Trapezoidal dynamics (defects in :data:`STATE_SCALE` units) + path constraints; returns the L
    (1×N) expression.  ``free_controls``: the knots whose controls are decision variables (default
    all); at the others the controls are given and only the leg-length rows are imposed there (a
    constraint on a given value has a zero gradient: a degenerate row for IPOPT).  ``named``: a dict
    that receives the constraints by name (for the multipliers of :func:`binding_limits`)."""
    import casadi as ca
    named = {} if named is None else named
    f, fl, fg = knot_functions(p, N)
    dt = T / (N - 1)
    fx = f(X, U)
    defect = X[:, 1:] - X[:, :-1] - 0.5 * dt * (fx[:, :-1] + fx[:, 1:])
    opti.subject_to(ca.vec(ca.diag(1.0 / ca.DM(STATE_SCALE)) @ defect) == 0)
    G = fg(X, U)
    free = list(range(N)) if free_controls is None else list(free_controls)
    given = [k for k in range(N) if k not in set(free)]
    named["path"] = (ca.vec(G[:, free]) >= 0, free, G.shape[0])
    opti.subject_to(named["path"][0])
    if given:
        named["path_given"] = (ca.vec(G[:LEG_ROWS, given]) >= 0, given, LEG_ROWS)
        opti.subject_to(named["path_given"][0])
    named["mass height >= 0.3 m"] = X[1, :] >= 0.3
    opti.subject_to(named["mass height >= 0.3 m"])
    return fl(X, U)


def cost_terms(L, U, dt, N, cost=None):
    """Σ (c₁ L̈² + c₂ u² + c₃ τ²) ΔT (eq. J_Jumping); ``cost``: the coefficients (default :data:`COST`)."""
    import casadi as ca
    c = COST if cost is None else cost
    Ldd = (L[2:] - 2 * L[1:-1] + L[:-2]) / dt ** 2
    return (c["c1"] * ca.sumsqr(Ldd) + c["c2"] * ca.sumsqr(U[2, :]) + c["c3"] * ca.sumsqr(U[1, :])) * dt


@dataclass
class JumpTask:
    kind: str
    apex: float              # COM apex above take-off ground, m
    distance: float = 0.0    # m, + forward
    platform: float = 0.0    # m, landing ground this much lower

    @property
    def sign(self):
        return SIGN[self.kind]


FZ_MIN = 0.5    # × m g, minimum normal force during the push (before the lift-off ramp)
FZ_RAMP = 3     # knots over which the minimum normal force ramps down to 0 at lift-off
U_SCALE = (None, 100.0, 10.0)    # F^s scaled by m g, τ by 100 N·m, u by 10 N·m
#: largest rates of the controls (F^s in m g/s, τ and u in N·m/s): the robot's leg is a spring
#: (≈3.5 Hz with the body on it) and its torques reach the ground through the leaf springs, so a
#: plan whose forces jump from knot to knot is not tracked (the feet unload and the robot lifts off
#: early); measured in closed loop with tsc_controller
RATE_LIMITS = (20.0, 5000.0, 1000.0)


RATE_NAMES = ("leg force rate", "flywheel torque rate", "foot torque rate")


def add_rate_limits(opti, U, dt, p, limits=RATE_LIMITS, named=None):
    """|U[:, k+1] − U[:, k]| ≤ rate · ΔT for the three controls (see :data:`RATE_LIMITS`), in units
    of the rate times ΔT."""
    import casadi as ca
    rate = [limits[0] * p.m * p.g, limits[1], limits[2]]
    dU = U[:, 1:] - U[:, :-1]
    for i in range(3):
        c = opti.bounded(-1.0, dU[i, :] / (rate[i] * dt), 1.0)
        opti.subject_to(c)
        if named is not None:
            named[RATE_NAMES[i]] = c


def _variables(opti, p, N):
    """(X, U, Us, T): states and controls as O(1) decision variables (in :data:`VAR_SCALE` and
    :func:`control_scale` units)."""
    import casadi as ca
    X = ca.diag(ca.DM(VAR_SCALE)) @ opti.variable(5, N)
    Us = opti.variable(3, N)
    U = ca.diag(ca.DM(control_scale(p))) @ Us
    return X, U, Us, opti.variable()


def control_scale(p):
    """Units of the controls (F^s in m g, τ and u in :data:`U_SCALE`)."""
    return np.array([p.m * p.g, U_SCALE[1], U_SCALE[2]])


H_SCALE = 10.0   # kg·m²/s, unit of the momentum decision variable
VAR_SCALE = (1.0, 1.0, 1.0, 1.0, H_SCALE)   # units of the state decision variables
#: units of the task rows (flip encoding rad, apex m, distance m) in the elastic problem
TASK_UNITS = (0.01, 0.01, 0.01)
#: L1 penalty per unit of task residual: well above the task rows' multipliers at an optimum (the
#: cost is O(1)), so that the elastic optimum meets the task exactly wherever that is possible
ELASTIC_WEIGHT = 100.0


class JumpingProblem:
    """The jumping NLP built once per (params, L0, N); the task (sign, apex, distance, platform)
    enters as ``opti.parameter`` so repeated requests reuse the same IPOPT instance.

    The given values are not decision variables: the first knot (standing at rest) and the
    lift-off controls (F^s = τ = u = 0 at the last knot) are constants, so that no equality pins a
    variable that an active inequality also bounds (a degenerate KKT system that IPOPT factorised
    or not depending on the BLAS kernel's rounding)."""

    def __init__(self, p: F.FSLIPParams, L0: float, N: int = 50, T_bounds=(0.3, 1.0), elastic=False):
        import casadi as ca
        self.p, self.L0, self.N, self.elastic = p, L0, N, elastic
        self.named = named = {}
        opti = ca.Opti()
        self.X0, self.U0 = F.static_state(p, L0)
        self.Xv = opti.variable(5, N - 1)                 # knots 1..N-1, H in H_SCALE units
        self.Usv = opti.variable(3, N - 2)                # knots 1..N-2, scaled controls
        self.T = T = opti.variable()
        X = ca.horzcat(ca.DM(self.X0), ca.diag(ca.DM(VAR_SCALE)) @ self.Xv)
        U = ca.horzcat(ca.DM(self.U0), ca.diag(ca.DM(control_scale(p))) @ self.Usv, ca.DM.zeros(3, 1))
        self.X, self.U = X, U
        self.P = opti.parameter(4)          # sign, apex, distance, platform
        sign, apex, dist, plat = (self.P[i] for i in range(4))
        dt = T / (N - 1)
        named["stance duration bounds"] = opti.bounded(T_bounds[0], T, T_bounds[1])
        opti.subject_to(named["stance duration bounds"])
        # lift-off at the last knot: F_z = F_x = u = 0 (the controls there are 0)
        self.Ls = Ls = transcribe(opti, X, U, T, p, N, free_controls=range(1, N - 1), named=named)
        add_rate_limits(opti, U, dt, p, named=named)
        # keep the feet loaded until the push-off (the robot's contact detector would otherwise see
        # an early lift-off): F_z ≥ FZ_MIN m g, ramping to 0 over the last FZ_RAMP knots
        xs, us = ca.SX.sym("x", 5), ca.SX.sym("u", 3)
        Fz = ca.Function("Fz", [xs, us], [F.grf(xs, us, p)[1]]).map(N)(X, U)
        ramp = np.minimum(1.0, (N - 1 - np.arange(N)) / FZ_RAMP) * FZ_MIN
        named["feet loaded until the push-off"] = Fz[1:N - 1] / (p.m * p.g) >= ramp[1:N - 1].reshape(1, -1)
        opti.subject_to(named["feet loaded until the push-off"])
        xN = X[:, N - 1]
        zd = xN[3]
        named["lift-off vertical speed >= 0.3 m/s"] = zd >= 0.3
        opti.subject_to(named["lift-off vertical speed >= 0.3 m/s"])
        self.Tf = Tf = F.flight_time(zd, plat, p.g)
        self.beta = beta = F.leg_angle(xN)
        self.thd = thd = xN[4] / p.I(Ls[N - 1])
        self.com_h = com_h = float(p.reg("com_h", L0))
        # task rows (named for failure diagnosis)
        self.task_rows = {
            "flip encoding (thetadot*T_flight = ±2π − 2β)": thd * Tf - (sign * 2 * math.pi - 2 * beta),
            "apex height": xN[1] + zd ** 2 / (2 * p.g) + com_h - apex,
            "forward distance": 2 * xN[0] + xN[2] * Tf - dist,
        }
        cost = cost_terms(Ls, U, dt, N)
        if elastic:
            # the task as soft rows (exact L1 penalty): always feasible, its optimum says how far the
            # request is from what the limits allow and, by its multipliers, which limits bind
            n = len(self.task_rows)
            self.slack = (opti.variable(n), opti.variable(n))
            opti.subject_to(ca.vertcat(*self.slack) >= 0)
            unit = ca.DM(TASK_UNITS)
            e = ca.vertcat(*self.task_rows.values()) / unit
            opti.subject_to(e == self.slack[0] - self.slack[1])
            cost = cost + ELASTIC_WEIGHT * ca.sum1(self.slack[0] + self.slack[1])
            opti.solver("ipopt", dict(IPOPT_OPTS, **{"ipopt.max_iter": 1000}))
        else:
            for e in self.task_rows.values():
                opti.subject_to(e == 0)
            opti.solver("ipopt", IPOPT_OPTS)
        opti.minimize(cost)
        self.opti = opti

    def _guess(self, task: "JumpTask"):
        p, N, opti = self.p, self.N, self.opti
        zd_g = math.sqrt(max(2 * p.g * (task.apex - self.com_h - p.L_max + 0.05), 1.0))
        Tf_g = float(F.flight_time(zd_g, task.platform, p.g))
        Tg = 0.6
        s = np.linspace(0, 1, N)
        z_lo = p.L_max - 0.06
        zg = self.X0[1] + (z_lo - self.X0[1]) * s ** 2 - 0.22 * np.sin(np.pi * s) ** 2 * (1 - s)
        zdg = np.gradient(zg, s * Tg)
        zdg[-1] = zd_g
        # most of a forward distance comes from leaning (x at lift-off), the rest from ẋ
        xg = 0.4 * task.distance * s ** 2
        H_g = task.sign * 2 * math.pi * float(p.I(p.L_max)) / Tf_g
        Xg = np.vstack([xg, zg, np.gradient(xg, s * Tg), zdg, H_g * s]) / np.array(VAR_SCALE)[:, None]
        opti.set_initial(self.Xv, Xg[:, 1:])
        Ug = np.vstack([(1.5 - s), H_g / Tg / U_SCALE[1] * np.ones(N), np.zeros(N)])
        opti.set_initial(self.Usv, Ug[:, 1:N - 1])
        opti.set_initial(self.T, Tg)

    def solve(self, task: "JumpTask", start: Optional[Solution] = None) -> Solution:
        """Cold solve for ``task`` from the fixed initial guess, or from the knots of ``start``
        (a solution of the same N); RuntimeError on IPOPT failure (the exception carries
        ``.problem``).  In the elastic problem, ``extra`` holds the task residuals and the binding
        limits (:meth:`binding_limits`)."""
        t0 = time.perf_counter()
        opti = self.opti
        opti.set_value(self.P, [task.sign, task.apex, task.distance, task.platform])
        self._guess(task)
        if start is not None:
            opti.set_initial(self.Xv, start.X.T[:, 1:] / np.array(VAR_SCALE)[:, None])
            opti.set_initial(self.Usv, start.U.T[:, 1:-1] / control_scale(self.p)[:, None])
            opti.set_initial(self.T, start.T)
        try:
            sol = opti.solve()
        except RuntimeError as e:
            stats = opti.stats()
            err = RuntimeError(f"IPOPT: {stats.get('return_status', e)}")
            err.problem = self
            raise err
        res = _collect(opti, sol, self.X, self.U, self.T, self.p, t0, opti.stats())
        res.extra.update(flight_time=float(sol.value(self.Tf)), beta=float(sol.value(self.beta)),
                         thetadot=float(sol.value(self.thd)), com_h=self.com_h)
        if self.elastic:
            res.extra["task_residuals"] = {k: float(sol.value(e)) for k, e in self.task_rows.items()}
            res.extra["binding"] = self.binding_limits(sol)
        return res

    def binding_limits(self, sol):
        """[(name, share, where)] of the constraints that hold the optimum, by the share of their
        multipliers' magnitude (the rows are in O(1) units, see :func:`row_scales`), largest first.
        ``where``: the span of the stance (s) over which the family binds."""
        T = float(sol.value(self.T))
        dt = T / (self.N - 1)
        weight = {}
        for name, c in self.named.items():
            if isinstance(c, tuple):                 # path rows: split by family
                con, knots, nrows = c
                lam = np.abs(np.array(sol.value(self.opti.dual(con))).ravel()).reshape(len(knots), nrows)
                for i in range(nrows):
                    if lam[:, i].sum() > 0:
                        k = np.asarray(knots)[lam[:, i] > 1e-3 * lam[:, i].max()]
                        prev = weight.get(PATH_ROWS[i], (0.0, []))
                        weight[PATH_ROWS[i]] = (prev[0] + lam[:, i].sum(), prev[1] + list(k))
            else:
                lam = np.abs(np.array(sol.value(self.opti.dual(c))).ravel())
                k = np.flatnonzero(lam > 1e-3 * lam.max()) + 1 if lam.size >= self.N - 3 and lam.max() > 0 else []
                weight[name] = (lam.sum(), list(k))
        total = sum(w for w, _ in weight.values()) or 1.0
        out = [(n, w / total, (min(k) * dt, max(k) * dt) if len(k) else None)
               for n, (w, k) in weight.items() if w / total >= 0.02]
        return sorted(out, key=lambda r: -r[1])


_PROBLEMS = {}


class PlannerFailure(RuntimeError):
    """The optimiser did not reach a verdict (neither a plan nor the elastic analysis converged)."""


def problem(p: F.FSLIPParams, L0: float, N: int = 50, elastic: bool = False) -> JumpingProblem:
    """The jumping NLP for (params, L0, N), built once and cached."""
    key = (id(p), round(L0, 6), N, elastic)
    if key not in _PROBLEMS:
        _PROBLEMS[key] = JumpingProblem(p, L0, N, elastic=elastic)
    return _PROBLEMS[key]


#: the elastic optimum meets the task when every residual is below this many task units (1e-5 m/rad)
TASK_MET = 1e-3


def solve_jumping(task: JumpTask, p: F.FSLIPParams, L0: float, N: int = 50) -> Solution:
    """Solve the jumping optimisation with a bounded, deterministic ladder:

    1. the NLP from its fixed initial guess;
    2. if IPOPT fails: the elastic NLP (task rows soft), which always has a feasible point.  If its
       optimum misses the task, the request is beyond the limits: :class:`TaskUnreachable` carries
       the residuals and the binding limits.  Otherwise the NLP again, started from that optimum;
    3. if that fails too, the elastic optimum is the plan when it meets the task to IPOPT's tolerance.

    ``extra['attempt']`` says which step gave the plan (0, 1, 2); :class:`PlannerFailure` if none did."""
    strict = problem(p, L0, N)
    try:
        sol = strict.solve(task)
        sol.extra["attempt"] = 0
        return sol
    except RuntimeError as e:
        first = str(e)
    try:
        el = problem(p, L0, N, elastic=True).solve(task)
    except RuntimeError as e:
        raise PlannerFailure(f"{first}; the elastic analysis failed too ({e})") from None
    res = el.extra["task_residuals"]
    miss = max(abs(v) / u for v, u in zip(res.values(), TASK_UNITS))
    if miss > TASK_MET:
        raise TaskUnreachable(res, el.extra["binding"], el)
    try:
        sol = strict.solve(task, start=el)
        sol.extra["attempt"] = 1
        return sol
    except RuntimeError:
        pass
    if max(abs(v) for v in res.values()) <= IPOPT_OPTS["ipopt.tol"]:
        el.extra["attempt"] = 2
        return el
    raise PlannerFailure(f"{first}; started again from the elastic optimum (task residuals "
                         f"{', '.join(f'{k} {v:.2g}' for k, v in res.items())}), IPOPT failed again")


class TaskUnreachable(RuntimeError):
    """The elastic optimum misses the task: ``residuals`` (task row → achieved − asked, rad or m)
    and ``binding`` (see :meth:`JumpingProblem.binding_limits`)."""

    def __init__(self, residuals, binding, solution):
        super().__init__("the task is beyond the limits")
        self.residuals, self.binding, self.solution = residuals, binding, solution
