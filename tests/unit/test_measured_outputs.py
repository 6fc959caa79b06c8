"""flip_tools.measured: the outputs recomputed from bag arrays (/joint_states + /odom + the model)
agree with the simulator's own figures (MuJoCo: COM, centroidal momentum) — an independent check."""
from pathlib import Path

import numpy as np

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from cassie_model.urdf import export_urdf
from flip_tools.bag import BagData
from flip_tools.measured import measured_outputs


def test_measured_outputs_match_the_simulator():
    sim = Simulator()
    rng = np.random.default_rng(3)
    qvel = rng.normal(0.0, 0.5, sim.model.nv)
    sim.reset(sim.standing_qpos, qvel)
    rows = []
    for k in range(40):                       # 20 ms with random torques: a moving, non-trivial state
        sim.step(rng.normal(0.0, 20.0, 11))
        p, quat = sim.pelvis_pose()
        lin, ang = sim.pelvis_twist("local")
        rows.append(dict(t=sim.time, pos=sim.joint_positions().copy(), vel=sim.joint_velocities().copy(),
                         p=p.copy(), q=np.r_[quat[1:], quat[0]], lin=lin.copy(), ang=ang.copy(),
                         com=sim.com_position().copy(), H=sim.centroidal_pitch_momentum()))
    t = np.array([r["t"] for r in rows])
    arrays = {
        "/robot_description": {"data": [export_urdf()]},
        "/robot_description_mjcf": {"data": [export_mjcf()]},
        "/joint_states": {"t": t, "names": list(sim.joint_names), "pos": np.array([r["pos"] for r in rows]),
                          "vel": np.array([r["vel"] for r in rows]), "eff": np.zeros((len(rows), len(sim.joint_names)))},
        "/odom": {"t": t, "pos": np.array([r["p"] for r in rows]), "quat": np.array([r["q"] for r in rows]),
                  "lin": np.array([r["lin"] for r in rows]), "ang": np.array([r["ang"] for r in rows])},
    }
    data = BagData(Path("."), topics={k: {"count": 1} for k in arrays}, arrays=arrays)
    m = measured_outputs(data, every_s=0.0)
    assert m is not None and len(m["t"]) == len(rows)
    np.testing.assert_allclose(m["x_com"], [r["com"][0] for r in rows], atol=1e-6)
    np.testing.assert_allclose(m["H_pitch"], [r["H"] for r in rows], rtol=1e-6, atol=1e-6)
    assert np.all((m["L"] > 0.6) & (m["L"] < 1.0))


def test_the_model_comes_from_the_mjcf_topic_or_an_older_bags_description():
    """/robot_description_mjcf is the model; /robot_description (a URDF now) is not used, but a
    bag from before the URDF took that topic still has its MJCF there."""
    from flip_tools.measured import bag_mjcf

    def bag(arrays):
        return BagData(Path("."), topics={k: {"count": 1} for k in arrays}, arrays=arrays)
    mjcf, urdf = export_mjcf(), export_urdf()
    assert bag_mjcf(bag({"/robot_description": {"data": [urdf]},
                         "/robot_description_mjcf": {"data": [mjcf]}})) == mjcf
    assert bag_mjcf(bag({"/robot_description": {"data": [urdf]}})) == ""
    assert bag_mjcf(bag({"/robot_description": {"data": [mjcf]}})) == mjcf
