"""MuJoCo <-> Pinocchio state mapping of the robot (:class:`PinocchioMap`) and its Pinocchio model
built from the exported MJCF (:func:`pinocchio_model`)."""
from __future__ import annotations

import mujoco
import numpy as np

from .model import FlywheelSpec, export_mjcf


class PinocchioMap:
    """Maps MuJoCo (qpos, qvel) to Pinocchio (q, v) and back, joint by joint by name.

    Conventions (checked in tests/unit/test_sim_model.py): quaternions wxyz (MuJoCo) vs xyzw
    (Pinocchio) for the free joint and the balls; free-joint linear velocity in the world frame
    (MuJoCo) vs the pelvis frame (Pinocchio); angular velocities of free and ball joints are
    local in both.  Hinges with ``ref`` (knees -45°, tarsi 58°): the angle is the same number in
    both (q_pin = qpos; Pinocchio's ``referenceConfigurations["qpos0"]`` = MuJoCo qpos0), BUT
    pin 4.1 stores ``lower/upperPositionLimit`` of those joints shifted by -ref — use the ranges
    of :mod:`robot_params` instead.  Pinocchio reads ``armature`` (model.armature) but adds no
    joint springs or damping to its dynamics: add -K (qpos - rest) yourself
    (:func:`robot_params.spring_params`).
    """

    def __init__(self, mj_model: mujoco.MjModel, pin_model):
        self.nq, self.nv = pin_model.nq, pin_model.nv
        self.items = []   # (type, mj_qadr, mj_vadr, pin_qadr, pin_vadr, ref)
        for jid in range(1, pin_model.njoints):
            name = pin_model.names[jid]
            mj = mujoco.mj_name2id(mj_model, mujoco.mjtObj.mjOBJ_JOINT, name)
            if mj < 0:
                raise KeyError(f"joint {name} not in MuJoCo model")
            t = int(mj_model.jnt_type[mj])
            qa, va = int(mj_model.jnt_qposadr[mj]), int(mj_model.jnt_dofadr[mj])
            ref = 0.0   # hinge angles are identical (see class doc)
            self.items.append((t, qa, va, pin_model.idx_qs[jid], pin_model.idx_vs[jid], ref))

    def to_pin(self, qpos, qvel=None):
        """(q, v) for Pinocchio from MuJoCo (qpos, qvel)."""
        q = np.zeros(self.nq)
        v = np.zeros(self.nv)
        for t, qa, va, pq, pv, ref in self.items:
            if t == mujoco.mjtJoint.mjJNT_FREE:
                q[pq:pq + 3] = qpos[qa:qa + 3]
                q[pq + 3:pq + 7] = np.r_[qpos[qa + 4:qa + 7], qpos[qa + 3]]
                if qvel is not None:
                    R = np.zeros(9)
                    mujoco.mju_quat2Mat(R, qpos[qa + 3:qa + 7])
                    v[pv:pv + 3] = R.reshape(3, 3).T @ qvel[va:va + 3]
                    v[pv + 3:pv + 6] = qvel[va + 3:va + 6]
            elif t == mujoco.mjtJoint.mjJNT_BALL:
                q[pq:pq + 4] = np.r_[qpos[qa + 1:qa + 4], qpos[qa]]
                if qvel is not None:
                    v[pv:pv + 3] = qvel[va:va + 3]
            else:
                q[pq] = qpos[qa] - ref
                if qvel is not None:
                    v[pv] = qvel[va]
        return q, v

    def to_mujoco(self, q, v=None, mj_nq=None, mj_nv=None):
        """(qpos, qvel) for MuJoCo from Pinocchio (q, v)."""
        qpos = np.zeros(mj_nq or self.nq)
        qvel = np.zeros(mj_nv or self.nv)
        for t, qa, va, pq, pv, ref in self.items:
            if t == mujoco.mjtJoint.mjJNT_FREE:
                qpos[qa:qa + 3] = q[pq:pq + 3]
                qpos[qa + 3:qa + 7] = np.r_[q[pq + 6], q[pq + 3:pq + 6]]
                if v is not None:
                    R = np.zeros(9)
                    mujoco.mju_quat2Mat(R, qpos[qa + 3:qa + 7])
                    qvel[va:va + 3] = R.reshape(3, 3) @ v[pv:pv + 3]
                    qvel[va + 3:va + 6] = v[pv + 3:pv + 6]
            elif t == mujoco.mjtJoint.mjJNT_BALL:
                qpos[qa:qa + 4] = np.r_[q[pq + 3], q[pq:pq + 3]]
                if v is not None:
                    qvel[va:va + 3] = v[pv:pv + 3]
            else:
                qpos[qa] = q[pq] + ref
                if v is not None:
                    qvel[va] = v[pv]
        return qpos, qvel

    def vel_matrix(self, qpos) -> np.ndarray:
        """T(qpos) with v_pin = T qvel (a permutation, plus R^T on the free linear block).
        Generalized forces map as tau_mujoco = T^T tau_pin; T is orthogonal."""
        T = np.zeros((self.nv, self.nv))
        T[np.arange(self.nv), self.dof_perm()] = 1.0
        for t, qa, va, pq, pv, ref in self.items:
            if t == mujoco.mjtJoint.mjJNT_FREE:
                R = np.zeros(9)
                mujoco.mju_quat2Mat(R, qpos[qa + 3:qa + 7])
                T[pv:pv + 3, va:va + 3] = R.reshape(3, 3).T
        return T

    def acc_offset(self, v_pin) -> np.ndarray:
        """a0 with v̇_pin = T q̈_mujoco + a0: the free-joint linear block is -ω × v_lin (local),
        since d/dt(Rᵀ v_world) = -ω × Rᵀ v_world.  Hence
        MuJoCo qfrc_bias = Tᵀ · pinocchio.rnea(q, v, a0) (= Tᵀ rnea(q, v, 0) only if ω × v = 0)."""
        a0 = np.zeros(self.nv)
        for t, qa, va, pq, pv, ref in self.items:
            if t == mujoco.mjtJoint.mjJNT_FREE:
                a0[pv:pv + 3] = -np.cross(v_pin[pv + 3:pv + 6], v_pin[pv:pv + 3])
        return a0

    def dof_perm(self) -> np.ndarray:
        """Index array p with v_pin[i] ~ qvel[p[i]] (same frames except free linear velocity)."""
        p = np.zeros(self.nv, dtype=int)
        for t, qa, va, pq, pv, ref in self.items:
            n = {mujoco.mjtJoint.mjJNT_FREE: 6, mujoco.mjtJoint.mjJNT_BALL: 3}.get(t, 1)
            p[pv:pv + n] = np.arange(va, va + n)
        return p


def pinocchio_model(flywheel: FlywheelSpec = "I", with_constraints: bool = False):
    """Pinocchio model (and, if asked, its loop-closure constraint models) from :func:`export_mjcf`."""
    import os
    import tempfile

    import pinocchio as pin
    xml = export_mjcf(flywheel)
    with tempfile.NamedTemporaryFile("w", suffix=".xml", delete=False) as f:
        f.write(xml)
        path = f.name
    try:
        if with_constraints:
            return pin.buildModelAndConstraintsFromMJCF(path)
        return pin.buildModelFromMJCF(path)
    finally:
        os.unlink(path)
