"""tsc_controller.dynamics / tsc: the eliminated constraint forces F = A_v u + b_v and qddot = Abar u + bbar
(paper eq. (utoF)) against independent computations:
  * Pinocchio's constraintDynamics with the MJCF loop closures and 3D point contacts (paper's model,
    springs free), and
  * a plain KKT solve built from Pinocchio's per-frame Jacobians / classical accelerations (rigid springs).
"""
import numpy as np
import pinocchio as pin
import pytest

from cassie_model.model import export_mjcf
from cassie_model.pinocchio_map import PinocchioMap
from cassie_flip_sim.simulator import Simulator
from tsc_controller.dynamics import SIDES, Dynamics
from tsc_controller.tsc import ConstrainedDynamics

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED


def _frame_terms(dyn, names, q, v):
    """Independent J (3 x nv) / classical drift of point frames via Pinocchio's frame API."""
    m = dyn.model
    d = m.createData()
    pin.forwardKinematics(m, d, q, v, np.zeros(m.nv))
    pin.computeJointJacobians(m, d, q)
    pin.updateFramePlacements(m, d)
    out = {}
    for n in names:
        f = dyn.points[n].frame_id
        out[n] = (d.oMf[f].copy(), pin.getFrameJacobian(m, d, f, LWA)[:3].copy(),
                  pin.getFrameClassicalAcceleration(m, d, f, LWA).linear.copy(),
                  pin.getFrameJacobian(m, d, f, LWA)[3:].copy())
    return out


def _independent_J(dyn, q, v, ground):
    """Full 3D loop rows, 3D toe + heel rows (world), spring rows — rank-deficient but consistent."""
    names = [n for n in dyn.points if n.startswith("loop") or n.endswith("_toe") or n.endswith("_heel")]
    T = _frame_terms(dyn, names, q, v)
    Js, ds = [], []
    for k in range(len(dyn._loops)):
        a, b = T[f"loop{k}_a"], T[f"loop{k}_b"]
        w1 = a[3] @ v
        Js.append(a[1] - b[1])
        ds.append(a[2] - b[2] - np.cross(w1, (a[1] - b[1]) @ v))
    if ground:
        for s in SIDES:
            for p in ("toe", "heel"):
                Js.append(T[f"{s}_{p}"][1])
                ds.append(T[f"{s}_{p}"][2])
    return np.vstack(Js), np.concatenate(ds)


def random_state(dyn, rng, ground, base=None, scale=0.15):
    """A configuration on the loop-closure manifold near the standing pose and a velocity that
    satisfies the domain's constraints (so every formulation of the constraints is consistent)."""
    sim = Simulator()
    pm = PinocchioMap(sim.model, dyn.model)
    q0, _ = pm.to_pin(sim.data.qpos, sim.data.qvel)
    dq = np.zeros(dyn.nv)
    dq[:6] = rng.normal(0, [0.05, 0.05, 0.05, 0.1, 0.1, 0.1])
    dq[dyn.motor_v] = rng.normal(0, scale, dyn.nu)
    dq[dyn.spring_v] = rng.normal(0, 0.03, len(dyn.spring_v))
    q = pin.integrate(dyn.model, q0, dq)
    passive = [i for i in range(6, dyn.nv) if i not in set(dyn.motor_v) | set(dyn.spring_v)]
    for _ in range(30):   # Gauss-Newton on the passive joints: close the loops
        dyn.update(q, np.zeros(dyn.nv))
        r = np.concatenate([dyn.data.oMf[dyn.points[f"loop{k}_a"].frame_id].translation
                            - dyn.data.oMf[dyn.points[f"loop{k}_b"].frame_id].translation
                            for k in range(len(dyn._loops))])
        if np.abs(r).max() < 1e-11:
            break
        Jr, _ = _independent_J(dyn, q, np.zeros(dyn.nv), False)
        step = np.zeros(dyn.nv)
        step[passive] = -np.linalg.lstsq(Jr[:, passive], r, rcond=None)[0]
        q = pin.integrate(dyn.model, q, step)
    assert np.abs(r).max() < 1e-9
    J, _ = _independent_J(dyn, q, np.zeros(dyn.nv), ground)
    if dyn.rigid_springs:
        J = np.vstack([J, dyn._Jspring])
    _, s, Vt = np.linalg.svd(J)
    N = Vt[np.sum(s > 1e-9 * s[0]):].T
    v = N @ rng.normal(0, 1.0, N.shape[1])
    return q, v


def _foot_wrenches_from_tsc(dyn, F):
    """World force and moment about the toe of each foot from the 5-row contact forces."""
    out = []
    for k, s in enumerate(SIDES):
        R = dyn.foot_frame(s)
        f = F[5 * k: 5 * k + 5]
        ft = R.T @ f[:3]
        fh = R[1:].T @ f[3:]
        r = dyn.point(f"{s}_heel")[0] - dyn.point(f"{s}_toe")[0]
        out.append((ft + fh, np.cross(r, fh)))
    return out


@pytest.fixture(scope="module")
def mjcf():
    return export_mjcf()


@pytest.mark.parametrize("ground", [True, False])
def test_forces_match_pinocchio_constraint_dynamics(mjcf, ground):
    """Paper's model (springs free): A_v u + b_v and Abar u + bbar vs pinocchio.constraintDynamics."""
    dyn = Dynamics(mjcf, rigid_springs=False)
    m = dyn.model
    cms = pin.StdVec_RigidConstraintModel()
    for (a, b) in dyn._loops:
        fa, fb = m.frames[a.frame_id], m.frames[b.frame_id]
        cms.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, m, fa.parentJoint, fa.placement,
                                            fb.parentJoint, fb.placement, pin.ReferenceFrame.LOCAL))
    if ground:
        for s in SIDES:
            for p in ("toe", "heel"):
                f = m.frames[dyn.points[f"{s}_{p}"].frame_id]
                cms.append(pin.RigidConstraintModel(pin.ContactType.CONTACT_3D, m, f.parentJoint, f.placement, LWA))
    cds = pin.StdVec_RigidConstraintData()
    for c in cms:
        cds.append(c.createData())
    data = m.createData()
    pin.initConstraintDynamics(m, data, cms, cds)
    prox = pin.ProximalSettings(1e-14, 1e-9, 200)
    rng = np.random.default_rng(7 + ground)
    for trial in range(5):
        q, v = random_state(dyn, rng, ground)
        dyn.update(q, v)
        cd = ConstrainedDynamics(dyn, ground)
        u = rng.uniform(-40, 40, dyn.nu)
        qdd = cd.Abar @ u + cd.bbar
        F = cd.A @ u + cd.b
        tau = dyn.B @ u + dyn.tau_passive
        qdd_ref = pin.constraintDynamics(m, data, q, v, tau, cms, cds, prox)
        scale = np.abs(qdd_ref).max()
        assert np.abs(qdd - qdd_ref).max() < 1e-6 * scale, (trial, np.abs(qdd - qdd_ref).max(), scale)
        # generalized constraint forces J^T F (unique, whatever the row basis) agree
        Jp = pin.getConstraintsJacobian(m, data, cms, cds)
        gf_ref = Jp.T @ data.lambda_c
        gf = cd.J.T @ F
        assert np.abs(gf - gf_ref).max() < 1e-6 * np.abs(gf_ref).max(), (trial, np.abs(gf - gf_ref).max())
        if ground:
            lam = data.lambda_c.copy()
            nl = 3 * len(dyn._loops)
            for k, (fw, mw) in enumerate(_foot_wrenches_from_tsc(dyn, F)):
                ft, fh = lam[nl + 6 * k: nl + 6 * k + 3], lam[nl + 6 * k + 3: nl + 6 * k + 6]
                r = dyn.point(f"{SIDES[k]}_heel")[0] - dyn.point(f"{SIDES[k]}_toe")[0]
                f_ref, m_ref = ft + fh, np.cross(r, fh)
                fs = max(np.abs(f_ref).max(), 1.0)
                assert np.abs(fw - f_ref).max() < 1e-6 * fs, (trial, fw, f_ref)
                # the moment about the toe-heel line is not transmitted; the rest must agree
                e = r / np.linalg.norm(r)
                assert np.abs((mw - m_ref) - e * (e @ (mw - m_ref))).max() < 1e-6 * fs * np.linalg.norm(r)


@pytest.mark.parametrize("ground", [True, False])
def test_forces_match_kkt_rigid_springs(mjcf, ground):
    """Controller model (rigid springs): vs a KKT solve with frame-API Jacobians and crba's M."""
    dyn = Dynamics(mjcf, rigid_springs=True)
    rng = np.random.default_rng(11 + ground)
    for trial in range(5):
        q, v = random_state(dyn, rng, ground)
        dyn.update(q, v)
        cd = ConstrainedDynamics(dyn, ground)
        u = rng.uniform(-40, 40, dyn.nu)
        # independent: full (rank-deficient) constraint set + spring rows, least-squares KKT
        Jl, dl = _independent_J(dyn, q, v, ground)
        J = np.vstack([Jl, dyn._Jspring])
        d = np.concatenate([dl, np.zeros(len(dyn.spring_v))])
        M = pin.crba(dyn.model, dyn.model.createData(), q)
        M = np.triu(M) + np.triu(M, 1).T
        h = pin.rnea(dyn.model, dyn.model.createData(), q, v, np.zeros(dyn.nv))
        nc = J.shape[0]
        K = np.block([[M, -J.T], [J, np.zeros((nc, nc))]])
        rhs = np.concatenate([dyn.B @ u + dyn.tau_passive - h, -d])
        sol = np.linalg.lstsq(K, rhs, rcond=1e-12)[0]
        qdd_ref = sol[:dyn.nv]
        qdd = cd.Abar @ u + cd.bbar
        assert np.abs(qdd - qdd_ref).max() < 1e-7 * max(1.0, np.abs(qdd_ref).max())
        # generalized constraint force J^T F is unique: compare it
        gf = cd.J.T @ (cd.A @ u + cd.b)
        gf_ref = J.T @ sol[dyn.nv:]
        assert np.abs(gf - gf_ref).max() < 1e-7 * max(1.0, np.abs(gf_ref).max())
        # and with Pinocchio's M^-1: M qdd + H = B u + J^T F
        resid = M @ qdd + h - dyn.tau_passive - dyn.B @ u - gf
        assert np.abs(resid).max() < 1e-7 * max(1.0, np.abs(h).max())


def test_minv_and_constraint_rank(mjcf):
    dyn = Dynamics(mjcf)
    rng = np.random.default_rng(3)
    q, v = random_state(dyn, rng, True)
    dyn.update(q, v)
    assert np.allclose(dyn.Minv @ dyn.M, np.eye(dyn.nv), atol=1e-8)
    J, _ = dyn.constraints(True)
    assert J.shape == (10 + 10 + 4, dyn.nv)
    assert np.linalg.matrix_rank(J) == J.shape[0]
