"""Rigid-body dynamics of Cassie + flywheel with Pinocchio (paper eq. (1)-(2)).

The model is loaded from the simulator's exported MJCF string (``cassie_model.model.export_mjcf``).
Pinocchio imports the kinematic tree, inertias, armature and the MJCF ``connect`` equalities (the four
loop closures); it does not import joint stiffness, so the spring torques tau_s = -K (q - q_spring) of the
shin and heel springs and the viscous joint damping -D v are read with MuJoCo's compiler from the same
string and added to the bias here.

Per tick (:meth:`Dynamics.update`): computeMinverse (M^-1), nonLinearEffects (H), dccrba (A_g, dA_g, the
world joint Jacobians J and their time variation dJ, the joint placements), updateFramePlacements, then
the point table in a few batched numpy operations (not per-frame calls).  A point p on joint j, support
columns S_j, has
    J_p = S_j (J_v - [p]x J_w),   pdot = J_p v,   drift dJ_p v = a_O - [p]x alpha - pdot x omega,
with omega = S_j J_w v and (a_O, alpha) = S_j dJ v the angular velocity of joint j and the time variation
of its twist at the world origin (world-aligned frame Jacobian, classical acceleration at zero joint
acceleration).

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
Contact and loop rows are linear maps of the stacked point Jacobians, J_rows = T J_points, T holding the
foot headings and the loops' S R1^T; all rows are built at once and selected per domain.  A loop row
S R1^T (J_a - J_b) has the drift S R1^T (a_a - a_b - omega_1 x (v_a - v_b)), so the point table takes a
loop point's drift relative to the loop's body 1, a_p - omega_1 x pdot_p (omega - omega_1 in the formula
above, support S_j - S_1): T times the drifts is then the rows' drift.

Backends: ``backend="native"`` (default) computes all of :meth:`Dynamics.update` (the Pinocchio terms,
the point table, the constraint rows) in one call of the compiled extension ``tsc_controller._native``
(native/tick.cpp), on this object's own Pinocchio model and data; ``backend="python"`` is the numpy
implementation (:mod:`dynamics_python`), the reference the native one is tested against
(tests/unit/test_tsc_native.py).  With the native backend the per-tick arrays (Minv, Ag, P, Jp, ..., and the views ``constraints`` returns) are
views of the compiled tick's buffers, rewritten by the next update: copy what must outlive the tick.
"""
from __future__ import annotations

import os
import tempfile
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from .dynamics_python import PythonTick, skew  # noqa: F401

LWA = pin.ReferenceFrame.LOCAL_WORLD_ALIGNED

MOTOR_NAMES = (
    "left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
    "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee", "right_foot",
    "flywheel",
)
SPRING_NAMES = ("left_shin", "left_heel_spring", "right_shin", "right_heel_spring")
SIDES = ("left", "right")
N_CONTACT = 10   # 5 rows per foot
BACKENDS = ("native", "python")


def _norm(name: str) -> str:
    return name.replace("-", "_")


@dataclass
class PointFrame:
    """A point fixed in a joint's frame (a Pinocchio OP_FRAME)."""
    name: str
    frame_id: int
    joint_id: int


class Dynamics(PythonTick):
    """Pinocchio model + per-tick terms: M^-1, H (incl. springs/damping), A_g, point table, constraint rows."""

    def __init__(self, mjcf: str, motor_names=MOTOR_NAMES, free_joint: str = "pelvis", rigid_springs: bool = True,
                 backend: str = "native"):
        if backend not in BACKENDS:
            raise ValueError(f"backend must be one of {BACKENDS}, not {backend!r}")
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
        # passive torques tau_p = -D v + Kq (q - q_spring), Kq: -k at (spring dof, spring coordinate)
        self._neg_D = -self.D
        self._Kq = np.zeros((self.nv, self.nq))
        self._Kq[self.spring_v, self.spring_q] = -self.spring_k
        self.motor_names = tuple(motor_names)
        self.nu = len(self.motor_names)
        self.motor_v = np.array([self.v_index(n) for n in self.motor_names])
        self.motor_q = np.array([self.q_index(n) for n in self.motor_names])
        self.B = np.zeros((self.nv, self.nu))
        self.B[self.motor_v, np.arange(self.nu)] = 1.0
        self.BH = np.zeros((self.nv, self.nu + 1))      # [B, -H] of the tick (H written by update)
        self.BH[:, :self.nu] = self.B

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
        self._pt_index = {n: k for k, n in enumerate(self.points)}
        self._loop_sel = self._loop_row_selection()
        self.n_loop = sum(s.shape[0] for s in self._loop_sel)
        self.n_contact = N_CONTACT
        self._Jspring = np.zeros((len(self.spring_v), self.nv))
        self._Jspring[np.arange(len(self.spring_v)), self.spring_v] = 1.0
        self._setup_point_table()
        self._setup_constraint_rows()
        self.flywheel_v = self.v_index("flywheel") if "flywheel" in self._jid else None
        self.q = None
        self.v = None
        self.backend = backend
        self.native = None
        if backend == "native":
            self._setup_native()

    # ------------------------------------------------------------------ setup helpers
    def q_index(self, joint: str) -> int:
        return self.model.idx_qs[self._jid[_norm(joint)]]

    def v_index(self, joint: str) -> int:
        return self.model.idx_vs[self._jid[_norm(joint)]]

    def has_joint(self, joint: str) -> bool:
        return _norm(joint) in self._jid

    def point_index(self, name: str) -> int:
        """Row of a point in the point table (:attr:`P`, :attr:`Jp`, ...)."""
        return self._pt_index[name]

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

    def _setup_point_table(self):
        """Index tables of the batched point kinematics: the joints whose placements a tick reads (those
        carrying points, and the base), each point's position in its joint, the supports."""
        model = self.model
        frames = [model.frames[p.frame_id] for p in self.points.values()]
        pj = [f.parentJoint for f in frames]
        joints = sorted(set(pj) | {self.base_jid})
        self._tj = joints
        self._tj_base = joints.index(self.base_jid)
        n = len(frames)
        jk = np.array([joints.index(j) for j in pj])
        # positions: all joints' placements stacked (4 joints x 4) @ L (4 x n), entry (joint of k, row i, k)
        self._pt_L = np.array([np.r_[f.placement.translation, 1.0] for f in frames]).T
        self._pt_take = ((jk[:, None] * 4 + np.arange(3)[None]) * n + np.arange(n)[:, None]).ravel()

        def support(j):
            m = np.zeros(self.nv)
            for a in model.supports[j]:
                if a > 0:
                    m[model.idx_vs[a]:model.idx_vs[a] + model.nvs[a]] = 1.0
            return m
        S = np.array([support(j) for j in pj]).T                  # nv x n
        body1 = {p.name: a.joint_id for a, b in self._loops for p in (a, b)}
        S1 = np.array([support(body1[k]) if k in body1 else np.zeros(self.nv) for k in self.points]).T
        self._pt_support = S
        self._pt_support_w = np.concatenate((S, S - S1), axis=1)   # omega, omega - omega_1 (loop points)
        self._pt_mask = S.T[:, None, :].copy()                   # n x 1 x nv

    def _setup_constraint_rows(self):
        """T (contact rows, loop rows) x (3 * points): its constant entries, where the per-tick foot
        headings (c, s) and loops' S R1^T go; the row sets of the one-foot domains."""
        n_pts = len(self.points)
        nr = N_CONTACT + self.n_loop
        T = np.zeros((nr, 3 * n_pts))
        ic = [self._pt_index[self.foot_points[s][i].name] for s in SIDES for i in (0, 1)]
        self._contact_idx = np.array(ic)
        cs_idx = []
        for f in range(2):
            toe, heel, r = 3 * ic[2 * f], 3 * ic[2 * f + 1], 5 * f
            T[r + 2, toe + 2] = T[r + 4, heel + 2] = 1.0                        # n rows
            # d = (c, s, 0), t = (-s, c, 0): entries [c, s, -s, c, -s, c]
            cs_idx += [(r, toe), (r, toe + 1), (r + 1, toe), (r + 1, toe + 1), (r + 3, heel), (r + 3, heel + 1)]
        self._cs_idx = np.array([i * T.shape[1] + j for i, j in cs_idx])
        self._T_flat = T.reshape(-1)
        # loops: S' R_j^T at point a and -S' R_j^T at point b, S' = S R_placement^T (S padded to 3 rows)
        nl = len(self._loops)
        Sp = np.zeros((2 * nl, 3, 3))
        take, put, row = [], [], N_CONTACT
        for k, ((a, b), S) in enumerate(zip(self._loops, self._loop_sel)):
            Rp = self.model.frames[a.frame_id].placement.rotation
            Sp[k, :S.shape[0]] = S @ Rp.T
            Sp[nl + k, :S.shape[0]] = -S @ Rp.T
            for i in range(S.shape[0]):
                for blk, pt in ((k, a), (nl + k, b)):
                    for c in range(3):
                        take.append((blk * 3 + i) * 3 + c)
                        put.append(row * T.shape[1] + 3 * self._pt_index[pt.name] + c)
                row += 1
        self._loop_S = Sp
        self._loop_take, self._loop_put = np.array(take), np.array(put)
        self._loop_R = np.array([self._tj.index(a.joint_id) for a, _ in self._loops] * 2)
        self._T = T
        ns = len(self.spring_v) if self.rigid_springs else 0
        self._spring_rows = ns
        self._spring_Jd = np.zeros((ns, self.nv + 1))
        self._spring_Jd[:, :self.nv] = self._Jspring[:ns]
        rest = np.arange(N_CONTACT, nr + ns)
        self._row_sets = {(True, False): np.r_[np.arange(5), rest], (False, True): np.r_[np.arange(5, 10), rest]}

    def _native_tables(self):
        """The index tables of the point table and the constraint rows, for the compiled tick."""
        m = self.model
        pts = list(self.points.values())
        nr, ns = self._T.shape[0], self._spring_rows
        every = np.arange(nr + ns)
        return dict(
            nq=m.nq, nv=m.nv, njoints=m.njoints, nframes=m.nframes, base_jid=self.base_jid, mass=self.mass,
            motor_v=self.motor_v, neg_D=self._neg_D, q_spring=self.q_spring, spring_v=self.spring_v,
            spring_q=self.spring_q, spring_k=self.spring_k,
            pt_joint=np.array([p.joint_id for p in pts]),
            pt_local=np.array([m.frames[p.frame_id].placement.translation for p in pts]),
            pt_support=self._pt_support, pt_support_w=self._pt_support_w,
            T=self._T, nr=nr, cs_idx=self._cs_idx, contact_idx=self._contact_idx, loop_S=self._loop_S,
            loop_take=self._loop_take, loop_put=self._loop_put,
            loop_joint=np.array([self._tj[i] for i in self._loop_R]),
            spring_Jd=self._spring_Jd, n_spring_rows=ns,
            row_sets=[every, self._row_sets[(True, False)], self._row_sets[(False, True)], every[N_CONTACT:]])

    def _setup_native(self):
        """The compiled tick on this model and data, its buffers as numpy views (rewritten by every
        update), and a check against the numpy path on one state (a wrong build fails here, not in
        the controller)."""
        from . import _native
        self.native = _native.Tick(self.model, self.data, self._native_tables())
        b = self.native.buffers()
        n, nv = len(self.points), self.nv
        rows = b["pt_rows"]
        self.BH = b["BH"]
        self._com = b["com"]
        self._views = (b["Minv"], b["tau_passive"], b["Ag"], b["dAg_v"], b["hg"], b["hg"][:3], b["R_base"], b["P"],
                       rows[:, :nv].reshape(n, 3, nv), rows[:, nv].reshape(n, 3), b["pdot"], b["omega"], rows,
                       b["rows"])
        rng = np.random.default_rng(0)
        q = pin.integrate(self.model, self.q_ref, 0.1 * rng.standard_normal(self.nv))
        v = rng.standard_normal(self.nv)
        self._update_python(q, v)
        ref = [np.array(x) for x in (self.Minv, self.H, self.Ag, self.dAg_v, self._pt_rows, self._constraint_rows())]
        self.update(q, v)
        got = (self.Minv, self.H, self.Ag, self.dAg_v, self._pt_rows, self._rows)
        for name, a, r in zip(("Minv", "H", "Ag", "dAg_v", "point table", "constraint rows"), got, ref):
            if not np.allclose(a, r, rtol=1e-9, atol=1e-9 * max(1.0, np.abs(r).max())):
                raise RuntimeError(f"tsc_controller._native: {name} differs from the numpy path (a build against "
                                   "other pinocchio/Eigen headers?); rebuild, or use backend='python'")

    def row_set(self, ground: bool, feet=(True, True)) -> int:
        """Index of a domain's constraint rows among the native row sets: 0 both feet, 1 left, 2 right,
        3 none (flight)."""
        left, right = bool(feet[0]), bool(feet[1])
        if not ground or not (left or right):
            return 3
        return 0 if left and right else (1 if left else 2)

    # ------------------------------------------------------------------ per tick
    def update(self, q, v):
        """All configuration/velocity-dependent terms of one tick: M^-1 (computeMinverse), H
        (nonLinearEffects + passive torques), A_g, dA_g v, h_g (dccrba), frame placements, point table,
        and (native backend) the constraint rows."""
        if self.native is None:
            return self._update_python(q, v)
        self.q, self.v = q, v
        self.native.update(q, v)
        (self.Minv, self.tau_passive, self.Ag, self.dAg_v, self.hg, self.hg_lin, self.R_base, self.P, self.Jp,
         self.drift, self.pdot, self.omega, self._pt_rows, self._rows) = self._views
        self._lists = None
        return self

    def point(self, name):
        """(p, J_lin (3 x nv), classical drift Jdot v (3,), pdot, omega) of a point, world-aligned
        (a loop point's drift is relative to the loop's body 1, see the module doc)."""
        k = self._pt_index[name]
        return self.P[k], self.Jp[k], self.drift[k], self.pdot[k], self.omega[k]

    def point_lists(self):
        """(P, pdot, drift) of the tick as nested Python lists (scalar arithmetic for the outputs)."""
        if self._lists is None:
            self._lists = (self.P.tolist(), self.pdot.tolist(), self.drift.tolist())
        return self._lists

    @property
    def H(self):
        """H of eq. (1): Coriolis + gravity - passive torques."""
        return -self.BH[:, -1]

    @property
    def com(self):
        """COM position (dccrba's data.com[0])."""
        return self.data.com[0] if self.native is None else self._com

    @property
    def M(self):
        """Joint-space inertia (crba, armature included), symmetric; not needed by the tick itself."""
        M = pin.crba(self.model, self.data, self.q).copy()
        M[self._il] = M.T[self._il]
        return M

    def com_terms(self):
        """COM position, Jacobian (A_g[:3]/m) and drift (dA_g v)[:3]/m."""
        return self.com, self.Ag[:3] / self.mass, self.dAg_v[:3] / self.mass

    def foot_frame(self, side):
        """Rows d (horizontal toe-heel direction), t = z x d, n = z of one foot, world frame."""
        toe = self.P[self._pt_index[self.foot_points[side][0].name]]
        heel = self.P[self._pt_index[self.foot_points[side][1].name]]
        dx, dy = toe[0] - heel[0], toe[1] - heel[1]
        nrm = max((dx * dx + dy * dy) ** 0.5, 1e-9)
        dx, dy = dx / nrm, dy / nrm
        return np.array([[dx, dy, 0.0], [-dy, dx, 0.0], [0.0, 0.0, 1.0]])

    def constraints(self, ground: bool, feet=(True, True)):
        """J_{h,v} and Jdot_{h,v} v of a domain.

        Rows: foot contact (5 per foot in contact, ground domains only; ``feet`` = (left, right) in
        contact), loop closures (always), then, if ``rigid_springs``, one row per leaf spring (spring
        acceleration 0; its force is the spring torque the motors must hold).  See the module doc for
        why the springs are held rigid in the QP model.
        """
        Jd = self._rows if self._rows is not None else self._constraint_rows()
        left, right = bool(feet[0]), bool(feet[1])
        if not ground or not (left or right):
            Jd = Jd[N_CONTACT:]
        elif not (left and right):
            Jd = Jd[self._row_sets[(left, right)]]
        return Jd[:, :-1], Jd[:, -1]
