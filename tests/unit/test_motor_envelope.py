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


def test_speed_cap_row_keeps_the_predicted_speed_within_the_cap():
    """limits.speed_cap_row (the LANDING's flywheel cap): row.u <= upper says the speed predicted for the
    next tick, w + drift + dt m.u, is at most the cap in magnitude: a torque on the row's bound lands on
    the cap exactly, from below (room to spin up) or above (a brake), for either sign of the speed and with
    a drift; beyond what the torque bounds can brake, the bound is the most brake there is."""
    from tsc_controller.limits import speed_cap_row
    m = np.array([0.5, -0.2, 10.0])                  # the legs' reaction and the wheel's own response
    lb, ub = np.full(3, -100.0), np.full(3, 100.0)
    dt = 5e-4
    for w, drift in ((300.0, 0.0), (300.8, 0.0), (301.1, 0.0), (300.8, 0.1), (-300.8, 0.0), (-301.1, -0.1),
                     (-300.8, 0.1)):
        row, up = speed_cap_row(m, w, 301.0, dt, drift, lb, ub)
        u = np.array([10.0, -30.0, 0.0])
        u[2] = (up - row[:2] @ u[:2]) / row[2]      # the wheel's torque that puts row.u on its bound
        assert abs(w + drift + dt * m @ u) == pytest.approx(301.0), (w, drift)
        brake = abs(w + drift + dt * m[:2] @ u[:2]) > 301.0
        assert (np.sign(u[2]) == -np.sign(w)) == brake, (w, drift, u)
    row, up = speed_cap_row(m, 350.0, 301.0, dt, 0.0, lb, ub)   # 49 rad/s over: more than 100 N m can brake
    assert up == pytest.approx(np.minimum(row * lb, row * ub).sum())
