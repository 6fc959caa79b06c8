"""Output Jacobians and drift terms (paper §V-A outputs, differentiated for §V-B) by finite differences
along q(t) = q (+) t v with vdot = 0:  d/dt h(q) = J v,  d/dt (J v) = drift."""
import numpy as np
import pinocchio as pin
import pytest

from cassie_model.model import export_mjcf
from test_tsc_dynamics import random_state
from tsc_controller import Controller


@pytest.fixture(scope="module")
def ctl():
    return Controller(export_mjcf())


def _outputs(c):
    f = c.flight
    return c.ground.outputs + [f.o_Hfw, f.o_j_pre, f.o_j_post, f.o_axis, f.o_sym] + f.o_Lleg + f.o_beta + f.o_toe


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_output_jacobians_and_drifts(ctl, seed):
    dyn = ctl.dyn
    rng = np.random.default_rng(seed)
    q, v = random_state(dyn, rng, False)
    eps = 1e-6
    qp, qm = pin.integrate(dyn.model, q, eps * v), pin.integrate(dyn.model, q, -eps * v)
    for o in _outputs(ctl):
        dyn.update(q, v)
        y, J, drift, ydot = o.evaluate(dyn)
        y, J, drift = np.array(y), np.array(J), np.array(drift)
        dyn.update(qp, v)
        yp, Jp_, _, _ = o.evaluate(dyn)
        yp, Jp_ = np.array(yp), np.array(Jp_)
        dyn.update(qm, v)
        ym, Jm, _, _ = o.evaluate(dyn)
        ym, Jm = np.array(ym), np.array(Jm)
        fd_drift = (Jp_ @ v - Jm @ v) / (2 * eps)
        tol = 1e-5 * max(1.0, np.abs(fd_drift).max())
        assert np.abs(fd_drift - drift).max() < tol, (o.name, fd_drift, drift)
        if o.degree == 2:
            fd_vel = (yp - ym) / (2 * eps)
            assert np.abs(fd_vel - J @ v).max() < 1e-6 * max(1.0, np.abs(fd_vel).max()), o.name
            assert np.allclose(ydot, J @ v)
        else:
            assert np.allclose(y, J @ v)


def test_leg_asymmetry_is_zero_for_mirrored_legs_and_names_the_leg_ahead(ctl):
    """LegAsymmetry (the somersault flight's leg_symmetry output): 0 in the model's reference posture,
    whose legs mirror each other; one foot ahead of the other (left hip pitch +d, right -d) shows as 2d
    in its hip-pitch row, a longer left leg (knee) in its knee row, and hip roll or yaw turned the same
    way on both legs (what the pelvis-axis hold uses) not at all."""
    dyn = ctl.dyn
    o = ctl.flight.o_sym
    assert list(o.JOINTS) == ["hip_pitch", "knee"]
    q = dyn.q_ref.copy()
    dyn.update(q, np.zeros(dyn.nv))
    assert np.abs(o.evaluate(dyn)[0]).max() < 1e-12
    d = 0.0024
    q2 = q.copy()
    q2[dyn.q_index("left_hip_pitch")] += d
    q2[dyn.q_index("right_hip_pitch")] -= d
    q2[dyn.q_index("left_knee")] += 0.01
    for j in ("hip_roll", "hip_yaw"):
        q2[dyn.q_index(f"left_{j}")] += 0.02
        q2[dyn.q_index(f"right_{j}")] += 0.02
    dyn.update(q2, np.zeros(dyn.nv))
    assert o.evaluate(dyn)[0] == pytest.approx([2 * d, 0.01])


def test_momentum_outputs_match_definitions(ctl):
    """H_pitch = world-y angular momentum about the COM (as the simulator reports it);
    H_flywheel = I_axis * world-y angular velocity of the wheel."""
    from cassie_flip_sim.simulator import Simulator
    from tsc_controller import StateConverter
    sim = Simulator()
    rng = np.random.default_rng(4)
    sim.data.qvel[:] = rng.normal(0, 1.0, sim.model.nv)
    import mujoco
    mujoco.mj_forward(sim.model, sim.data)
    q, v = StateConverter(ctl.dyn).from_simulator(sim)
    ctl.dyn.update(q, v)
    H = ctl.ground.o_H.evaluate(ctl.dyn)[0][0]
    assert H == pytest.approx(sim.centroidal_pitch_momentum(), rel=1e-9, abs=1e-9)
    fw = mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_BODY, "flywheel")
    w = np.zeros(6)
    mujoco.mj_objectVelocity(sim.model, sim.data, mujoco.mjtObj.mjOBJ_BODY, fw, w, 0)   # world frame
    I_axis = sim.model.body_inertia[fw][1]
    assert ctl.flight.o_Hfw.evaluate(ctl.dyn)[0][0] == pytest.approx(I_axis * w[1], rel=1e-9, abs=1e-9)


def test_foot_pitch_is_the_foot_line_angle_with_a_gradient_at_vertical(ctl):
    """toe pitch = atan2(z_toe - z_heel, x_toe - x_heel): the standing foot gives ~0; the robot pitched
    forward by 80 deg (a foot near vertical, as a frontflip's held foot is at T1) gives ~-80 deg, and the output still has a full gradient
    there (the sine it replaced had 1/6 of it: cos 80 deg)."""
    from cassie_flip_sim.simulator import Simulator
    from tsc_controller import StateConverter
    sim = Simulator()
    q, v = StateConverter(ctl.dyn).from_simulator(sim)
    dyn, o = ctl.dyn, ctl.flight.o_toe[0]
    dyn.update(q, v)
    y0, J0 = o.evaluate(dyn)[:2]
    assert abs(float(y0[0])) < np.radians(3)
    qr = q.copy()
    R = pin.Quaternion(q[6], q[3], q[4], q[5]).toRotationMatrix()
    quat = pin.Quaternion(pin.utils.rpyToMatrix(0.0, np.radians(80.0), 0.0) @ R)
    qr[3:7] = [quat.x, quat.y, quat.z, quat.w]
    dyn.update(qr, v)
    y1, J1 = o.evaluate(dyn)[:2]
    P, _, _ = dyn.point_lists()
    t, h = o._idx[0]
    line = np.asarray(P[t]) - np.asarray(P[h])
    assert float(y1[0]) == pytest.approx(np.arctan2(line[2], line[0]), abs=1e-9)
    assert float(y1[0]) == pytest.approx(float(y0[0]) - np.radians(80.0), abs=np.radians(2))   # nose down: toe down
    assert np.linalg.norm(J1) == pytest.approx(np.linalg.norm(J0), rel=0.05)
