"""The compiled tick (tsc_controller._native, Dynamics(backend="native"), the default) against the numpy
reference (backend="python"): every per-tick term, the constraint rows of every domain's row set and the
constrained dynamics, on random states and on states of simulated runs; and the controller's torques."""

import numpy as np
import pinocchio as pin
import pytest

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from tsc_controller import Controller, StateConverter
from tsc_controller.dynamics import Dynamics
from tsc_controller.tsc import ConstrainedDynamics

RTOL = 1e-9
FIELDS = ("Minv", "H", "BH", "tau_passive", "Ag", "dAg_v", "hg", "hg_lin", "com", "R_base", "P", "Jp", "drift",
          "pdot", "omega")
# (ground, feet) of the domains: both feet, left / right foot only, flight
ROW_SETS = ((True, (True, True)), (True, (True, False)), (True, (False, True)), (False, (True, True)))


@pytest.fixture(scope="module")
def mjcf():
    return export_mjcf()


@pytest.fixture(scope="module", params=[True, False], ids=["rigid_springs", "free_springs"])
def pair(request, mjcf):
    """(native, reference) Dynamics of one model."""
    return (Dynamics(mjcf, rigid_springs=request.param),
            Dynamics(mjcf, rigid_springs=request.param, backend="python"))


def _close(a, b, what):
    a, b = np.asarray(a), np.asarray(b)
    assert a.shape == b.shape, what
    err = np.abs(a - b).max() if a.size else 0.0
    assert err <= RTOL * max(1.0, np.abs(b).max()), f"{what}: |native - reference| = {err:.3g}"


def _compare(dn, dp, q, v):
    """Every term of dn (native) and dp (reference) at (q, v)."""
    dn.update(q, v)
    dp.update(q, v)
    assert dn.native is not None and dp.native is None
    for f in FIELDS:
        _close(getattr(dn, f), getattr(dp, f), f)
    _close(dn.point_lists()[2], dp.point_lists()[2], "point_lists")
    # the Pinocchio data the rest of the controller reads (frame placements, base placement)
    for k in (dn.base_jid, dn.model.njoints - 1):
        _close(dn.data.oMi[k].homogeneous, dp.data.oMi[k].homogeneous, f"data.oMi[{k}]")
    for p in dn.points.values():
        _close(dn.data.oMf[p.frame_id].homogeneous, dp.data.oMf[p.frame_id].homogeneous, f"data.oMf {p.name}")
    for ground, feet in ROW_SETS:
        dom = f"ground={ground} feet={feet}"
        Jn, dn_ = dn.constraints(ground, feet)
        Jp, dp_ = dp.constraints(ground, feet)
        _close(Jn, Jp, f"J {dom}")
        _close(dn_, dp_, f"Jdot v {dom}")
        cn = ConstrainedDynamics(dn, ground, feet)
        cp = ConstrainedDynamics(dp, ground, feet)
        # on the same terms (the elimination alone) and end to end
        cx = ConstrainedDynamics(dn, ground, feet, backend="python")
        _close(cn.J, cp.J, f"ConstrainedDynamics.J {dom}")
        _close(cn.dJv, cp.dJv, f"ConstrainedDynamics.dJv {dom}")
        for name in ("A", "b", "Abar", "bbar"):
            _close(getattr(cn, name), getattr(cx, name), f"{name} {dom} (same terms)")
            _close(getattr(cn, name), getattr(cp, name), f"{name} {dom}")


def test_native_is_the_default(mjcf):
    d = Dynamics(mjcf)
    assert d.backend == "native" and d.native is not None
    assert Controller(mjcf).dyn.backend == "native"


def test_random_states(pair):
    """Configurations around qpos0 (loops not closed: the terms do not assume it), random velocities."""
    dn, dp = pair
    rng = np.random.default_rng(7)
    for k in range(40):
        dq = rng.normal(0.0, 0.3 if k % 2 else 0.05, dn.nv)
        q = pin.integrate(dn.model, dn.q_ref, dq)
        v = rng.normal(0.0, 2.0 if k % 3 else 0.2, dn.nv)
        if k % 5 == 0:
            v[dn.flywheel_v] = rng.normal(0.0, 200.0)    # a spinning flywheel
        _compare(dn, dp, q, v)


def _simulated_states(dyn, n_stand=300, n_noise=300, n_flight=100, every=10):
    """States of the simulator: standing under the controller, then with noisy torques, and tossed
    into the air with random velocities."""
    sim = Simulator()
    ctl = Controller(export_mjcf(), rigid_springs=dyn.rigid_springs)
    sc = StateConverter(ctl.dyn)
    rng = np.random.default_rng(3)
    out = []
    for k in range(n_stand + n_noise):
        q, v = sc.from_simulator(sim)
        u, _ = ctl.compute(q, v, sim.time)
        if k >= n_stand:
            u = u + rng.normal(0.0, 20.0, u.shape)
        sim.step(u)
        if k % every == 0:
            out.append((q, v))
    qpos, qvel = sim.data.qpos.copy(), sim.data.qvel.copy()
    qpos[2] += 0.5
    qvel += rng.normal(0.0, 1.0, qvel.shape)
    sim.reset(qpos, qvel, in_contact=False)
    for k in range(n_flight):
        q, v = sc.from_simulator(sim)
        sim.step(rng.normal(0.0, 10.0, 11))
        if k % every == 0:
            out.append((q, v))
    return out


def test_simulated_states(pair):
    dn, dp = pair
    states = _simulated_states(dn)
    assert len(states) >= 60
    for q, v in states:
        _compare(dn, dp, q, v)


def test_controller_torques_match(mjcf):
    """The whole tick: a controller on each backend (ControllerConfig.backend), fed the same simulated
    standing states, commands the same torques (the QP amplifies the 1e-12 differences of the terms,
    hence the looser bound)."""
    sim = Simulator()
    cn = Controller(mjcf)
    cp = Controller(mjcf, backend="python")
    assert cn.dyn.backend == "native" and cp.dyn.backend == "python"
    sc = StateConverter(cn.dyn)
    for k in range(400):
        q, v = sc.from_simulator(sim)
        un, info_n = cn.compute(q, v, sim.time)
        up, info_p = cp.compute(q, v, sim.time)
        assert info_n["qp_status"] == info_p["qp_status"]
        assert np.abs(un - up).max() < 1e-6 * max(1.0, np.abs(up).max()), k
        sim.step(un)


def _all_outputs(ctl):
    """Every output object of a controller (each domain's)."""
    f = ctl.flight
    outs = [*ctl.ground.outputs, *ctl.jumping.outputs, f.o_Hfw, f.o_pitch, *f.o_Lleg, *f.o_beta, *f.o_toe,
            f.o_j_pre, f.o_j_post, *ctl.ground.o_swing, f.o_axis, f.o_sym]
    return outs


def test_compiled_outputs_match_evaluate(mjcf):
    """The compiled task rows (outputs.py's native_spec) against each output's evaluate."""
    from tsc_controller.tsc import _Task
    ctl = Controller(mjcf)
    dyn = ctl.dyn
    ctl.pitch = 0.3
    outs = _all_outputs(ctl)
    states = _simulated_states(dyn, n_stand=100, n_noise=100, n_flight=50)
    rng = np.random.default_rng(11)
    for k in range(20):
        q = pin.integrate(dyn.model, dyn.q_ref, rng.normal(0.0, 0.3, dyn.nv))
        states.append((q, rng.normal(0.0, 2.0, dyn.nv)))
    dyn.update(*states[0])
    task = _Task(outs, [o.evaluate(dyn) for o in outs])
    task.compile(dyn)
    assert task.native is not None and len(task.native) == task.m
    J = task.native.buffers()["J"]
    for q, v in states:
        dyn.update(q, v)
        task.native.evaluate(dyn.native, [o.value() for o in task.valued])
        for o, (name, sl) in zip(outs, task.slices):
            y, Jo, drift, ydot = o.evaluate(dyn)
            _close(task.y[sl], y, f"{name} y")
            _close(J[sl], Jo, f"{name} J")
            _close(task.drift[sl], drift, f"{name} drift")
            if o.degree == 2:
                _close(task.ydot[sl], ydot, f"{name} ydot")


def test_qp_terms_match(mjcf, monkeypatch):
    """The QP the TSC hands the solver (H, g, GRF rows C, up, bounds), native vs numpy, in every row set."""
    from tsc_controller import tsc as T
    from tsc_controller.tsc import TSC, Desired
    dn, dp = Dynamics(mjcf), Dynamics(mjcf, backend="python")
    tn, tp = TSC(dn, cop_margin=0.1), TSC(dp, cop_margin=0.1)
    ctl = Controller(mjcf)
    f = ctl.flight
    lists = [ctl.ground.outputs, ctl.jumping.outputs + [ctl.ground.o_swing[0]],
             [f.o_Hfw, *f.o_Lleg, f.o_j_pre], [f.o_pitch, *f.o_Lleg, f.o_axis, f.o_j_pre],
             [f.o_pitch, *f.o_Lleg, *f.o_beta, *f.o_toe, f.o_j_post]]
    seen = []
    orig = T.SOLVERS["daqp"].solve

    def capture(self, *args):
        seen.append([None if a is None else np.array(a) for a in args])
        return orig(self, *args)
    monkeypatch.setattr(T.SOLVERS["daqp"], "solve", capture)
    rng = np.random.default_rng(5)
    states = _simulated_states(dn, n_stand=60, n_noise=60, n_flight=20, every=20)
    for q, v in states:
        dn.update(q, v)
        dp.update(q, v)
        for outs in lists:
            des = [Desired(rng.normal(0.0, 0.1, o.evaluate(dn)[0].shape), rng.normal(0.0, 0.1),
                           None if k % 2 else rng.normal(0.0, 0.1)) for k, o in enumerate(outs)]
            u_prev = rng.normal(0.0, 5.0, 11)
            for ground, feet in ROW_SETS:
                seen.clear()
                rn = tn.solve(outs, des, ground, -np.full(11, 50.0), np.full(11, 50.0), feet, u_prev, 10.0)
                k = len(seen)
                rp = tp.solve(outs, des, ground, -np.full(11, 50.0), np.full(11, 50.0), feet, u_prev, 10.0)
                assert len(seen) == 2 * k
                for a, b in zip(seen[:k], seen[k:]):
                    for x, y in zip(a, b):
                        assert (x is None) == (y is None)
                        if x is not None:
                            _close(x, y, f"QP term, ground={ground} feet={feet}")
                for name in rp.y:
                    _close(rn.y[name], rp.y[name], f"error {name}")


@pytest.mark.parametrize("scale", [1.0, 3.0])
def test_torque_bounds_match(scale):
    """limits.TorqueLimits.bounds (compiled) against the envelope's Python reference
    (cassie_model.motor_limits.MotorLimits.bounds), bit for bit, at and beyond the no-load speeds, at
    rest, and for non-finite speeds."""
    from tsc_controller.limits import TorqueLimits
    lim = TorqueLimits(speed_scale=scale, flywheel_torque=260.0)
    rng = np.random.default_rng(2)
    for k in range(200):
        w = rng.normal(0.0, [5.0, 50.0, 500.0][k % 3], 11)
        if k % 7 == 0:
            w[rng.integers(11)] = 0.0
        if k % 11 == 0:
            w[rng.integers(11)] = [np.inf, -np.inf, np.nan][k % 3]
        with np.errstate(invalid="ignore"):           # inf speed x 0 (the flywheel's 1/w0) in numpy
            ref = lim.limits.bounds(w)
        for a, b in zip(lim.bounds(w), ref):
            np.testing.assert_array_equal(a, b)


def test_output_subclass_without_compiled_form_falls_back(mjcf):
    """An output whose evaluate is re-defined (and not its native_spec) keeps the list in Python."""
    from tsc_controller import outputs as O
    from tsc_controller.tsc import _Task

    class Shifted(O.LegLength):
        def evaluate(self, dyn):
            y, J, drift, ydot = super().evaluate(dyn)
            return y + 1.0, J, drift, ydot
    dyn = Dynamics(mjcf)
    dyn.update(dyn.q_ref, np.zeros(dyn.nv))
    outs = [O.CentroidalPitchMomentum("H"), Shifted("L")]
    task = _Task(outs, [o.evaluate(dyn) for o in outs])
    task.compile(dyn)
    assert task.native is None
    outs = [O.CentroidalPitchMomentum("H"), O.LegLength("L")]
    task = _Task(outs, [o.evaluate(dyn) for o in outs])
    task.compile(dyn)
    assert task.native is not None


class _Twin:
    """Two controllers fed the same events, references and states (tests/offline_flip.py's calls);
    every tick's torques of the second must equal the first's to the bit.  Counts the situations the
    second (the Python targets) went through."""

    def __init__(self, a, b):
        self.a, self.b = a, b
        self.seen = set()
        self.ticks = 0

    def __getattr__(self, name):
        return getattr(self.a, name)

    def set_reference(self, ref):
        self.a.set_reference(ref)
        self.b.set_reference(ref)

    def on_contact_event(self, *args):
        self.a.on_contact_event(*args)
        self.b.on_contact_event(*args)

    def compute(self, q, v, t, details=True):
        ua, info = self.a.compute(q, v, t, details)
        ub, _ = self.b.compute(q, v, t, details)
        assert ua.tobytes() == ub.tobytes(), f"t={t}: compiled and Python targets differ by {ua - ub}"
        wa, wb = self.a.standing.outputs[0].weight, self.b.standing.outputs[0].weight
        assert wa == wb, f"t={t}: STANDING H_pitch weights {wa} (compiled), {wb}"
        self.ticks += 1
        b = self.b
        if wb < b.standing.H_w0:
            self.seen.add("COM past the feet")
        self.seen.add(("domain", int(b.domain)))
        if not all(b.ground.feet_contact):
            self.seen.add("one foot or none")
        if b.ground.stand is not None and "tL" in b.ground.stand:
            self.seen.add("leg catch re-anchored")
        return ua, info


# (the in-place frontflip from 0.98 s, whose rebound put the COM past the feet in STANDING, no longer
# does so with the kernel-independent planner and start state: that branch has no twin case now)
@pytest.mark.parametrize("flip", ["C", "D"])
def test_compiled_targets_equal_python_targets(flip):
    """ControllerConfig.compiled_targets (the ground domains' targets in C++, _native.GroundTargets)
    against its Python reference over an offline flip of the somersault robot: the same torques
    and STANDING momentum weights to the bit at every tick, through every domain, with the landing's
    leg catch re-anchored on the sink rate (flip C's 3.8 m/s touch-down), with feet off the ground
    (flip D's rebounds), and with the COM past the feet in STANDING (the in-place frontflip from
    0.98 s, whose rebound in the landing starts STANDING in the air, the COM ahead of the toes)."""
    import offline_flip as of
    from cassie_model.model import Scenario
    scenario, request, start, seconds, seen = {
        "C": (Scenario.platform(0.5), dict(forward_distance=0.6, platform_height=0.5, apex_height=1.2), 0.5,
              5.0, "leg catch re-anchored"),
        "D": (Scenario.raised_landing(0.1), dict(forward_distance=0.6, apex_height=1.2), 0.5, 5.0,
              "one foot or none"),
        "in place from 0.98 s": (Scenario.flat(), dict(apex_height=1.3), 0.98, 5.5, "COM past the feet"),
    }[flip]
    robot = dict(motor_speed_scale=3, flywheel_torque=260)
    sim = Simulator(scenario=scenario, **robot)
    mj = export_mjcf(sim.flywheel)
    # 1 N least normal force everywhere (f_min_domains empty): with the default 25 N in JUMPING and
    # LANDING these runs no longer re-anchor the catch or lift a foot, and the branches go untested;
    # the controller's own landing (the fallback when no landing plan arrives), whose targets these are
    cfg = dict(f_min_domains={}, track_landing_reference=False)
    twin = _Twin(Controller(mj, **robot, **cfg), Controller(mj, compiled_targets=False, **robot, **cfg))
    assert twin.a.ground.compiled is not None and twin.b.ground.compiled is None
    # the jump anchored at the initial COM (an input here): the run whose landing re-anchors the catch
    r = of.run("frontflip", seconds=seconds, start=start, sim=sim, controller=twin, x_start=float(sim.com_position()[0]),
               **robot, **request)
    # (under the published motor curve with 1 N these runs fall after their landings, C at 3.5 s, D
    # at 3.1 s: the twins are compared on every tick up to the fall, every domain and branch included)
    end = seconds if r["fell"] is None else r["fell"]
    assert abs(twin.ticks - end / 0.0005) <= 1.0 and end > 3.0
    assert {("domain", d) for d in range(4)} <= twin.seen
    assert seen in twin.seen
