"""Correspondence of the FSLIP to the robot (paper §III-A, "Correspondence to the robot").

Over a grid of standing configurations of the MuJoCo model (knee angle swept from a deep crouch to
near full extension; pelvis level, both legs equal, loops closed, feet flat, whole-body COM above the
feet) we compute, per configuration:

* ``L``: leg length, hip-pitch joint origin -> foot joint origin (mean of both legs; the
  controller's ``L`` output);
* ``K``: axial leg stiffness projected from the joint springs (shin 1500, heel 1250 N·m/rad).  With
  the knee and hip locked, the foot-joint position p(q_s) relative to the hip depends on the two
  spring deflections q_s (the tarsus follows from the achilles loop).  J_s = dp/dq_s by central
  differences with the loop re-closed; the axial compliance is c = nᵀ J_s K_s⁻¹ J_sᵀ n (n = unit
  hip->foot vector), i.e. the static spring deflection per unit leg force is
  dq_s/dL = K_s⁻¹ J_sᵀ n / c and K_leg = (dq_s/dL)ᵀ K_s (dq_s/dL) = 1/c; both legs in parallel:
  K = 2 K_leg;
* ``D``: the same projection of the joint damping: D = 2 (dq_s/dL)ᵀ D_s (dq_s/dL);
* ``I``: centroidal pitch inertia of the whole robot about its COM (world y), flywheel included,
  from MuJoCo's body inertias (principal inertia rotated by ``ximat`` + parallel-axis term);
* ``dqk_dL``: knee-angle change per unit leg length (springs at rest), giving the leg-force limit
  F_max(L) = 2 τ_knee,max / |dL/dq_knee| (virtual work, both knees);
* ``com_h``: COM height above the ground minus L (the FSLIP point mass sits at the COM);
* ``rho``: the knee's tangential lever, L (dα/dq_knee) / (dL/dq_knee) (α: the hip->foot direction,
  + forward): a knee turn also swings the foot about the hip, so the knee torque of a foot force with
  axial part F^s and tangential part f_t is (F^s + rho f_t) dL/dq_knee (virtual work) — used by the
  planner's ``knee_tangential`` model (:mod:`fslip_planner.jumping`).

Polynomials in L (degree 3) are fitted per flywheel variant and written to
``data/fslip_regression.json`` by ``scripts/fit_fslip_regression.py``; :func:`load` reads it.
"""
from __future__ import annotations

import json
import os
from dataclasses import dataclass
from typing import Dict

import numpy as np

DATA_FILE = os.path.join(os.path.dirname(__file__), "data", "fslip_regression.json")
FIT_DEGREE = 3
QUANTITIES = ("K", "D", "I", "F_max", "com_h", "rho")


def _robot():
    import mujoco

    from cassie_model import model as M
    from cassie_model import robot_params as P
    return mujoco, M, P


class _Kin:
    """Standing-configuration kinematics on the MuJoCo model (loops closed by Gauss-Newton)."""

    def __init__(self, flywheel="I"):
        mujoco, M, P = _robot()
        self.mj, self.M, self.P = mujoco, M, P
        self.model = M.build_model(flywheel, "flat")
        self.data = mujoco.MjData(self.model)
        m = self.model
        jid = lambda n: mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n)  # noqa: E731
        self.jid = jid
        self.qadr = lambda n: int(m.jnt_qposadr[jid(n)])  # noqa: E731
        self.dadr = lambda n: int(m.jnt_dofadr[jid(n)])  # noqa: E731
        self.passive = []
        for side in ("left", "right"):
            for j in ("achilles_rod", "tarsus", "foot_crank", "plantar_rod", "foot"):
                a = self.dadr(f"{side}_{j}")
                n = 3 if m.jnt_type[jid(f"{side}_{j}")] == mujoco.mjtJoint.mjJNT_BALL else 1
                self.passive += list(range(a, a + n))
        self.pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        gids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, g) for s in ("left", "right")
                for g in M.FOOT_GEOMS[s]]
        self._foot_bodies = [int(m.geom_bodyid[g]) for g in gids]

    def fk(self, qpos):
        d = self.data
        d.qpos[:] = qpos
        self.mj.mj_kinematics(self.model, d)
        self.mj.mj_comPos(self.model, d)

    def close(self, qpos, dofs=None, balance=False, tol=1e-11, max_iter=60):
        """Close the loops (connects + flat feet) over ``dofs`` (default: passive joints); with
        ``balance`` also put the COM above the mid-foot using both hip pitches (kept equal)."""
        mj, m, d = self.mj, self.model, self.data
        dofs = list(self.passive if dofs is None else dofs)
        hp = [self.dadr("left_hip_pitch"), self.dadr("right_hip_pitch")]
        qpos = qpos.copy()
        for _ in range(max_iter):
            self.fk(qpos)
            r, J = self.M._closure_system(m, d)
            if balance:
                jc = np.zeros((3, m.nv))
                mj.mj_jacSubtreeCom(m, d, jc, self.pelvis)
                feet = self.M.foot_points_world(m, d)
                r = np.r_[r, d.subtree_com[self.pelvis][0] - feet[:, 0].mean()]
                jf = np.zeros((3, m.nv))
                for p, b in zip(feet, self._foot_bodies):
                    jp = np.zeros((3, m.nv))
                    mj.mj_jac(m, d, jp, None, p, b)
                    jf += jp / len(feet)
                J = np.vstack([J, jc[0] - jf[0]])
                cols = dofs + hp
            else:
                cols = dofs
            if np.max(np.abs(r)) < tol:
                return qpos
            A = J[:, cols]
            if balance:   # equal hip pitches: one column for both
                A = np.c_[J[:, dofs], J[:, hp].sum(axis=1)]
            step = -np.linalg.lstsq(A, r, rcond=None)[0]
            dq = np.zeros(m.nv)
            dq[dofs] = step[:len(dofs)]
            if balance:
                dq[hp] = step[-1]
            mj.mj_integratePos(m, qpos, dq, 1.0)
        raise RuntimeError(f"loop closure did not converge (residual {np.max(np.abs(r)):.2e})")

    def legs(self, qpos):
        """[(hip->foot vector) per side] in the world frame."""
        self.fk(qpos)
        d = self.data
        out = []
        for s in ("left", "right"):
            out.append(d.xanchor[self.jid(f"{s}_foot")] - d.xanchor[self.jid(f"{s}_hip_pitch")])
        return out

    def leg_length(self, qpos):
        return float(np.mean([np.linalg.norm(v) for v in self.legs(qpos)]))

    def pitch_inertia(self, qpos):
        """Whole-robot centroidal inertia about world y (kg·m²)."""
        self.fk(qpos)
        m, d = self.model, self.data
        c = d.subtree_com[self.pelvis]
        Iyy = 0.0
        for b in range(1, m.nbody):
            R = d.ximat[b].reshape(3, 3)
            Ib = R @ np.diag(m.body_inertia[b]) @ R.T
            r = d.xipos[b] - c
            Iyy += Ib[1, 1] + m.body_mass[b] * (r[0] ** 2 + r[2] ** 2)
        return float(Iyy)


def standing_grid(flywheel="I", n=15, knee_range=(-2.20, -0.80)):
    """Rows (knee, L, K, D, I, dqk_dL, com_h, rho) over a grid of knee angles (rad)."""
    kin = _Kin(flywheel)
    mj, M, P = kin.mj, kin.M, kin.P
    m = kin.model
    q0, _ = M.standing_state(m, "flat")
    springs = P.spring_params()
    Ks = np.diag([springs["left_shin"][0], springs["left_heel_spring"][0]])
    damp = {b.joint.name: b.joint.damping for b in P.BODIES if b.joint is not None}
    Ds = np.diag([damp["left_shin"], damp["left_heel_spring"]])
    rows = []
    qprev = q0.copy()
    for k in np.linspace(knee_range[0], knee_range[1], n):
        q = qprev.copy()
        k0 = q[kin.qadr("left_knee")]
        for kk in np.linspace(k0, k, 2 + int(abs(k - k0) / 0.05))[1:]:   # continuation
            for s in ("left", "right"):
                q[kin.qadr(f"{s}_knee")] = kk
            q = kin.close(q, balance=True)
        qprev = q
        kin.fk(q)
        feet = M.foot_points_world(m, kin.data)
        zc = kin.data.subtree_com[kin.pelvis][2] - (feet[:, 2].min() - P.FOOT_RADIUS)
        L = kin.leg_length(q)
        # spring Jacobian per leg (knee, hip locked; passive joints re-close the loops)
        K_leg, D_leg, dqk, rho = [], [], [], []
        for si, s in enumerate(("left", "right")):
            leg = kin.legs(q)[si]
            n_vec = leg / np.linalg.norm(leg)
            Js = np.zeros((3, 2))
            h = 1e-4
            for j, name in enumerate((f"{s}_shin", f"{s}_heel_spring")):
                pts = []
                for sign in (1, -1):
                    qq = q.copy()
                    qq[kin.qadr(name)] += sign * h
                    qq = kin.close(qq)
                    pts.append(kin.legs(qq)[si])
                Js[:, j] = (pts[0] - pts[1]) / (2 * h)
            g = Js.T @ n_vec                     # dL/dq_s
            c = g @ np.linalg.solve(Ks, g)       # axial compliance
            dq_dL = np.linalg.solve(Ks, g) / c   # static spring deflection per unit L
            K_leg.append(dq_dL @ Ks @ dq_dL)
            D_leg.append(dq_dL @ Ds @ dq_dL)
            pts, ang = [], []
            for sign in (1, -1):
                qq = q.copy()
                qq[kin.qadr(f"{s}_knee")] += sign * h
                qq = kin.close(qq)
                v = kin.legs(qq)[si]
                pts.append(np.linalg.norm(v))
                ang.append(np.arctan2(v[0], -v[2]))
            dqk.append(2 * h / abs(pts[0] - pts[1]))
            rho.append(np.linalg.norm(leg) * (ang[0] - ang[1]) / (pts[0] - pts[1]))
        rows.append((k, L, sum(K_leg), sum(D_leg), kin.pitch_inertia(q), float(np.mean(dqk)), zc - L,
                     float(np.mean(rho))))
    return np.array(rows)


def fit(rows, knee_torque, degree=FIT_DEGREE) -> dict:
    """Polynomial fits (numpy.polyfit, highest power first) of K, D, I, F_max, com_h, rho over L."""
    L = rows[:, 1]
    data = {"K": rows[:, 2], "D": rows[:, 3], "I": rows[:, 4],
            "F_max": 2.0 * knee_torque * rows[:, 5], "com_h": rows[:, 6], "rho": rows[:, 7]}
    out = {"L_min": float(L.min()), "L_max": float(L.max()), "degree": degree, "fits": {},
           "samples": {"L": L.tolist(), "knee": rows[:, 0].tolist(),
                       "dqknee_dL": rows[:, 5].tolist(), **{k: v.tolist() for k, v in data.items()}}}
    for name, y in data.items():
        c = np.polyfit(L, y, degree)
        yh = np.polyval(c, L)
        ss = float(np.sum((y - y.mean()) ** 2))
        r2 = 1.0 - float(np.sum((y - yh) ** 2)) / ss if ss > 0 else 1.0
        rel = float(np.max(np.abs(y - yh) / np.maximum(np.abs(y), 1e-9)))
        out["fits"][name] = {"coeffs": c.tolist(), "r2": r2, "max_rel_err": rel,
                             "min": float(y.min()), "max": float(y.max())}
    return out


@dataclass(frozen=True)
class Regression:
    """Fitted FSLIP-to-robot correspondence for one flywheel variant."""
    flywheel: str
    L_min: float
    L_max: float
    coeffs: Dict[str, tuple]
    info: dict

    def __call__(self, name, L):
        """Polynomial ``name`` (K, D, I, F_max, com_h, rho) at L; works for floats and CasADi symbols."""
        c = self.coeffs[name]
        y = 0.0 * L + c[0]
        for a in c[1:]:
            y = y * L + a
        return y


_CACHE: Dict[str, Regression] = {}


def load(flywheel="I", path: str = DATA_FILE) -> Regression:
    """The fitted regression for a Table I flywheel ("I", "II", "III") from the JSON data file."""
    key = f"{path}:{flywheel}"
    if key in _CACHE:
        return _CACHE[key]
    if not os.path.exists(path):
        raise FileNotFoundError(
            f"{path} missing: generate it with `.venv/bin/python scripts/fit_fslip_regression.py`")
    with open(path) as f:
        doc = json.load(f)
    if flywheel not in doc["flywheels"]:
        raise ValueError(f"flywheel {flywheel!r} not in {path} (have {sorted(doc['flywheels'])})")
    e = doc["flywheels"][flywheel]
    reg = Regression(flywheel, e["L_min"], e["L_max"],
                     {k: tuple(v["coeffs"]) for k, v in e["fits"].items()}, e)
    _CACHE[key] = reg
    return reg


def knee_torque_limit() -> float:
    _, _, P = _robot()
    return next(mo.torque_limit for mo in P.CASSIE_MOTORS if mo.joint == "left_knee")


def knee_no_load_speed() -> float:
    _, _, P = _robot()
    return next(mo.no_load_speed for mo in P.CASSIE_MOTORS if mo.joint == "left_knee")


def compute_all(flywheels=("I", "II", "III"), n=15) -> dict:
    tk = knee_torque_limit()
    doc = {"description": __doc__.strip().splitlines()[0], "knee_torque_limit": tk,
           "knee_no_load_speed": knee_no_load_speed(), "flywheels": {}}
    for fw in flywheels:
        e = fit(standing_grid(fw, n=n), tk)
        e["knee_torque_limit"] = tk
        doc["flywheels"][fw] = e
    return doc


if __name__ == "__main__":  # pragma: no cover
    np.set_printoptions(precision=4, suppress=True)
    print("knee, L, K, D, I, dqknee/dL, com_h, rho")
    print(standing_grid("I", n=6))
