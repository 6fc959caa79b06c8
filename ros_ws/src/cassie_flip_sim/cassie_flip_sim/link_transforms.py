"""Parent-link -> child-link transforms of a URDF's joints from ``/joint_states`` positions (no ROS):
the math of a robot_state_publisher (``state_publisher``), on Pinocchio built from the URDF.

One transform per URDF joint, ``parent`` link -> ``child`` link, as ``(x, y, z, qx, qy, qz, qw)``
(the order of geometry_msgs/Transform). Moving joints (:meth:`LinkTransforms.moving`) depend on the
joint positions; fixed joints (:attr:`LinkTransforms.fixed`) do not (``/tf_static``).
Positions are given as ``/joint_states`` carries them: a hinge's angle under its joint name, a ball
joint (the URDF's three continuous joints ``<name>_x/_y/_z``, intrinsic XYZ Euler angles) as its
rotation vector under those three names, converted with :func:`urdf.ball_angles`. A URDF joint
without a position stays at zero; names the URDF lacks are ignored.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from typing import Dict, Iterable, List, Sequence, Tuple

import numpy as np
import pinocchio as pin
from cassie_model.urdf import ball_angles

#: ``(parent link, child link, joint name)`` of one URDF joint
Edge = Tuple[str, str, str]


def rotvec_to_quat(rv) -> np.ndarray:
    """(w, x, y, z) quaternion of a rotation vector (MuJoCo's order, for :func:`urdf.ball_angles`)."""
    rv = np.asarray(rv, float)
    angle = float(np.linalg.norm(rv))
    if angle < 1e-12:
        return np.array([1.0, *(0.5 * rv)])
    return np.r_[np.cos(0.5 * angle), np.sin(0.5 * angle) / angle * rv]


def quat_xyzw(R: np.ndarray) -> np.ndarray:
    """``(n, 4)`` unit quaternions (x, y, z, w) of ``(n, 3, 3)`` rotation matrices (Shepperd: each
    from its largest component)."""
    d0, d1, d2 = R[:, 0, 0], R[:, 1, 1], R[:, 2, 2]
    s01, s02, s12 = R[:, 0, 1] + R[:, 1, 0], R[:, 0, 2] + R[:, 2, 0], R[:, 1, 2] + R[:, 2, 1]
    a21, a02, a10 = R[:, 2, 1] - R[:, 1, 2], R[:, 0, 2] - R[:, 2, 0], R[:, 1, 0] - R[:, 0, 1]
    t = np.stack([1 + d0 - d1 - d2, 1 - d0 + d1 - d2, 1 - d0 - d1 + d2, 1 + d0 + d1 + d2], axis=1)
    cands = np.stack([np.stack([t[:, 0], s01, s02, a21], 1), np.stack([s01, t[:, 1], s12, a02], 1),
                      np.stack([s02, s12, t[:, 2], a10], 1), np.stack([a21, a02, a10, t[:, 3]], 1)], axis=1)
    q = cands[np.arange(len(R)), np.argmax(t, axis=1)]      # = 4 q_i q, q_i the largest component
    return q / np.linalg.norm(q, axis=1, keepdims=True)


def pose7(T: pin.SE3) -> np.ndarray:
    """``(x, y, z, qx, qy, qz, qw)`` of a transform."""
    return np.r_[T.translation, pin.Quaternion(T.rotation).coeffs()]


def matrix(pose) -> np.ndarray:
    """4x4 matrix of an ``(x, y, z, qx, qy, qz, qw)`` pose."""
    p = np.asarray(pose, float)
    T = np.eye(4)
    T[:3, :3] = pin.Quaternion(p[6], p[3], p[4], p[5]).normalized().toRotationMatrix()
    T[:3, 3] = p[:3]
    return T


def urdf_edges(urdf: str) -> Tuple[List[Edge], List[Edge]]:
    """``(moving, fixed)`` joints of a URDF, in document order."""
    moving, fixed = [], []
    for j in ET.fromstring(urdf).iter("joint"):
        edge = (j.find("parent").get("link"), j.find("child").get("link"), j.get("name"))
        (fixed if j.get("type") == "fixed" else moving).append(edge)
    return moving, fixed


class LinkTransforms:
    """Transforms of every URDF joint for given joint positions."""

    def __init__(self, urdf: str):
        self.model = pin.buildModelFromXML(urdf)
        self.data = self.model.createData()
        self.edges, fixed = urdf_edges(urdf)
        children = {c for _, c, _ in self.edges + fixed}
        #: every link of the URDF
        self.links = [lk.get("name") for lk in ET.fromstring(urdf).iter("link")]
        #: the URDF's root link (the floating base: ``world`` -> root comes from elsewhere, /odom)
        self.root = next(lk for lk in self.links if lk not in children)
        self._frame = {}
        for parent, child, _ in self.edges + fixed:
            for link in (parent, child):
                self._frame.setdefault(link, self.model.getFrameId(link, pin.BODY))
        # per Pinocchio joint: (first q index, nq): nq 2 = a continuous joint as (cos, sin)
        self._q_slot = {self.model.names[j]: (self.model.joints[j].idx_q, self.model.joints[j].nq)
                        for j in range(1, self.model.njoints)}
        self.q = pin.neutral(self.model)
        #: ``(parent, child, pose)`` of every fixed joint
        self.fixed = self._relative(fixed)
        # a moving joint's transform = inv(parent link in its joint's frame) liMi[joint] (child link
        # in the joint's frame): Pinocchio's joint j moves the child link, its parent joint the parent
        fr = self.model.frames
        self._joint = [fr[self._frame[c]].parentJoint for _, c, _ in self.edges]
        if any(self.model.parents[j] != fr[self._frame[p]].parentJoint
               for j, (p, _, _) in zip(self._joint, self.edges)):
            raise ValueError("a moving joint's parent link is not on its parent joint")
        self._parent_inv = np.array([fr[self._frame[p]].placement.inverse().homogeneous
                                     for p, _, _ in self.edges])
        self._child = np.array([fr[self._frame[c]].placement.homogeneous for _, c, _ in self.edges])
        self._plan = None           # (names, plan) of the last name list seen by set_positions

    def _balls(self, names: Sequence[str]) -> List[Tuple[int, int, int, str]]:
        """Ball joints among ``names``: indices of ``<b>_x, <b>_y, <b>_z`` and ``<b>``."""
        index = {n: i for i, n in enumerate(names)}
        out = []
        for n in names:
            base = n[:-2]
            if n.endswith("_x") and all(f"{base}_{s}" in index and f"{base}_{s}" in self._q_slot
                                        for s in "xyz"):
                out.append((index[f"{base}_x"], index[f"{base}_y"], index[f"{base}_z"], base))
        return out

    def _make_plan(self, names: Sequence[str]):
        balls = self._balls(names)
        in_ball = {i for b in balls for i in b[:3]}
        scalars = [(i, *self._q_slot[n]) for i, n in enumerate(names)
                   if n in self._q_slot and i not in in_ball]
        ball_slots = [(b[:3], [self._q_slot[f"{b[3]}_{s}"] for s in "xyz"]) for b in balls]
        return scalars, ball_slots

    def _set(self, slot, angle: float) -> None:
        a, nq = slot
        if nq == 2:
            self.q[a], self.q[a + 1] = np.cos(angle), np.sin(angle)
        else:
            self.q[a] = angle

    def set_positions(self, names: Sequence[str], positions: Iterable[float]) -> None:
        """Joint positions as ``/joint_states`` carries them (module doc)."""
        names = tuple(names)
        if self._plan is None or self._plan[0] != names:
            self._plan = (names, self._make_plan(names))
        scalars, ball_slots = self._plan[1]
        pos = np.asarray(positions, float)
        for i, a, nq in scalars:
            self._set((a, nq), pos[i])
        for idx, slots in ball_slots:
            for slot, angle in zip(slots, ball_angles(rotvec_to_quat(pos[list(idx)]))):
                self._set(slot, angle)

    def _relative(self, edges: Sequence[Edge]) -> List[Tuple[str, str, np.ndarray]]:
        pin.framesForwardKinematics(self.model, self.data, self.q)
        oMf = self.data.oMf
        return [(p, c, pose7(oMf[self._frame[p]].actInv(oMf[self._frame[c]]))) for p, c, _ in edges]

    def moving_poses(self) -> np.ndarray:
        """``(n, 7)`` poses of the moving joints (order of :attr:`edges`) at the positions last set."""
        if not self.edges:
            return np.zeros((0, 7))
        pin.forwardKinematics(self.model, self.data, self.q)
        liMi = self.data.liMi
        T = self._parent_inv @ np.array([liMi[j].homogeneous for j in self._joint]) @ self._child
        return np.concatenate([T[:, :3, 3], quat_xyzw(T[:, :3, :3])], axis=1)

    def moving(self) -> List[Tuple[str, str, np.ndarray]]:
        """``(parent, child, pose)`` of every moving joint (order of :attr:`edges`) at the positions
        last set."""
        return [(p, c, pose) for (p, c, _), pose in zip(self.edges, self.moving_poses())]


def link_poses(root: str, root_pose,
               transforms: Iterable[Tuple[str, str, np.ndarray]]) -> Dict[str, np.ndarray]:
    """4x4 pose in the frame of ``root_pose`` of every link reached from ``root`` through the
    ``(parent, child, pose)`` transforms (a tf tree's replay)."""
    children: Dict[str, list] = {}
    for p, c, pose in transforms:
        children.setdefault(p, []).append((c, pose))
    out = {root: matrix(root_pose)}
    stack = [root]
    while stack:
        p = stack.pop()
        for c, pose in children.get(p, ()):
            if c not in out:
                out[c] = out[p] @ matrix(pose)
                stack.append(c)
    return out
