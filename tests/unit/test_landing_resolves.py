"""The landing re-solve at a touch-down (paper §III-C) in the cases around a rebound: a touch-down
that still rises, one that rises beyond the leg's reach, a bounce after the landing, a warm
re-solve whose Hessian regularisation ran away, the barrier's start by how near the warm start is, the
warm start between two solved touch-downs, and the predictions for a fall shorter than the lift-off's."""
import math

import numpy as np

from fslip_planner import plan as P
from fslip_planner.landing import (PREDICTED_SHIFTS, WARM_NEAR, LandingProblem, mirrored_touchdown,
                                  predicted_touchdowns)

FLIP = dict(platform_height=0.5, apex_height=1.2, motor_speed_scale=3.0, flywheel_torque=260.0)


def test_a_rebounds_rising_touch_down_gets_a_landing_plan():
    """A touch-down after a rebound can come while the COM still rises (flip C: ż +0.59 m/s, the
    momentum reversed).  The landing plan may go on rising at that rate, no faster, and comes to rest
    (with the rise bound at 0.2 m/s from the first knot, the problem was infeasible and the landing got
    the blend-to-standing fallback)."""
    s = P.FlipSession("frontflip", apex_height=1.2, forward_distance=0.6, platform_height=0.5,
                      motor_speed_scale=3.0, flywheel_torque=260.0)
    s.jumping_reference()
    p = s.robot.params
    x0 = np.array([-0.055, 0.911, 0.272, 0.588, -6.711])     # measured offline, C from 2.1 s
    sol = LandingProblem(p, s.robot.L0).solve(x0, warm=False)
    X = sol.X
    assert np.max(X[:, 3]) <= 0.588 + 1e-6
    assert np.allclose(X[-1, [0, 2, 3, 4]], 0.0, atol=1e-6)
    assert np.all(sol.Fz >= -1e-3) and np.all(np.abs(sol.Fx) <= p.mu * sol.Fz + 1e-3)


def test_a_bounce_after_the_landing_is_re_solved_at_its_touch_down_without_predictions():
    """A lift-off after the touch-down (a rebound) gets a level hop's flight plan, is not an aborted
    flip, predicts no landings from the jump's lift-off, and its touch-down gets a landing plan."""
    s = P.FlipSession("backflip", **FLIP)
    jr = s.jumping_reference()
    s.started(1.0)
    lo = s.result.lift_off
    t_lo = 1.0 + jr.duration
    s.flight_reference(P.MeasuredState(t_lo, np.array([0.0, 0.0, 1.0]), np.array([lo["xdot"], 0.0, lo["zdot"]]),
                                       lo["momentum"], lo["beta"], 0.0))
    td = P.MeasuredState(t_lo + 0.6, np.array([0.05, 0.0, 0.95]), np.array([0.2, 0.0, -3.0]), lo["momentum"],
                         -2 * math.pi, 0.0, support_center=np.array([0.0, 0.0, 0.0]))
    assert s.landing_reference(td).domain == 3
    bounce = P.MeasuredState(td.t + 0.2, np.array([0.0, 0.0, 0.9]), np.array([0.0, 0.0, 0.3]), 2.0,
                             -2 * math.pi, 0.0, support_center=np.array([0.0, 0.0, 0.0]))
    fr = s.flight_reference(bounce)
    assert s.bounced and not s.aborted and fr.figures["aborted"] == 0.0
    assert s.predict_landing(bounce) is None
    again = P.MeasuredState(bounce.t + 0.05, np.array([0.0, 0.0, 0.88]), np.array([0.0, 0.0, -0.2]), 2.0,
                            -2 * math.pi, 0.0, support_center=np.array([0.0, 0.0, 0.0]))
    lr = s.landing_reference(again)
    assert lr.domain == 3 and lr.figures["fallback"] == 0.0


def test_a_touch_down_rising_beyond_the_legs_reach_gets_the_blend_at_once():
    """A rebound's foot can brush the ground while the COM still rises at 0.92 m/s (flip C from 1.2 s):
    even with no leg force the COM rises beyond the leg's reach, so no landing plan exists; the planner
    answers with its blend to standing without trying the solves that cannot succeed (they took 2.4 s).
    A sinking touch-down, or one rising within reach, is planned as before."""
    from fslip_planner.landing import rise_beyond_reach
    s = P.FlipSession("frontflip", apex_height=1.2, forward_distance=0.6, platform_height=0.5,
                      motor_speed_scale=3.0, flywheel_torque=260.0)
    s.jumping_reference()
    p = s.robot.params
    brush = np.array([-0.109, 0.907, 0.185, 0.92, 1.941])     # measured offline, C from 1.2 s, no noise
    assert rise_beyond_reach(brush, p)
    assert not rise_beyond_reach(np.array([-0.109, 0.907, 0.185, 0.3, 1.941]), p)
    assert not rise_beyond_reach(np.array([-0.116, 0.906, 0.64, -3.886, 27.0]), p)
    s.started(1.0)
    lo = s.result.lift_off
    s.flight_reference(P.MeasuredState(1.0 + s.result.solution.T, np.array([0.0, 0.0, 1.5]),
                                       np.array([lo["xdot"], 0.0, lo["zdot"]]), lo["momentum"], lo["beta"], 0.0))
    com = np.array([0.0, 0.0, 0.95])
    td = P.MeasuredState(3.0, com, np.array([0.185, 0.0, 0.92]), 1.941, 2 * math.pi, 0.0,
                         support_center=com - np.array([-0.109, 0.0, 0.907]))
    lr = s.landing_reference(td)
    assert lr.domain == 3 and lr.figures["fallback"] == 3.0 and lr.figures["rise_beyond_reach"] == 1.0
    assert lr.figures["iterations"] == 0


def test_a_warm_landing_re_solve_whose_regularisation_runs_away_still_converges():
    """Flip A's touch-down (a graph run, start 1.985 s) re-solved warm from the landings its lift-off
    predicted: IPOPT's Hessian regularisation ran up to 1e16 and the warm attempt spent 60 iterations
    (1.45 s) and failed, leaving it to the cold one.  With the regularisation capped
    (landing.LANDING_IPOPT) the warm re-solve converges."""
    from fslip_planner import landing as LD
    s = P.FlipSession("frontflip", apex_height=1.2, forward_distance=1.0, motor_speed_scale=3.0,
                      flywheel_torque=260.0)
    s.jumping_reference()
    prob = LandingProblem(s.robot.params, s.robot.L0)
    nominal = [-0.30806038200023705, 0.8903295026250913, 0.8877094404628394, -2.121108063942203, 35.958599921605796]
    prob.solve(np.array(nominal), warm=False)
    v = [1.1973550918359306, -2.3249866668600325, 36.14033890474158]
    for x, z in ((-0.30806038200023705, 0.8903295026250913), (-0.35806038200023704, 0.8714244574514871),
                 (-0.4080603820002371, 0.8491610841557655), (-0.458060382000237, 0.8232669728858139),
                 (-0.25806038200023707, 0.9060864536260688)):      # the predictions, in their order
        prob.solve(np.array([x, z, *v]), warm=True)
    td = np.array([-0.31387721401593216, 0.8882955120478608, 1.2130981714809548, -2.204814878199094,
                   35.692976727901815])
    sol = prob.solve(td, warm=True)                          # raises if the warm attempt fails
    assert sol.iterations < LD.WARM_OPTS["ipopt.max_iter"]
    assert np.allclose(sol.X[-1, [0, 2, 3, 4]], 0.0, atol=1e-6)


def test_planner_node_says_which_attempt_answered_a_landing_and_why():
    """planner_node's warning for a landing reference from a fallback attempt (the figures of
    FlipSession.landing_reference); nothing when the warm re-solve answered."""
    from fslip_planner.landing import landing_attempt_note
    assert landing_attempt_note({"fallback": 0.0}) is None and landing_attempt_note({}) is None
    assert landing_attempt_note({"fallback": 1.0}) == "landing plan from a cold solve: the attempts before it failed"
    assert landing_attempt_note({"fallback": 3.0, "rise_beyond_reach": 1.0}) == (
        "landing plan from the blend to standing: the touch-down rises beyond the leg's reach")


def test_a_touch_down_near_a_prediction_starts_the_barrier_low_and_reaches_the_same_plan():
    """A backflip's touch-down as measured offline (read noise) but with the COM 0.05 m behind the feet,
    0.13 WARM_SCALE units from the nearest landing its lift-off predicted (at the 0.086 m measured, 0.82
    units, the low start took 19 iterations against 13; on the offline flips' touch-downs it pays, flip A's
    median 7 against 14: docs/measurements.md, "The landing's knees"): within landing.WARM_NEAR the touch-down's
    re-solve starts IPOPT's barrier at 1e-5 (NEAR_OPTS) instead of 1e-3 and converges in fewer iterations
    to the same plan: the barrier's start changes the path, not the optimum (the two within IPOPT's
    tolerance 1e-4 on a flat optimum: 0.052 in the decision variables' units, a vertical speed late in the
    plan; 0.02 at tolerance 1e-5).  The
    predictions themselves keep the 1e-3 start, and so does a touch-down farther than WARM_NEAR from every
    solved one (flip C's, from the jump's nominal touch-down)."""
    from fslip_planner import landing as LD
    s = P.FlipSession("backflip", apex_height=1.3, motor_speed_scale=3.0, flywheel_torque=260.0)
    s.jumping_reference()
    s.started(1.0)
    lift_off = P.MeasuredState(2.0, np.array([0.0, 0.0, 1.0]), np.array([0.207, 0.0, 3.16]), -38.492, -0.05, 0.0,
                               support_center=np.array([0.05, 0.0, 0.0]))
    s.flight_reference(lift_off)
    s.predict_landing(lift_off)
    prob = s._landing
    assert prob.last_start in ("far", "cold")                 # the predictions: the 1e-3 start (or cold, failed)
    touch_down = P.MeasuredState(2.65, np.array([0.0, 0.0, 0.95]), np.array([0.196, 0.0, -3.167]), -38.387, 0.0,
                                 0.0, support_center=np.array([0.05, 0.0, 0.0]))
    x0 = s._touchdown_state(touch_down)
    d = [float(np.linalg.norm((q[0] - x0) / LD.WARM_SCALE)) for q in prob._points]
    assert min(d) < LD.WARM_NEAR
    _, xv, lam_g, lam_x = prob._points[int(np.argmin(d))]
    lbg, ubg = prob._bounds(x0)
    far = prob.warm(x0=xv, lam_g0=lam_g, lam_x0=lam_x, p=x0, lbg=lbg, ubg=ubg)
    assert prob.warm.stats()["success"]
    ref = s.landing_reference(touch_down)
    assert prob.last_start == "near" and ref.figures["fallback"] == 0.0
    near = prob._points[-1][1]                                # the touch-down's solution, kept last
    n_far = prob.warm.stats()["iter_count"]
    assert ref.figures["iterations"] < n_far, (ref.figures["iterations"], n_far, min(d))
    assert np.allclose(np.array(near).ravel(), np.array(far["x"]).ravel(), atol=6e-2)
    c = LandingProblem(s.robot.params, s.robot.L0, near_start=True)
    c.solve(np.array([-0.174, 0.896, 0.421, -3.767, 26.613]), warm=False)   # flip C's nominal touch-down
    c_td = np.array([-0.115, 0.906, 0.640, -3.858, 26.991])                # C's, measured offline (read noise)
    assert np.linalg.norm((c_td - c._points[0][0]) / LD.WARM_SCALE) > LD.WARM_NEAR
    c.solve(c_td, warm=True, near=LD.WARM_NEAR)
    assert c.last_start == "far"


def test_the_warm_start_between_two_solved_states_is_their_secant_blend():
    """landing._warm_start: the nearest solution moved towards the second-nearest by the share of the
    state's projection on the segment between theirs (WARM_SCALE units), clipped to [0, 1]; the nearest
    alone beyond it, or without ``blend``."""
    from fslip_planner.landing import WARM_SCALE, _warm_start
    a, b = np.array([0.0, 0.9, 0.2, -3.0, -38.0]), np.array([-0.05, 0.9, 0.2, -3.0, -38.0])
    pts = [(a, np.array([1.0, 2.0]), np.array([3.0]), np.array([5.0, 6.0])),
           (b, np.array([3.0, 4.0]), np.array([7.0]), np.array([9.0, 10.0]))]
    d2, xv, lg, lx, t = _warm_start(pts, a + 0.25 * (b - a))
    assert t == 0.25 and d2 == np.sum((0.25 * (b - a) / WARM_SCALE) ** 2)
    np.testing.assert_allclose(xv, [1.5, 2.5])
    np.testing.assert_allclose(lg, [4.0])
    np.testing.assert_allclose(lx, [6.0, 7.0])
    x_off = a + 0.75 * (b - a) + np.array([0.0, 0.0, 0.0, 0.1, 0.0])     # nearer b, off the segment
    _, xv, _, _, t = _warm_start(pts, x_off)
    assert math.isclose(t, 0.25) and math.isclose(xv[0], 2.5)              # its projection, from b
    for x0 in (a - 0.5 * (b - a), a + 0.25 * (b - a)):                    # beyond a; or not asked to blend
        d2, xv, lg, lx, t = _warm_start(pts, x0, blend=x0[0] > 0)
        assert t == 0.0 and xv is pts[0][1] and lg is pts[0][2] and lx is pts[0][3]
    assert _warm_start(pts[:1], b)[4] == 0.0


def test_a_touch_down_between_two_solved_ones_reaches_the_same_plan_from_their_blend():
    """A backflip touch-down with the COM between two leans solved before (as two of the predictions
    a lift-off makes): the re-solve warm from their blend (FlipSession's touch-down) reaches the plan
    the re-solve from the nearest alone reaches, in no more iterations."""
    s = P.FlipSession("backflip", apex_height=1.3, motor_speed_scale=3.0, flywheel_torque=260.0)
    prob = LandingProblem(s.robot.params, s.robot.L0, near_start=True)

    def state(x, xd=0.21, zd=-3.153, H=-38.49):
        return np.array([x, math.sqrt(0.948 ** 2 - x * x), xd, zd, H])
    plans = {}
    for blend in (False, True):
        prob.forget()
        prob.solve(state(-0.045), warm=False)
        prob.solve(state(-0.095), warm=True)
        plans[blend] = prob.solve(state(-0.066, 0.197, -3.165, -38.27), warm=True, near=1.25, blend=blend)
        assert prob.last_start == "near" and (prob.last_blend > 0.2) == blend
    assert plans[True].iterations <= plans[False].iterations
    # the same plan, to IPOPT's tolerance: a millimetre, a centimetre per second, 0.05 kg m^2/s
    err = np.abs(plans[True].X - plans[False].X).max(axis=0)
    assert np.all(err < [1e-3, 1e-3, 1e-2, 1e-2, 5e-2]), err
    assert abs(plans[True].t[-1] - plans[False].t[-1]) < 1e-3


def test_the_landing_counts_the_knees_tangential_share():
    """The landing NLP bounds the knees by F^s + rho(L) f_t (landing.KNEE_TANGENTIAL) on a robot that plans
    its jump on F^s alone: from flip C's predicted touch-down, which brakes with f_t < 0 (that relieves
    the knees), the plan's leg force goes past the axial bound F_max(L) in the catch (on F^s alone it
    stays within it, and the catch sinks deeper) and keeps every knee row with the tangential share."""
    from fslip_planner import jumping as Jm
    from fslip_planner import landing as LD
    s = P.FlipSession("frontflip", **FLIP)
    s.jumping_reference()
    p = s.robot.params
    assert not p.knee_tangential
    lp = LandingProblem(p, s.robot.L0)
    assert lp.p.knee_tangential and LD.with_knee_tangential(p) is lp.p
    sol = lp.solve(LD.mirrored_touchdown(s.result.lift_off, FLIP["platform_height"]), warm=False)
    over = np.array([sol.U[k, 0] - float(p.F_max(sol.L[k])) for k in range(len(sol.t))])
    assert over.max() > 100.0, over.max()                        # N beyond the axial bound
    g = np.array(Jm.knot_functions(lp.p, len(sol.t))[2](sol.X.T, sol.U.T))
    assert g.min() > -1e-6, g.min()
    ft = (sol.U[:, 1] + sol.U[:, 2]) / np.hypot(sol.X[:, 0], sol.X[:, 1])
    assert ft[np.argmax(over)] < 0.0


def test_a_touch_down_that_falls_less_than_predicted_starts_next_to_a_shorter_fall_prediction():
    """Flip C's legs come down longer than they left, so its COM meets the ground higher above the feet
    and falls less than the lift-off predicts (offline from 1.5 s with read noise: ż −3.84 m/s against
    −4.03 predicted).  The predictions for a shorter fall (``PREDICTED_SHIFTS`` with dh > 0) put a solved
    state next to it, and its re-solve takes far fewer iterations than from the lean shifts alone
    (10 against 17 from this state)."""
    s = P.FlipSession("frontflip", forward_distance=0.6, **FLIP)
    s.jumping_reference()
    mirrored = mirrored_touchdown(s.result.lift_off, FLIP["platform_height"])
    lift_off_velocity, momentum = np.array([0.644, 0.0, 2.532]), 26.695      # measured, as the docstring's
    touch_down = np.array([-0.110, 0.906, 0.634, -3.836, 27.215])
    its = {}
    for name, shifts in (("lean", [sh for sh in PREDICTED_SHIFTS if sh[1] == 0.0]), ("all", PREDICTED_SHIFTS)):
        prob = LandingProblem(s.robot.params, s.robot.L0, near_start=True)
        prob.solve(mirrored, warm=False)
        predicted = predicted_touchdowns(mirrored, lift_off_velocity, momentum, FLIP["platform_height"], shifts)
        assert len(predicted) == len(shifts)
        for x0 in predicted:
            prob.solve(x0, warm=True)
        its[name] = prob.solve(touch_down, warm=True, near=WARM_NEAR, blend=True).iterations
    assert its["all"] <= its["lean"] - 5, its


def test_a_low_hop_predicts_no_touch_down_below_its_own_lift_off_height():
    """A shortened fall the COM never reaches falling (a hop's ż = 1 m/s rises 0.05 m, less than the
    0.08 m shorter fall) is not predicted: no touch-down state with a made-up sink."""
    mirrored = np.array([0.0, 0.9, 0.0, -1.0, 0.0])
    predicted = predicted_touchdowns(mirrored, np.array([0.0, 0.0, 1.0]), 0.0, 0.0)
    assert len(predicted) == sum(1 for sh in PREDICTED_SHIFTS if sh[1] == 0.0)
    assert all(x0[3] == -1.0 for x0 in predicted)


def test_a_backflip_landing_with_the_com_behind_the_feet_takes_the_momentum_out_through_the_feet():
    """B's measured touch-down (COM 0.066 m behind the feet, offline from 1.1 s with read noise): the
    landing plan takes the momentum out without first growing it past the touch-down's, which the
    flywheel would take (with the jump's foot-torque cost it ran from -38.3 to -48.4 kg m^2/s), with the
    foot torque inside the centre of pressure the controller's LANDING QP can realise after the first knot,
    and comes to rest."""
    from fslip_planner import landing as LD
    s = P.FlipSession("backflip", apex_height=1.3, motor_speed_scale=3.0, flywheel_torque=260.0)
    p = s.robot.params
    x0 = np.array([-0.066, 0.945, 0.196, -3.17, -38.3])
    sol = LandingProblem(p, s.robot.L0).solve(x0, warm=False)
    H = sol.X[:, 4]
    assert np.max(np.abs(H)) < 1.05 * abs(x0[4]), np.min(H)
    assert np.max(H) < 0.5                                     # no swing through zero
    half = (0.5 - LD.COP_MARGIN) * p.foot_length * (sol.Fz[1:] - 4.0 * LD.POINT_FORCE_MIN)
    assert np.all(np.abs(sol.U[1:, 2]) <= half + 1e-3)
    assert np.max(np.abs(sol.U[:, 2])) > 20.0                  # N m: the feet do take part
    assert np.allclose(sol.X[-1, [0, 2, 3, 4]], 0.0, atol=1e-6)


def test_the_landing_plans_centre_of_pressure_is_the_one_the_controller_keeps():
    """The landing NLP's narrowed ZMP row uses the LANDING QP's least force per toe and heel and the
    centre-of-pressure margin the controller keeps in the push-off (where the feet were seen to roll)."""
    from fslip_planner import landing as LD
    from tsc_controller.config import ControllerConfig
    from tsc_controller.reference import Domain
    cfg = ControllerConfig()
    assert LD.POINT_FORCE_MIN == cfg.f_min_domains[int(Domain.LANDING)]
    assert LD.COP_MARGIN == cfg.cop_margin_domains[int(Domain.JUMPING)]
