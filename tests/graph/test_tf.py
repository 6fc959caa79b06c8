"""The robot's transforms: cassie_flip_sim.link_transforms against MuJoCo's forward kinematics
(offline), and /tf, /tf_static, /robot_description as a `flip stand` run records them: a tree from
`world` to the feet and the flywheel, stamped on the sim clock's grid, and the same link poses as
the bag's URDF (yourdfpy) at the bag's /joint_states and /odom."""
import io
import re
import subprocess
import sys

import mujoco
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from ros_harness import FLIP, new_domain

from cassie_flip_sim.link_transforms import LinkTransforms, link_poses, matrix, quat_xyzw, rotvec_to_quat
from cassie_flip_sim.simulator import Simulator
from cassie_model.urdf import ball_angles, export_urdf

POS_TOL, ROT_TOL = 1e-3, 1e-6
GRID_NS = 5_000_000                    # sim_node's /clock period (200 Hz)
BALLS = ("left_achilles_rod", "right_achilles_rod")


def random_qpos(model, rng):
    """Every hinge uniform in its range (or ±pi), random ball and pelvis rotations."""
    q = model.qpos0.copy()
    for j in range(model.njnt):
        a, t = model.jnt_qposadr[j], model.jnt_type[j]
        if t == mujoco.mjtJoint.mjJNT_FREE:
            q[a:a + 3] = rng.uniform(-1, 1, 3)
            q[a + 3:a + 7] = Rotation.random(random_state=rng).as_quat(scalar_first=True)
        elif t == mujoco.mjtJoint.mjJNT_BALL:
            q[a:a + 4] = Rotation.from_rotvec(rng.uniform(-1.5, 1.5, 3)).as_quat(scalar_first=True)
        else:
            lo, hi = model.jnt_range[j] if model.jnt_limited[j] else (-np.pi, np.pi)
            q[a] = rng.uniform(lo, hi)
    return q


def pose_errors(T, pos, rot):
    return np.abs(T[:3, 3] - pos).max(), np.abs(T[:3, :3] - rot).max()


# ---------------------------------------------------------------------------------------------
# (a) offline: the transforms composed from world -> pelvis are MuJoCo's body poses
def test_link_transforms_match_mujoco_body_poses():
    sim = Simulator()
    m, d = sim.model, sim.data
    lt = LinkTransforms(export_urdf(sim.flywheel))
    assert lt.root == "pelvis" and {c for _, c, _ in lt.fixed} == {"left_knee_spring", "right_knee_spring"}
    rng = np.random.default_rng(7)
    dp = dr = 0.0
    for _ in range(20):
        d.qpos[:] = random_qpos(m, rng)
        mujoco.mj_kinematics(m, d)
        # as /joint_states and /odom carry them: ball joints as rotation vectors, quaternion x y z w
        lt.set_positions(sim.joint_names, sim.joint_positions())
        p, quat = sim.pelvis_pose()
        poses = link_poses("pelvis", np.r_[p, quat[1:], quat[0]], lt.moving() + lt.fixed)
        assert {m.body(b).name for b in range(1, m.nbody)} <= set(poses)
        for b in range(1, m.nbody):
            e = pose_errors(poses[m.body(b).name], d.xpos[b], d.xmat[b].reshape(3, 3))
            dp, dr = max(dp, e[0]), max(dr, e[1])
    print(f"max position error {dp:.2e} m, rotation error {dr:.2e}")
    assert dp < POS_TOL and dr < ROT_TOL


def test_ball_joints_need_the_euler_conversion():
    """The rotation vector fed as if it were the URDF's Euler angles misplaces the rods' children:
    the check above can fail."""
    rv = np.array([0.4, -0.7, 0.9])
    assert not np.allclose(ball_angles(rotvec_to_quat(rv)), rv, atol=1e-2)
    R = Rotation.from_rotvec(rv).as_matrix()
    a, b, c = ball_angles(rotvec_to_quat(rv))
    np.testing.assert_allclose(Rotation.from_euler("XYZ", [a, b, c]).as_matrix(), R, atol=1e-12)


def test_quaternions_of_rotation_matrices():
    half_turns = np.pi * np.array([[1, 0, 0], [0, 1, 0], [0, 0, 1], [0.6, -0.8, 0], [0, 0.8, 0.6]])
    rots = Rotation.concatenate([Rotation.random(2000, random_state=3), Rotation.from_rotvec(half_turns)])
    q, ref = quat_xyzw(rots.as_matrix()), rots.as_quat()
    assert np.minimum(np.abs(q - ref).max(1), np.abs(q + ref).max(1)).max() < 1e-12


def test_tf_template_serializes_the_poses_and_stamp():
    from rclpy.serialization import deserialize_message
    from tf2_msgs.msg import TFMessage

    from cassie_flip_sim.state_publisher import TfTemplate
    frames = [("world", "pelvis"), ("pelvis", "left_hip_roll"), ("left_knee", "left_knee_spring")]
    poses = np.random.default_rng(1).normal(size=(3, 7))
    msg = deserialize_message(TfTemplate(frames).fill(7_123_000_000 + 5_000_000, poses), TFMessage)
    assert [(t.header.frame_id, t.child_frame_id) for t in msg.transforms] == frames
    for t, pose in zip(msg.transforms, poses):
        assert (t.header.stamp.sec, t.header.stamp.nanosec) == (7, 128_000_000)
        tr, r = t.transform.translation, t.transform.rotation
        assert [tr.x, tr.y, tr.z, r.x, r.y, r.z, r.w] == list(pose)


# ---------------------------------------------------------------------------------------------
# (b), (c) a graph run's bag
@pytest.fixture(scope="module")
def stand_bag(tmp_path_factory):
    from flip_tools.bag import load_bag
    out = tmp_path_factory.mktemp("tf") / "stand"
    claim = new_domain()
    try:
        r = subprocess.run([sys.executable, str(FLIP), "stand", "--duration", "1", "--out", str(out),
                            "--domain", str(claim.domain_id)], capture_output=True, text=True, timeout=600)
    finally:
        claim.release()
    assert r.returncode == 0, r.stdout + r.stderr
    # the summary's reading leaves /tf out, but counts it: every /tf state_publisher published (its
    # log's count; flip stops the writers once the recorder has them), nearly one per 5 ms of the 1 s
    from flip_tools.bag import NOT_SUMMARIZED
    summarized = load_bag(out / "bag", exclude=NOT_SUMMARIZED)
    published = int(re.search(r"published /tf for (\d+) stamps", (out / "logs" / "state.log").read_text()).group(1))
    assert summarized.get("/tf") is None and summarized.count("/tf") == published >= 180, published
    return load_bag(out / "bag", topics=["/tf", "/tf_static", "/clock", "/joint_states", "/odom",
                                         "/robot_description"])


def stamp_ns(t):
    return t.header.stamp.sec * 1_000_000_000 + t.header.stamp.nanosec


def edges(msgs):
    return [(t.header.frame_id, t.child_frame_id,
             np.array([t.transform.translation.x, t.transform.translation.y, t.transform.translation.z,
                       t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z,
                       t.transform.rotation.w]))
            for m in msgs for t in m.transforms]


def tf_at(bag):
    """{stamp ns: /tf message}"""
    out = {}
    for m in bag["/tf"]["msgs"]:
        stamps = {stamp_ns(t) for t in m.transforms}
        assert len(stamps) == 1, stamps
        out[stamps.pop()] = m
    return out


def test_tf_tree_reaches_the_feet_and_flywheel_on_the_sim_clock(stand_bag):
    static = stand_bag["/tf_static"]["msgs"]
    assert static
    assert {t.child_frame_id for t in static[-1].transforms} == {"left_knee_spring", "right_knee_spring"}
    tfs = tf_at(stand_bag)
    clock_ns = np.round(stand_bag["/clock"]["sim_t"] * 1e9).astype(np.int64)
    grid_clock = {int(c) for c in clock_ns if c % GRID_NS == 0}
    assert len(grid_clock) >= 190                          # 1 s of sim time
    # every /tf stamp a /clock-grid time within the run, and one /tf at every /clock-grid time
    assert all(ns % GRID_NS == 0 and 0 <= ns <= clock_ns.max() for ns in tfs), sorted(tfs)[-3:]
    assert grid_clock <= set(tfs), sorted(grid_clock - set(tfs))[:5]
    urdf_links = set(LinkTransforms(stand_bag["/robot_description"]["data"][-1]).links)
    for ns in sorted(tfs)[::40]:
        reached = link_poses("world", [0, 0, 0, 0, 0, 0, 1], edges([tfs[ns]] + static[-1:]))
        assert {"pelvis", "left_foot", "right_foot", "flywheel"} <= set(reached)
        assert urdf_links <= set(reached), urdf_links - set(reached)
        assert reached["left_foot"][2, 3] < 0.2 and reached["pelvis"][2, 3] > 0.8   # standing


def test_bag_urdf_with_joint_states_matches_tf(stand_bag):
    import yourdfpy
    robot = yourdfpy.URDF.load(io.StringIO(stand_bag["/robot_description"]["data"][-1]), load_meshes=False,
                               build_collision_scene_graph=False)
    js, od = stand_bag["/joint_states"], stand_bag["/odom"]
    names = list(js["names"])
    js_at = {int(round(t * 1e9)): i for i, t in enumerate(js["t"])}
    od_at = {int(round(t * 1e9)): i for i, t in enumerate(od["t"])}
    tfs = tf_at(stand_bag)
    static = edges(stand_bag["/tf_static"]["msgs"][-1:])
    instants = [ns for ns in sorted(tfs) if ns in js_at and ns in od_at]
    assert len(instants) >= 150
    for ns in instants[::30]:
        pos = js["pos"][js_at[ns]]
        cfg = {n: float(v) for n, v in zip(names, pos) if not n.startswith(BALLS)}
        for b in BALLS:
            rv = [pos[names.index(f"{b}_{s}")] for s in "xyz"]
            cfg.update(zip((f"{b}_x", f"{b}_y", f"{b}_z"), ball_angles(rotvec_to_quat(rv))))
        robot.update_cfg(cfg)
        j = od_at[ns]
        world_pelvis = matrix(np.r_[od["pos"][j], od["quat"][j]])
        from_tf = link_poses("world", [0, 0, 0, 0, 0, 0, 1], edges([tfs[ns]]) + static)
        for link in ("pelvis", "left_foot", "right_foot", "flywheel"):
            T = world_pelvis @ robot.get_transform(link, "pelvis")
            dp, dr = pose_errors(from_tf[link], T[:3, 3], T[:3, :3])
            assert dp < POS_TOL and dr < ROT_TOL, (ns, link, dp, dr)
