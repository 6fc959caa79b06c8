"""Each foot's ground contact wrench from MuJoCo, as a force/torque sensor in the foot reads it (no ROS).

A foot's wrench is the sum over MuJoCo's contacts of that foot's geoms (its toe and heel spheres)
with the terrain: each contact's force (``mj_contactForce``, in the contact frame) rotated to the
world, its moment taken about the foot body's origin, and the sums expressed in the foot body's
axes: the URDF link ``<side>_foot`` (a /tf frame; link = MuJoCo body), what sim_node publishes as
geometry_msgs/WrenchStamped with ``header.frame_id`` = that link.  It is the force the ground
exerts on the foot: standing at rest the two forces, rotated to the world, sum to m·g upward.

Valid where ``data.contact`` and ``data.efc_force`` belong to one state, with that state's
kinematics (``xpos``, ``xmat``): between ``mj_step2`` and ``mj_step1`` (where
``Simulator.step(u, wrench=True)`` computes it) or after ``mj_forward``.  Such a wrench is the
contact force solved at that state, which acts over the step that follows; sim_node stamps it
with that state's time (the stamp of its /joint_states and /tf).  native/step.cpp computes the
same with the same MuJoCo functions in the same order (the same numbers to the bit).
"""
from __future__ import annotations

from typing import Optional

import mujoco
import numpy as np
from cassie_model.model import FOOT_GEOMS

#: the feet, in the order of a wrench array's rows (URDF links = MuJoCo bodies)
FOOT_LINKS = ("left_foot", "right_foot")
#: sim_node's topics of the feet's wrenches (geometry_msgs/WrenchStamped, frame_id = the foot link)
WRENCH_TOPICS = tuple(f"/{link}/wrench" for link in FOOT_LINKS)


class FootWrenches:
    """``(2, 6)`` wrenches (left, right; force x y z, torque x y z) of the feet's ground contacts,
    in each foot body's frame about its origin (module doc)."""

    def __init__(self, model: mujoco.MjModel):
        gid = lambda n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n)
        #: geom id -> row (0 left, 1 right)
        self.side_of = {gid(g): k for k, side in enumerate(("left", "right")) for g in FOOT_GEOMS[side]}
        self.bodies = np.array([mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, b) for b in FOOT_LINKS])
        for g, k in self.side_of.items():
            if model.geom_bodyid[g] != self.bodies[k]:
                raise ValueError(f"foot geom {model.geom(g).name} is not on body {FOOT_LINKS[k]}")
        self._f6 = np.zeros(6)
        self._tmp = np.zeros((4, 3))       # force, torque, lever, lever x force (world)

    def world(self, model: mujoco.MjModel, data: mujoco.MjData, out: Optional[np.ndarray] = None) -> np.ndarray:
        """``(2, 6)``: each foot's force and its moment about the foot's origin, in world axes."""
        w = np.zeros((2, 6)) if out is None else out
        w[:] = 0.0
        f6, (F, T, r, rxF) = self._f6, self._tmp
        for i in range(data.ncon):
            c = data.contact[i]
            g1, g2 = int(c.geom[0]), int(c.geom[1])
            # the contact frame's normal points from geom1 to geom2: its force acts on geom2
            side, sign = self.side_of.get(g2), 1.0
            if side is None:
                side, sign = self.side_of.get(g1), -1.0
            if side is None or c.efc_address < 0:
                continue
            mujoco.mj_contactForce(model, data, i, f6)
            mujoco.mju_mulMatTVec3(F, c.frame, f6[:3])
            mujoco.mju_mulMatTVec3(T, c.frame, f6[3:])
            if sign < 0:
                mujoco.mju_scl3(F, F, -1.0)
                mujoco.mju_scl3(T, T, -1.0)
            mujoco.mju_sub3(r, c.pos, data.xpos[self.bodies[side]])
            mujoco.mju_cross(rxF, r, F)
            mujoco.mju_addTo3(w[side, :3], F)
            mujoco.mju_addTo3(w[side, 3:], rxF)
            mujoco.mju_addTo3(w[side, 3:], T)
        return w

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData, out: Optional[np.ndarray] = None) -> np.ndarray:
        """``(2, 6)``: :meth:`world`'s wrenches in each foot's own axes (what sim_node publishes)."""
        w = self.world(model, data)
        o = np.zeros((2, 6)) if out is None else out
        for k, b in enumerate(self.bodies):
            for a in (0, 3):
                mujoco.mju_mulMatTVec3(o[k, a:a + 3], data.xmat[b], w[k, a:a + 3])
        return o

    def rotations(self, data: mujoco.MjData) -> np.ndarray:
        """``(2, 3, 3)`` foot-to-world rotations of the state (``R @ foot-frame vector = world``)."""
        return data.xmat[self.bodies].reshape(2, 3, 3).copy()


def to_world(wrench: np.ndarray, rotation: np.ndarray, origin: Optional[np.ndarray] = None,
             point: Optional[np.ndarray] = None) -> np.ndarray:
    """One foot-frame wrench ``(6,)`` in world axes, its moment moved from the foot origin
    ``origin`` (world) to ``point`` (world) when both are given: τ_p = R τ + (o − p) × R f."""
    R = np.asarray(rotation, float).reshape(3, 3)
    f, t = R @ wrench[:3], R @ wrench[3:]
    if origin is not None and point is not None:
        t = t + np.cross(np.asarray(origin, float) - np.asarray(point, float), f)
    return np.r_[f, t]
