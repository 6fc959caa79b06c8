"""URDF of Cassie + flywheel generated from the compiled MuJoCo model (no ROS).

:func:`export_urdf` compiles :func:`model.build_model` and walks MuJoCo's kinematic tree, so the
URDF cannot drift from the MJCF: one link per MuJoCo body (the world is left out; the floating
pelvis is the URDF root), one joint per MuJoCo joint (three per ball), link names = body names, joint names =
the ``/joint_states`` names of the simulator (cassie_flip_sim.simulator.Simulator).

Tree approximation: Cassie's closed chains (achilles rods, plantar rods) are closed in MuJoCo by
``connect`` equality constraints; URDF has no loops, so the URDF is the spanning tree MuJoCo
already has and the constraints are omitted.  A consumer moving the joints independently can
open the loops.

Other mappings:

- hinge -> ``revolute`` (limits = ``jnt_range``) or ``continuous`` if unlimited; slide ->
  ``prismatic`` (an unlimited one gets no lower/upper: URDF has no unlimited prismatic).  The URDF angle equals MuJoCo ``qpos``: a hinge ``ref`` (qpos0) is folded into
  the joint origin, and a joint anchor off the body origin (``jnt_pos``) gets a fixed joint after
  the moving one.
- ball -> three ``continuous`` joints ``<name>_x``, ``<name>_y``, ``<name>_z`` about the x, y, z
  axes (intrinsic XYZ Euler angles, :func:`ball_angles`).  ``/joint_states`` carries the same
  names with the rotation vector, which agrees with those angles only to first order (standing,
  the achilles rods come out up to 0.6 deg off, 5 mm at the rod's end, if fed it unconverted).
- a body with several URDF joints (several MuJoCo joints, or a ball) chains them through
  massless links ``<body>__<joint>``; a body without a joint is welded by a fixed joint
  ``<body>_fixed``.
- inertial: ``body_mass``, ``body_ipos``, principal ``body_inertia`` in the ``body_iquat`` frame.
- geoms -> visuals (all) and collisions (geoms with contype or conaffinity): box, sphere,
  cylinder; a capsule is a cylinder plus two spheres; mesh, ellipsoid and other shapes URDF lacks
  are boxes of their bounding box (``geom_aabb``).
- effort limit = the joint motor's force range (0 without a motor); velocity limits are not in the
  MuJoCo model (0 = not given); joint springs are not representable and are left out.
"""
from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import dataclass
from typing import Dict, List, Optional, Tuple

import mujoco
import numpy as np

from . import model as M

# plain ints: numpy's int32 is not `in` a tuple of pybind enums
_FREE, _BALL, _SLIDE, _HINGE = (int(mujoco.mjtJoint.mjJNT_FREE), int(mujoco.mjtJoint.mjJNT_BALL),
                                int(mujoco.mjtJoint.mjJNT_SLIDE), int(mujoco.mjtJoint.mjJNT_HINGE))
_PLANE, _SPHERE, _CAPSULE, _CYLINDER, _BOX = (int(getattr(mujoco.mjtGeom, f"mjGEOM_{n}"))
                                              for n in ("PLANE", "SPHERE", "CAPSULE", "CYLINDER", "BOX"))


def _fmt(*vals) -> str:
    return " ".join(repr(float(v) + 0.0) for v in vals)


def _tf(pos=(0.0, 0.0, 0.0), quat=(1.0, 0.0, 0.0, 0.0)) -> np.ndarray:
    """4x4 transform from a position and a MuJoCo (w, x, y, z) quaternion."""
    T = np.eye(4)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, np.asarray(quat, float))
    T[:3, :3] = R.reshape(3, 3)
    T[:3, 3] = pos
    return T


def _rot(axis, angle: float) -> np.ndarray:
    q = np.zeros(4)
    mujoco.mju_axisAngle2Quat(q, np.asarray(axis, float), angle)
    return _tf(quat=q)


def rpy(R: np.ndarray) -> Tuple[float, float, float]:
    """URDF roll-pitch-yaw (R = Rz(yaw) Ry(pitch) Rx(roll)) of a rotation matrix; exact at
    pitch = ±90° too (yaw set to 0 there), which Cassie's hip frames hit."""
    cp = np.hypot(R[0, 0], R[1, 0])
    pitch = np.arctan2(-R[2, 0], cp)
    if cp < 1e-12:
        s = -np.sign(R[2, 0])
        return float(np.arctan2(s * R[0, 1], R[1, 1])), float(pitch), 0.0
    return float(np.arctan2(R[2, 1], R[2, 2])), float(pitch), float(np.arctan2(R[1, 0], R[0, 0]))


def ball_angles(quat) -> np.ndarray:
    """URDF values (x, y, z) of a ball joint's three joints from its MuJoCo qpos quaternion:
    intrinsic XYZ Euler angles, R = Rx(a) Ry(b) Rz(c)."""
    R = _tf(quat=quat)[:3, :3]
    b = np.arctan2(R[0, 2], np.hypot(R[1, 2], R[2, 2]))
    return np.array([np.arctan2(-R[1, 2], R[2, 2]), b, np.arctan2(-R[0, 1], R[0, 0])])


def _origin(parent: ET.Element, T: np.ndarray) -> None:
    ET.SubElement(parent, "origin", xyz=_fmt(*T[:3, 3]), rpy=_fmt(*rpy(T[:3, :3])))


def _name(model, obj, i: int, prefix: str) -> str:
    return mujoco.mj_id2name(model, obj, i) or f"{prefix}{i}"


# ------------------------------------------------------------------------------------ joints

@dataclass
class _Joint:
    """One URDF joint: anchor in the body frame, ``offset`` folds qpos0 into the origin."""
    name: str
    kind: str
    axis: np.ndarray
    anchor: np.ndarray
    offset: np.ndarray
    limits: Optional[Tuple[float, float]] = None
    dof: int = -1


def _urdf_joints(model, b: int) -> List[_Joint]:
    """The URDF joints of body ``b``'s MuJoCo joints, in MuJoCo's order of application."""
    out = []
    for j in range(model.body_jntadr[b], model.body_jntadr[b] + model.body_jntnum[b]):
        t, name = int(model.jnt_type[j]), _name(model, mujoco.mjtObj.mjOBJ_JOINT, j, "joint")
        axis, anchor = model.jnt_axis[j].copy(), model.jnt_pos[j].copy()
        ref = model.qpos0[model.jnt_qposadr[j]]
        lim = tuple(model.jnt_range[j]) if model.jnt_limited[j] else None
        dof = model.jnt_dofadr[j]
        if t == _HINGE:
            out.append(_Joint(name, "revolute" if lim else "continuous", axis, anchor,
                              _rot(axis, -ref), lim, dof))
        elif t == _SLIDE:
            out.append(_Joint(name, "prismatic", axis, anchor, _tf(-ref * axis), lim, dof))
        elif t == _BALL:
            for k, s in enumerate("xyz"):
                out.append(_Joint(f"{name}_{s}", "continuous", np.eye(3)[k], anchor, np.eye(4),
                                  None, dof + k))
        else:
            raise ValueError(f"free joint {name!r} below the root body: no URDF equivalent")
    return out


def _motor_effort(model) -> Dict[int, float]:
    """Per dof: max |force| of the joint-transmission motors on it (ctrlrange * gear)."""
    eff: Dict[int, float] = {}
    for a in range(model.nu):
        if model.actuator_trntype[a] == mujoco.mjtTrn.mjTRN_JOINT and model.actuator_ctrllimited[a]:
            dof = model.jnt_dofadr[model.actuator_trnid[a, 0]]
            f = np.max(np.abs(model.actuator_ctrlrange[a])) * abs(model.actuator_gear[a, 0])
            eff[dof] = max(eff.get(dof, 0.0), float(f))
    return eff


def _add_joint(robot, name, kind, parent, child, T, j: Optional[_Joint] = None, model=None,
               effort: Optional[Dict[int, float]] = None) -> None:
    e = ET.SubElement(robot, "joint", name=name, type=kind)
    _origin(e, T)
    ET.SubElement(e, "parent", link=parent)
    ET.SubElement(e, "child", link=child)
    if j is None:
        return
    ET.SubElement(e, "axis", xyz=_fmt(*j.axis))
    eff = effort.get(j.dof, 0.0) if effort else 0.0
    if j.limits is not None or kind != "continuous" or eff:
        lim = ET.SubElement(e, "limit", effort=_fmt(eff), velocity="0.0")
        if j.limits is not None:
            lim.set("lower", _fmt(j.limits[0]))
            lim.set("upper", _fmt(j.limits[1]))
    damping, friction = model.dof_damping[j.dof], model.dof_frictionloss[j.dof]
    if damping or friction:
        ET.SubElement(e, "dynamics", damping=_fmt(damping), friction=_fmt(friction))


def _connect(robot, model, b: int, effort) -> None:
    """Joints from body ``b``'s parent link to its link, through massless links if several."""
    body = _name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body")
    parent = _name(model, mujoco.mjtObj.mjOBJ_BODY, model.body_parentid[b], "body")
    T, prev = _tf(model.body_pos[b], model.body_quat[b]), np.zeros(3)
    joints = _urdf_joints(model, b)
    for k, j in enumerate(joints):
        # MuJoCo: body frame <- Trans(anchor) Rot(axis, qpos - qpos0) Trans(-anchor), per joint
        T = T @ _tf(j.anchor - prev) @ j.offset
        last = k == len(joints) - 1 and not np.any(j.anchor)
        child = body if last else f"{body}__{j.name}"
        if not last:
            ET.SubElement(robot, "link", name=child)
        _add_joint(robot, j.name, j.kind, parent, child, T, j, model, effort)
        parent, T, prev = child, np.eye(4), j.anchor
    if parent != body:
        _add_joint(robot, f"{body}_fixed", "fixed", parent, body, T @ _tf(-prev))


# ------------------------------------------------------------------------------------- links

def _shapes(model, g: int) -> List[Tuple[str, Dict[str, str], np.ndarray]]:
    """URDF primitives (tag, attributes, pose in the body frame) of geom ``g``."""
    t, s = int(model.geom_type[g]), model.geom_size[g]
    T = _tf(model.geom_pos[g], model.geom_quat[g])
    if t == _PLANE:
        return []
    if t == _SPHERE:
        return [("sphere", {"radius": _fmt(s[0])}, T)]
    if t == _BOX:
        return [("box", {"size": _fmt(*(2 * s))}, T)]
    if t in (_CYLINDER, _CAPSULE):
        out = [("cylinder", {"radius": _fmt(s[0]), "length": _fmt(2 * s[1])}, T)]
        if t == _CAPSULE:
            out += [("sphere", {"radius": _fmt(s[0])}, T @ _tf((0, 0, z))) for z in (-s[1], s[1])]
        return out
    # mesh, ellipsoid, ...: the geom-frame bounding box (centre, half sizes)
    aabb = model.geom_aabb[g]
    return [("box", {"size": _fmt(*(2 * aabb[3:]))}, T @ _tf(aabb[:3]))]


def _add_link(robot, model, b: int, materials: Dict[tuple, str]) -> None:
    link = ET.SubElement(robot, "link", name=_name(model, mujoco.mjtObj.mjOBJ_BODY, b, "body"))
    if model.body_mass[b] > 0:
        inertial = ET.SubElement(link, "inertial")
        _origin(inertial, _tf(model.body_ipos[b], model.body_iquat[b]))
        ET.SubElement(inertial, "mass", value=_fmt(model.body_mass[b]))
        i = model.body_inertia[b]
        ET.SubElement(inertial, "inertia", ixx=_fmt(i[0]), iyy=_fmt(i[1]), izz=_fmt(i[2]),
                      ixy="0.0", ixz="0.0", iyz="0.0")
    for g in np.flatnonzero(model.geom_bodyid == b):
        t = int(model.geom_type[g])
        if t not in (_SPHERE, _BOX, _CYLINDER, _CAPSULE, _PLANE):
            link.append(ET.Comment(f" geom {g} ({mujoco.mjtGeom(t).name}): its bounding box "))
        mat = model.geom_matid[g]
        rgba = np.asarray(model.mat_rgba[mat] if mat >= 0 else model.geom_rgba[g], float)
        rgba = tuple(np.round(rgba, 4))     # float32 in MuJoCo
        mname = materials.setdefault(rgba, f"material_{len(materials)}")
        collides = model.geom_contype[g] or model.geom_conaffinity[g]
        gname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        for tag, attrs, T in _shapes(model, g):
            for kind in ("visual", "collision") if collides else ("visual",):
                e = ET.SubElement(link, kind, **({"name": gname} if gname else {}))
                _origin(e, T)
                ET.SubElement(ET.SubElement(e, "geometry"), tag, **attrs)
                if kind == "visual":
                    ET.SubElement(e, "material", name=mname)


def urdf_from_model(model: mujoco.MjModel, name: str = "robot") -> str:
    """URDF (string) of a compiled MuJoCo model with one tree below the world."""
    roots = [b for b in range(1, model.nbody) if model.body_parentid[b] == 0]
    if len(roots) != 1:
        raise ValueError(f"need exactly one body below the world, found {len(roots)}")
    root = roots[0]
    if any(int(model.jnt_type[j]) != _FREE
           for j in range(model.body_jntadr[root], model.body_jntadr[root] + model.body_jntnum[root])):
        raise ValueError("the root body may only have a free joint (it becomes the URDF root)")
    robot = ET.Element("robot", name=name)
    materials: Dict[tuple, str] = {}
    effort = _motor_effort(model)
    for b in range(1, model.nbody):      # MuJoCo orders bodies parents first
        _add_link(robot, model, b, materials)
        if b != root:
            _connect(robot, model, b, effort)
    for k, (rgba, mname) in enumerate(materials.items()):
        m = ET.Element("material", name=mname)
        ET.SubElement(m, "color", rgba=_fmt(*rgba))
        robot.insert(k, m)
    robot.insert(0, ET.Comment(" generated by cassie_model.urdf from the MuJoCo model; "
                                 "loop-closure constraints omitted (tree approximation) "))
    ET.indent(robot)
    return ET.tostring(robot, encoding="unicode") + "\n"


def export_urdf(flywheel: M.FlywheelSpec = "I") -> str:
    """URDF of Cassie with flywheel ``flywheel`` ("I", "II", "III"), from :func:`model.build_model`."""
    return urdf_from_model(M.build_model(flywheel), name="cassie_flywheel")
