"""Jumping optimisation (paper §III-B): dynamics, constraints and the task at every knot."""
import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from fslip_planner import fslip as F
from fslip_planner import jumping as Jm
from fslip_planner import plan as P

# the somersault robot (leg motors x3, 260 N·m flywheel): the published robot's flywheel cannot turn a
# flip in the flight its knees give it (tests/unit/test_fslip_feasibility.py)
ROBOT = dict(motor_speed_scale=3.0, flywheel_torque=260.0)
CASES = {"backflip": dict(forward_distance=0.0, apex_height=1.3, **ROBOT),
         "frontflip": dict(forward_distance=1.0, apex_height=1.3, **ROBOT),
         "hop": dict(forward_distance=0.0)}


@pytest.fixture(scope="module")
def plans():
    return {k: P.plan_flip(k, **kw) for k, kw in CASES.items()}


@pytest.mark.parametrize("kind", list(CASES))
def test_reintegration_reproduces_states(plans, kind):
    s = plans[kind].solution
    p = s.params

    def f(t, x):
        u = [np.interp(t, s.t, s.U[:, i]) for i in range(3)]
        return F.dynamics_np(x, u, p)
    sol = solve_ivp(f, (0, s.T), s.X[0], t_eval=s.t, rtol=1e-9, atol=1e-9, max_step=s.T / 200)
    err = np.abs(sol.y.T - s.X).max(axis=0)
    assert err[0] < 0.01 and err[1] < 0.01            # positions, m
    assert err[2] < 0.05 and err[3] < 0.05            # velocities, m/s
    assert err[4] < 1e-3 * max(1.0, np.abs(s.X[:, 4]).max())


@pytest.mark.parametrize("kind", list(CASES))
def test_constraints_hold_at_every_knot(plans, kind):
    s = plans[kind].solution
    p = s.params
    tol = 1e-5
    Fs, tau, u = s.U.T
    assert np.all(s.Fz >= -tol * p.m * p.g)
    assert np.all(np.abs(s.Fx) <= p.mu * s.Fz + tol * p.m * p.g)
    assert np.all(np.abs(u) <= 0.5 * p.foot_length * s.Fz + 1e-4)
    assert np.all(np.abs(tau) <= p.tau_max + 1e-4)
    assert np.all((s.L >= p.L_min - 1e-6) & (s.L <= p.L_max + 1e-6))
    Fmax = np.array([float(p.F_max(L)) for L in s.L])
    assert np.all(Fs <= Fmax + 1e-3) and np.all(Fs >= -1e-6)
    rdot = (s.X[:, 0] * s.X[:, 2] + s.X[:, 1] * s.X[:, 3]) / np.hypot(s.X[:, 0], s.X[:, 1])
    # the simulator's motor envelope (cassie_model.motor_limits): linear from stall to no-load
    ratio = np.array([float(p.dqknee_dL(L)) for L in s.L]) * rdot / p.knee_no_load_speed
    env = Fmax * np.clip(1.0 - ratio, 0.0, 1.0)
    assert np.all(Fs <= env + 1e-3)
    # start at rest standing, lift-off at the last knot
    np.testing.assert_allclose(s.X[0, 2:], 0.0, atol=1e-9)
    assert s.Fz[0] == pytest.approx(p.m * p.g, rel=1e-6)
    assert abs(s.Fz[-1]) < 1e-6 and abs(s.Fx[-1]) < 1e-6
    assert s.X[-1, 3] > 0.3
    # control rates (Jm.RATE_LIMITS): forces the spring legs and leaf springs can follow
    dt = np.diff(s.t)
    rate = np.array([Jm.RATE_LIMITS[0] * p.m * p.g, Jm.RATE_LIMITS[1], Jm.RATE_LIMITS[2]])
    assert np.all(np.abs(np.diff(s.U, axis=0)) <= rate * dt[:, None] * (1 + 1e-6) + 1e-6)


@pytest.mark.parametrize("kind", list(CASES))
def test_task_encoding(plans, kind):
    r = plans[kind]
    lo, fig = r.lift_off, r.figures
    h = CASES[kind].get("platform_height", 0.0)
    T = (lo["zdot"] + math.sqrt(lo["zdot"] ** 2 + 2 * 9.81 * h)) / 9.81
    assert fig["flight_time"] == pytest.approx(T, rel=1e-6)
    sign = Jm.SIGN[kind]
    assert lo["thetadot"] * T == pytest.approx(sign * 2 * math.pi - 2 * lo["beta"], abs=1e-5)
    assert lo["momentum"] == pytest.approx(lo["thetadot"] * lo["inertia"], rel=1e-6)
    com_h = r.solution.extra["com_h"]
    assert lo["z"] + lo["zdot"] ** 2 / (2 * 9.81) + com_h == pytest.approx(r.request["apex_height"], abs=1e-5)
    d = CASES[kind]["forward_distance"]
    assert 2 * lo["x"] + lo["xdot"] * T == pytest.approx(d, abs=1e-5)
    if kind == "backflip":
        assert lo["momentum"] < -10
    elif kind == "frontflip":
        assert lo["momentum"] > 10 and lo["beta"] > 0      # leaning into a forward jump
    else:
        assert abs(lo["momentum"]) < 1e-6 and abs(lo["beta"]) < 1e-6


def test_platform_flight_time():
    r = P.plan_flip("backflip", platform_height=0.5, apex_height=1.2, **ROBOT)
    zd = r.lift_off["zdot"]
    T = (zd + math.sqrt(zd ** 2 + 2 * 9.81 * 0.5)) / 9.81
    assert r.figures["flight_time"] == pytest.approx(T, rel=1e-6)
    assert r.lift_off["thetadot"] * T == pytest.approx(-2 * math.pi - 2 * r.lift_off["beta"], abs=1e-5)


def test_plan_dict_contents(plans):
    d = plans["frontflip"].to_dict()
    for k in ("zdot", "xdot", "beta", "thetadot", "momentum"):
        assert math.isfinite(d["lift_off"][k])
    for k in ("liftoff_zdot", "flight_time", "peak_flywheel_speed", "solve_time", "iterations", "solve_time_s"):
        assert k in d
    n = len(d["knots"]["t"])
    assert 40 <= n <= 60
    for k in ("x", "z", "xdot", "zdot", "L", "s", "F_z", "F_x", "tau", "u", "H"):
        assert len(d["knots"][k]) == n
    assert d["knots"]["F_z"][-1] == pytest.approx(0.0, abs=1e-6)
    # peak flywheel speed: at least the lift-off momentum over the flywheel inertia, minus body share
    assert d["peak_flywheel_speed"] > 0.5 * abs(d["lift_off"]["momentum"]) / 0.1074
    assert d["solve_time_s"] < 5.0


def test_the_knee_tangential_plan_keeps_the_knees_within_their_torque():
    """Flip C planned with ``knee_tangential``: at every knot the knees' share F^s + rho(L) f_t stays
    within F_max(L); the axial-only plan of the same request goes past it where its frontflip torque
    pushes the foot back (it counts F^s alone), and the request records the model."""
    req = dict(apex_height=1.2, forward_distance=0.6, platform_height=0.5, **ROBOT)
    over = {}
    for tangential in (False, True):
        r = P.plan_flip("frontflip", knee_tangential=tangential, **req)
        assert r.request["knee_tangential"] is tangential
        s = r.solution
        q = F.params_for("I", knee_tangential=True, **ROBOT)        # the knee-torque model, either plan
        share = np.array([float(q.knee_leg_force(s.X[k], s.U[k])) for k in range(len(s.t))])
        over[tangential] = float(np.max(share - np.array([float(q.F_max(L)) for L in s.L])))
    assert over[True] <= 1e-3
    assert over[False] > 20.0
