"""Planner API used by ``planner_node`` and ``scripts/flip plan``: :class:`FlipSession`
(jumping → flight → landing), :func:`plan_flip`, :class:`MeasuredState`, :class:`InfeasibleRequest`
(the states and references defined in :mod:`plan_types`; FSLIP knots to references in
:mod:`ground_reference`).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Dict, Optional

import numpy as np

from . import fslip as F
from . import flight as Fl
from . import jumping as Jm
from .feasibility import (InfeasibleRequest, check_flight, check_landing, com_of_standing, flight_requirement,
                          max_vertical_jump, precheck, rotation_xyzw, standing_com_x, unreachable_message,
                          validate_inputs)
from .ground_reference import DT_SAMPLE, ground_reference, knot_outputs, leg_offset
from .heading_frame import HeadingFrame
from .landing import (WARM_NEAR, LandingProblem, blend_to_standing, mirrored_touchdown, predicted_touchdowns,
                      rise_beyond_reach, shared_problem)
from .landing_predictions import Predictions
from .plan_types import MeasuredState, PelvisState, Reference

__all__ = ["FlipSession", "InfeasibleRequest", "MeasuredState", "PelvisState", "Reference", "PlanResult",
           "plan_flip", "default_apex", "standing_com_x"]

#: a LIFT_OFF earlier than this fraction of the planned stance, or slower than this fraction of the
#: planned lift-off ż, aborts the flip (the flight plan asks no rotation; see flight_reference)
ABORT_STANCE_FRACTION = 0.5
ABORT_ZDOT_FRACTION = 0.5
#: default COM apex above the take-off ground (m): the paper's ~1 m scale, set by what the knee
#: torque–speed envelope can reach: max reachable apex (feasibility.max_vertical_jump) minus this
#: margin (flywheel I: 1.14 − 0.09 = 1.05 m).
DEFAULT_APEX_MARGIN = 0.09
JUMPING, FLIGHT, LANDING = 1, 2, 3
#: largest leg lean (rad from vertical) a landing is planned from; a measured touch-down beyond it is
#: planned from this lean
MAX_TOUCHDOWN_LEAN = math.radians(45.0)

#: share of the flywheel torque limit the flight's pitch profile may use (the rest is the feedback's)
FLYWHEEL_TORQUE_SHARE = 0.7
#: touch-down leg length = standing length + this (m), not the lift-off length: a leg nearly straight
#: at touch-down cannot brake the fall (docs/measurements.md, Planner and robot-model values)
LANDING_LEG_EXTENSION = 0.04


# ------------------------------------------------------------------------------------------ robot
class _Robot:
    """Per-(flywheel, motor speed scale, flywheel torque, knee model) constants of the robot model (cached)."""
    _cache: Dict[tuple, "_Robot"] = {}

    def __init__(self, flywheel, motor_speed_scale=1.0, flywheel_torque=None, knee_tangential=False):
        from cassie_model import robot_params as P
        from cassie_model.model import standing_figures
        st = standing_figures(flywheel)
        self.com0 = st.com
        p0, q0 = st.pelvis_position, st.pelvis_quaternion
        self.pelvis0 = p0
        # the standing COM in the pelvis frame: where the COM is when the robot stands, wherever it is
        self.com_in_pelvis = rotation_xyzw(np.r_[q0[1:], q0[0]]).T @ (self.com0 - p0)
        self.mass = st.mass
        self.L0 = st.leg_length
        self.params = F.params_for(flywheel, motor_speed_scale=motor_speed_scale,
                                   flywheel_torque=flywheel_torque, knee_tangential=knee_tangential)
        fw = P.flywheel(flywheel)
        self.I_fw = fw.inertia_pitch
        self.fw_max_speed = (fw.max_speed_rpm * 2 * math.pi / 60) if fw.max_speed_rpm else math.inf

    @classmethod
    def get_by_params(cls, p):
        """The robot whose FSLIP parameters are ``p``."""
        for robot in cls._cache.values():
            if robot.params is p:
                return robot
        raise KeyError("no robot built with these FSLIP parameters")

    @classmethod
    def get(cls, flywheel, motor_speed_scale=1.0, flywheel_torque=None, knee_tangential=False):
        key = (flywheel, float(motor_speed_scale), _check_torque(flywheel_torque), bool(knee_tangential))
        if key not in cls._cache:
            cls._cache[key] = cls(flywheel, motor_speed_scale, key[2], key[3])
        return cls._cache[key]


def default_apex(flywheel="I", motor_speed_scale=1.0, flywheel_torque=None, knee_tangential=False):
    """Default apex (m): the reachable maximum minus :data:`DEFAULT_APEX_MARGIN` (I: 1.05 m)."""
    p = _Robot.get(flywheel, motor_speed_scale, flywheel_torque, knee_tangential).params
    return round(max_vertical_jump(p)[0] - DEFAULT_APEX_MARGIN, 2)


# ------------------------------------------------------------------------------------------ result
@dataclass
class PlanResult:
    """A solved jumping plan (what ``scripts/flip plan`` writes)."""
    kind: str
    request: dict
    solution: Jm.Solution
    figures: dict
    lift_off: dict

    def to_dict(self):
        s = self.solution
        o = knot_outputs(s)
        d = {"kind": self.kind, "request": self.request, "lift_off": self.lift_off,
             "solve_time_s": s.solve_time, "iterations": s.iterations, "status": s.status,
             "stance_time": s.T,
             "knots": {"t": s.t, "x": s.X[:, 0], "z": s.X[:, 1], "xdot": s.X[:, 2], "zdot": s.X[:, 3],
                       "H": s.X[:, 4], "L": s.L, "s": o["s"], "beta": o["beta"][0], "F_s": s.U[:, 0],
                       "F_z": s.Fz, "F_x": s.Fx, "tau": s.U[:, 1], "u": s.U[:, 2],
                       "thetadot": s.X[:, 4] / np.array([float(s.params.I(L)) for L in s.L])}}
        d.update(self.figures)
        return {k: (v.tolist() if isinstance(v, np.ndarray) else v) for k, v in _tolist(d).items()}


def _tolist(d):
    if isinstance(d, dict):
        return {k: _tolist(v) for k, v in d.items()}
    if isinstance(d, np.ndarray):
        return d.tolist()
    if isinstance(d, np.generic):
        return d.item()
    return d


def _solve(kind, apex, distance, platform, robot: _Robot, flight_check=True):
    """The jumping plan of a request, checked for its flight (``flight_check`` False: the flywheel
    torque its flight needs is reported, not enforced); InfeasibleRequest naming the binding limit
    otherwise."""
    p = robot.params
    precheck(kind, apex, distance, platform, p, robot.L0)
    task = Jm.JumpTask(kind, apex, distance, platform)
    what = _what(kind, apex, distance, platform)
    try:
        sol = Jm.solve_jumping(task, p, robot.L0)
    except Jm.TaskUnreachable as e:
        msg, limit = unreachable_message(e, p)
        raise InfeasibleRequest(f"{what}: {msg}", limit) from None
    except Jm.PlannerFailure as e:
        raise InfeasibleRequest(f"{what}: no verdict, the optimiser failed: {e}", "optimiser") from None
    X = sol.X[-1]
    omega0 = float((X[1] * X[2] - X[0] * X[3]) / (X[0] ** 2 + X[1] ** 2))     # β̇ at lift-off
    lo = {"beta": float(sol.extra["beta"]), "L": float(sol.L[-1])}
    flight = (kind, lo, omega0, float(sol.extra["flight_time"]), p, robot.I_fw, robot.L0 + LANDING_LEG_EXTENSION)
    try:
        need = check_flight(*flight)
    except InfeasibleRequest as e:
        if flight_check:
            raise InfeasibleRequest(f"{what}: {e}", e.limit) from None
        need = flight_requirement(*flight), flight_requirement(*flight, tucked=True)
    sol.extra["flight_torque_needed"], sol.extra["flight_torque_needed_tucked"] = need
    return sol


def _what(kind, apex, distance, platform):
    return f"{kind} apex {apex:.2f} m distance {distance:.2f} m platform {platform:.2f} m"


def _check_landing(robot: _Robot, lift_off, kind, apex, distance, platform, rest):
    """feasibility.check_landing from the touch-down the plan predicts, the refusal prefixed by the request."""
    try:
        return check_landing(mirrored_touchdown(lift_off, platform), rest, robot.L0)
    except InfeasibleRequest as e:
        raise InfeasibleRequest(f"{_what(kind, apex, distance, platform)}: {e}", e.limit) from None


def _figures(sol: Jm.Solution, robot: _Robot):
    X = sol.X[-1]
    L = sol.L[-1]
    p = sol.params
    I_tot = float(p.I(L))
    thd = X[4] / I_tot
    # flywheel spin (joint speed relative to the pelvis): the rest of the robot turns with the
    # pelvis at β̇ (the pelvis tracks β), the flywheel carries H − (I(L) − I_fw) β̇
    Xs = sol.X
    bd = (Xs[:, 1] * Xs[:, 2] - Xs[:, 0] * Xs[:, 3]) / (Xs[:, 0] ** 2 + Xs[:, 1] ** 2)
    I_L = np.array([float(p.I(v)) for v in sol.L])
    H_fw = Xs[:, 4] - (I_L - robot.I_fw) * bd
    peak = float(np.max(np.abs(H_fw / robot.I_fw - bd)))
    T_f = sol.extra["flight_time"]
    f = {"liftoff_zdot": float(X[3]), "liftoff_xdot": float(X[2]), "liftoff_pitch_rate": float(thd),
         "flight_time": float(T_f), "rotation_to_go": float(thd * T_f),
         "peak_flywheel_speed": float(peak), "solve_time": float(sol.solve_time),
         "iterations": int(sol.iterations), "attempt": int(sol.extra.get("attempt", 0)),
         "flight_torque_needed": float(sol.extra.get("flight_torque_needed", 0.0)),
         "flight_torque_needed_tucked": float(sol.extra.get("flight_torque_needed_tucked", 0.0))}
    lo = {"zdot": float(X[3]), "xdot": float(X[2]), "beta": float(sol.extra["beta"]),
          "thetadot": float(thd), "momentum": float(X[4]), "L": float(L), "x": float(X[0]),
          "z": float(X[1]), "inertia": I_tot}
    return f, lo


def plan_flip(kind, apex_height=None, forward_distance=0.0, platform_height=0.0, flywheel="I",
              motor_speed_scale=1.0, flywheel_torque=None, flight_check=True,
              knee_tangential=False) -> PlanResult:
    """Jumping plan alone (no ROS).  ``apex_height`` None or 0 → :func:`default_apex`;
    ``motor_speed_scale`` multiplies the leg motors' no-load speeds and ``flywheel_torque`` (N·m;
    None or 0: the flywheel's own) is the flywheel motor's limit (as in the simulator);
    ``flight_check`` and ``knee_tangential`` as :class:`FlipSession`'s."""
    apex, dist, plat = validate_inputs(kind, apex_height or None, forward_distance, platform_height, flywheel)
    _check_scale(motor_speed_scale)
    _check_torque(flywheel_torque)
    robot = _Robot.get(flywheel, motor_speed_scale, flywheel_torque, knee_tangential)
    apex = default_apex(flywheel, motor_speed_scale, flywheel_torque, knee_tangential) if apex is None else apex
    sol = _solve(kind, apex, dist, plat, robot, flight_check)
    fig, lo = _figures(sol, robot)
    _check_landing(robot, lo, kind, apex, dist, plat, shared_problem(robot.params, robot.L0, "rest"))
    req = dict(kind=kind, apex_height=apex, forward_distance=dist, platform_height=plat, flywheel=flywheel,
               motor_speed_scale=float(motor_speed_scale), flywheel_torque=float(robot.params.tau_max),
               knee_tangential=bool(knee_tangential))
    return PlanResult(kind, req, sol, fig, lo)


def _check_scale(scale):
    if not (isinstance(scale, (int, float)) and math.isfinite(scale) and scale > 0):
        raise ValueError(f"motor_speed_scale must be a finite number > 0, got {scale!r}")


def _check_torque(torque):
    """The flywheel torque limit override (None: the flywheel's own); ValueError if invalid."""
    from cassie_model.motor_limits import flywheel_torque_override
    return flywheel_torque_override(torque)


# ------------------------------------------------------------------------------------------ session
class FlipSession:
    """One flip: jumping plan at construction/request, flight plan at lift-off, landing re-solve at
    touch-down; ``finished`` once the landing reference has ended (or the flip was abandoned)."""

    GRACE = 0.5   # s after the planned end of a phase before the flip counts as abandoned

    def __init__(self, kind, apex_height=None, forward_distance=0.0, platform_height=0.0, flywheel="I",
                 motor_speed_scale=1.0, flywheel_torque=None, flight_check=True, knee_tangential=False):
        """``flight_check`` False (design studies, ``scripts/bench_landings.py --no-flight-check``): a
        jump whose planned flight needs more flywheel torque than the motor gives is not refused.
        ``knee_tangential``: plan with the knee torque of the tangential foot force too
        (:class:`fslip_planner.fslip.FSLIPParams`; ``scripts/bench_landings.py --knee-tangential``)."""
        apex, dist, plat = validate_inputs(kind, apex_height or None, forward_distance, platform_height,
                                           flywheel)
        _check_scale(motor_speed_scale)
        self.kind, self.flywheel = kind, flywheel
        self.motor_speed_scale = float(motor_speed_scale)
        self.flywheel_torque = _check_torque(flywheel_torque)
        self.robot = _Robot.get(flywheel, motor_speed_scale, flywheel_torque, knee_tangential)
        self.apex = (default_apex(flywheel, motor_speed_scale, flywheel_torque, knee_tangential)
                     if apex is None else apex)
        self.distance, self.platform = dist, plat
        self.flight_check = bool(flight_check)
        self.result: Optional[PlanResult] = None
        self.x_start: Optional[float] = None      # COM x the jump starts from (heading frame)
        #: the frame of the pelvis at the request: the plans' x is along its heading (None: world)
        self.heading: Optional[HeadingFrame] = None
        self.t_start = self.t_liftoff = self.t_touchdown = None
        self.landing_end = None
        self._landing: Optional[LandingProblem] = None
        self._predictions = Predictions()      # the touch-downs predicted at the lift-off
        self._flight_T = None
        self.aborted = False
        #: a lift-off came after the landing's touch-down (a rebound): its flight is a hop, and the next
        #: touch-down is re-solved from its measured state, without predictions
        self.bounced = False

    # --- jumping
    def jumping_reference(self, state: Optional[PelvisState] = None) -> Reference:
        """JUMPING reference from the measured ``state`` (refused unless it is standing:
        :func:`standing_com_x`), its COM x targets relative to where the robot stands; ``state``
        None: from the robot's initial standing state (offline runs that start there)."""
        if self.x_start is None:
            self.x_start = (float(self.robot.com0[0]) if state is None
                            else standing_com_x(state, self.robot, self.platform))
            if state is not None:
                self.heading = HeadingFrame.of_pelvis(state.position, state.orientation)
                if self.heading.psi != 0.0:        # the standing COM in that frame
                    self.x_start = float(self.heading.point(com_of_standing(state, self.robot))[0])
        if self.result is None:
            sol = _solve(self.kind, self.apex, self.distance, self.platform, self.robot, self.flight_check)
            fig, lo = _figures(sol, self.robot)
            # the landing NLPs built now, and solved for the predicted touch-down (a warm start later);
            # refused when the robot could not land from it
            self._landing = LandingProblem(self.robot.params, self.robot.L0, near_start=True)
            self._free_landing()                    # the touch-down's fallback NLP, built now
            _check_landing(self.robot, lo, self.kind, self.apex, self.distance, self.platform, self._landing)
            self.result = PlanResult(self.kind, {}, sol, fig, lo)
        r = self.result
        # x_start and the heading frame: where and how the plans start (published, so that an offline
        # re-run starts there, to the bit)
        par = {"flight_time": r.figures["flight_time"], "beta_liftoff": -r.lift_off["beta"], "x_start": self.x_start,
               # the body's net pitch turn the flip asks for (rad; + forwards): a bag reader's expectation
               "turn": 2.0 * math.pi * Jm.SIGN[self.kind]}
        if self.heading is not None:
            par.update(heading=self.heading.psi, heading_pivot_x=self.heading.pivot[0],
                       heading_pivot_y=self.heading.pivot[1])
        return ground_reference(JUMPING, r.solution, self.x_start, self.robot.L0, r.figures, par)

    def reanchored(self, state: PelvisState) -> Reference:
        """The solved jump's JUMPING reference anchored at a newer measured ``state`` (refused unless it
        stands, as :meth:`jumping_reference`).  The jump NLP's solution does not depend on where the
        robot stands, only its anchor (``x_start``, ``heading``) does: planner_node re-reads the robot
        once the solve is done, so that a plan starts from where the robot is when it goes out, not
        where it was when asked (a robot still settling moves ~1 cm in between)."""
        if self.result is None:
            raise RuntimeError("reanchored: no jump solved yet (jumping_reference first)")
        self.x_start, self.heading = None, None
        return self.jumping_reference(state)

    def predict_landing(self, state: MeasuredState, stop=None, interrupt=None) -> Optional[float]:
        """Solve the landing NLP for the touch-downs the measured lift-off ``state`` predicts
        (:func:`landing.predicted_touchdowns` around the mirrored lean), in order, each warm from the
        nearest solved, so that the touch-down's warm re-solve (§III-C) starts next to its answer.  Run
        after the flight reference is out; ``stop()``, asked before each solve, ends it early (the
        touch-down is near): the touch-down first solves those of the rest, in order, up to the two its warm
        start uses (:meth:`landing_reference`), so that its plan does not depend on how fast the machine
        is.  ``interrupt()``, asked at each IPOPT iteration, abandons the solve under way (it stays to be
        done) and ends it too (planner_node: a contact event is waiting).  Returns the time spent (s),
        None when there is nothing to predict."""
        _check_state(state)
        if (self.result is None or self.t_liftoff is None or self.t_touchdown is not None or self.aborted
                or self.bounced):
            return None
        if self.heading is not None:
            state = self.heading.measured(state)
        if self._landing is None:
            self._landing = LandingProblem(self.robot.params, self.robot.L0, near_start=True)
        t0 = time.perf_counter()
        self._predictions.start(predicted_touchdowns(
            self._touchdown_state(None), state.com_velocity, state.pitch_momentum, self.platform))
        self._predictions.solve(self._landing, stop, interrupt=interrupt)
        return time.perf_counter() - t0

    def _touchdown_state(self, state: Optional[MeasuredState]):
        """FSLIP state [x, z, ẋ, ż, H] at touch-down: the predicted one (``state`` None: the lift-off
        mirrored), or the measured velocities and momentum with the COM where it is over the feet
        (``support_center``; without it, the lift-off's lean mirrored).  The leg keeps the lift-off
        length r (FSLIP units): x = COM − foot (at most r sin MAX_TOUCHDOWN_LEAN), z = √(r² − x²)."""
        lo = self.result.lift_off
        mirrored = mirrored_touchdown(lo, self.platform)
        if state is None:
            return mirrored
        r, x = math.hypot(lo["x"], lo["z"]), float(mirrored[0])
        v = np.asarray(state.com_velocity, float)
        if state.support_center is not None:
            lim = r * math.sin(MAX_TOUCHDOWN_LEAN)
            x = min(lim, max(-lim, float(state.com[0]) - float(state.support_center[0])))
        return np.array([x, math.sqrt(r * r - x * x), v[0], v[2], float(state.pitch_momentum)])

    def started(self, t_start: float):
        self.t_start = float(t_start)

    # --- flight
    def flight_reference(self, state: MeasuredState) -> Optional[Reference]:
        """FLIGHT reference at LIFT_OFF; None for contact events before the jump has started.

        A premature (< ½ the planned stance) or weak (ż < ½ planned) lift-off, or a bounce after
        the landing, gets a no-rotation flight plan (level pelvis); the first two mark the flip
        ``aborted``, a bounce ``bounced`` (its touch-down is re-solved like the first, §III-C)."""
        _check_state(state)
        if self.result is None or self.t_start is None or state.t < self.t_start:
            return None
        self.t_liftoff = float(state.t)
        lo = self.result.lift_off
        kind, beta, plat = self.kind, lo["beta"], self.platform
        zd = float(state.com_velocity[2])
        early = state.t - self.t_start < ABORT_STANCE_FRACTION * self.result.solution.T
        weak = zd < ABORT_ZDOT_FRACTION * lo["zdot"]
        bounce = self.t_touchdown is not None
        if bounce or early or weak:
            # a bounce after the landing, or a premature / weak lift-off: a flip in this flight time
            # is impossible, so no rotation is asked (level pelvis); a premature / weak one abandons it
            kind, beta, plat = "hop", 0.0, 0.0
            self.t_touchdown = self.landing_end = None
            self.bounced = self.bounced or bounce
            self.aborted = self.aborted or (not bounce and (early or weak))
        p = self.robot.params
        I_rest = float(p.I(lo["L"])) - self.robot.I_fw
        fp = Fl.flight_plan(kind, float(state.pelvis_pitch), float(state.pelvis_pitch_rate),
                            float(state.com_velocity[2]), beta, lo["L"], plat,
                            max_body_acc=FLYWHEEL_TORQUE_SHARE * p.tau_max / I_rest,
                            hard_body_acc=p.tau_max / I_rest,
                            L_land=self.robot.L0 + LANDING_LEG_EXTENSION)
        self._flight_T = fp["T"]
        th, L = fp["theta"], fp["L"]
        V = np.column_stack([th[0], L[0]])
        D = np.column_stack([th[1], L[1]])
        DD = np.column_stack([th[2], L[2]])
        fig = dict(self.result.figures)
        fig.update(flight_time=fp["T"], rotation_to_go=fp["theta_T"] - float(state.pelvis_pitch),
                   solve_time=0.0, iterations=0, aborted=float(self.aborted))
        return Reference(FLIGHT, fp["t"], ["phi_pitch", "L"], V, D, DD,
                         {"flight_time": fp["T"], "T1": fp["T1"], "beta_liftoff": -lo["beta"],
                          "leg_offset": leg_offset(p, self.robot.L0)}, fig)

    # --- landing
    def landing_reference(self, state: MeasuredState) -> Optional[Reference]:
        """LANDING reference at TOUCH_DOWN (None if there was no lift-off of this flip).

        Warm re-solve from the touch-downs solved before (the nominal one, those predicted at the lift-off:
        predict_landing, solved first up to the two nearest if the flight had no time for them), the
        nearest's solution blended towards the second-nearest's (landing._warm_start); if IPOPT fails:
        cold, then with the momentum left free (the flywheel keeps spinning), and as a last resort a blend
        to standing (``figures['fallback']`` = 1, 2 or 3 says which), so that a reference always goes out.  A
        touch-down whose COM rises beyond the leg's reach (:func:`landing.rise_beyond_reach`: a foot
        brushing the ground in a rebound) gets the blend at once (``figures['rise_beyond_reach']``)."""
        _check_state(state)
        if self.result is None or self.t_liftoff is None or state.t < self.t_liftoff:
            return None
        t_left = time.perf_counter()
        if self.heading is not None:
            state = self.heading.measured(state)
        x0 = self._touchdown_state(state)
        # what the lift-off's prediction had no time for, as far as this touch-down's warm start needs it
        left = self._predictions.solve(self._landing, needed_by=x0) if self._landing is not None else 0
        self._predictions.drop_unneeded(self._landing, x0)
        t0 = time.perf_counter()
        self.t_touchdown = float(state.t)
        foot_x = float(state.com[0]) - x0[0]        # the measured feet (up to the lean bound)
        fig = dict(self.result.figures)
        if self._landing is None:
            self._landing = LandingProblem(self.robot.params, self.robot.L0, near_start=True)
        fig.update(predictions_left=float(left), predictions_left_time=t0 - t_left)
        sol, fallback = None, 0
        attempts = [(lambda: self._landing.solve(x0, warm=True, near=WARM_NEAR, blend=True)),
                    (lambda: self._landing.solve(x0, warm=False)),
                    (lambda: self._free_landing().solve(x0, warm=False))]
        beyond = rise_beyond_reach(x0, self.robot.params)
        fig.update(rise_beyond_reach=float(beyond))
        if beyond:                  # no landing plan exists: the blend at once, not after the failed solves
            attempts = []
        for i, attempt in enumerate(attempts):
            try:
                sol, fallback = attempt(), i
                break
            except RuntimeError:
                continue
        if sol is not None:
            sol.solve_time = time.perf_counter() - t0
            fig.update(solve_time=sol.solve_time, iterations=sol.iterations, rotation_to_go=0.0,
                       fallback=float(fallback))
            ref = ground_reference(LANDING, sol, foot_x, self.robot.L0, fig)
        else:
            fig.update(solve_time=time.perf_counter() - t0, iterations=0, rotation_to_go=0.0, fallback=3.0)
            ref = blend_to_standing(x0, self.result.lift_off["L"], self.robot.L0, foot_x, fig, LANDING, DT_SAMPLE)
        self.landing_end = self.t_touchdown + ref.duration
        return ref

    def _free_landing(self):
        if getattr(self, "_landing_free", None) is None:
            self._landing_free = LandingProblem(self.robot.params, self.robot.L0, free_momentum=True)
        return self._landing_free

    def finished(self, t: float) -> bool:
        if self.landing_end is not None:
            return t >= self.landing_end
        if self.t_start is None:
            return self.result is None
        if self.t_liftoff is None:   # never lifted off: abandoned after the jumping plan + grace
            return t > self.t_start + self.result.solution.T + self.GRACE
        if self.t_touchdown is None:
            return t > self.t_liftoff + (self._flight_T or 0.0) + 2.0
        return False


def _check_state(s: MeasuredState):
    vals = np.r_[np.ravel(s.com), np.ravel(s.com_velocity), s.pitch_momentum, s.pelvis_pitch,
                 s.pelvis_pitch_rate, s.t, np.ravel(s.support_center if s.support_center is not None else [])]
    if (not np.all(np.isfinite(vals)) or np.size(s.com) != 3 or np.size(s.com_velocity) != 3
            or (s.support_center is not None and np.size(s.support_center) != 3)):
        raise ValueError(f"malformed measured state: {s}")
