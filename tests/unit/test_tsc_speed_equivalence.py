"""The batched per-tick terms of tsc_controller.dynamics (issue 5, tick time) against Pinocchio's
per-frame API, on random states: point positions, world-aligned Jacobians, classical drifts, velocities,
and the constraint rows (contact rows in the foot-heading basis, loop rows S R1^T (J_a - J_b) with drift
S R1^T (a_a - a_b - w_1 x (v_a - v_b)))."""
import numpy as np
import pytest

from cassie_model.model import export_mjcf
from test_tsc_dynamics import _frame_terms, random_state
from tsc_controller.dynamics import N_CONTACT, SIDES, Dynamics


@pytest.fixture(scope="module")
def dyn():
    return Dynamics(export_mjcf())


def _frame(dyn, name, q, v):
    """(p, J_lin, classical drift, pdot, omega, R) of a point by Pinocchio's frame API."""
    M, J, a, Jw = _frame_terms(dyn, [name], q, v)[name]
    return M.translation, J, a, J @ v, Jw @ v, M.rotation


@pytest.mark.parametrize("seed", [0, 1])
def test_point_table_matches_frame_api(dyn, seed):
    rng = np.random.default_rng(seed)
    q, v = random_state(dyn, rng, False)
    v = v + rng.normal(0, 0.5, dyn.nv)          # off the constraint manifold too: the table does not assume it
    dyn.update(q, v)
    for name in dyn.points:
        p, J, a, pd, w, _ = _frame(dyn, name, q, v)
        P, Jt, drift, pdot, omega = dyn.point(name)
        assert np.allclose(P, p, atol=1e-12) and np.allclose(Jt, J, atol=1e-12)
        assert np.allclose(pdot, pd, atol=1e-10) and np.allclose(omega, w, atol=1e-10)
        if not name.startswith("loop"):           # loop points: drift relative to the loop's body 1
            assert np.allclose(drift, a, atol=1e-9 * max(1.0, np.abs(a).max())), name


@pytest.mark.parametrize("seed", [2, 3])
def test_constraint_rows_match_frame_api(dyn, seed):
    rng = np.random.default_rng(seed)
    q, v = random_state(dyn, rng, True)
    v = v + rng.normal(0, 0.5, dyn.nv)
    dyn.update(q, v)
    J, d = dyn.constraints(True)
    rows, drifts = [], []
    for s in SIDES:
        toe, heel = (_frame(dyn, f"{s}_{k}", q, v) for k in ("toe", "heel"))
        R = dyn.foot_frame(s)
        rows += [R @ toe[1], R[1:] @ heel[1]]
        drifts += [R @ toe[2], R[1:] @ heel[2]]
    for (a, b), S in zip(dyn._loops, dyn._loop_sel):
        fa, fb = _frame(dyn, a.name, q, v), _frame(dyn, b.name, q, v)
        SR = S @ fa[5].T
        rows.append(SR @ (fa[1] - fb[1]))
        drifts.append(SR @ (fa[2] - fb[2] - np.cross(fa[4], fa[3] - fb[3])))
    rows.append(dyn._Jspring)
    drifts.append(np.zeros(len(dyn.spring_v)))
    J_ref, d_ref = np.vstack(rows), np.concatenate(drifts)
    assert np.abs(J - J_ref).max() < 1e-12
    assert np.abs(d - d_ref).max() < 1e-9 * max(1.0, np.abs(d_ref).max())
    # domain row sets: flight (no contact rows), one foot
    Jf, df = dyn.constraints(False)
    assert np.array_equal(Jf, J[N_CONTACT:]) and np.array_equal(df, d[N_CONTACT:])
    Jl, dl = dyn.constraints(True, (True, False))
    assert np.array_equal(Jl, np.vstack([J[:5], J[N_CONTACT:]])) and np.array_equal(dl, np.r_[d[:5], d[N_CONTACT:]])
    Jr, _ = dyn.constraints(True, (False, True))
    assert np.array_equal(Jr, np.vstack([J[5:N_CONTACT], J[N_CONTACT:]]))
