"""flip_tools.video: MuJoCo states rebuilt from bag arrays (/joint_states + /odom) equal the
simulator's own qpos, and they render to a file."""
import mujoco
import numpy as np

from cassie_flip_sim.render import render_states
from cassie_flip_sim.simulator import Simulator
from flip_tools.video import qpos_from_bag


def test_qpos_from_bag_arrays_reproduces_the_simulator_and_renders(tmp_path):
    sim = Simulator()
    rng = np.random.default_rng(1)
    sim.reset(sim.standing_qpos, rng.normal(0.0, 0.5, sim.model.nv))
    rows = []
    for _ in range(3):
        for _ in range(30):
            sim.step(rng.normal(0.0, 20.0, 11))
        p, quat = sim.pelvis_pose()
        rows.append((sim.time, sim.joint_positions().copy(), p.copy(), np.r_[quat[1:], quat[0]], sim.data.qpos.copy()))
    js = {"t": np.array([r[0] for r in rows]), "names": list(sim.joint_names), "pos": np.array([r[1] for r in rows])}
    od = {"t": js["t"], "pos": np.array([r[2] for r in rows]), "quat": np.array([r[3] for r in rows])}
    qs = qpos_from_bag(sim.model, js, od, fps=1000.0)
    assert len(qs) == 3
    for q, r in zip(qs, rows):
        expected = r[4]
        # quaternions may differ in sign: compare rotations through the joint-by-joint difference
        dq = np.zeros(sim.model.nv)
        mujoco.mj_differentiatePos(sim.model, dq, 1.0, expected, q)
        assert np.abs(dq).max() < 1e-9
    path = render_states(sim.model, qs, tmp_path / "clip.gif", fps=10, width=160, height=90)
    assert path.exists() and path.stat().st_size > 1000
