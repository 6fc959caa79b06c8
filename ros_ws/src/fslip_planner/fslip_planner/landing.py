"""Landing optimisation on the FSLIP (paper §III-C), re-solved from the measured post-impact state.

Same transcription and physical constraints as :mod:`fslip_planner.jumping` (the knees' load with the
tangential foot force: :data:`KNEE_TANGENTIAL`); the initial state
X(0) is an ``opti.parameter`` (post-impact state, foot at the origin), the initial controls are
free (the impact is over, the leg force starts wherever it is).  Final state at rest standing:
z_N = z_des, ẋ_N = ż_N = x_N = 0, H_N = 0 (θ̇ = 0), F^s_N = m g (τ_N = u_N = 0), held over
the last knot interval so that the reference ends with L̇ = 0.
Cost: the jumping cost + α Σ ṡ² ΔT (spring oscillation; ṡ by differences of s = L − r).
The mass rises at most e·|ż(0)| (e = :data:`RISE_RESTITUTION`, at least :data:`RISE_FLOOR`): a landing
stands up, it does not jump again (see the constant).

``free_momentum=True`` (fallback when a measured state cannot be brought to H = 0, e.g. an
under-rotated flip with a fast-spinning flywheel) drops H_N = 0: the flywheel keeps its momentum.

The Opti object is kept: :meth:`LandingProblem.solve` sets the parameter, warm-starts IPOPT from the
primal/dual solution of the nearest state solved before (:data:`WARM_POINTS` kept; the planner solves
the touch-downs a lift-off predicts during the flight) and re-solves.
"""
from __future__ import annotations

import math
import time
from dataclasses import replace

import numpy as np

from . import flight as Fl
from . import fslip as F
from . import jumping as Jm
from .plan_types import Reference

ALPHA = 1e-1
#: eq. J_Landing's c₁, c₂, c₃ with the foot torque u weighing as the flywheel torque τ.  Ḣ = τ, and u = −τ
#: takes the momentum out through the centre of pressure without pushing the COM; at the jump's c₂ = 100 c₃
#: the optimum takes it out with τ alone, whose push F_t = τ/r swings the COM ahead first and grows |H| past
#: the touch-down's (a backflip's −38 → −48 kg·m²/s, spun into the flywheel; docs/measurements.md,
#: "The landing's centre of pressure")
LANDING_COST = dict(Jm.COST, c2=Jm.COST["c3"])
#: N, the least normal force the controller's LANDING QP keeps at each toe and heel (tsc_controller's
#: ``f_min_domains``), and the share of the foot length its centre of pressure keeps from either end
#: (tsc_controller's JUMPING ``cop_margin``: at the foot's ends the real feet roll).  The landing's ZMP row
#: (eq. ZMP) narrowed to what the QP can realise, |u| ≤ (F_z − 4 f)(1/2 − m) l, after the touch-down's knot;
#: with the whole foot (m = 0) flip D's landing plans put the centre of pressure at the toes at a low F_z and
#: the feet left the ground in most landings
POINT_FORCE_MIN = 25.0
COP_MARGIN = 0.2
# Landing duration bounds (s) and knots.  A somersault lands with up to ~50 kg·m²/s of pitch momentum,
# which leaves through the foot torque, |u| ≤ F_z l/2 ≈ 34 N·m standing (ZMP; less within the QP's,
# POINT_FORCE_MIN): at least ~1.5 s.  With at most 1.2 s the optimum sat on the bound and removed it with
# flywheel torque τ, whose reaction on the leg (F_t = (τ + u)/r) swung the point mass 0.25 m forward and
# back; the robot tracking that bounced off after a backflip (docs/measurements.md, Landing plan tracked).
# 40 knots keep ΔT ≤ 0.05 s.
T_BOUNDS = (0.4, 2.0)
N_KNOTS = 40
#: The plan's COM rises at most RISE_RESTITUTION times the touch-down sink speed (a restitution bound,
#: not below RISE_FLOOR m/s, nor below the touch-down's own rate when it is rising: a rebound's).
#: Unbounded, the optimum crouches on the spring and springs back up at ~0.8 m/s with F_z falling to
#: ~50 N; the robot, lagging the crouch, overshoots that rise and its feet leave the ground (the
#: "rebound" fallback in most landings of flip C and D; docs/measurements.md).
RISE_RESTITUTION = 0.2
RISE_FLOOR = 0.2
#: The landing bounds the knees by their load from the axial and the tangential foot force, F^s + ρ(L) f_t
#: (:attr:`FSLIPParams.knee_tangential`, docs/planner.md), not by F^s alone: a frontflip's landing brakes
#: with f_t < 0, which relieves the knees, and planned on F^s alone it sinks deeper and slower (flip C landed
#: 25 of 30 so, 28 with this; docs/measurements.md, "The landing's knees").  The jumping NLP keeps the
#: robot's setting: planned with it, the frontflips' pushes lift off in their crouch
KNEE_TANGENTIAL = True
#: warm starts from a solved neighbour: barrier and bound pushes at 1e-3 (at 1e-6 a neighbour 0.05–0.14 m
#: away in lean took 35–60 iterations, more than a cold solve's ~25; at 1e-3, 15–18); at most
#: 60 iterations (at 30, flip C's re-solves fell back to cold ones, which landed worse).  The Hessian's
#: regularisation at most 1e8 (IPOPT's default 1e20): a warm re-solve of flip A whose regularisation ran
#: up to 1e16 spent 1.45 s in 60 iterations and failed; capped, it converges in 16 (landings that never
#: need that much are solved to the bit as before).  Rows that bound one variable (the initial state, the
#: rest at the end, the heights, the rise) go to IPOPT as bounds (``detect_simple_bounds``): a smaller KKT
#: system, the same optimum, a warm re-solve ~25 % faster.  The warm solves stop at tolerance 1e-4 (IPOPT's
#: scaled NLP error): against 1e-5 the plans differ by at most 0.18 kg·m²/s in H, 0.7 mm in x and 13 ms in
#: duration, and a touch-down takes ~3 iterations fewer (docs/measurements.md, "The warm solves' tolerance")
LANDING_IPOPT = {"ipopt.max_hessian_perturbation": 1e8, "detect_simple_bounds": True}
WARM_OPTS = dict(Jm.IPOPT_OPTS, **LANDING_IPOPT)
WARM_OPTS.update({"ipopt.warm_start_init_point": "yes", "ipopt.warm_start_bound_push": 1e-3,
                  "ipopt.warm_start_mult_bound_push": 1e-3, "ipopt.mu_init": 1e-3,
                  "ipopt.warm_start_slack_bound_push": 1e-3, "ipopt.mu_strategy": "monotone",
                  "ipopt.max_iter": 60, "ipopt.tol": 1e-4})
#: ... and the touch-down's re-solve from a prediction within WARM_NEAR (WARM_SCALE units) with the
#: barrier at 1e-5: the touch-downs of B, F, A, D took 13–17 iterations at 1e-3, 7–13 at 1e-5 (with
#: WARM_NEAR 0.45 instead, A's took 14 against 7, median of 30).  Not flip C's (1.5–1.8 units from its
#: nearest), nor the predictions, which chain 1 unit apart and failed more often at 1e-5
NEAR_OPTS = dict(WARM_OPTS, **{"ipopt.mu_init": 1e-5})
WARM_NEAR = 1.25
#: solved states kept as warm starts, and the scale of each state component [x, z, ẋ, ż, H] in the
#: distance that picks the nearest (a 0.05 m lean, a 0.2 m/s speed, 2 kg m^2/s weigh alike)
WARM_POINTS = 10
WARM_SCALE = np.array([0.05, 0.05, 0.2, 0.2, 2.0])
#: the touch-downs a lift-off predicts (:func:`predicted_touchdowns`), each (COM − foot shift from the
#: mirrored lean, fall shortened; m).  Measured touch-downs came 0.17 m behind to 0.08 m ahead of the
#: mirrored lean, and fell 0.01 m more to 0.09 m less than the lift-off predicts: the COM meets the ground
#: higher above the feet when the legs come down longer than they left (flip C, +0.06 m) or the ground is
#: higher than told (flip D, 0.1 m).  A warm start 0.05 m (or 0.2 m/s of sink) away takes ~15 IPOPT
#: iterations, 0.14 m away as many as a cold one; the four shorter falls took C's touch-down re-solve
#: from 12 / 17 iterations (median / max of 30) to 8 / 10 and D's from 11 / 11 to 3 / 4 (docs/measurements.md,
#: "Predictions for a shorter fall").  In solve order: a touch-down waits for those it needs that the
#: flight had no time for (C's flight, the longest, needs the shorter falls ahead of the mirror)
PREDICTED_SHIFTS = ((0.0, 0.0), (-0.05, 0.0), (-0.1, 0.0), (-0.15, 0.0), (0.05, 0.0),
                    (0.05, 0.08), (0.0, 0.08), (-0.075, 0.08), (-0.15, 0.08))
COLD_OPTS = dict(Jm.IPOPT_OPTS, **LANDING_IPOPT)
COLD_OPTS.update({"ipopt.max_iter": 300})


def _cop_rows(p: F.FSLIPParams, N: int):
    """(F_z − 4 POINT_FORCE_MIN)(1/2 − COP_MARGIN) l ∓ u ≥ 0 in m g·l units, mapped over N knots: the
    centre of pressure the controller can realise (eq. ZMP narrowed; see POINT_FORCE_MIN)."""
    import casadi as ca
    x, u = ca.SX.sym("x", 5), ca.SX.sym("u", 3)
    Fz = F.grf(x, u, p)[1]
    half = (0.5 - COP_MARGIN) * p.foot_length * (Fz - 4.0 * POINT_FORCE_MIN)
    unit = p.m * p.g * p.foot_length
    return ca.Function("cop", [x, u], [ca.vertcat(half - u[2], half + u[2]) / unit]).map(N)


class SolveInterrupted(Exception):
    """A solve stopped by :attr:`LandingProblem.interrupt` (nothing kept from it)."""


def _interrupt_callback(problem, nx: int, ng: int):
    """IPOPT's iteration callback: stops the solve when ``problem.interrupt()`` says so."""
    import casadi as ca

    class _Interrupt(ca.Callback):
        def __init__(self):
            ca.Callback.__init__(self)
            self.construct("landing_interrupt", {})

        def get_n_in(self):
            return ca.nlpsol_n_out()

        def get_n_out(self):
            return 1

        def get_name_in(self, i):
            return ca.nlpsol_out(i)

        def get_name_out(self, i):
            return "stop"

        def get_sparsity_in(self, i):
            name = ca.nlpsol_out(i)
            return (ca.Sparsity.scalar() if name == "f" else ca.Sparsity.dense(nx) if name in ("x", "lam_x")
                    else ca.Sparsity.dense(ng) if name in ("g", "lam_g") else ca.Sparsity(0, 0))

        def eval(self, arg):
            return [1 if problem.interrupt is not None and problem.interrupt() else 0]

    return _Interrupt()


class LandingProblem:
    """Landing Opti built once per (params, L_stand, N); :meth:`solve` from a post-impact state.
    ``interrupt``: None, or a callable asked at each IPOPT iteration; True stops the solve, which then
    raises :class:`SolveInterrupted` (planner_node: a contact event came while it solved predictions)."""

    def __init__(self, p: F.FSLIPParams, L_stand: float, N: int = N_KNOTS, T_bounds=T_BOUNDS,
                 free_momentum: bool = False, near_start: bool = False):
        """``near_start``: also build the low-barrier solver that :meth:`solve` uses with ``near`` > 0
        (~0.3 s more; only the touch-down's re-solve needs it)."""
        import casadi as ca
        if KNEE_TANGENTIAL:
            p = with_knee_tangential(p)
        self.p, self.N = p, N
        opti = ca.Opti()
        X, U, Us, T = Jm._variables(opti, p, N)
        self.X, self.U, self.Us, self.T = X, U, Us, T
        self.X0 = opti.parameter(5)
        Xs, Ust = F.static_state(p, L_stand)
        self.X_stand, self.U_stand = Xs, Ust
        opti.subject_to(X[:, 0] == self.X0)
        opti.subject_to(opti.bounded(T_bounds[0], T, T_bounds[1]))
        L = Jm.transcribe(opti, X, U, T, p, N)
        self.L = L
        # not at knot 0: the touch-down's leg, at its full length, may carry less than 4 f
        opti.subject_to(ca.vec(_cop_rows(p, N - 1)(X[:, 1:], U[:, 1:])) >= 0)
        # a touch-down that is already rising (a rebound's) may go on rising at that rate, no faster
        opti.subject_to(X[3, :] <= ca.fmax(ca.fmax(-RISE_RESTITUTION * self.X0[3], RISE_FLOOR), self.X0[3]))
        rows = slice(0, 4) if free_momentum else slice(0, 5)
        for k in (N - 2, N - 1):       # at rest over the last interval (L̇ = 0 at the end)
            opti.subject_to(X[rows, k] == Xs[rows])
            opti.subject_to(U[:, k] == Ust)
        dt = T / (N - 1)
        r = ca.sqrt(X[0, :] ** 2 + X[1, :] ** 2)
        s = L - r
        sd = (s[1:] - s[:-1]) / dt
        opti.minimize(Jm.cost_terms(L, U, dt, N, LANDING_COST) + ALPHA * ca.sumsqr(sd) * dt)
        self.opti = opti
        # one IPOPT instance reused for every solve (Opti.solve would rebuild it each time)
        opti.solver("ipopt", dict(Jm.IPOPT_OPTS))     # bakes opti.x / opti.g / opti.p
        nlp = {"x": opti.x, "p": opti.p, "f": opti.f, "g": opti.g}
        self._bounds = ca.Function("bounds", [opti.p], [opti.lbg, opti.ubg])
        self.interrupt = None
        self._callback = _interrupt_callback(self, opti.nx, opti.ng)
        cb = {"iteration_callback": self._callback}
        self.cold = ca.nlpsol("landing_cold", "ipopt", nlp, dict(COLD_OPTS, **cb))
        self.warm = ca.nlpsol("landing_warm", "ipopt", nlp, dict(WARM_OPTS, **cb))
        self.warm_near = ca.nlpsol("landing_warm_near", "ipopt", nlp, dict(NEAR_OPTS, **cb)) if near_start else None
        self._unpack = ca.Function("unpack", [opti.x], [X, U, T])
        self._points = []         # (x0, primal, dual g, dual x) of the latest solves, newest last
        self.last_start = None    # how the latest solve started: "near", "far" (warm) or "cold"
        self.last_blend = 0.0     # its warm start's share of the second-nearest solution (_warm_start)

    @property
    def has_solutions(self) -> bool:
        """Has a solve succeeded (a warm start exists)?"""
        return bool(self._points)

    @property
    def solved_states(self) -> list:
        """The states whose solutions are kept as warm starts, oldest first."""
        return [q[0] for q in self._points]

    def drop(self, states):
        """Drop the kept solutions of these states."""
        self._points = [q for q in self._points if not any(np.array_equal(q[0], x) for x in states)]

    def forget(self):
        """Drop the solutions kept as warm starts: the next solves depend on nothing solved before."""
        self._points = []

    def _initial_guess(self, x0):
        s = np.linspace(0, 1, self.N)
        w = 3 * s ** 2 - 2 * s ** 3
        Xg = np.outer(1 - w, x0) + np.outer(w, self.X_stand)
        Xg /= np.array(Jm.VAR_SCALE)
        Usg = np.vstack([1.0 + 0.5 * np.sin(np.pi * s), np.zeros((2, self.N))])
        # decision vector order = order of creation in _variables: X, Us, T
        return np.r_[Xg.ravel(), Usg.T.ravel(), 0.7]

    def solve(self, x0, warm=True, near=0.0, blend=False) -> Jm.Solution:
        """Solve from the post-impact FSLIP state x0 = [x, z, ẋ, ż, H] (foot at the origin); ``warm``:
        from the nearest state solved before (cold if none), with IPOPT's barrier starting low
        (NEAR_OPTS) when that state is within ``near`` (WARM_SCALE units); ``blend``: from the nearest
        moved towards the second-nearest (:func:`_warm_start`)."""
        if near > 0.0 and self.warm_near is None:
            raise ValueError("solve(near=...) needs a LandingProblem built with near_start=True")
        t0 = time.perf_counter()
        x0 = np.asarray(x0, float)
        if warm and self._points:
            d2, xv, lam_g, lam_x, self.last_blend = _warm_start(self._points, x0, blend)
            self.last_start = "near" if d2 <= near ** 2 else "far"
            solver = self.warm_near if self.last_start == "near" else self.warm
            lbg, ubg = self._bounds(x0)
            res = solver(x0=xv, lam_g0=lam_g, lam_x0=lam_x, p=x0, lbg=lbg, ubg=ubg)
            stats = solver.stats()
        else:
            self.last_start, self.last_blend = "cold", 0.0
            lbg, ubg = self._bounds(x0)
            res = self.cold(x0=self._initial_guess(x0), p=x0, lbg=lbg, ubg=ubg)
            stats = self.cold.stats()
        if stats.get("return_status") == "User_Requested_Stop":
            raise SolveInterrupted("landing solve interrupted")
        if not stats.get("success", False):
            raise RuntimeError(f"IPOPT (landing): {stats.get('return_status')}")
        self._points = (self._points + [(x0, res["x"], res["lam_g"], res["lam_x"])])[-WARM_POINTS:]
        X, U, T = (np.array(v) for v in self._unpack(res["x"]))
        return _solution(X.T, U.T, float(np.ravel(T)[0]), self.p, t0, stats)


def nearest_first(states, x0):
    """Squared distances of ``states`` to x0 (WARM_SCALE units), and their indices nearest first (ties in
    the given order): how a warm start picks its solutions."""
    d2 = [float(np.sum(((np.asarray(x) - x0) / WARM_SCALE) ** 2)) for x in states]
    return d2, np.argsort(d2, kind="stable")


def _warm_start(points, x0, blend=True):
    """Warm start for the state ``x0`` from the solved ``points`` [(state, primal, dual g, dual x)]: the
    nearest solution moved towards the second-nearest by the share t in [0, 1] of x0's projection on the
    segment between their states (WARM_SCALE units), a secant step along the solution's dependence on
    the state.  Returns (squared distance to the nearest, primal, dual g, dual x, t); t = 0 is the nearest
    alone, and the only start without ``blend``.  Between two predicted touch-downs it saves iterations
    (docs/measurements.md, "The touch-down's warm start between two predictions")."""
    d2, order = nearest_first([q[0] for q in points], x0)
    near, t = points[order[0]], 0.0
    if blend and len(points) > 1:
        other = points[order[1]]
        a, b = (x0 - near[0]) / WARM_SCALE, (other[0] - near[0]) / WARM_SCALE
        bb = float(b @ b)
        t = float(np.clip(float(a @ b) / bb, 0.0, 1.0)) if bb > 0.0 else 0.0
    if t == 0.0:
        return d2[order[0]], near[1], near[2], near[3], 0.0
    return (d2[order[0]],) + tuple((1.0 - t) * near[i] + t * other[i] for i in (1, 2, 3)) + (t,)


_TANGENTIAL: dict = {}     # id of the parameters -> (them, kept alive; their knee_tangential copy)


def with_knee_tangential(p: F.FSLIPParams) -> F.FSLIPParams:
    """``p`` with :attr:`FSLIPParams.knee_tangential` on: ``p`` itself, or one copy per parameters (the
    NLP functions are cached by the parameters' identity)."""
    if p.knee_tangential:
        return p
    return _TANGENTIAL.setdefault(id(p), (p, replace(p, knee_tangential=True)))[1]


#: (id of the parameters, L_stand) -> (the parameters, kept alive; {name: LandingProblem})
_SHARED: dict = {}


def shared_problem(p: F.FSLIPParams, L_stand: float, name: str) -> LandingProblem:
    """The landing NLP ``name`` of these parameters, built once (a build takes ~0.3 s) and shared: "rest",
    "free" (the momentum left free) or "unbounded" (free, without the knee torque–speed envelope).  For
    cold solves, or warm ones after :meth:`LandingProblem.forget`."""
    entry = _SHARED.setdefault((id(p), float(L_stand)), (p, {}))[1]
    if name not in entry:
        q = replace(p, knee_no_load_speed=math.inf) if name == "unbounded" else p
        entry[name] = LandingProblem(q, L_stand, free_momentum=name != "rest")
    return entry[name]


def _solution(X, U, T, p, t0, stats) -> Jm.Solution:
    N = X.shape[0]
    L = np.array([float(F.leg_length(X[k], U[k], p)) for k in range(N)])
    g = np.array([[float(v) for v in F.grf(X[k], U[k], p)] for k in range(N)])
    return Jm.Solution(np.linspace(0, T, N), X, U, L, g[:, 0], g[:, 1], time.perf_counter() - t0,
                       int(stats.get("iter_count", -1)), str(stats.get("return_status")), p)


def rise_beyond_reach(x0, p: F.FSLIPParams) -> bool:
    """A touch-down [x, z, ẋ, ż, H] whose COM rises higher than the leg reaches even with no leg force
    (z + ż²/2g above √(L_max² − x²), x as near the foot as ẋ takes it meanwhile): the foot leaves the
    ground again whatever the plan, so no landing plan exists (a foot brushing the ground in a rebound)."""
    x, z, xd, zd = (float(v) for v in x0[:4])
    if zd <= 0.0:
        return False
    t_up = zd / p.g
    x_near = max(0.0, abs(x) - abs(xd) * t_up)
    return z + zd * zd / (2.0 * p.g) > math.sqrt(max(p.L_max ** 2 - x_near ** 2, 0.0))


#: the landing re-solve's attempts in their order (FlipSession.landing_reference, figures 'fallback')
LANDING_ATTEMPTS = ("the warm re-solve", "a cold solve", "a cold solve with the momentum left free",
                    "the blend to standing")


def landing_attempt_note(figures: dict) -> str | None:
    """What planner_node says when a landing reference came from a fallback attempt (which, and why);
    None when the warm re-solve answered."""
    attempt = int(figures.get("fallback", 0))
    if attempt <= 0:
        return None
    why = ("the touch-down rises beyond the leg's reach" if figures.get("rise_beyond_reach")
           else "the attempts before it failed")
    return f"landing plan from {LANDING_ATTEMPTS[attempt]}: {why}"


def mirrored_touchdown(lift_off, platform):
    """The touch-down a jumping plan predicts, FSLIP [x, z, ẋ, ż, H] with the foot at the origin: the
    lift-off's lean mirrored by the foot placement (§IV-B) on a leg of the lift-off length, ẋ and H kept
    (conserved in flight), ż from the fall to a landing ground ``platform`` lower (``lift_off``: a
    plan's ``PlanResult.lift_off``)."""
    r, b = math.hypot(lift_off["x"], lift_off["z"]), lift_off["beta"]
    zd = float(F.touchdown_zdot(lift_off["zdot"], platform))
    return np.array([-r * math.sin(b), r * math.cos(b), lift_off["xdot"], zd, lift_off["momentum"]])


def predicted_touchdowns(mirrored, com_velocity, momentum, platform, shifts=PREDICTED_SHIFTS):
    """FSLIP touch-down states [x, z, ẋ, ż, H] a measured lift-off predicts: ẋ and the pitch momentum H
    kept (conserved in flight), and for each (dx, dh) of ``shifts`` the lean of ``mirrored`` (the
    lift-off's, mirrored by the foot placement) shifted by dx on a leg of the same length, and ż from
    the fall to a landing ground ``platform`` − dh lower.  A shortened fall the COM never reaches
    falling (ż² + 2 g (platform − dh) ≤ 0: a low hop) is left out."""
    r = float(np.hypot(mirrored[0], mirrored[1]))
    zd_lo = max(float(com_velocity[2]), 0.0)
    out = []
    for dx, dh in shifts:
        if dh and zd_lo * zd_lo + 2.0 * F.G * (platform - dh) <= 0.0:
            continue
        x = float(mirrored[0]) + dx
        zd = float(F.touchdown_zdot(zd_lo, platform - dh))
        out.append(np.array([x, np.sqrt(max(r * r - x * x, 0.0)), float(com_velocity[0]), zd, float(momentum)]))
    return out


def blend_to_standing(x0, L_td, L_stand, foot_x, figures, domain, dt, T=1.0) -> Reference:
    """Last-resort landing reference (no landing plan answered): momentum held, L and pelvis pitch
    min-jerk to standing, COM x min-jerk to above the foot; sampled every ``dt``."""
    t = np.linspace(0.0, T, int(round(T / dt)) + 1)
    z = np.zeros_like(t)
    cols = [(np.full_like(t, x0[4]), z, z), Fl.min_jerk(L_td, L_stand, T, t),
            Fl.min_jerk(foot_x + x0[0], foot_x, T, t), Fl.min_jerk(math.atan2(x0[0], x0[1]), 0.0, T, t)]
    V, D, DD = (np.column_stack([c[i] for c in cols]) for i in range(3))
    return Reference(domain, t, ["H_pitch", "L", "x_com", "phi_pitch"], V, D, DD, {}, figures)
