"""One motor envelope, Cassie's published one (Agility's cassie-mujoco-sim ``motor()``, Agility's
Gazebo ``CassiePlugin::setMotor``, dairlib's Cassie motor model):

    tlim = clamp(2 tau_max (1 - |w|/w0), 0, tau_max),   -tlim <= u <= tlim

in every copy: the Python definition (``motor_limits.available_torque``), the simulator's
(``MotorLimits.bounds`` / ``clip``, the compiled step of ``Simulator(backend="native")`` and its numpy
step) and the controller's (``TorqueLimits.bounds``, compiled, and ``bounds_python``).  The motor
parameters are those of ``robot_params.CASSIE_MOTORS``; a motor without a speed limit (the flywheel)
keeps +-tau_max at any speed."""
import math

import numpy as np
import pytest

from cassie_flip_sim import robot_params as P
from cassie_flip_sim.motor_limits import MotorLimits, available_torque, torque_bounds
from cassie_flip_sim.simulator import Simulator
from tsc_controller.limits import TorqueLimits

N = len(P.MOTOR_NAMES)
FLYWHEEL = P.MOTOR_NAMES.index("flywheel")
MOTORS = ("left_knee", "left_hip_pitch", "right_knee", "right_hip_pitch")
# |w|/w0 -> tlim/tau_max of the published model: full torque up to half the no-load speed, then
# linearly down to 0 at the no-load speed, and 0 beyond
POINTS = {0.0: 1.0, 0.25: 1.0, 0.5: 1.0, 0.6: 0.8, 0.75: 0.5, 0.9: 0.2, 1.0: 0.0, 1.25: 0.0, 4.0: 0.0}


def published(w, tau_max, w0):
    """The published formula, written out (cassie-mujoco-sim: tlim = 2 * tmax * (1 - fabs(w) / wmax);
    tlim = fmax(fmin(tlim, tmax), 0))."""
    tlim = 2.0 * tau_max * (1.0 - abs(w) / w0)
    return max(min(tlim, tau_max), 0.0)


def _motor(name):
    i = P.MOTOR_NAMES.index(name)
    m = P.CASSIE_MOTORS[i]
    return i, m.torque_limit, m.no_load_speed


def _speeds(i, w, rest=0.0):
    v = np.full(N, rest)
    v[i] = w
    return v


def _cases():
    for name in MOTORS:
        for frac, f_tau in POINTS.items():
            for sign in (1.0, -1.0):
                yield name, sign * frac, f_tau


def test_published_numbers_of_the_knee_and_hip_pitch():
    """The table's knee and hip pitch: 12.2 N·m x gear 16 = 195.2 N·m, 1300 rpm / 16 = 8.51 rad/s."""
    for name in ("left_knee", "right_knee", "left_hip_pitch", "right_hip_pitch"):
        m = P.CASSIE_MOTORS[P.MOTOR_NAMES.index(name)]
        assert (m.gear, m.motor_torque_limit, m.no_load_rpm) == (16, 12.2, 1300)
        assert m.torque_limit == pytest.approx(195.2)
        assert m.no_load_speed == pytest.approx(1300 * 2 * math.pi / 60 / 16)
        assert m.no_load_speed == pytest.approx(8.508, abs=1e-3)


@pytest.mark.parametrize("name,frac,f_tau", list(_cases()))
def test_envelope_points(name, frac, f_tau):
    """tau_max at 0, 1/4 and 1/2 of the no-load speed, 0.8 tau_max at 0.6, tau_max/2 at 3/4, 0.2 tau_max
    at 0.9, 0 at and beyond the no-load speed, either direction of turning, in every Python copy."""
    i, tau, w0 = _motor(name)
    w = frac * w0
    expect = f_tau * tau
    assert published(w, tau, w0) == pytest.approx(expect, rel=1e-12, abs=1e-9)
    assert available_torque(w, tau, 1.0 / w0) == pytest.approx(expect, rel=1e-12, abs=1e-9)
    v = _speeds(i, w)
    sim_lim = MotorLimits.from_flywheel("I")
    tl = TorqueLimits()
    for lb, ub in (sim_lim.bounds(v), torque_bounds(v), tl.bounds(v), tl.bounds_python(v)):
        assert ub[i] == pytest.approx(expect, rel=1e-12, abs=1e-9)
        assert lb[i] == pytest.approx(-expect, rel=1e-12, abs=1e-9)
        # the other motors at rest: their full torque
        others = np.arange(N) != i
        assert np.array_equal(ub[others], sim_lim.torque_limit[others])
        assert np.array_equal(lb[others], -sim_lim.torque_limit[others])
    # clip: motoring and braking alike saturate at +-tlim (braking is not given the full tau_max)
    for u in (1e4, -1e4):
        assert sim_lim.clip(_speeds(i, u), v)[i] == pytest.approx(math.copysign(expect, u), rel=1e-12, abs=1e-9)
    inside = 0.5 * expect
    assert sim_lim.clip(_speeds(i, inside), v)[i] == inside
    assert sim_lim.clip(_speeds(i, -inside), v)[i] == -inside


def test_copies_agree_with_the_published_formula_bit_for_bit_between_them():
    """A sweep of speeds over every motor (0 to 1.5 w0, both signs): the Python definition, the
    simulator's bounds and the controller's compiled and numpy bounds are the same numbers, and they
    are the published formula to rounding."""
    lim = MotorLimits.from_flywheel("I")
    tl = TorqueLimits()
    w0 = lim.no_load_speed
    for frac in np.linspace(-1.5, 1.5, 241):
        v = np.where(np.isfinite(w0), frac * np.where(np.isfinite(w0), w0, 1.0), 50.0 * frac)
        ref = available_torque(v, lim.torque_limit, lim.inv_no_load_speed)
        for lb, ub in (lim.bounds(v), tl.bounds(v), tl.bounds_python(v)):
            np.testing.assert_array_equal(ub, ref)
            np.testing.assert_array_equal(lb, -ref)
        for k in range(N):
            assert ref[k] == pytest.approx(published(v[k], lim.torque_limit[k], w0[k]), rel=1e-12, abs=1e-9)


def test_speed_scale_stretches_the_envelope():
    """``speed_scale`` multiplies w0: the knee's tau_max/2 moves to 3/4 of the scaled no-load speed."""
    i, tau, w0 = _motor("left_knee")
    for scale in (1.0, 3.0):
        v = _speeds(i, 0.75 * scale * w0)
        for lb, ub in (MotorLimits.from_flywheel("I", scale).bounds(v), TorqueLimits(speed_scale=scale).bounds(v)):
            assert (lb[i], ub[i]) == pytest.approx((-0.5 * tau, 0.5 * tau), rel=1e-12)
        v = _speeds(i, 0.5 * scale * w0)
        assert TorqueLimits(speed_scale=scale).bounds(v)[1][i] == pytest.approx(tau, rel=1e-12)


@pytest.mark.parametrize("flywheel_torque", [None, 260.0])
def test_flywheel_keeps_its_torque_at_any_speed(flywheel_torque):
    lim = MotorLimits.from_flywheel("I", flywheel_torque=flywheel_torque)
    tau = flywheel_torque or P.FLYWHEELS["I"].max_torque
    assert math.isinf(lim.no_load_speed[FLYWHEEL]) and lim.inv_no_load_speed[FLYWHEEL] == 0.0
    tl = TorqueLimits(flywheel_torque=flywheel_torque)
    for w in (0.0, 1.0, 100.0, 1e4, 1e9, -1.0, -1e4, -1e9):
        v = _speeds(FLYWHEEL, w)
        assert available_torque(w, tau, 0.0) == tau
        for lb, ub in (lim.bounds(v), tl.bounds(v), tl.bounds_python(v)):
            assert (lb[FLYWHEEL], ub[FLYWHEEL]) == (-tau, tau)
        assert lim.clip(_speeds(FLYWHEEL, 1e4), v)[FLYWHEEL] == tau
        assert lim.clip(_speeds(FLYWHEEL, -1e4), v)[FLYWHEEL] == -tau


@pytest.fixture(scope="module")
def sims():
    return Simulator("I", "flat", backend="native"), Simulator("I", "flat", backend="python")


@pytest.mark.parametrize("name", MOTORS[:2] + ("flywheel",))
def test_simulator_steps_clip_at_the_published_envelope(sims, name):
    """The compiled step (cassie_flip_sim/native/step.cpp) and the numpy step clip a command of
    +-10 kN·m at the envelope of the motor's speed (set in qvel before the step): the same torques,
    bit for bit, as MotorLimits.clip."""
    i = P.MOTOR_NAMES.index(name)
    sim = sims[0]
    tau, w0 = sim.limits.torque_limit[i], sim.limits.no_load_speed[i]
    dof = sim._motor_dof[i]
    fracs = POINTS.items() if math.isfinite(w0) else ((1.0, 1.0), (1e3, 1.0))
    scale = w0 if math.isfinite(w0) else 100.0
    for frac, f_tau in fracs:
        for sign in (1.0, -1.0):
            for u_sign in (1.0, -1.0):
                w = sign * frac * scale
                u = _speeds(i, u_sign * 1e4)
                applied = []
                for s in sims:
                    s.reset()
                    s.data.qvel[dof] = w
                    s.step(u)
                    applied.append(s.last_command[i])
                expect = u_sign * f_tau * tau
                assert applied[0] == applied[1] == sim.limits.clip(u, _speeds(i, w))[i]
                assert applied[0] == pytest.approx(expect, rel=1e-12, abs=1e-9), (name, frac, sign, u_sign)
