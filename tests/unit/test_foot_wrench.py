"""The feet's contact wrenches (cassie_flip_sim.foot_wrench), offline: a standing robot's feet carry
its weight and no net moment about its COM; the compiled step computes them as the numpy reference
does, to the bit, and computing them leaves the simulation as it is."""
import numpy as np
import pytest

from cassie_flip_sim.foot_wrench import FOOT_LINKS, FootWrenches, to_world
from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from tsc_controller import Controller, StateConverter

G = 9.81
EVERY = 10                     # sim_node's default: every 10th step (200 Hz)


@pytest.fixture(scope="module")
def standing():
    """2.5 s of the controller holding the standing pose; every EVERY-th step the feet's wrenches
    (foot frames) with the foot poses and the COM of the state they were solved at."""
    sim = Simulator()
    ctl = Controller(export_mjcf(sim.flywheel))
    sc = StateConverter(ctl.dyn)
    fw = FootWrenches(sim.model)
    out = {"t": [], "wrench": [], "R": [], "origin": [], "com": []}
    for k in range(5000):
        q, v = sc.from_simulator(sim)
        u, _ = ctl.compute(q, v, sim.time)
        due = k % EVERY == 0
        if due:       # the state the wrench belongs to: before the step out of it
            out["t"].append(sim.time)
            out["R"].append(fw.rotations(sim.data))
            out["origin"].append(sim.data.xpos[fw.bodies].copy())
            out["com"].append(sim.com_position())
        sim.step(u, wrench=due)
        if due:
            assert sim.wrench_step == k
            out["wrench"].append(sim.wrenches.copy())
    return sim, {key: np.asarray(v) for key, v in out.items()}


def test_standing_feet_carry_the_robots_weight(standing):
    """Once settled (after 1.5 s), the feet's forces in world axes sum to m·g upward (m from the
    model, ~42.9 kg: ~420 N), shared between the feet, with no net horizontal force."""
    sim, r = standing
    weight = sim.total_mass() * G
    assert 400 < weight < 440
    late = r["t"] >= 1.5
    world = np.array([[to_world(w[f], R[f]) for f in range(2)] for w, R in zip(r["wrench"], r["R"])])
    total = world[late, :, :3].sum(axis=1)
    np.testing.assert_allclose(total[:, 2], weight, rtol=0.02)
    assert np.abs(total[:, :2]).max() < 0.02 * weight
    each = world[late, :, 2]
    assert np.all(each > 0.4 * weight) and np.all(each < 0.6 * weight)   # both feet, about half each


def test_standing_feet_wrenches_have_no_moment_about_the_com(standing):
    """At rest the ground's wrench about the COM is zero (no change of angular momentum): the moments,
    moved from each foot's origin to the COM, cancel to < 1 N·m against each foot's > 10 N·m about
    the COM. Left about the feet's origins (~2 cm behind the COM) they do not (8 N·m)."""
    sim, r = standing
    late = np.flatnonzero(r["t"] >= 1.5)
    about_com, each = [], []
    for i in late:
        m = [to_world(r["wrench"][i][f], r["R"][i][f], r["origin"][i][f], r["com"][i])[3:] for f in range(2)]
        about_com.append(m[0] + m[1])
        each.append(np.linalg.norm(m[0]))
    assert np.abs(about_com).max() < 1.0 and min(each) > 10.0, (np.abs(about_com).max(), min(each))
    # the same sums with the moments taken as if about the COM already (no lever): not zero
    wrong = [sum(to_world(r["wrench"][i][f], r["R"][i][f])[3:] for f in range(2)) for i in late]
    assert np.abs(wrong).min(axis=0)[1] > 5.0


def test_wrenches_are_in_the_foot_frames():
    """FootWrenches gives each foot's wrench in its body's axes: rotated back by the body's pose it
    is FootWrenches.world's; the foot bodies are the URDF's foot links."""
    sim = Simulator(backend="python")
    m, d = sim.model, sim.data
    assert [m.body(b).name for b in FootWrenches(m).bodies] == list(FOOT_LINKS)
    import mujoco
    sim.step(np.zeros(11))
    d.ctrl[:] = 0.0
    mujoco.mj_step2(m, d)               # the state's contacts and forces, as the step sees them
    fw = FootWrenches(m)
    foot, world, R = fw(m, d), fw.world(m, d), fw.rotations(d)
    assert np.abs(world[:, 2]).sum() > 1.0                             # the feet touch
    for f in range(2):
        np.testing.assert_allclose(to_world(foot[f], R[f]), world[f], atol=1e-9)
    assert not np.allclose(foot, world, atol=1.0)                     # the foot frames are tilted


def test_native_wrenches_follow_the_numpy_reference_bit_for_bit():
    """Pushed about by random torques until it falls (contacts come and go): the compiled step's
    wrenches equal the numpy reference's, and computing them (every third step) leaves the
    trajectory the same to the bit as a run without."""
    kw = dict(motor_speed_scale=3.0, flywheel_torque=260.0)
    a, b, c = Simulator(backend="native", **kw), Simulator(backend="python", **kw), Simulator(**kw)
    rng = np.random.default_rng(1)
    nonzero = 0
    for k in range(3000):
        u = rng.normal(0.0, 60.0, 11) if k % 400 < 150 else np.zeros(11)
        w = k % 3 == 0
        a.step(u, wrench=w)
        b.step(u, wrench=w)
        c.step(u)
        assert np.array_equal(a.wrenches, b.wrenches), k
        assert np.array_equal(a.data.qpos, c.data.qpos) and np.array_equal(a.data.qvel, c.data.qvel), k
        nonzero += bool(w and np.any(a.wrenches != 0))
    assert nonzero > 300 and a.wrench_step == 2997
