"""FSLIP model (paper §III-A) and its regression to the robot."""
import math

import numpy as np
import pytest

from fslip_planner import fslip as F
from fslip_planner import regression as R


@pytest.fixture(scope="module")
def p():
    return F.params_for("I")


def test_dynamics_numpy_matches_casadi(p):
    ca = pytest.importorskip("casadi")
    x = np.array([0.1, 0.8, 0.3, 1.2, 5.0])
    u = np.array([800.0, 40.0, 3.0])
    xs, us = ca.SX.sym("x", 5), ca.SX.sym("u", 3)
    f = ca.Function("f", [xs, us], [ca.vertcat(*F.dynamics(xs, us, p))])
    np.testing.assert_allclose(np.array(f(x, u)).ravel(), F.dynamics_np(x, u, p), rtol=1e-12)


def test_paper_equations(p):
    """m ẍ = −(τ+u)/r cosβ + F sinβ, m z̈ = −mg + (τ+u)/r sinβ + F cosβ, Ḣ = τ."""
    x, z, F_s, tau, u = 0.2, 0.7, 600.0, 50.0, -4.0
    r, b = math.hypot(x, z), math.atan2(x, z)
    d = F.dynamics_np([x, z, 0, 0, 0], [F_s, tau, u], p)
    assert d[2] == pytest.approx((-(tau + u) / r * math.cos(b) + F_s * math.sin(b)) / p.m)
    assert d[3] == pytest.approx(-p.g + ((tau + u) / r * math.sin(b) + F_s * math.cos(b)) / p.m)
    assert d[4] == pytest.approx(tau)
    # the GRF moment about the mass is τ + u about +y (foot couple −u closes Ḣ = τ)
    Fx, Fz = F.grf([x, z, 0, 0, 0], [F_s, tau, u], p)
    a = (-x, -z)                                 # mass -> foot
    assert a[1] * Fx - a[0] * Fz == pytest.approx(tau + u)


def test_flywheel_torque_bound(p):
    """``flywheel_torque`` sets the plan's flywheel torque bound (default: the flywheel's 195 N·m);
    the planner caches one robot per value and refuses an invalid one."""
    from fslip_planner import plan as PL
    assert p.tau_max == 195.0
    assert F.params_for("I", flywheel_torque=260).tau_max == 260.0
    assert F.params_for("I", flywheel_torque=0).tau_max == 195.0
    assert PL._Robot.get("I", flywheel_torque=260).params.tau_max == 260.0
    assert PL._Robot.get("I").params.tau_max == 195.0
    for bad in (-1.0, math.nan):
        with pytest.raises(ValueError, match="flywheel torque limit"):
            F.params_for("I", flywheel_torque=bad)
        with pytest.raises(ValueError, match="flywheel torque limit"):
            PL.FlipSession("backflip", flywheel_torque=bad)


def test_static_state_is_equilibrium(p):
    X, U = F.static_state(p, 0.86)
    assert float(F.leg_length(X, U, p)) == pytest.approx(0.86, abs=1e-9)
    np.testing.assert_allclose(F.dynamics_np(X, U, p), 0.0, atol=1e-9)


def test_regression_fit_quality():
    reg = R.load("I")
    fits = reg.info["fits"]
    assert fits["I"]["r2"] > 0.9999 and fits["I"]["max_rel_err"] < 0.005
    assert fits["K"]["r2"] > 0.99 and fits["K"]["max_rel_err"] < 0.10
    assert fits["F_max"]["r2"] > 0.99 and fits["F_max"]["max_rel_err"] < 0.05
    # physically sensible ranges: stiffer and more inertia as the leg extends
    assert 5e3 < fits["K"]["min"] < fits["K"]["max"] < 5e4
    assert 1.5 < fits["I"]["min"] < fits["I"]["max"] < 3.0
    L = np.linspace(reg.L_min, reg.L_max, 20)
    assert np.all(np.diff(reg("I", L)) > 0)
    # heavier flywheels add inertia (same legs: same K)
    assert R.load("III")("I", 0.8) > R.load("II")("I", 0.8) > reg("I", 0.8)
    assert R.load("III")("K", 0.8) == pytest.approx(reg("K", 0.8))


def test_regression_recomputed_matches_file():
    rows = R.standing_grid("I", n=3, knee_range=(-1.9, -1.0))
    reg = R.load("I")
    for knee, L, K, D, I, dq, comh, rho in rows:
        assert reg("I", L) == pytest.approx(I, rel=5e-3)
        assert reg("rho", L) == pytest.approx(rho, rel=0.08)
        assert reg("K", L) == pytest.approx(K, rel=0.10)
        assert reg("com_h", L) == pytest.approx(comh, rel=5e-3)


def test_the_knee_swings_the_foot_forward_more_the_straighter_the_leg():
    """rho(L) = L (dα/dq_knee) / (dL/dq_knee): a knee extension moves the foot forward about the hip as
    well as away from it, by about half as much in a deep crouch and more than twice as much near full
    extension (so a tangential foot force loads the knee too)."""
    reg = R.load("I")
    fit = reg.info["fits"]["rho"]
    assert fit["r2"] > 0.99
    assert 0.3 < fit["min"] < 0.7 and 2.0 < fit["max"] < 3.0
    L = np.linspace(reg.L_min, reg.L_max, 20)
    assert np.all(np.diff(reg("rho", L)) > 0)


@pytest.mark.parametrize("tau, loaded", [(80.0, True), (-80.0, False)])
def test_the_knee_model_counts_the_tangential_force_when_asked(tau, loaded):
    """``knee_tangential``: the knees' share is F^s + rho(L) f_t (f_t = (τ+u)/r), so at F^s = F_max(L)
    a frontflip's pitching torque (τ > 0: the ground pushes the foot back) violates the knee row and a
    backflip's leaves slack; without it the row sees F^s alone (0 at F_max)."""
    pytest.importorskip("casadi")
    from fslip_planner import jumping as Jm
    rows = {}
    for tangential in (False, True):
        q = F.params_for("I", motor_speed_scale=3.0, flywheel_torque=260.0, knee_tangential=tangential)
        x = np.array([0.02, 0.62, 0.0, 0.0, 0.0])             # at rest: the envelope rows equal the limit row
        Fs = 1.0
        for _ in range(30):                                   # F^s = F_max(L(F^s))
            Fs = float(q.F_max(F.leg_length(x, [Fs, tau, 0.0], q)))
        u = np.array([Fs, tau, 0.0])
        g = np.array(Jm.knot_functions(q, 1)[2](x, u)).ravel() * Jm.row_scales(q)[:13]
        rows[tangential] = g[Jm.PATH_ROWS.index("leg force limit (knee torque)")]
        L = float(F.leg_length(x, u, q))
        f_t = tau / float(np.hypot(*x[:2]))
        assert float(q.knee_leg_force(x, u)) == pytest.approx(Fs + (q.reg("rho", L) * f_t if tangential else 0.0))
    assert rows[False] == pytest.approx(0.0, abs=1e-6)
    assert (rows[True] < -50.0) if loaded else (rows[True] > 50.0)


def test_missing_data_file_names_script(tmp_path):
    with pytest.raises(FileNotFoundError, match="fit_fslip_regression.py"):
        R.load("I", path=str(tmp_path / "none.json"))
