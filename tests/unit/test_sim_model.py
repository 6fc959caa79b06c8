"""cassie_flip_sim model: parameters, MJCF export, Pinocchio agreement, standing state, limits."""
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import mujoco
import numpy as np
import pytest
from cassie_flip_sim.simulator import Simulator

from cassie_model import model as M
from cassie_model import pinocchio_map as PM
from cassie_model import robot_params as P
from cassie_model.motor_limits import MotorLimits, torque_bounds

pin = pytest.importorskip("pinocchio")

REFERENCE = Path(__file__).resolve().parents[3] / "shared" / "reference" / "agility_cassie" / "cassie.xml"


@pytest.fixture(scope="module")
def mj():
    return M.build_model("I")


@pytest.fixture(scope="module")
def pinm():
    return PM.pinocchio_model("I")


def test_mass_dofs_actuators(mj):
    assert P.CASSIE_MASS == pytest.approx(33.312, abs=1e-9)
    assert mujoco.mj_getTotalmass(mj) == pytest.approx(33.312 + 9.54, abs=1e-9)
    assert (mj.nq, mj.nv, mj.nu, mj.neq) == (36, 33, 11, 4)
    assert [mj.actuator(i).name for i in range(mj.nu)] == list(P.MOTOR_NAMES)
    assert list(P.MOTOR_NAMES) == ["left_hip_roll", "left_hip_yaw", "left_hip_pitch", "left_knee", "left_foot",
                                   "right_hip_roll", "right_hip_yaw", "right_hip_pitch", "right_knee",
                                   "right_foot", "flywheel"]
    assert mj.opt.timestep == 0.0005
    plain = M.build_model(None)
    assert (plain.nq, plain.nv, plain.nu) == (35, 32, 10)


@pytest.mark.parametrize("variant,inertia,mass", [("I", 0.1074, 9.54), ("II", 0.2148, 19.09),
                                                   ("III", 0.3222, 28.63), ((0.5, 12.0), 0.5, 12.0)])
def test_flywheel_variants(variant, inertia, mass):
    m = M.build_model(variant)
    b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "flywheel")
    j = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, "flywheel")
    assert m.body_mass[b] == pytest.approx(mass)
    assert np.allclose(m.body_pos[b], [0, 0, 0.15])
    assert np.allclose(m.jnt_axis[j], [0, 1, 0])
    # spin inertia about the body y axis (MuJoCo may reorder principal axes: check the y row)
    R = np.zeros(9)
    mujoco.mju_quat2Mat(R, m.body_iquat[b])
    I = R.reshape(3, 3) @ np.diag(m.body_inertia[b]) @ R.reshape(3, 3).T
    assert I[1, 1] == pytest.approx(inertia)
    assert m.body_parentid[b] == mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")


def test_collisions_are_robot_terrain_only(mj):
    """Feet and the upper body (a fall) collide with the terrain; nothing collides with itself."""
    feet = {n for s in ("left", "right") for n in M.FOOT_GEOMS[s]}
    upper = set()
    for g in range(mj.ngeom):
        name = mj.geom(g).name
        pair = (mj.geom_contype[g], mj.geom_conaffinity[g])
        if name in feet:
            assert pair == (M.FOOT_CONTYPE, 0)
        elif name in M.TERRAIN_GEOMS:
            assert pair == (0, M.FOOT_CONTYPE | M.BODY_CONTYPE)
        else:
            assert pair in ((0, 0), (M.BODY_CONTYPE, 0)), name
            if pair[0]:
                upper.add(mj.body(mj.geom_bodyid[g]).name)
    assert {"pelvis", "flywheel", "left_knee", "right_knee"} <= upper
    assert not any(b.endswith(("_tarsus", "_foot", "_foot_crank", "_plantar_rod")) for b in upper)
    assert P.FOOT_LENGTH == pytest.approx(0.16, abs=1e-3)


def test_standing_touches_with_feet_only_and_a_collapse_is_seen():
    sim = Simulator()
    assert sim.body_contacts() == []
    for _ in range(4000):
        sim.step(np.zeros(11))
        if sim.body_contacts():
            break
    assert sim.body_contacts(), "zero torque for 2 s must bring the upper body to the ground"


def test_standing_state_closes_loops_feet_flat(mj):
    qpos, qvel = M.standing_state(mj)
    d = mujoco.MjData(mj)
    d.qpos[:] = qpos
    mujoco.mj_kinematics(mj, d)
    assert np.abs(M.loop_residual(mj, d)).max() < 1e-6
    home = mujoco.MjData(mj)
    home.qpos[:35] = P.HOME_QPOS
    mujoco.mj_kinematics(mj, home)
    assert 5e-4 < np.abs(M.loop_residual(mj, home)).max() < 2e-3    # the published gap
    pts = M.foot_points_world(mj, d)
    assert np.allclose(pts[:, 2], P.FOOT_RADIUS, atol=1e-6)         # flat, on z = 0
    assert pts[1, 0] > pts[0, 0] and pts[3, 0] > pts[2, 0]          # toe ahead of heel (+x)
    assert not np.any(qvel)
    sc = M.Scenario.platform(0.5)
    qp, _ = M.standing_state(M.build_model("I", sc), sc)
    assert qp[2] == pytest.approx(qpos[2] + 0.5)


def test_scenarios_terrain():
    sc = M.Scenario.platform(0.5)
    m = M.build_model("I", sc)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "start_platform")
    top = m.geom_pos[g, 2] + m.geom_size[g, 2]
    front = m.geom_pos[g, 0] + m.geom_size[g, 0]
    assert top == pytest.approx(0.5) and front == pytest.approx(sc.platform_edge_x)
    qp, _ = M.standing_state(m, sc)
    d = mujoco.MjData(m)
    d.qpos[:] = qp
    mujoco.mj_kinematics(m, d)
    assert M.foot_points_world(m, d)[:, 0].max() + P.FOOT_RADIUS < front   # toes on the platform
    sd = M.Scenario.raised_landing(0.1)
    m = M.build_model("I", sd)
    g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, "landing_slab")
    assert m.geom_pos[g, 2] + m.geom_size[g, 2] == pytest.approx(0.1)
    assert m.geom_pos[g, 0] - m.geom_size[g, 0] == pytest.approx(sd.landing_start_x)
    assert sd.planner_landing_height == 0.0


def test_export_roundtrip_mujoco(mj):
    """The exported MJCF alone compiles to the same robot (no dropped inertials)."""
    m2 = mujoco.MjModel.from_xml_string(M.export_mjcf("I"))
    assert np.array_equal(m2.body_mass, mj.body_mass[: m2.nbody])
    assert np.allclose(m2.body_inertia, mj.body_inertia[: m2.nbody])
    assert np.array_equal(m2.qpos0, mj.qpos0)
    assert np.allclose(m2.eq_data, mj.eq_data)


def _random_states(mj, n, seed=0):
    rng = np.random.default_rng(seed)
    q0, _ = M.standing_state(mj)
    for _ in range(n):
        qpos = q0.copy()
        mujoco.mj_integratePos(mj, qpos, 0.4 * rng.normal(size=mj.nv), 1.0)
        yield qpos, rng.normal(size=mj.nv)


def test_pinocchio_model_structure(mj, pinm):
    assert (pinm.nq, pinm.nv) == (mj.nq, mj.nv)
    assert sum(i.mass for i in pinm.inertias) == pytest.approx(mujoco.mj_getTotalmass(mj))
    mp = PM.PinocchioMap(mj, pinm)
    # Pinocchio's "qpos0" reference configuration is MuJoCo's qpos0 (hinge refs included)
    q_ref = dict((e.key(), e.data()) for e in pinm.referenceConfigurations)["qpos0"]
    assert np.allclose(q_ref, mp.to_pin(mj.qpos0)[0])
    # armature is imported by Pinocchio
    assert np.allclose(pinm.armature, mj.dof_armature[mp.dof_perm()])
    # known pin 4.1 quirk: limits of joints with ref are stored shifted by -ref
    j = pinm.getJointId("left_knee")
    assert pinm.lowerPositionLimit[pinm.idx_qs[j]] == pytest.approx(math.radians(-164 + 45))


def test_state_mapping_kinematics_and_roundtrip(mj, pinm):
    mp = PM.PinocchioMap(mj, pinm)
    pd = pinm.createData()
    d = mujoco.MjData(mj)
    for qpos, qvel in _random_states(mj, 3, seed=1):
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_forward(mj, d)
        q, v = mp.to_pin(qpos, qvel)
        pin.forwardKinematics(pinm, pd, q, v)
        pin.updateFramePlacements(pinm, pd)
        for b in range(1, mj.nbody):
            f = pinm.getFrameId(mj.body(b).name, pin.BODY)
            assert np.allclose(pd.oMf[f].translation, d.xpos[b], atol=1e-12)
            assert np.allclose(pd.oMf[f].rotation, d.xmat[b].reshape(3, 3), atol=1e-12)
        # pelvis velocity: Pinocchio local linear velocity = R^T MuJoCo world linear velocity
        R = d.xmat[1].reshape(3, 3)
        assert np.allclose(pin.getVelocity(pinm, pd, 1).linear, R.T @ qvel[:3])
        qp2, qv2 = mp.to_mujoco(q, v)
        assert np.allclose(qp2, qpos, atol=1e-15) and np.allclose(qv2, qvel, atol=1e-14)


def test_pinocchio_mass_matrix_and_bias_match_mujoco(mj, pinm):
    """M and h (paper eq. (1)) agree through export_mjcf + PinocchioMap (relative < 1e-8).
    MuJoCo qfrc_bias excludes passive forces; springs are compared separately."""
    mp = PM.PinocchioMap(mj, pinm)
    pd = pinm.createData()
    d = mujoco.MjData(mj)
    springs = P.spring_params()
    for qpos, qvel in _random_states(mj, 5, seed=2):
        d.qpos[:], d.qvel[:] = qpos, qvel
        mujoco.mj_forward(mj, d)
        Mm = np.zeros((mj.nv, mj.nv))
        mujoco.mj_fullM(mj, d, Mm)
        q, v = mp.to_pin(qpos, qvel)
        T = mp.vel_matrix(qpos)
        Mp = pin.crba(pinm, pd, q)
        Mp = np.triu(Mp) + np.triu(Mp, 1).T
        assert np.abs(T.T @ Mp @ T - Mm).max() < 1e-8 * np.abs(Mm).max()
        h = T.T @ pin.rnea(pinm, pd, q, v, mp.acc_offset(v))
        assert np.abs(h - d.qfrc_bias).max() < 1e-8 * np.abs(d.qfrc_bias).max()
        # with the pelvis not rotating, plain rnea(q, v, 0) is MuJoCo's bias
        qvel0 = qvel.copy()
        qvel0[3:6] = 0
        d.qvel[:] = qvel0
        mujoco.mj_forward(mj, d)
        q, v = mp.to_pin(qpos, qvel0)
        h0 = T.T @ pin.rnea(pinm, pd, q, v, np.zeros(pinm.nv))
        assert np.abs(h0 - d.qfrc_bias).max() < 1e-8 * np.abs(d.qfrc_bias).max()
        # springs: MuJoCo qfrc_spring = -K (q - rest); Pinocchio adds none
        for name, (k, rest) in springs.items():
            j = mujoco.mj_name2id(mj, mujoco.mjtObj.mjOBJ_JOINT, name)
            assert d.qfrc_spring[mj.jnt_dofadr[j]] == pytest.approx(-k * (qpos[mj.jnt_qposadr[j]] - rest))


def test_pinocchio_loop_closures_match(mj):
    pm, point_constraints, _ = PM.pinocchio_model("I", with_constraints=True)
    assert len(point_constraints) == 4
    qpos, _ = M.standing_state(mj)
    q, _ = PM.PinocchioMap(mj, pm).to_pin(qpos)
    pd = pm.createData()
    pin.forwardKinematics(pm, pd, q)
    for c in point_constraints:
        p1 = pd.oMi[c.joint1_id].act(c.joint1_placement).translation
        p2 = pd.oMi[c.joint2_id].act(c.joint2_placement).translation
        assert np.linalg.norm(p1 - p2) < 1e-6


def test_motor_limits():
    lim = MotorLimits.from_flywheel("I")
    assert lim.names == P.MOTOR_NAMES
    assert np.allclose(lim.torque_limit, [112.5, 112.5, 195.2, 195.2, 45.0] * 2 + [195.0])
    lb, ub = torque_bounds(np.zeros(11))
    assert np.allclose(ub, lim.torque_limit) and np.allclose(lb, -lim.torque_limit)
    w0 = lim.no_load_speed
    assert w0[3] == pytest.approx(1300 * 2 * math.pi / 60 / 16)     # knee: 81.25 rpm joint side
    w = np.where(np.isfinite(w0), 0.75 * w0, 1e3)          # published curve: half the torque at 3/4 w0
    lb, ub = torque_bounds(w)
    assert np.allclose(ub[:10], 0.5 * lim.torque_limit[:10]) and np.allclose(lb[:10], -0.5 * lim.torque_limit[:10])
    assert ub[10] == 195.0 and lb[10] == -195.0                          # flywheel: constant
    lb, ub = torque_bounds(-2 * np.where(np.isfinite(w0), w0, 1.0))     # beyond no-load: none, either sign
    assert np.allclose(lb[:10], 0) and np.allclose(ub[:10], 0)
    capped = MotorLimits.from_flywheel(P.Flywheel(0.1074, 9.54, max_speed_rpm=1645))
    assert capped.bounds(np.full(11, 200.0))[1][10] == 0.0


def test_reference_numbers_equal_published_model():
    """Cross-check the parameter table against the published cassie.xml (skipped without it)."""
    if not REFERENCE.exists():
        pytest.skip("reference model not available")
    root = ET.parse(REFERENCE).getroot()
    floats = lambda s: tuple(float(x) for x in s.split())
    bodies = {b.name: b for b in P.BODIES}
    seen = 0
    for el in root.iter("body"):
        name = el.get("name").replace("-", "_").replace("cassie_pelvis", "pelvis")
        b = bodies[name]
        seen += 1
        assert floats(el.get("pos")) == tuple(map(float, b.pos))
        assert (floats(el.get("xyaxes")) if el.get("xyaxes") else None) == (
            tuple(map(float, b.xyaxes)) if b.xyaxes else None)
        ine = el.find("inertial")
        assert float(ine.get("mass")) == b.inertial.mass
        assert floats(ine.get("pos")) == tuple(map(float, b.inertial.pos))
        assert floats(ine.get("fullinertia")) == tuple(map(float, b.inertial.fullinertia))
        j = el.find("joint")
        if j is not None:
            bj = b.joint
            assert j.get("name").replace("-", "_") == bj.name and j.get("type") == bj.type
            assert (floats(j.get("range")) if j.get("range") else None) == (
                tuple(map(float, bj.range_deg)) if bj.range_deg else None)
            for attr, val in (("ref", bj.ref_deg), ("stiffness", bj.stiffness), ("damping", bj.damping),
                              ("armature", bj.armature)):
                assert float(j.get(attr, 0)) == val, (name, attr)
    assert seen == len(P.BODIES)
    conn = [(c.get("body1").replace("-", "_"), c.get("body2").replace("-", "_"), floats(c.get("anchor")))
            for c in root.iter("connect")]
    assert conn == [(c.body1, c.body2, tuple(map(float, c.anchor))) for c in P.CONNECTS]
    motors = [(m.get("joint").replace("-", "_"), float(m.get("gear")), floats(m.get("ctrlrange"))[1],
               float(m.get("user"))) for m in root.iter("motor")]
    assert motors == [(m.joint, m.gear, m.motor_torque_limit, m.no_load_rpm) for m in P.CASSIE_MOTORS]
    key = root.find("keyframe/key")
    assert floats(key.get("qpos")) == tuple(map(float, P.HOME_QPOS))
    assert float(root.find("option").get("timestep")) == P.TIMESTEP
    assert floats(root.find("default/equality").get("solref")) == P.EQUALITY_SOLREF
