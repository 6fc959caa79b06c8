"""cassie_flip_sim simulator behaviour: free fall and touch-down, collapse, clipping,
determinism, momentum, contact-event hysteresis."""
import math

import numpy as np
import pytest

from cassie_model import model as M
from cassie_model import robot_params as P
from cassie_flip_sim.contacts import ContactDetector, Event
from cassie_flip_sim.simulator import Simulator


@pytest.fixture(scope="module")
def sim():
    return Simulator("I", "flat")


def _drop(sim, height):
    q = sim.standing_qpos.copy()
    q[2] += height
    sim.reset(q, in_contact=False)


def test_drop_touch_down_at_predicted_step(sim):
    height = 0.2
    _drop(sim, height)
    gap0 = M.foot_points_world(sim.model, sim.data)[:, 2].min() - P.FOOT_RADIUS
    assert gap0 == pytest.approx(height, abs=1e-6)
    g, h = -sim.model.opt.gravity[2], sim.timestep
    # semi-implicit Euler from rest: z_n = z_0 - g h^2 n (n + 1) / 2; contact exists at the first
    # state with negative gap, and its force acts in the step taken from that state
    n_pred = next(n for n in range(1, 100000) if g * h * h * n * (n + 1) / 2 > gap0)
    for _ in range(n_pred + 20):
        sim.step(np.zeros(11))
        if sim.events:
            break
    ev = sim.pop_events()
    assert len(ev) == 1 and ev[0].kind == Event.TOUCH_DOWN
    assert abs(ev[0].step - n_pred) <= 1
    assert ev[0].time == pytest.approx(ev[0].step * h)
    # rigid free fall up to then: pelvis fell by the discrete amount
    z_expected = sim.standing_qpos[2] + height - g * h * h * sim.step_index * (sim.step_index + 1) / 2
    assert abs(sim.pelvis_pose()[0][2] - z_expected) < 2e-3


def test_zero_torque_collapses(sim):
    sim.reset()
    z0 = sim.pelvis_pose()[0][2]
    for _ in range(int(2.0 / sim.timestep)):
        sim.step(np.zeros(11))
    assert z0 - sim.pelvis_pose()[0][2] > 0.3


def test_deterministic():
    a, b = Simulator("I"), Simulator("I")
    rng = np.random.default_rng(0)
    us = rng.normal(scale=20.0, size=(200, 11))
    for s in (a, b):
        for u in us:
            s.step(u)
    assert np.array_equal(a.data.qpos, b.data.qpos) and np.array_equal(a.data.qvel, b.data.qvel)
    assert a.foot_normal_forces() == b.foot_normal_forces()


def test_torques_are_clipped(sim):
    sim.reset()
    sim.step(np.full(11, 1e4))
    assert np.allclose(sim.last_command, sim.limits.torque_limit)
    assert np.allclose(sim.data.qfrc_actuator[sim._motor_dof], sim.limits.torque_limit)


def test_flywheel_torque_knob_clips_the_flywheel_command(sim):
    """``flywheel_torque`` replaces the flywheel motor's 195 N·m limit: a ±300 N·m command acts as
    ±260 N·m (±195 by default), and ``sim.flywheel`` and the actuator range follow it."""
    big = Simulator("I", "flat", flywheel_torque=260.0)
    assert big.flywheel.max_torque == 260.0 and sim.flywheel.max_torque == 195.0
    u = np.zeros(11)
    for s, lim in ((big, 260.0), (sim, 195.0)):
        assert tuple(s.model.actuator_ctrlrange[s._act_ids[-1]]) == (-lim, lim)
        s.reset()
        for sign in (1.0, -1.0):
            u[-1] = 300.0 * sign
            s.step(u)
            assert s.last_command[-1] == sign * lim
            assert s.data.qfrc_actuator[s._motor_dof[-1]] == pytest.approx(sign * lim)
            assert np.allclose(s.last_command[:10], 0.0)
    assert Simulator("I", "flat", flywheel_torque=0.0).flywheel.max_torque == 195.0   # 0: its own
    for bad in (-1.0, math.nan, math.inf):
        with pytest.raises(ValueError, match="flywheel torque limit"):
            Simulator("I", "flat", flywheel_torque=bad)


def test_standing_forces_and_accessors(sim):
    sim.reset()
    for _ in range(200):
        sim.step(np.zeros(11))
    fl, fr = sim.foot_normal_forces()
    assert fl > 0 and fr > 0
    names = sim.joint_names
    assert len(names) == len(sim.joint_positions()) == len(sim.joint_velocities()) == len(sim.joint_efforts()) == 27
    assert "left_achilles_rod_x" in names and "flywheel" in names and "pelvis" not in names
    assert sim.step_index == 200 and sim.time == pytest.approx(200 * sim.timestep)
    pos, quat = sim.pelvis_pose()
    assert quat.shape == (4,) and abs(np.linalg.norm(quat) - 1) < 1e-9
    lin_w, ang_w = sim.pelvis_twist("world")
    lin_l, ang_l = sim.pelvis_twist("local")
    assert np.allclose(np.linalg.norm(lin_w), np.linalg.norm(lin_l))
    assert np.allclose(np.linalg.norm(ang_w), np.linalg.norm(ang_l))


def test_support_center_is_under_the_standing_robot_and_moves_with_the_feet(sim):
    """support_center: mean of the four foot contact spheres; standing, it is under the COM (the
    standing state puts the COM over the feet) at the spheres' radius; shifting the robot moves it."""
    from cassie_model import robot_params as P
    sim.reset()
    sc, c = sim.support_center(), sim.com_position()
    assert abs(sc[0] - c[0]) < 0.03 and abs(sc[1] - c[1]) < 1e-3
    assert sc[2] == pytest.approx(P.FOOT_RADIUS, abs=0.01)
    q = sim.data.qpos.copy()
    q[0] += 0.3
    sim.reset(q, in_contact=True)
    assert sim.support_center()[0] == pytest.approx(sc[0] + 0.3, abs=1e-9)


def test_flight_momentum_conserved_with_flywheel_torque(sim):
    """In flight, flywheel torque changes the flywheel's spin but not H_pitch (paper eq. (8))."""
    _drop(sim, 1.0)
    h0 = sim.centroidal_pitch_momentum()
    u = np.zeros(11)
    u[10] = 100.0
    for _ in range(200):
        sim.step(u)
    assert abs(sim.data.qvel[-1]) > 10.0            # flywheel spun up
    # exact up to the first-order Euler error (halves with the timestep): < 0.1 % of the
    # momentum moved into the flywheel
    h_fw = abs(sim.data.qvel[-1]) * P.FLYWHEELS["I"].inertia_pitch
    assert abs(sim.centroidal_pitch_momentum() - h0) < 1e-3 * h_fw
    _, ang = sim.pelvis_twist("world")
    assert ang[1] < -1.0                             # pelvis counter-rotates


def test_contact_detector_hysteresis():
    det = ContactDetector(True, lift_off_steps=3, touch_down_force=5.0, min_flight_steps=10)
    seq = [100, 50, 0, 20, 0, 0, 0, 0] + [0] * 9 + [3, 10, 0, 0]
    events = [det.update(k, k * 5e-4, f, f) for k, f in enumerate(seq)]
    got = [(e.kind, e.step, e.detected_step) for e in events if e is not None]
    # one zero-force step (k=2) does not lift off; the run from k=4 does (confirmed at k=6);
    # touch-down only above 5 N and after the minimum flight: k=18
    assert got == [(Event.LIFT_OFF, 4, 6), (Event.TOUCH_DOWN, 18, 18)]
    assert det.phase == "stance"
