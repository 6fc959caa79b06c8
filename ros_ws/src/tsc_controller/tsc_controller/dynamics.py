"""Rigid-body dynamics of Cassie + flywheel with Pinocchio (paper eq. (1)-(2)).

The model is loaded from the simulator's exported MJCF string (``cassie_flip_sim.model.export_mjcf``).
Pinocchio imports the kinematic tree, inertias, armature and the MJCF ``connect`` equalities (the four
loop closures); it does not import joint stiffness, so the spring torques tau_s = -K (q - q_spring) of the
shin and heel springs and the viscous joint damping -D v are read with MuJoCo's compiler from the same
string and added to the bias here.

Per tick (:meth:`Dynamics.update`): crba (M), nonLinearEffects (H), dccrba (A_g, dA_g, the joint
Jacobians and their time variation), then frame Jacobians / drifts J v-dot terms of the points the
constraints and outputs use.

Holonomic constraints J_{h,v} (eq. (2)):
  * loop closures (always): each MJCF ``connect`` is a 3D point coincidence.  A loop whose hinges are all
    parallel (Cassie's foot crank / plantar rod / foot four-bar) is planar, so one of its three rows is
    identically zero; that row (the hinge-axis direction, constant in the body-1 frame) is dropped so
    that J keeps full row rank.
  * ground contact (STANDING, JUMPING, LANDING): Cassie's foot is a line (a capsule), so each foot is
    held flat by its two capsule end points (toe, heel).  Two 3D point constraints on one body have a
    redundant row (the force component along the toe-heel line is split arbitrarily); we keep
    toe (d, t, n) and heel (t, n), with n = world z, d = horizontal toe-heel direction, t = n x d.  This
    is 5 independent rows per foot (roll about the foot line stays free, as on the real line foot),
    and the normal rows at both ends make f_n >= 0 at toe and heel a centre-of-pressure condition.
  * leaf springs held rigid (``rigid_springs=True``, default): with the shin and heel springs free,
    the ground forces at an instant do not depend on u at all (the motors only accelerate the light
    links in front of the springs; u reaches the ground through the spring deflection, two
    integrations later), so the torque-only QP of §V-B cannot shape F_v.  The controller model
    therefore adds qddot_spring = 0 rows (the usual rigid-spring model of Cassie controllers); the
    measured spring deflections still enter the kinematics and tau_s.  False = the paper's model.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED
_CROW = np.array([0, 1, 2, 1, 2, 0, 1, 2, 1, 2])   # d, t, n of the contact basis
_CPT = np.array([0, 0, 0, 1, 1, 2, 2, 2, 3, 3])    # toe_l, heel_l, toe_r, heel_r
_gFJ = pin.getFrameJacobian
_gFJTV = pin.getFrameJacobianTimeVariation

MOTOR_NAMES = (
    "left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
    "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee", "right_foot",
    "flywheel",
)
SPRING_NAMES = ("left_shin", "left_heel_spring", "right_shin", "right_heel_spring")
SIDES = ("left", "right")


def _norm(name: str) -> str:
    return name.replace("-", "_")


@dataclass
class PointFrame:
    """A point fixed in a joint's frame (a Pinocchio OP_FRAME)."""
    name: str
    frame_id: int
    joint_id: int


class Dynamics:
    """Pinocchio model + per-tick terms: M, H (incl. springs/damping), A_g, constraint J, J v-dot."""

    def __init__(self, mjcf: str, motor_names=MOTOR_NAMES, free_joint: str = "pelvis", rigid_springs: bool = True):
        self.mjcf = mjcf
        self.rigid_springs = rigid_springs
        fd, path = tempfile.mkstemp(suffix=".xml")
        try:
            with os.fdopen(fd, "w") as f:
                f.write(mjcf)
            model, loops = pin.buildModelAndLegacyConstraintsFromMJCF(path)
        finally:
            os.unlink(path)
        self.model = model
        self.nq, self.nv = model.nq, model.nv
        names = [_norm(n) for n in model.names]
        self._jid = {n: i for i, n in enumerate(names)}
        # the free joint: by name, else the first joint (Pinocchio names it <body>_free)
        self.base_jid = self._jid.get(free_joint, 1)
        assert model.joints[self.base_jid].nv == 6, "first joint must be the floating base"
        self.mass = float(sum(model.inertias[i].mass for i in range(model.njoints)))
        refs = model.referenceConfigurations
        self.q_ref = refs["qpos0"].copy() if "qpos0" in refs else pin.neutral(model)   # MuJoCo qpos0

        # joint-space passive terms and actuation map from MuJoCo's compiled model
        self._read_passive(mjcf)
        self.motor_names = tuple(motor_names)
        self.nu = len(self.motor_names)
        self.motor_v = np.array([self.v_index(n) for n in self.motor_names])
        self.motor_q = np.array([self.q_index(n) for n in self.motor_names])
        self.B = np.zeros((self.nv, self.nu))
        self.B[self.motor_v, np.arange(self.nu)] = 1.0

        # points used by constraints and outputs
        self.points: dict[str, PointFrame] = {}
        self._loops = []
        for k, c in enumerate(loops):
            f1 = self._add_point(f"loop{k}_a", c.joint1_id, c.joint1_placement)
            f2 = self._add_point(f"loop{k}_b", c.joint2_id, c.joint2_placement)
            self._loops.append((f1, f2))
        self.foot_points = {}
        for side in SIDES:
            toe, heel = self._foot_ends(side)
            jf = self._jid[f"{side}_foot"]
            self.foot_points[side] = (
                self._add_point(f"{side}_toe", jf, pin.SE3(np.eye(3), toe)),
                self._add_point(f"{side}_heel", jf, pin.SE3(np.eye(3), heel)),
            )
            self._add_point(f"{side}_hip", self._jid[f"{side}_hip_pitch"], pin.SE3.Identity())
            self._add_point(f"{side}_foot", jf, pin.SE3.Identity())
        self.data = self.model.createData()
        self._il = np.tril_indices(self.nv, -1)
        self._tab = None
        self._pt_fids = [p.frame_id for p in self.points.values()]
        self._P = np.zeros((len(self._pt_fids), 3))
        self._pos_idx = [k for k, n in enumerate(self.points) if not n.startswith("loop")]
        self._pt_index = {n: k for k, n in enumerate(self.points)}
        self._loop_sel = self._loop_row_selection()
        self.n_loop = sum(s.shape[0] for s in self._loop_sel)
        self.n_contact = 10  # 5 rows per foot
        self._Jspring = np.zeros((len(self.spring_v), self.nv))
        self._Jspring[np.arange(len(self.spring_v)), self.spring_v] = 1.0
        self._zspring = np.zeros(len(self.spring_v))
        # index tables for the batched constraint rows
        self._loop_a = np.array([self._pt_index[a.name] for a, _ in self._loops], dtype=int)
        self._loop_b = np.array([self._pt_index[b.name] for _, b in self._loops], dtype=int)
        self._loop_fid = [a.frame_id for a, _ in self._loops]
        self._loop_S = np.zeros((len(self._loops), 3, 3))
        rows = []
        for k, S in enumerate(self._loop_sel):
            self._loop_S[k, :S.shape[0]] = S
            rows += [3 * k + i for i in range(S.shape[0])]
        self._loop_rows = np.array(rows, dtype=int)
        self._contact_idx = np.array([self._pt_index[self.foot_points[s][i].name] for s in SIDES for i in (0, 1)])
        self._contact_rows = np.array([0, 1, 2, 4, 5, 6, 7, 8, 10, 11])   # toe d,t,n; heel t,n (per foot)
        self._cons = {}
        self.flywheel_v = self.v_index("flywheel") if "flywheel" in self._jid else None
        self.q = None
        self.v = None

    # ------------------------------------------------------------------ setup helpers
    def q_index(self, joint: str) -> int:
        return self.model.idx_qs[self._jid[_norm(joint)]]

    def v_index(self, joint: str) -> int:
        return self.model.idx_vs[self._jid[_norm(joint)]]

    def has_joint(self, joint: str) -> bool:
        return _norm(joint) in self._jid

    def _add_point(self, name, joint_id, placement) -> PointFrame:
        fid = self.model.addFrame(pin.Frame(name, joint_id, placement, pin.FrameType.OP_FRAME))
        p = PointFrame(name, fid, joint_id)
        self.points[name] = p
        return p

    def _read_passive(self, mjcf: str):
        """Stiffness, spring rest position, damping and foot capsules via MuJoCo's compiler."""
        import mujoco
        m = mujoco.MjModel.from_xml_string(mjcf)
        self._mj = m
        self.K = np.zeros(self.nv)
        self.q_spring = np.zeros(self.nq)
        self.D = np.zeros(self.nv)
        self.spring_q, self.spring_v, spring_k = [], [], []
        for j in range(m.njnt):
            name = _norm(m.joint(j).name)
            if name not in self._jid:
                continue
            jid = self._jid[name]
            iv, nvj = self.model.idx_vs[jid], self.model.nvs[jid]
            self.D[iv:iv + nvj] = m.dof_damping[m.jnt_dofadr[j]:m.jnt_dofadr[j] + nvj]
            if m.jnt_stiffness[j] > 0:
                if nvj != 1:
                    raise NotImplementedError("stiffness only for hinges")
                self.spring_q.append(self.model.idx_qs[jid])
                self.spring_v.append(iv)
                spring_k.append(m.jnt_stiffness[j])
                self.q_spring[self.model.idx_qs[jid]] = m.qpos_spring[m.jnt_qposadr[j]]
        self.spring_q = np.array(self.spring_q, dtype=int)
        self.spring_v = np.array(self.spring_v, dtype=int)
        self.spring_k = np.array(spring_k)
        self.D[: 6] = 0.0  # free joint has none
        # armature: Pinocchio imports it (model.armature) and crba adds it; keep MuJoCo's as a check
        self.mj_armature = {(_norm(m.joint(j).name)): m.dof_armature[m.jnt_dofadr[j]] for j in range(m.njnt)}

    def _foot_ends(self, side):
        """Toe/heel contact points in the foot frame: the MJCF sites ``<side>_foot_toe/heel``
        (centres of the contact spheres), else the two ends of the foot's capsule geom."""
        import mujoco
        m = self._mj
        ids = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, f"{side}_foot_{k}") for k in ("toe", "heel")]
        if min(ids) >= 0:
            g = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, f"{side}_foot_{k}") for k in ("toe", "heel")]
            self.foot_radius = float(m.geom_size[g[0]][0]) if g[0] >= 0 else 0.0
            return m.site_pos[ids[0]].copy(), m.site_pos[ids[1]].copy()
        bid = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, f"{side}_foot")
        best = None
        for g in range(m.ngeom):
            if m.geom_bodyid[g] == bid and m.geom_type[g] == mujoco.mjtGeom.mjGEOM_CAPSULE:
                if best is None or m.geom_size[g][1] > m.geom_size[best][1]:
                    best = g
        if best is None:
            raise ValueError(f"no toe/heel sites or capsule geom on {side}_foot")
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, m.geom_quat[best])
        axis = R.reshape(3, 3)[:, 2] * m.geom_size[best][1]
        c = m.geom_pos[best].copy()
        self.foot_radius = float(m.geom_size[best][0])
        # fromto="a b" compiles to axis b - a: the first end (toe, as in the published model) is c - axis
        return c - axis, c + axis

    def _loop_row_selection(self):
        """Rows (in the body-1 frame) to keep for each loop: drop an identically-zero direction."""
        sel = []
        rng = np.random.default_rng(0)
        for f1, f2 in self._loops:
            acc = np.zeros((3, 3))
            for k in range(4):  # base poses vary; the loop itself stays closed (q_ref = qpos0)
                dv = np.zeros(self.nv)
                dv[:6] = rng.standard_normal(6)
                q = pin.integrate(self.model, self.q_ref, dv)
                pin.computeJointJacobians(self.model, self.data, q)
                pin.updateFramePlacements(self.model, self.data)
                J1 = pin.getFrameJacobian(self.model, self.data, f1.frame_id, LWA)[:3]
                J2 = pin.getFrameJacobian(self.model, self.data, f2.frame_id, LWA)[:3]
                R1 = self.data.oMf[f1.frame_id].rotation
                Jl = R1.T @ (J1 - J2)
                acc += Jl @ Jl.T
            w, U = np.linalg.eigh(acc)
            keep = U[:, w > 1e-9 * w.max()].T
            sel.append(keep)
        return sel

    # ------------------------------------------------------------------ per tick
    def update(self, q, v):
        """All configuration/velocity-dependent terms of one tick (Minv by computeMinverse, H by
        nonLinearEffects + passive torques, A_g and dA_g by dccrba, frame placements)."""
        model, data = self.model, self.data
        self.q, self.v = q, v
        self.Minv = pin.computeMinverse(model, data, q)     # full symmetric M^-1 (pin >= 3)
        h = pin.nonLinearEffects(model, data, q, v)
        tau_p = -self.D * v
        tau_p[self.spring_v] -= self.spring_k * (q[self.spring_q] - self.q_spring[self.spring_q])
        self.tau_passive = tau_p                 # J_s^T tau_s (springs) and joint damping
        self.H = h - tau_p                       # H of eq. (1) with the passive torques moved in
        pin.dccrba(model, data, q, v)            # returns dA_g; sets data.Ag, data.J, data.dJ, data.oMi
        self.Ag = data.Ag
        self.dAg_v = data.dAg @ v
        self.hg_lin = data.Ag[:3] @ v             # m * COM velocity
        pin.updateFramePlacements(model, data)
        self._tab = None
        self._cons = {}
        return self

    @property
    def M(self):
        """Joint-space inertia (crba, armature included), symmetric; not needed by the tick itself."""
        M = pin.crba(self.model, self.data, self.q).copy()
        M[self._il] = M.T[self._il]
        return M

    def _point_table(self):
        """World-aligned Jacobians (getFrameJacobian) and classical drifts (getFrameJacobianTimeVariation v,
        from dccrba's data.dJ) of every point frame; positions of the non-loop points."""
        model, data, v = self.model, self.data, self.v
        fids = self._pt_fids
        Js = np.array([_gFJ(model, data, f, LWA) for f in fids])         # (k, 6, nv)
        dJv = np.array([_gFJTV(model, data, f, LWA) for f in fids]) @ v  # (k, 6): [classical acc, alpha]
        tw = Js @ v                                                       # (k, 6): [pdot, omega]
        P = self._P
        oMf = data.oMf
        for k in self._pos_idx:
            P[k] = oMf[fids[k]].translation
        self._tab = (P, Js[:, :3], dJv[:, :3], tw[:, :3], tw[:, 3:])

    def point(self, name):
        """(p, J_lin (3 x nv), classical drift Jdot v (3,), pdot, omega) of a point, world-aligned."""
        if self._tab is None:
            self._point_table()
        k = self._pt_index[name]
        P, Jp, drift, pdot, w = self._tab
        return P[k], Jp[k], drift[k], pdot[k], w[k]

    def com_terms(self):
        """COM position, Jacobian (A_g[:3]/m) and drift (dA_g v)[:3]/m."""
        return self.data.com[0], self.Ag[:3] / self.mass, self.dAg_v[:3] / self.mass

    def loop_constraints(self):
        """Stacked loop-closure Jacobian and drift: c = S R1^T (p1 - p2) (rows S kept in the body-1 frame),
        c_ddot = S R1^T (a1 - a2 - w1 x (v1 - v2)) + terms in (p1 - p2) = 0."""
        if self._tab is None:
            self._point_table()
        P, Jp, drift, pdot, w = self._tab
        ia, ib = self._loop_a, self._loop_b
        oMf = self.data.oMf
        R1 = np.array([oMf[f].rotation for f in self._loop_fid])                   # (4,3,3)
        SR = self._loop_S @ R1.transpose(0, 2, 1)                                  # (4,3,3), padded rows
        wa = w[ia]
        dd = drift[ia] - drift[ib] - _cross(wa, pdot[ia] - pdot[ib])
        Jl = (SR @ (Jp[ia] - Jp[ib])).reshape(-1, self.nv)[self._loop_rows]
        dl = (SR @ dd[:, :, None]).reshape(-1)[self._loop_rows]
        return Jl, dl

    def foot_frame(self, side):
        """Rows d (horizontal toe-heel direction), t = z x d, n = z of one foot, world frame."""
        toe = self.data.oMf[self.foot_points[side][0].frame_id].translation
        heel = self.data.oMf[self.foot_points[side][1].frame_id].translation
        dx, dy = toe[0] - heel[0], toe[1] - heel[1]
        nrm = max((dx * dx + dy * dy) ** 0.5, 1e-9)
        dx, dy = dx / nrm, dy / nrm
        return np.array([[dx, dy, 0.0], [-dy, dx, 0.0], [0.0, 0.0, 1.0]])

    def contact_constraints(self):
        """Flat-foot contact rows: per foot toe (d, t, n) and heel (t, n) -> 5 rows; forces in that basis."""
        if self._tab is None:
            self._point_table()
        P, Jp, drift, _, _ = self._tab
        ic = self._contact_idx                       # toe_l, heel_l, toe_r, heel_r
        dxy = P[ic[0::2], :2] - P[ic[1::2], :2]      # (2, 2) toe - heel per foot
        dxy /= np.sqrt((dxy * dxy).sum(1))[:, None]
        cs = dxy[[0, 0, 1, 1]]                       # (4, 2): (cos, sin) of each point's foot heading
        c, s_ = cs[:, :1], cs[:, 1:]
        Jx, Jy = Jp[ic, 0], Jp[ic, 1]                # (4, nv)
        a = drift[ic]                                # (4, 3)
        Jall = np.stack([c * Jx + s_ * Jy, c * Jy - s_ * Jx, Jp[ic, 2]])             # (3: d t n, 4, nv)
        dall = np.stack([c[:, 0] * a[:, 0] + s_[:, 0] * a[:, 1], c[:, 0] * a[:, 1] - s_[:, 0] * a[:, 0], a[:, 2]])
        # rows: toe_l d,t,n  heel_l t,n  toe_r d,t,n  heel_r t,n
        Jc = Jall[_CROW, _CPT]
        dc = dall[_CROW, _CPT]
        return Jc, dc

    def constraints(self, ground: bool, feet=(True, True)):
        """J_{h,v} and Jdot_{h,v} v of a domain.

        Rows: foot contact (5 per foot in contact, ground domains only; ``feet`` = (left, right) in
        contact), loop closures (always), then, if ``rigid_springs``, one row per leaf spring (spring
        acceleration 0; its force is the spring torque the motors must hold).  See the module doc for
        why the springs are held rigid in the QP model.
        """
        feet = tuple(bool(f) for f in feet)
        key = (bool(ground), feet if ground else None)
        c = self._cons.get(key)
        if c is not None:
            return c
        Jl, dl = self.loop_constraints()
        Js, ds = [Jl], [dl]
        if ground and any(feet):
            Jc, dc = self.contact_constraints()
            if not all(feet):
                rows = np.r_[0:5] if feet[0] else np.r_[5:10]
                Jc, dc = Jc[rows], dc[rows]
            Js.insert(0, Jc)
            ds.insert(0, dc)
        if self.rigid_springs:
            Js.append(self._Jspring)
            ds.append(self._zspring)
        c = self._cons[key] = (np.concatenate(Js), np.concatenate(ds))
        return c


def cross3(a, b):
    """Cross product of two 3-vectors (np.cross is ~20x slower for this size)."""
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


def _cross(a, b):
    """Row-wise cross product of k x 3 arrays."""
    return np.stack([a[:, 1] * b[:, 2] - a[:, 2] * b[:, 1],
                     a[:, 2] * b[:, 0] - a[:, 0] * b[:, 2],
                     a[:, 0] * b[:, 1] - a[:, 1] * b[:, 0]], axis=1)
