"""The TSC QP (paper eq. (QP)) respects every bound on random states: torque-speed envelope,
unilateral normal force, friction pyramid; ProxQP, OSQP and DAQP agree."""
import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_model.motor_limits import torque_bounds
from test_tsc_dynamics import random_state
from tsc_controller import Controller
from tsc_controller.limits import grf_constraints
from tsc_controller.tsc import ConstrainedDynamics, Desired


@pytest.fixture(scope="module")
def controllers():
    x = export_mjcf()
    return {s: Controller(x, solver=s) for s in ("proxqp", "daqp", "osqp")}


def _random_task(ctl, rng):
    """Standing outputs with random desired offsets (so the QP is pushed against its bounds)."""
    dyn = ctl.dyn
    outs = ctl.ground.outputs
    des = []
    for o in outs:
        y = o.evaluate(dyn)[0]
        scale = {"H_pitch": 5.0, "L": 0.1, "com": 0.1, "pelvis": 0.3}[o.name]
        des.append(Desired(y + rng.normal(0, scale, len(y)), rng.normal(0, 1, len(y)), rng.normal(0, 20, len(y))))
    return outs, des


def _random_problems(ctl, seed, n=25):
    """n random states (halved velocities) with standing outputs pushed off their values: yields
    (trial, lb, ub, outputs, desired), the dynamics updated to that state."""
    dyn = ctl.dyn
    rng = np.random.default_rng(seed)
    for trial in range(n):
        q, v = random_state(dyn, rng, True)
        v *= 0.5
        dyn.update(q, v)
        lb, ub = torque_bounds(v[dyn.motor_v])
        yield (trial, lb, ub, *_random_task(ctl, rng))


@pytest.mark.parametrize("solver", ["proxqp", "daqp", "osqp"])
def test_qp_respects_bounds(controllers, solver):
    ctl = controllers[solver]
    dyn = ctl.dyn
    C, c = grf_constraints(2, ctl.cfg.mu, ctl.cfg.f_min)
    n_solved = 0
    for trial, lb, ub, outs, des in _random_problems(ctl, 5):
        res = ctl.tsc.solve(outs, des, True, lb, ub)
        u = res.u
        assert np.all(u >= lb - 1e-6) and np.all(u <= ub + 1e-6), (trial, u, lb, ub)
        F = ConstrainedDynamics(dyn, True).A @ u + ConstrainedDynamics(dyn, True).b
        assert np.allclose(F, res.forces)
        if res.status == "solved":
            n_solved += 1
            viol = C @ F[:10] - c
            assert viol.max() < 1e-4 * max(1.0, np.abs(F).max()), (trial, viol.max())
            # unilateral, friction explicitly
            for k in range(2):
                f = F[5 * k: 5 * k + 5]
                assert f[2] >= ctl.cfg.f_min - 1e-4 and f[4] >= ctl.cfg.f_min - 1e-4
                assert abs(f[1]) <= ctl.cfg.mu * f[2] + 1e-4 and abs(f[3]) <= ctl.cfg.mu * f[4] + 1e-4
                assert abs(f[0]) <= ctl.cfg.mu * (f[2] + f[4]) + 1e-4
        else:
            assert "box_only" in res.status or "zero" in res.status
    assert n_solved >= 15


@pytest.mark.parametrize("solver", ["proxqp", "osqp"])
def test_solvers_agree(controllers, solver):
    a, b = controllers[solver], controllers["daqp"]
    rng = np.random.default_rng(9)
    for trial in range(10):
        q, v = random_state(a.dyn, rng, True)
        v *= 0.3
        a.dyn.update(q, v)
        b.dyn.update(q, v)
        lb, ub = torque_bounds(v[a.dyn.motor_v])
        r2 = np.random.default_rng(trial)
        outs, des = _random_task(a, r2)
        ra = a.tsc.solve(outs, des, True, lb, ub)
        r2 = np.random.default_rng(trial)
        outs, des = _random_task(b, r2)
        rb = b.tsc.solve(outs, des, True, lb, ub)
        if ra.status == rb.status == "solved":
            assert np.allclose(ra.u, rb.u, atol=1e-2 * max(1.0, np.abs(ra.u).max())), (trial, ra.u - rb.u)


def test_flight_qp_respects_torque_bounds(controllers):
    ctl = controllers["proxqp"]
    dyn = ctl.dyn
    rng = np.random.default_rng(2)
    for trial in range(10):
        q, v = random_state(dyn, rng, False)
        dyn.update(q, v)
        lb, ub = torque_bounds(v[dyn.motor_v])
        outs = [ctl.flight.o_Hfw] + ctl.flight.o_Lleg + [ctl.flight.o_j_pre]
        des = [Desired(o.evaluate(dyn)[0] + rng.normal(0, 0.5, o.dim)) for o in outs]
        res = ctl.tsc.solve(outs, des, False, lb, ub)
        assert res.status == "solved"
        assert np.all(res.u >= lb - 1e-6) and np.all(res.u <= ub + 1e-6)


def test_torque_limits_match_simulator_envelope():
    from tsc_controller.limits import TorqueLimits
    rng = np.random.default_rng(1)
    tl = TorqueLimits()
    for _ in range(200):
        w = rng.normal(0, 30, 11) * rng.integers(0, 2, 11)
        lb, ub = tl.bounds(w)
        lb2, ub2 = torque_bounds(w)
        assert np.allclose(lb, lb2) and np.allclose(ub, ub2)


def test_torque_limits_flywheel_torque():
    """``flywheel_torque`` moves the flywheel's bound (last entry) to ±260 N·m at any speed, as in the
    simulator; the leg motors' envelope is unchanged; ``Controller(flywheel_torque=...)`` uses it."""
    from cassie_model.motor_limits import MotorLimits
    from tsc_controller.limits import TorqueLimits
    tl, tl0 = TorqueLimits(flywheel_torque=260), TorqueLimits()
    lb, ub = tl.bounds(np.zeros(11))
    lb0, ub0 = tl0.bounds(np.zeros(11))
    assert (lb[-1], ub[-1]) == (-260.0, 260.0) and (lb0[-1], ub0[-1]) == (-195.0, 195.0)
    assert np.array_equal(lb[:10], lb0[:10]) and np.array_equal(ub[:10], ub0[:10])
    sim_lim = MotorLimits.from_flywheel("I", flywheel_torque=260)
    w = np.random.default_rng(2).normal(0, 30, 11)
    lb, ub = tl.bounds(w)
    lb2, ub2 = sim_lim.bounds(w)
    assert np.allclose(lb, lb2) and np.allclose(ub, ub2) and (lb[-1], ub[-1]) == (-260.0, 260.0)
    # the flywheel's torque limit comes with the robot description (its actuator's ctrlrange, the
    # simulator's); a configured one must agree with it
    from cassie_model.motor_limits import with_flywheel_torque
    from cassie_model.robot_params import flywheel
    fw260 = export_mjcf(with_flywheel_torque(flywheel("I"), 260.0))
    assert Controller(fw260).limits.tau_max[-1] == 260.0
    assert Controller(fw260, flywheel_torque=260.0).limits.tau_max[-1] == 260.0
    assert Controller(export_mjcf()).limits.tau_max[-1] == 195.0
    with pytest.raises(ValueError, match="differs from the robot description's 195"):
        Controller(export_mjcf(), flywheel_torque=260.0)
    with pytest.raises(ValueError):
        TorqueLimits(flywheel_torque=-1.0)


def test_cop_margin_per_solve(controllers):
    """``cop_margin`` passed to a solve keeps each foot's centre of pressure that fraction of the foot
    length from toe and heel (each carries >= margin of the foot's load); without it the same tasks
    put it at an end (the load all on toe or heel, up to f_min) in some of the trials."""
    ctl = controllers["daqp"]
    share_free, share_margin = [], []
    for _, lb, ub, outs, des in _random_problems(ctl, 11):
        for margin, shares in ((None, share_free), (0.2, share_margin)):
            res = ctl.tsc.solve(outs, des, True, lb, ub, cop_margin=margin)
            if res.status != "solved":
                continue
            for k in range(2):
                toe, heel = res.forces[5 * k + 2], res.forces[5 * k + 4]
                shares.append(min(toe, heel) / (toe + heel))
    assert len(share_margin) >= 20 and len(share_free) >= 20
    assert min(share_margin) >= 0.2 - 1e-4
    assert min(share_free) < 0.2


def test_a_weight_changed_between_ticks_is_used(controllers):
    """An output's weight may change from tick to tick (the own landing's H_pitch weight rises after
    touch-down): the cached task must solve with the new weight, i.e. give the torques of a controller
    built with that weight, and not those of the weight it first saw."""
    from tsc_controller.config import DEFAULT_GAINS
    ctl = controllers["daqp"]
    light = Controller(export_mjcf(), solver="daqp", gains=dict(DEFAULT_GAINS, H_pitch=(0.05, 10.0, 0.0)))
    rng = np.random.default_rng(5)
    differ = 0
    for _ in range(5):
        q, v = random_state(ctl.dyn, rng, True)
        v *= 0.5
        for c in (ctl, light):
            c.dyn.update(q, v)
        lb, ub = ctl.limits.bounds(v[ctl.dyn.motor_v])
        outs, des = _random_task(ctl, rng)
        w0 = ctl.ground.o_H.weight
        u_default = ctl.tsc.solve(outs, des, True, lb, ub).u        # the task is cached with weight w0
        try:
            ctl.ground.o_H.weight = 0.05
            u_changed = ctl.tsc.solve(outs, des, True, lb, ub).u
        finally:
            ctl.ground.o_H.weight = w0
        u_light = light.tsc.solve(light.ground.outputs, des, True, lb, ub).u
        assert np.allclose(u_changed, u_light, atol=1e-6 * max(1.0, np.abs(u_light).max()))
        differ += not np.allclose(u_default, u_light, atol=1e-3)
        assert np.allclose(ctl.tsc.solve(outs, des, True, lb, ub).u, u_default, atol=1e-6 * max(1.0, np.abs(u_default).max()))
    assert differ >= 3                      # the weight matters for these tasks
