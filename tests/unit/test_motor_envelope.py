"""The motor torque–speed envelope is Cassie's published curve (its simulators' motor model:
|τ| ≤ min(τ_max, 2 τ_max (1 − |ω|/ω₀)), clamped at 0, for either sign of the torque), and the
simulator's and the controller's copies give its values at 0, ½ and 1 no-load speed for a knee and
a hip motor; the planner's leg-force rows stay inside it."""
import math

import numpy as np
import pytest

from cassie_model import robot_params as P
from cassie_model.motor_limits import MotorLimits, available_fraction, planning_fraction
from cassie_flip_sim.simulator import Simulator

KNEE, HIP_PITCH, HIP_ROLL = P.MOTOR_NAMES.index("left_knee"), P.MOTOR_NAMES.index("left_hip_pitch"), \
    P.MOTOR_NAMES.index("left_hip_roll")


def published(tau_max, w, w0):
    """The formula as Cassie's simulators write it (cassie-mujoco-sim motor())."""
    return max(0.0, min(tau_max, 2.0 * tau_max * (1.0 - abs(w) / w0)))


def cases(scale=1.0):
    lim = MotorLimits.from_flywheel("I", speed_scale=scale)
    for i in (KNEE, HIP_PITCH, HIP_ROLL):
        w0 = float(lim.no_load_speed[i])
        for share in (0.0, 0.5, 0.75, 1.0):
            for sign in (1.0, -1.0):
                yield lim, i, sign * share * w0, published(float(lim.torque_limit[i]), share * w0, w0)


def test_published_values_at_rest_half_and_full_no_load_speed():
    lim = MotorLimits.from_flywheel("I")
    assert lim.no_load_speed[KNEE] == pytest.approx(1300 * 2 * math.pi / 60 / 16)       # 81.25 rpm
    assert lim.no_load_speed[HIP_ROLL] == pytest.approx(2900 * 2 * math.pi / 60 / 25)
    for i in (KNEE, HIP_PITCH, HIP_ROLL):
        tau, w0 = lim.torque_limit[i], lim.no_load_speed[i]
        w = np.zeros(11)
        for share, expect in ((0.0, tau), (0.5, tau), (0.75, 0.5 * tau), (1.0, 0.0), (2.0, 0.0)):
            for sign in (1.0, -1.0):              # driving or braking: the same
                w[i] = sign * share * w0
                lb, ub = lim.bounds(w)
                assert ub[i] == pytest.approx(expect) and lb[i] == pytest.approx(-expect), (i, share, sign)


@pytest.mark.parametrize("scale", [1.0, 3.0])
def test_controller_copy_gives_the_published_values(scale):
    from tsc_controller.limits import TorqueLimits
    tl = TorqueLimits(speed_scale=scale)
    for _, i, w, expect in cases(scale):
        v = np.zeros(11)
        v[i] = w
        lb, ub = tl.bounds(v)
        assert ub[i] == pytest.approx(expect, abs=1e-12) and lb[i] == pytest.approx(-expect, abs=1e-12)


@pytest.mark.parametrize("backend", ["native", "python"])
def test_simulator_copy_clips_to_the_published_values(backend):
    """The simulator's torque clip (compiled step, and its numpy reference) at a joint speed set on the
    motor's joint: a ±1000 N·m command comes out as ± the published torque."""
    sim = Simulator("I", "flat", backend=backend)
    for _, i, w, expect in cases():
        for sign in (1.0, -1.0):
            sim.reset()
            sim.data.qvel[sim._motor_dof[i]] = w
            u = np.zeros(11)
            u[i] = 1000.0 * sign
            sim.step(u)
            assert sim.last_command[i] == pytest.approx(sign * expect, abs=1e-12), (backend, i, w, sign)


def test_planner_rows_stay_inside_the_envelope():
    r = np.linspace(-1.5, 1.5, 601)
    plan, env = planning_fraction(r), available_fraction(r)
    assert np.all(plan <= env + 1e-15)
    assert planning_fraction(0.0) == 1.0 and planning_fraction(1.0) == 0.0
    assert planning_fraction(0.5) == 0.5                       # driving: the chord, half the envelope
    assert planning_fraction(-0.75) == pytest.approx(0.5)      # braking: the envelope itself


def test_speed_capped_bounds_the_torque_along_the_speed_to_what_reaches_the_cap_in_a_tick():
    """limits.speed_capped (the LANDING's flywheel cap): the torque along the speed is at most
    I (w_cap - |w|) / dt, a brake above the cap, never past the other bound; the torque against the
    speed, the other motors and the inputs stay as they were; a negative speed mirrors it."""
    from tsc_controller.limits import speed_capped
    lb, ub = np.full(3, -100.0), np.full(3, 100.0)
    I, dt = 0.1, 5e-4
    for w, expect_lb, expect_ub in ((300.0, -100.0, 100.0),      # 1 rad/s below: 200 N m would reach it
                                    (300.8, -100.0, 40.0),       # 0.2 below: 40
                                    (301.0, -100.0, 0.0),        # at the cap: nothing along the speed
                                    (301.1, -100.0, -20.0),      # 0.1 above: a 20 N m brake
                                    (310.0, -100.0, -100.0),     # far above: the full brake, not past it
                                    (-300.8, -40.0, 100.0), (-301.1, 20.0, 100.0)):
        lo, up = speed_capped(lb, ub, 2, w, 301.0, I, dt)
        assert (lo[2], up[2]) == pytest.approx((expect_lb, expect_ub)), w
        assert lo[:2].tolist() == [-100.0, -100.0] and up[:2].tolist() == [100.0, 100.0]
    assert lb.tolist() == [-100.0] * 3 and ub.tolist() == [100.0] * 3
    # the body's motion carrying the joint speed 0.1 rad/s further from 0 over the tick: 0.1 less room
    assert speed_capped(lb, ub, 2, 300.8, 301.0, I, dt, drift=0.1)[1][2] == pytest.approx(20.0)
    assert speed_capped(lb, ub, 2, -300.8, 301.0, I, dt, drift=-0.1)[0][2] == pytest.approx(-20.0)
    assert speed_capped(lb, ub, 2, -300.8, 301.0, I, dt, drift=0.1)[0][2] == pytest.approx(-60.0)
