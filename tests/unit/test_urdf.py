"""cassie_model.urdf: the generated URDF, loaded by yourdfpy, places every link where MuJoCo's
forward kinematics places the body of the same name, and carries the model's masses and
inertias."""
import io
import xml.etree.ElementTree as ET

import mujoco
import numpy as np
import pytest
import yourdfpy
from scipy.spatial.transform import Rotation

from cassie_model import model as M
from cassie_model.urdf import ball_angles, export_urdf, urdf_from_model


POS_TOL, ROT_TOL = 1e-3, 1e-6

# Generic paths Cassie does not use: two hinges with off-origin anchors and a ref on one body, a
# slide, a ball, a mesh, an ellipsoid, a welded body.
SYNTHETIC = """
<mujoco>
  <asset><mesh name="m" vertex="0 0 0  0.1 0 0  0 0.2 0  0 0 0.3  0.1 0.2 0.3"/></asset>
  <worldbody>
    <body name="base" pos="0 0 1">
      <freejoint name="base"/>
      <geom type="box" size="0.1 0.1 0.1" mass="2"/>
      <body name="two_hinges" pos="0.2 0 0" quat="0.9 0.1 0.3 0.2">
        <joint name="h1" type="hinge" axis="0 1 0" pos="0.05 0 0.02" range="-1 1" ref="0.3"/>
        <joint name="h2" type="hinge" axis="1 1 0" pos="0 0.03 -0.04"/>
        <geom type="capsule" size="0.02 0.1" mass="0.5"/>
        <body name="slider" pos="0 0 -0.2">
          <joint name="s" type="slide" axis="0 0 1" range="-0.1 0.1" ref="0.05"/>
          <geom type="mesh" mesh="m" mass="0.3"/>
          <body name="welded" pos="0.1 0 0" euler="0 0.5 0">
            <geom type="ellipsoid" size="0.03 0.02 0.01" mass="0.1"/>
          </body>
        </body>
      </body>
      <body name="balled" pos="-0.2 0 0">
        <joint name="b" type="ball" pos="0.01 0.02 0.03"/>
        <geom type="cylinder" size="0.02 0.05" mass="0.2"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


def load(xml: str):
    return yourdfpy.URDF.load(io.StringIO(xml), load_meshes=False, build_collision_scene_graph=False)


def random_state(model, rng):
    """qpos with every hinge/slide uniform in its range (or ±pi), random ball and root rotations;
    and the URDF joint values by name (balls as intrinsic XYZ Euler angles, computed by scipy)."""
    qpos, cfg = model.qpos0.copy(), {}
    for j in range(model.njnt):
        a, name, t = model.jnt_qposadr[j], model.joint(j).name, model.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_FREE:
            qpos[a:a + 3] = rng.uniform(-1, 1, 3)
            qpos[a + 3:a + 7] = Rotation.random(random_state=rng).as_quat(scalar_first=True)
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            rot = Rotation.from_rotvec(rng.uniform(-1, 1, 3))
            qpos[a:a + 4] = rot.as_quat(scalar_first=True)
            cfg.update(zip((f"{name}_x", f"{name}_y", f"{name}_z"), rot.as_euler("XYZ")))
        else:
            lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-np.pi, np.pi)
            qpos[a] = cfg[name] = rng.uniform(lo, hi)
    return qpos, cfg


def max_pose_errors(model, robot, root: str, n_configs: int = 5, seed: int = 0):
    """Max over random configurations and all bodies of the URDF link's world position and
    rotation-matrix error against MuJoCo's xpos/xmat."""
    rng = np.random.default_rng(seed)
    data = mujoco.MjData(model)
    rid = model.body(root).id
    dp = dr = 0.0
    for _ in range(n_configs):
        data.qpos[:], cfg = random_state(model, rng)
        mujoco.mj_kinematics(model, data)
        robot.update_cfg(cfg)
        T_root = np.eye(4)
        T_root[:3, :3], T_root[:3, 3] = data.xmat[rid].reshape(3, 3), data.xpos[rid]
        for b in range(1, model.nbody):
            T = T_root @ robot.get_transform(model.body(b).name, root)
            dp = max(dp, np.abs(T[:3, 3] - data.xpos[b]).max())
            dr = max(dr, np.abs(T[:3, :3] - data.xmat[b].reshape(3, 3)).max())
    return dp, dr


@pytest.fixture(scope="module")
def cassie():
    return M.build_model("I"), export_urdf("I")


def test_cassie_link_poses_match_mujoco(cassie):
    model, xml = cassie
    dp, dr = max_pose_errors(model, load(xml), "pelvis")
    print(f"max position error {dp:.2e} m, rotation error {dr:.2e}")
    assert dp < POS_TOL and dr < ROT_TOL


def test_cassie_tree_and_names(cassie):
    model, xml = cassie
    robot = load(xml)
    root = ET.fromstring(xml)
    children = {j.find("child").get("link") for j in root.iter("joint")}
    links = [link.get("name") for link in root.iter("link")]
    assert [n for n in links if n not in children] == ["pelvis"]
    assert {model.body(b).name for b in range(1, model.nbody)} <= set(links)
    assert "flywheel" in links and robot.joint_map["flywheel"].child == "flywheel"
    assert robot.joint_map["flywheel"].type == "continuous"
    # the /joint_states names, in the simulator's order (simulator.Simulator._build_joint_table)
    names = []
    for j in range(model.njnt):
        n, t = model.joint(j).name, model.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_BALL:
            names += [f"{n}_x", f"{n}_y", f"{n}_z"]
        elif t != mujoco.mjtJoint.mjJNT_FREE:
            names.append(n)
    assert robot.actuated_joint_names == names
    knee = robot.joint_map["left_knee"]
    assert (knee.limit.lower, knee.limit.upper) == pytest.approx(tuple(model.joint("left_knee").range))


def test_cassie_masses_and_inertias(cassie):
    model, xml = cassie
    robot = load(xml)
    total = sum(link.inertial.mass for link in robot.robot.links if link.inertial is not None)
    assert total == pytest.approx(model.body_mass[1:].sum(), rel=1e-12)
    for b in range(1, model.nbody):
        link = robot.link_map[model.body(b).name]
        T = link.inertial.origin
        R = np.zeros(9)
        mujoco.mju_quat2Mat(R, model.body_iquat[b])
        R = R.reshape(3, 3)
        assert link.inertial.mass == pytest.approx(model.body_mass[b], rel=1e-12)
        assert T[:3, 3] == pytest.approx(model.body_ipos[b], abs=1e-12)
        full_mj = R @ np.diag(model.body_inertia[b]) @ R.T
        full_urdf = T[:3, :3] @ link.inertial.inertia @ T[:3, :3].T
        assert np.abs(full_urdf - full_mj).max() < 1e-9 * model.body_inertia[b].max()


@pytest.mark.parametrize("flywheel", ["II", "III"])
def test_other_flywheels(flywheel):
    model = M.build_model(flywheel)
    robot = load(export_urdf(flywheel))
    assert robot.link_map["flywheel"].inertial.mass == pytest.approx(model.body("flywheel").mass[0], rel=1e-12)
    assert model.body("flywheel").mass[0] != M.build_model("I").body("flywheel").mass[0]


def test_generic_joints_and_meshes():
    """Multi-joint bodies, joint anchors, refs, slides, balls, meshes and welds map exactly."""
    model = mujoco.MjModel.from_xml_string(SYNTHETIC)
    xml = urdf_from_model(model)
    robot = load(xml)
    dp, dr = max_pose_errors(model, robot, "base", n_configs=10)
    assert dp < 1e-9 and dr < 1e-9
    assert robot.joint_map["welded_fixed"].type == "fixed"
    assert robot.joint_map["s"].type == "prismatic" and robot.joint_map["h2"].type == "continuous"
    aabb = model.geom_aabb[model.body("slider").geomadr[0]]
    box = robot.link_map["slider"].visuals[0].geometry.box
    assert box.size == pytest.approx(2 * aabb[3:])
    assert "bounding box" in xml


def test_ball_angles_are_intrinsic_xyz_euler():
    rng = np.random.default_rng(1)
    for rot in Rotation.random(20, random_state=rng):
        assert ball_angles(rot.as_quat(scalar_first=True)) == pytest.approx(rot.as_euler("XYZ"), abs=1e-12)
