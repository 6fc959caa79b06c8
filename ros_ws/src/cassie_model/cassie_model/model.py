"""Cassie + flywheel model: MJCF export (the one source for MuJoCo and Pinocchio), scenarios,
MuJoCo model build (``mujoco.MjSpec``), standing state on the loop-closure manifold (and the
figures a planner takes of it: mass, COM, leg length); the MuJoCo <-> Pinocchio state mapping is in
:mod:`cassie_model.pinocchio_map`.

Built from :mod:`cassie_model.robot_params` only.  Robot geometry uses primitives; only the
foot contact spheres collide, and only with the terrain.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple, Union
from xml.sax.saxutils import quoteattr

import mujoco
import numpy as np

from . import robot_params as P

FlywheelSpec = Union[str, P.Flywheel, Tuple[float, float], None]

#: Contact geom names per foot (heel, toe).
FOOT_GEOMS = {"left": ("left_foot_heel", "left_foot_toe"), "right": ("right_foot_heel", "right_foot_toe")}
TERRAIN_GEOMS = ("ground", "start_platform", "landing_slab", "takeoff_slab")
#: contact bits: feet (contype 1) and upper body (contype 2) collide with terrain only
FOOT_CONTYPE, BODY_CONTYPE = 1, 2
#: bodies (by name suffix) whose geoms collide with the terrain besides the pelvis and flywheel
BODY_COLLIDERS = ("_hip_roll", "_hip_yaw", "_hip_pitch", "_knee", "_shin")


# --------------------------------------------------------------------------------------------
# MJCF export
# --------------------------------------------------------------------------------------------

def quat_from_xyaxes(xyaxes) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of the frame given by MJCF ``xyaxes`` (as MuJoCo does it)."""
    x = np.asarray(xyaxes[:3], float)
    y = np.asarray(xyaxes[3:], float)
    x = x / np.linalg.norm(x)
    y = y - x * (x @ y)
    y = y / np.linalg.norm(y)
    z = np.cross(x, y)
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.column_stack([x, y, z]).ravel())
    return q


def _f(*vals) -> str:
    return " ".join(repr(float(v)) for v in vals)


def _visual_geoms(lines: list, b: P.Body, children: dict, indent: str):
    """The massless visual geoms of body ``b`` and, on a foot, its contact spheres and toe/heel sites."""
    # visual primitives (massless): pelvis box, capsules towards the children
    if b.parent == "world":
        lines.append(f'{indent}  <geom name="pelvis_vis" type="box" size="0.08 0.12 0.06" pos="0.03 0 0.03"/>')
    for c in children.get(b.name, []):
        if np.linalg.norm(c.pos) > 1e-3 and b.parent != "world":
            lines.append(f'{indent}  <geom type="capsule" size="0.015" fromto="0 0 0 {_f(*c.pos)}"/>')
    if b.name.endswith("_achilles_rod") or b.name.endswith("_plantar_rod"):
        length = 0.5012 if b.name.endswith("_achilles_rod") else 0.35012
        lines.append(f'{indent}  <geom type="capsule" size="0.008" fromto="0 0 0 {length!r} 0 0"/>')
    if b.name.endswith("_tarsus") or b.name.endswith("_heel_spring") or b.name.endswith("_shin"):
        tip = {"_tarsus": (0.43, -0.04, 0), "_heel_spring": (0.1, 0, 0), "_shin": (0.43476, 0, 0)}
        for k, v in tip.items():
            if b.name.endswith(k):
                lines.append(f'{indent}  <geom type="capsule" size="0.02" fromto="0 0 0 {_f(*v)}"/>')
    if b.name.endswith("_foot") and b.parent.endswith("_tarsus"):
        side = b.name.split("_")[0]
        h, t, r = P.FOOT_HEEL, P.FOOT_TOE, P.FOOT_RADIUS
        lines.append(f'{indent}  <geom type="capsule" size="0.012" fromto="{_f(*h, *t)}"/>')
        for gname, pt in zip(FOOT_GEOMS[side], (h, t)):
            lines.append(f'{indent}  <geom name="{gname}" type="sphere" size="{r!r}" pos="{_f(*pt)}" '
                         f'contype="1" conaffinity="0" condim="3" friction="{_f(*P.FRICTION)}" group="3" '
                         f'rgba="0.2 0.2 0.2 1"/>')
        lines.append(f'{indent}  <site name="{side}_foot_heel" pos="{_f(*h)}"/>')
        lines.append(f'{indent}  <site name="{side}_foot_toe" pos="{_f(*t)}"/>')


def _flywheel_xml(lines: list, fw, indent: str):
    """The flywheel body (inertia, hinge about y, visual disc) inside the pelvis."""
    ind = indent + "  "
    lines.append(f'{ind}<body name="flywheel" pos="0 0 {fw.height!r}">')
    lines.append(f'{ind}  <inertial pos="0 0 0" mass="{fw.mass!r}" '
                 f'diaginertia="{_f(fw.inertia_transverse, fw.inertia_pitch, fw.inertia_transverse)}"/>')
    lines.append(f'{ind}  <joint name="flywheel" type="hinge" axis="0 1 0"/>')
    lines.append(f'{ind}  <geom type="cylinder" size="{_f(fw.radius, fw.thickness / 2)}" '
                 f'quat="0.7071067811865476 0.7071067811865476 0 0" rgba="0.6 0.6 0.65 1"/>')
    lines.append(f'{ind}  <geom type="box" size="0.01 {fw.thickness / 2 + 0.002!r} {0.9 * fw.radius!r}" rgba="0.1 0.1 0.1 1"/>')
    lines.append(f"{ind}</body>")


def export_mjcf(flywheel: FlywheelSpec = "I", *, model_name: str = "cassie_flywheel") -> str:
    """Robot MJCF (no terrain) that both MuJoCo and Pinocchio load.

    Angles are exported in radians, frames as quaternions; inertials are explicit and geoms carry
    no mass (``inertiafromgeom="false"``).  Hinge ``ref`` is kept (MuJoCo qpos0 = ref).
    ``flywheel=None`` gives the plain Cassie (10 motors).
    """
    fw = P.flywheel(flywheel)
    children = {}
    for b in P.BODIES:
        children.setdefault(b.parent, []).append(b)
    lines = [
        f"<mujoco model={quoteattr(model_name)}>",
        '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
        f'  <option timestep="{P.TIMESTEP!r}" integrator="{P.INTEGRATOR}" cone="{P.CONE}" impratio="{P.IMPRATIO!r}"/>',
        "  <default>",
        f'    <geom contype="0" conaffinity="0" condim="1" solref="{_f(*P.GEOM_SOLREF)}" group="2" rgba="0.9 0.5 0.1 1"/>',
        f'    <equality solref="{_f(*P.EQUALITY_SOLREF)}"/>',
        "  </default>",
        "  <worldbody>",
    ]

    def body_xml(b: P.Body, indent: str):
        attrs = f"name={quoteattr(b.name)} pos={quoteattr(_f(*b.pos))}"
        if b.xyaxes is not None:
            attrs += f" quat={quoteattr(_f(*quat_from_xyaxes(b.xyaxes)))}"
        lines.append(f"{indent}<body {attrs}>")
        i = b.inertial
        lines.append(f'{indent}  <inertial pos="{_f(*i.pos)}" mass="{i.mass!r}" fullinertia="{_f(*i.fullinertia)}"/>')
        if b.parent == "world":
            lines.append(f'{indent}  <freejoint name="{b.name}"/>')
        elif b.joint is not None:
            j = b.joint
            a = f'name="{j.name}" type="{j.type}"'
            if j.range_deg is not None:
                a += f' range="{_f(*np.radians(j.range_deg))}"'
            if j.ref_deg:
                a += f' ref="{_f(math.radians(j.ref_deg))}"'
            if j.stiffness:
                a += f' stiffness="{j.stiffness!r}"'
            if j.damping:
                a += f' damping="{j.damping!r}"'
            if j.armature:
                a += f' armature="{j.armature!r}"'
            lines.append(f"{indent}  <joint {a}/>")
        _visual_geoms(lines, b, children, indent)
        for c in children.get(b.name, []):
            body_xml(c, indent + "  ")
        if b.parent == "world" and fw is not None:
            _flywheel_xml(lines, fw, indent)
        lines.append(f"{indent}</body>")

    body_xml(P.PELVIS, "    ")
    lines.append("  </worldbody>")
    lines.append("  <equality>")
    for c in P.CONNECTS:
        lines.append(f'    <connect body1="{c.body1}" body2="{c.body2}" anchor="{_f(*c.anchor)}"/>')
    lines.append("  </equality>")
    lines.append("  <actuator>")
    motors = list(P.CASSIE_MOTORS) + ([P.flywheel_motor(fw)] if fw is not None else [])
    for m in motors:
        # gear 1: ctrl is the joint-side torque; ctrlrange is a backstop, the simulator clips first.
        lines.append(f'    <motor name="{m.joint}" joint="{m.joint}" gear="1" '
                     f'ctrlrange="{_f(-m.torque_limit, m.torque_limit)}"/>')
    lines.append("  </actuator>")
    lines.append("</mujoco>")
    return "\n".join(lines) + "\n"


# --------------------------------------------------------------------------------------------
# Scenarios
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Scenario:
    """Terrain: ground z = 0; optional start platform (top at ``start_height``, front edge at
    world x = ``platform_edge_x``, extending backwards); optional landing area at ``landing_height``
    from world x = ``landing_start_x`` forwards: raised, a slab on the ground; lowered (negative),
    the ground plane at that height and a take-off slab, top at z = 0, behind ``landing_start_x``.
    The planner is told ``planner_landing_height`` (paper flip D: told 0, truth +0.1 m).  The robot
    stands at x = 0."""
    name: str = "flat"
    start_height: float = 0.0
    platform_edge_x: float = 0.15
    landing_height: float = 0.0
    landing_start_x: float = 0.4
    planner_landing_height: float = 0.0
    friction: float = P.FRICTION[0]

    @staticmethod
    def flat() -> "Scenario":
        return Scenario("flat")

    @staticmethod
    def platform(height: float = 0.5, edge_x: float = 0.15) -> "Scenario":
        """Paper flip C: start on a 0.5 m platform, land on the ground ahead."""
        return Scenario("platform", start_height=height, platform_edge_x=edge_x)

    @staticmethod
    def raised_landing(dh: float = 0.1, start_x: float = 0.4) -> "Scenario":
        """Paper flip D: landing surface 0.1 m higher than the planner is told."""
        return Scenario("raised_landing", landing_height=dh, landing_start_x=start_x,
                        planner_landing_height=0.0)

    @property
    def landing_surface_height(self) -> float:
        """True height of the surface ahead of the robot."""
        return self.landing_height if self.landing_height else 0.0


SCENARIOS = {"flat": Scenario.flat(), "platform": Scenario.platform(), "raised_landing": Scenario.raised_landing()}


def scenario(name_or_scenario: Union[str, Scenario, None]) -> Scenario:
    if name_or_scenario is None:
        return Scenario.flat()
    if isinstance(name_or_scenario, Scenario):
        return name_or_scenario
    return SCENARIOS[name_or_scenario]


def build_spec(flywheel: FlywheelSpec = "I", scen: Union[str, Scenario, None] = None) -> mujoco.MjSpec:
    """MjSpec of robot (from :func:`export_mjcf`) plus terrain, light and a tracking camera."""
    sc = scenario(scen)
    spec = mujoco.MjSpec.from_string(export_mjcf(flywheel))
    wb = spec.worldbody
    fr = [sc.friction, P.FRICTION[1], P.FRICTION[2]]

    def terrain(name, gtype, size, pos, rgba):
        g = wb.add_geom()
        g.name, g.type, g.size, g.pos, g.rgba = name, gtype, size, pos, rgba
        g.contype, g.conaffinity, g.condim, g.friction = 0, FOOT_CONTYPE | BODY_CONTYPE, 3, fr
        g.solref = list(P.GEOM_SOLREF)
        g.group = 0

    # The upper body (pelvis, flywheel, thighs, shins) also hits the terrain, so that a fall is a
    # fall; the lower-leg linkage near the ground does not (it would touch when standing).
    for body in spec.bodies:
        if body.name == "flywheel" or body.name == "pelvis" or body.name.endswith(BODY_COLLIDERS):
            for g in body.geoms:
                if g.contype == 0 and g.name not in sum(FOOT_GEOMS.values(), ()):
                    g.contype = BODY_CONTYPE

    lowered = min(sc.landing_height, 0.0)
    terrain("ground", mujoco.mjtGeom.mjGEOM_PLANE, [0, 0, 0.125], [0, 0, lowered], [0.25, 0.3, 0.35, 1])
    if sc.start_height > 0:
        h = sc.start_height
        terrain("start_platform", mujoco.mjtGeom.mjGEOM_BOX, [1.5, 1.5, h / 2],
                [sc.platform_edge_x - 1.5, 0, h / 2], [0.45, 0.4, 0.35, 1])
    if sc.landing_height > 0:
        h = sc.landing_height
        terrain("landing_slab", mujoco.mjtGeom.mjGEOM_BOX, [3.0, 1.5, h / 2],
                [sc.landing_start_x + 3.0, 0, h / 2], [0.35, 0.45, 0.35, 1])
    elif lowered < 0:
        terrain("takeoff_slab", mujoco.mjtGeom.mjGEOM_BOX, [3.0, 1.5, -lowered / 2],
                [sc.landing_start_x - 3.0, 0, lowered / 2], [0.45, 0.4, 0.35, 1])
    light = wb.add_light()
    light.pos, light.dir = [0, -1, 4], [0, 0.25, -1]
    cam = wb.add_camera()
    cam.name, cam.pos, cam.mode = "side", [0.3, -4.0, 1.0], mujoco.mjtCamLight.mjCAMLIGHT_FIXED
    cam.quat = quat_from_xyaxes([1, 0, 0, 0, 0.2, 1])
    spec.visual.global_.offwidth = 1280
    spec.visual.global_.offheight = 720
    return spec


def build_model(flywheel: FlywheelSpec = "I", scen: Union[str, Scenario, None] = None) -> mujoco.MjModel:
    """Compiled MjModel of Cassie + flywheel on the scenario's terrain."""
    return build_spec(flywheel, scen).compile()


# --------------------------------------------------------------------------------------------
# Standing state (loop closures satisfied, feet flat)
# --------------------------------------------------------------------------------------------

_PASSIVE = ("achilles_rod", "tarsus", "foot_crank", "plantar_rod", "foot")


def loop_residual(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """Connect residuals (world frame, m), 3 per loop; needs positions computed (mj_kinematics)."""
    r = []
    for i in range(model.neq):
        if model.eq_type[i] != mujoco.mjtEq.mjEQ_CONNECT:
            continue
        b1, b2 = model.eq_obj1id[i], model.eq_obj2id[i]
        p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ model.eq_data[i, 0:3]
        p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ model.eq_data[i, 3:6]
        r.append(p1 - p2)
    return np.concatenate(r) if r else np.zeros(0)


def _point_jac(model, data, body, point):
    jp = np.zeros((3, model.nv))
    mujoco.mj_jac(model, data, jp, None, point, body)
    return jp


def _closure_system(model, data):
    r, J = [], []
    for i in range(model.neq):
        b1, b2 = model.eq_obj1id[i], model.eq_obj2id[i]
        p1 = data.xpos[b1] + data.xmat[b1].reshape(3, 3) @ model.eq_data[i, 0:3]
        p2 = data.xpos[b2] + data.xmat[b2].reshape(3, 3) @ model.eq_data[i, 3:6]
        r.append(p1 - p2)
        J.append(_point_jac(model, data, b1, p1) - _point_jac(model, data, b2, p2))
    for side in ("left", "right"):   # flat foot: toe and heel at the same height
        h = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{side}_foot_heel")
        t = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, f"{side}_foot_toe")
        fb = model.site_bodyid[t]
        r.append(np.array([data.site_xpos[t, 2] - data.site_xpos[h, 2]]))
        J.append((_point_jac(model, data, fb, data.site_xpos[t]) - _point_jac(model, data, fb, data.site_xpos[h]))[2:3])
    return np.concatenate(r), np.vstack(J)


def foot_points_world(model: mujoco.MjModel, data: mujoco.MjData) -> np.ndarray:
    """(4, 3) world positions of the foot contact-sphere centres: left heel, left toe, right heel, right toe."""
    ids = [mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, g) for s in ("left", "right") for g in FOOT_GEOMS[s]]
    return data.geom_xpos[ids].copy()


def standing_state(model: mujoco.MjModel, scen: Union[str, Scenario, None] = None, *,
                   tol: float = 1e-12, max_iter: int = 50) -> Tuple[np.ndarray, np.ndarray]:
    """(qpos, qvel) standing still: the published ``home`` pose projected by Gauss-Newton over the
    passive joints (achilles balls, tarsus, foot crank, plantar rod, foot) onto the connect
    manifold (paper eq. (2)) with flat feet; springs at rest; pelvis lowered so the foot spheres
    touch the start surface.  Flywheel angle 0."""
    sc = scenario(scen)
    d = mujoco.MjData(model)
    qpos = model.qpos0.copy()
    qpos[: len(P.HOME_QPOS)] = P.HOME_QPOS    # flywheel (last) stays at 0
    dofs = []
    for side in ("left", "right"):
        for j in _PASSIVE:
            jid = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{side}_{j}")
            n = 3 if model.jnt_type[jid] == mujoco.mjtJoint.mjJNT_BALL else 1
            dofs.extend(range(model.jnt_dofadr[jid], model.jnt_dofadr[jid] + n))
    dofs = np.array(dofs)
    for _ in range(max_iter):
        d.qpos[:] = qpos
        mujoco.mj_kinematics(model, d)
        mujoco.mj_comPos(model, d)
        r, J = _closure_system(model, d)
        if np.max(np.abs(r)) < tol:
            break
        dq = np.zeros(model.nv)
        dq[dofs] = -np.linalg.lstsq(J[:, dofs], r, rcond=None)[0]
        mujoco.mj_integratePos(model, qpos, dq, 1.0)
    # lstsq's last bits depend on the BLAS kernel, and the feet are then placed exactly on the
    # ground (contact at distance 0): rounded to 1e-10 (the closure holds to 1e-12 before), the
    # start state is the same on every machine
    qpos = np.round(qpos, 10)
    mujoco.mj_normalizeQuat(model, qpos)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(model, d)
    lowest = foot_points_world(model, d)[:, 2].min() - P.FOOT_RADIUS
    qpos[2] += sc.start_height - lowest
    return qpos, np.zeros(model.nv)


@dataclass(frozen=True)
class StandingFigures:
    """The robot standing still on flat ground (:func:`standing_state`): what a planner takes of it."""
    mass: float                   # kg, the whole robot
    com: np.ndarray               # (3,) COM, world frame
    pelvis_position: np.ndarray   # (3,) pelvis origin, world frame
    pelvis_quaternion: np.ndarray  # (4,) pelvis orientation, wxyz
    leg_length: float             # m, hip pitch axis to foot joint, the two legs' mean


def standing_figures(flywheel: FlywheelSpec = "I") -> StandingFigures:
    """:class:`StandingFigures` of the robot with ``flywheel`` in its standing state on flat ground:
    forward kinematics (``mj_forward``) of :func:`standing_state` on :func:`build_model`, the state
    the simulator starts from."""
    model = build_model(flywheel, None)
    qpos, qvel = standing_state(model, None)
    d = mujoco.MjData(model)
    d.qpos[:] = qpos
    d.qvel[:] = qvel
    mujoco.mj_forward(model, d)
    pelvis = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
    legs = []
    for s in ("left", "right"):
        a = d.xanchor[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{s}_foot")]
        b = d.xanchor[mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, f"{s}_hip_pitch")]
        legs.append(np.linalg.norm(a - b))
    return StandingFigures(mass=float(mujoco.mj_getTotalmass(model)), com=d.subtree_com[pelvis].copy(),
                           pelvis_position=d.qpos[0:3].copy(), pelvis_quaternion=d.qpos[3:7].copy(),
                           leg_length=float(np.mean(legs)))
