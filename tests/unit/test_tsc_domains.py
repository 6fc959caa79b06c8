"""Domain switching and references of tsc_controller (no ROS; the state conversion: test_tsc_state.py)."""
import math
from types import SimpleNamespace

import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from tsc_controller import Controller, Domain, SampledReference, StateConverter


def test_sampled_reference_interpolates_and_clamps():
    t = np.array([0.0, 0.1, 0.2])
    val = np.array([[0.0, 1.0], [1.0, 2.0], [2.0, 4.0]])
    r = SampledReference(Domain.JUMPING, t, ["a", "b"], val.ravel(), 2 * val, 3 * val, start_time=5.0)
    s = r.sample(0.05)
    assert s["a"] == pytest.approx((0.5, 1.0, 1.5)) and s["b"] == pytest.approx((1.5, 3.0, 4.5))
    assert r.sample(-1.0)["b"][0] == 1.0 and r.sample(9.0)["b"][0] == 4.0
    msg = SimpleNamespace(domain=1, t=list(t), output_names=["a", "b"], value=list(val.ravel()),
                          d_value=[0.0] * 6, dd_value=[0.0] * 6,
                          start_time=SimpleNamespace(sec=5, nanosec=500_000_000),
                          plan_id=3, parameter_names=["T1"], parameter_values=[0.2])
    m = SampledReference.from_msg(msg)
    assert m.start_time == 5.5 and m.plan_id == 3 and m.parameters == {"T1": 0.2}
    assert m.sample(0.1)["b"] == (2.0, 0.0, 0.0)


def test_reference_from_msg_reads_it_as_tsc_node_does():
    """SampledReference.from_msg is tsc_node's reading of a /fslip/reference: the start time is the
    stamp's integer nanoseconds times 1e-9, as the tick's time is formed from a state's stamp (not
    sec + 1e-9 nanosec, which differs in the last bit for this stamp), and samples that are not
    len(t) x len(output_names), an empty derivative included, are refused (the node logs and ignores
    the message)."""
    def msg(**kw):
        m = dict(domain=1, t=[0.0, 0.1], output_names=["L"], value=[0.8, 0.9], d_value=[0.0, 1.0],
                 dd_value=[0.0, 0.0], start_time=SimpleNamespace(sec=1, nanosec=1_000_000), plan_id=1,
                 parameter_names=[], parameter_values=[])
        m.update(kw)
        return SimpleNamespace(**m)
    ref = SampledReference.from_msg(msg())
    assert ref.start_time == 1_001_000_000 * 1e-9 and ref.start_time != 1 + 1e-9 * 1_000_000
    assert ref.sample(0.05)["L"] == pytest.approx((0.85, 0.5, 0.0))
    for bad in (dict(d_value=[]), dict(dd_value=[0.0]), dict(value=[0.8, 0.9, 1.0]), dict(domain=7)):
        with pytest.raises(ValueError):
            SampledReference.from_msg(msg(**bad))


def _run(ctl, sim, t_end, on_tick=None):
    sc = StateConverter(ctl.dyn)
    doms = []
    while sim.time < t_end - 1e-9:
        if on_tick:
            on_tick(sim.time)
        for ev in sim.pop_events():
            ctl.on_contact_event(int(ev.kind), ev.time)
        q, v = sc.from_simulator(sim)
        u, info = ctl.compute(q, v, sim.time)
        sim.step(u)
        doms.append(info["domain"])
    return np.array(doms)


def test_reference_without_liftoff_falls_back_to_standing():
    """A JUMPING reference that ends without lift-off (a plan that is too weak, or a late/stale one)
    returns the robot to the standing outputs instead of leaving it on the last sample."""
    sim, ctl = Simulator(), Controller(export_mjcf())
    z0 = sim.pelvis_pose()[0][2]
    ts = np.linspace(0, 0.6, 301)
    sent = []

    def tick(t):
        if not sent and t >= 0.5:
            Ls = ctl.cfg.L_stand
            val = np.c_[Ls - 0.05 * np.sin(np.pi * ts / 0.6) ** 2, np.zeros_like(ts)]
            ctl.set_reference(SampledReference(Domain.JUMPING, ts, ["L", "H_pitch"], val, start_time=0.6))
            sent.append(1)
    doms = _run(ctl, sim, 2.5, tick)
    assert Domain.JUMPING in doms and doms[-1] == Domain.STANDING
    assert Domain.FLIGHT not in doms
    assert abs(sim.pelvis_pose()[0][2] - z0) < 0.01


def test_stale_reference_is_ignored():
    """A JUMPING reference whose time window has already passed never starts a jump."""
    sim, ctl = Simulator(), Controller(export_mjcf())
    ctl.set_reference(SampledReference(Domain.JUMPING, [0.0, 0.1], ["L"], [0.5, 0.5], start_time=-1.0))
    doms = _run(ctl, sim, 0.3)
    assert np.all(doms == Domain.STANDING)


def test_late_reference_is_not_joined_midway():
    """A JUMPING reference that arrives after its start time (planner or transport late) is dropped:
    the robot keeps standing rather than jumping into the middle of the plan."""
    sim, ctl = Simulator(), Controller(export_mjcf())
    ts = np.linspace(0, 1.0, 101)
    sent = []

    def tick(t):
        if not sent and t >= 0.2:
            ctl.set_reference(SampledReference(Domain.JUMPING, ts, ["L"], np.full(101, 0.7), start_time=0.1))
            sent.append(1)
    doms = _run(ctl, sim, 0.4, tick)
    assert np.all(doms == Domain.STANDING)
    assert Domain.JUMPING not in ctl.refs
    # and says so (tsc_node logs it): plan 0, its start, when it was dropped
    assert len(ctl.dropped) == 1 and ctl.dropped[0][:2] == (0, 0.1) and ctl.dropped[0][2] >= 0.2


def test_push_under_way_is_not_abandoned():
    """JUMPING past its reference's end: back to STANDING after ``grace`` if the COM is not rising,
    but kept (outputs held at the plan's end) while it rises fast, up to ``push_grace``; a LIFT_OFF
    in that time enters FLIGHT."""
    ctl = Controller(export_mjcf())
    cfg, m = ctl.cfg, ctl.dyn.mass
    ref = SampledReference(Domain.JUMPING, [0.0, 1.0], ["L"], [0.8, 0.95], start_time=0.5)

    def state_after(late, vz, event=None):
        ctl.refs = {Domain.JUMPING: ref}
        ctl.domain, ctl._pending_event = Domain.JUMPING, event
        ctl.dyn.hg_lin = np.array([0.0, 0.0, m * vz])   # COM momentum of the last update
        ctl._switch(1.5 + late)
        return ctl.domain
    assert state_after(0.5 * cfg.grace, 0.0) == Domain.JUMPING
    assert state_after(2.0 * cfg.grace, 0.0) == Domain.STANDING
    assert cfg.push_grace > 2.0 * cfg.grace
    assert state_after(2.0 * cfg.grace, 2.0 * cfg.push_rising) == Domain.JUMPING
    assert state_after(cfg.push_grace + 0.01, 2.0 * cfg.push_rising) == Domain.STANDING
    assert state_after(2.0 * cfg.grace, 2.0 * cfg.push_rising, (0, 1.5 + 2.0 * cfg.grace)) == Domain.FLIGHT


def test_controller_overrides_from_json():
    """``config_overrides`` (tsc_node's ``controller`` parameter, ``flip run --controller``): gains are
    merged into the defaults, domains given by name or number, and anything else is refused with
    the reason, before a controller is built."""
    from tsc_controller.config import DEFAULT_GAINS, JUMPING_GAINS, config_overrides
    o = config_overrides('{"cop_margin_domains": {"JUMPING": 0.2, "3": 0.1}, "jumping_gains": {"H_pitch": [3, 10, 0]},'
                         ' "landing_moment": 8, "per_foot_contact": false}')
    assert o["cop_margin_domains"] == {int(Domain.JUMPING): 0.2, int(Domain.LANDING): 0.1}
    assert o["jumping_gains"]["H_pitch"] == (3.0, 10.0, 0.0)
    assert o["jumping_gains"]["com"] == JUMPING_GAINS["com"]
    assert o["landing_moment"] == 8.0 and o["per_foot_contact"] is False
    ctl = Controller(export_mjcf(), **o)
    assert ctl.cfg.cop_margin_domains[int(Domain.JUMPING)] == 0.2 and ctl.cfg.gains == DEFAULT_GAINS
    assert config_overrides("") == {}
    # the tracked landing's overrides: merged as the other domains', and its outputs use them
    o = config_overrides('{"landing_gains": {"H_pitch": [0.1, 10, 0]}}')
    assert o["landing_gains"]["H_pitch"] == (0.1, 10.0, 0.0)
    assert Controller(export_mjcf(), **o).landing.plan_outputs[0].weight == 0.1
    # the numpy reference tick instead of the compiled one
    assert Controller(export_mjcf(), **config_overrides('{"backend": "python"}')).dyn.native is None
    for bad, why in [('{"backend": "fortran"}', "backend must be one of native, python"),
                     ('{"solver": "gurobi"}', "solver must be one of"),('{"no_such": 1}', "unknown controller setting"), ("[1, 2]", "JSON object"),
                     ("{oops", "not JSON"), ('{"gains": {"com": [1, 2]}}', "three numbers"),
                     ('{"gains": {"nose": [1, 2, 3]}}', "unknown output"),
                     ('{"cop_margin_domains": {"AIR": 0.1}}', "not a domain"),
                     ('{"cop_margin_domains": {"1": 0.6}}', "below 0.5"),
                     ('{"motor_speed_scale": 3}', "robot parameter"), ('{"landing_moment": "x"}', "number"),
                     ('{"per_foot_contact": 1}', "true or false")]:
        with pytest.raises(ValueError, match=why):
            config_overrides(bad)


def test_fallen_robot_is_only_damped():
    """After a BODY_CONTACT event (a fall) every motor, the flywheel included, only damps its own
    motion (u = -k w within the limits), whatever the domain and references say; before it, the same
    state gets the QP's answer."""
    sim, ctl = Simulator(), Controller(export_mjcf())
    sc = StateConverter(ctl.dyn)
    q, v = sc.from_simulator(sim)
    rng = np.random.default_rng(3)
    v = v.copy()
    v[ctl.dyn.motor_v] = rng.uniform(-3.0, 3.0, len(ctl.dyn.motor_v))
    v[ctl.dyn.motor_v[-1]] = 300.0                       # a spinning flywheel
    u_qp, info = ctl.compute(q, v, 0.0)
    assert info["qp_status"] != "fallen"
    ctl.on_contact_event(2, 0.0005)                    # flip_msgs/ContactEvent.BODY_CONTACT
    u, info = ctl.compute(q, v, 0.001)
    assert info["qp_status"] == "fallen" and ctl.fallen
    w = v[ctl.dyn.motor_v]
    lb, ub = ctl.limits.bounds(w)
    assert np.allclose(u, np.clip(-ctl.cfg.fall_damping * w, lb, ub))
    assert np.all(u * w <= 0.0) and u[-1] < -100.0       # braking, the flywheel hard


def test_quintic_of_short_vectors_equals_its_array_form():
    """quintic's element-by-element path (1-D float vectors, the outputs of a tick) gives the same
    numbers, to the bit, as its numpy form (which a 2-D input takes), with and without a start
    velocity, before, inside and after the blend."""
    from tsc_controller.profiles import quintic
    rng = np.random.default_rng(3)
    for n in (1, 2, 3):
        for _ in range(300):
            y0, y1, v0 = (rng.normal(size=n) * 10.0 ** rng.uniform(-3, 3) for _ in range(3))
            T, s = rng.uniform(0.05, 2.0), rng.uniform(-0.5, 2.5)
            for v in (None, v0):
                fast = quintic(y0, y1, T, s, v)
                ref = quintic(y0[None], y1[None], T, s, None if v is None else v[None])
                for f, r in zip(fast, ref):
                    assert f.shape == (n,) and np.array_equal(f, np.asarray(r).reshape(-1)), (n, T, s, v)


def test_compute_without_details_gives_the_same_torques():
    """compute(details=False) (the controller node's call) leaves forces, ground reaction and errors
    out of info and gives the same torques, to the bit, tick after tick."""
    sim = Simulator()
    full, lean = Controller(export_mjcf()), Controller(export_mjcf())
    conv = StateConverter(full.dyn)
    for _ in range(400):
        q, v = conv.from_simulator(sim)
        u, info = full.compute(q, v, sim.time)
        u2, info2 = lean.compute(q, v, sim.time, details=False)
        assert np.array_equal(u, u2)
        assert "forces" in info and "grf" in info and "errors" in info
        # the lean call keeps the elimination in the compiled tick: no forces to be had from it
        with pytest.raises(ValueError, match="details=False"):
            lean.tsc.last.forces(u2)
        assert not {"forces", "grf", "errors"} & set(info2) and info2["qp_status"] == info["qp_status"]
        sim.step(u)
    assert sim.pelvis_pose()[0][2] > 0.8                  # still standing: the ticks were real ones


def test_standing_momentum_weight_gives_way_while_the_com_is_off_the_feet():
    """STANDING's H_pitch weight is its own while the COM is over the feet and falls to
    standing_H_edge_weight of it once the COM is well past the toes (Standing.H_weight;
    frontflip from 0.98 s offline: kept at 1, the flywheel held the COM ahead of the toes while
    H_pitch grew to 112 kg*m^2/s, and the robot was not at rest after 10 s).  On the Python targets,
    whose foot anchors are attributes to move; the compiled ones give the same weights to the bit
    (tests/unit/test_tsc_native.py)."""
    sim = Simulator(motor_speed_scale=3.0, flywheel_torque=260.0)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=3.0, flywheel_torque=260.0,
                     compiled_targets=False)
    _run(ctl, sim, 0.05)
    o, w0 = ctl.standing.outputs[0], ctl.standing.H_w0
    assert ctl.domain == Domain.STANDING and o.weight == w0
    x = float(ctl.dyn.com[0])
    anchors = [a.copy() for a in ctl.ground.foot_anchor]
    for dx, f in ((0.0, 1.0), (x - 0.10 - max(a[0] for a in anchors), ctl.cfg.standing_H_edge_weight)):
        # the feet moved by dx: with the COM 0.1 m past the toes the weight is the edge weight's
        ctl.ground.foot_anchor = [a + np.array([dx, 0, 0, dx, 0, 0]) for a in anchors]
        ctl.standing.H_weight()
        assert o.weight == pytest.approx(w0 * f)
    ctl.ground.foot_anchor = anchors


def _tracking_a_landing_plan(**cfg):
    """A controller in LANDING tracking a 1 s landing reference (after a hop, ``track_hop_landing_reference``):
    (sim, ctl, state converter, the reference's times, the reference, tick() at the sim's time)."""
    sim, ctl = Simulator(), Controller(export_mjcf(), track_hop_landing_reference=True, **cfg)
    sc = StateConverter(ctl.dyn)
    ts = np.linspace(0.0, 1.0, 11)
    land = SampledReference(Domain.LANDING, ts, ["L"], np.full(11, ctl.cfg.L_stand or 0.86), start_time=0.0)

    def tick():
        q, v = sc.from_simulator(sim)
        ctl.compute(q, v, sim.time)
    tick()
    ctl._enter(Domain.LANDING, sim.time)
    ctl.set_reference(land)
    tick()
    return sim, ctl, sc, ts, land, tick


def test_a_rebound_under_the_tracked_landing_plan_keeps_it_until_the_next_touch_downs_re_solve():
    """LANDING with the planner's landing reference (default ``rebound_keeps_landing_plan``): a LIFT_OFF
    (the feet left the ground under the plan) is recorded as a rebound and the plan goes on, past its end
    while the feet are in the air; the re-solve of the next touch-down replaces it and is tracked from its
    own start to its end; no fallback."""
    sim, ctl, sc, ts, land, tick = _tracking_a_landing_plan()
    ctl.on_contact_event(0, sim.time)              # LIFT_OFF while the plan is tracked
    tick()
    assert ctl.domain == Domain.LANDING and ctl.refs.get(Domain.LANDING) is land
    assert ctl.rebounds == [pytest.approx(sim.time)] and ctl.landing_fallback is None
    assert ctl.landing_fallbacks == []
    q, v = sc.from_simulator(sim)
    ctl.compute(q, v, 1.5)                         # past the plan's end, still in the air: not over
    assert ctl.domain == Domain.LANDING
    ctl.on_contact_event(1, 1.5)                   # the rebound's touch-down, and its re-solve
    again = SampledReference(Domain.LANDING, ts, ["L"], np.full(11, 0.8), start_time=1.5)
    ctl.set_reference(again)
    ctl.compute(q, v, 1.6)
    assert ctl.refs.get(Domain.LANDING) is again and ctl.domain == Domain.LANDING
    assert ctl.landing_fallbacks == []
    ctl.compute(q, v, 2.6)                         # the re-solve has ended on the ground: standing
    assert ctl.domain == Domain.STANDING and ctl.landing_fallbacks == []


def test_a_rebound_under_the_tracked_landing_plan_hands_over_to_the_own_landing_when_so_configured():
    """With ``rebound_keeps_landing_plan`` off: a LIFT_OFF under the tracked plan drops it for the
    controller's own landing, says why (``landing_fallback``), and keeps the re-solve of the next
    touch-down as ``landing_plan`` only; the next flight clears it."""
    sim, ctl, sc, ts, land, tick = _tracking_a_landing_plan(rebound_keeps_landing_plan=False)
    assert ctl.refs.get(Domain.LANDING) is land and ctl.landing_fallback is None
    ctl.on_contact_event(0, sim.time)              # LIFT_OFF while the plan is tracked
    tick()
    assert ctl.domain == Domain.LANDING and Domain.LANDING not in ctl.refs
    assert ctl.landing_fallback == "rebound" and [why for _, why in ctl.landing_fallbacks] == ["rebound"]
    again = SampledReference(Domain.LANDING, ts, ["L"], np.full(11, 0.8), start_time=sim.time)
    ctl.set_reference(again)                       # the re-solve at the next touch-down
    assert Domain.LANDING not in ctl.refs and ctl.landing_plan is again
    ctl._enter(Domain.FLIGHT, sim.time)
    assert ctl.landing_fallback is None


def test_the_landing_after_a_jump_is_tracked_in_the_jumps_heading_frame():
    """The landing plan's x is along the heading the jump started with (the planner turns the measured
    touch-down state into that frame: fslip_planner.heading_frame): the same plan tracked by a robot
    turned 0.3 rad about its pelvis gives the torques it gives the robot facing x."""
    ts = np.linspace(0.0, 1.0, 11)
    x0 = float(Simulator().com_position()[0])     # the standing COM x facing x: its x along the heading

    def landing_command(psi):
        sim, ctl = Simulator(), Controller(export_mjcf())
        q = sim.standing_qpos.copy()
        q[3:7] = [math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)]
        sim.reset(q)
        sc = StateConverter(ctl.dyn)
        qq, v = sc.from_simulator(sim)
        ctl.compute(qq, v, sim.time)
        ctl._heading_frame(qq)                       # the heading taken at the jump's start
        ctl._somersault = True
        ctl._enter(Domain.LANDING, sim.time)
        ctl.set_reference(SampledReference(Domain.LANDING, ts, ["L", "x_com"],
                                           np.column_stack([np.full(11, 0.8), x0 + 0.03 * ts]), start_time=0.0))
        ctl.u_prev = np.zeros(ctl.dyn.nu)             # (STANDING, in the world frame, differs: its x and y differ)
        u, _ = ctl.compute(qq, v, sim.time + 0.1)
        assert ctl.domain == Domain.LANDING and Domain.LANDING in ctl.refs
        return u

    u0, u_turned = landing_command(0.0), landing_command(0.3)
    assert np.max(np.abs(u_turned - u0)) < 1e-9 * np.max(np.abs(u0))


@pytest.mark.parametrize("stop", [0.32, None])
def test_a_landing_stops_the_pelvis_yaw_where_its_touch_down_rate_takes_it(stop):
    """LANDING brings the pelvis yaw to rest at psi0 + psi_dot0 * landing_yaw_stop / 2, not back to the
    feet's heading (a yaw rate with the flywheel spinning is a roll moment on the feet: config's field);
    STANDING then brings it to the feet.  ``None``: the feet's heading, as before."""
    sim = Simulator()
    q, v = sim.standing_qpos.copy(), np.zeros(sim.model.nv)
    v[5] = -1.2                                   # pelvis yaw rate (rad/s, local z of the upright pelvis)
    sim.reset(q, v)
    ctl = Controller(export_mjcf(), landing_yaw_stop=stop)
    sc = StateConverter(ctl.dyn)
    qq, vv = sc.from_simulator(sim)
    ctl.compute(qq, vv, sim.time)                 # standing seen (its leg length); then a touch-down
    ctl._somersault = True
    ctl._enter(Domain.LANDING, sim.time)
    ctl.compute(qq, vv, sim.time)
    psi0, psi_dot0 = ctl.ground.stand["p0"][2], ctl.ground.stand["pd0"][2]
    assert psi_dot0 == pytest.approx(-1.2, abs=1e-6)
    end = ctl.ground.targets(sim.time + ctl.cfg.blend_time + 0.1, True)["pelvis"]
    feet_yaw = ctl.ground.feet()[1]
    expected = feet_yaw if stop is None else psi0 + 0.5 * psi_dot0 * stop
    assert end.value[2] == pytest.approx(expected, abs=1e-9)
    assert end.d_value[2] == 0.0
    if stop is not None:                          # the stop, not the feet: 0.19 rad apart here
        assert abs(end.value[2] - feet_yaw) > 0.15
    ctl._enter(Domain.STANDING, sim.time + 2.0)   # STANDING turns the pelvis back to the feet
    ctl.compute(qq, vv, sim.time + 2.0)
    assert ctl.ground.targets(sim.time + 2.0 + ctl.cfg.blend_time + 0.1, False)["pelvis"].value[2] == \
        pytest.approx(feet_yaw, abs=1e-9)


def test_the_tracked_landing_scales_its_momentum_to_what_the_impact_left():
    """Landing.scale_to_impact: the landing plan is solved from the touch-down's pre-impact state; the
    impact then takes momentum out within a few ms (a backflip: -38.0 -> -35.4 kg m^2/s), which the plan,
    tracked as solved, put back.  ``landing_impact_time`` after the touch-down the plan's momentum is
    scaled by measured / planned (at most 1) and stays so; a rebound's new plan is scaled at its own
    impact; more momentum than planned, or a sign change, leaves the plan as it is."""
    from tsc_controller.config import ControllerConfig
    from tsc_controller.landing import Landing
    from tsc_controller.tsc import Desired
    H_now = {"H": -35.4}

    class Dyn:                                 # the centroidal pitch momentum is Ag[4] @ v
        v = np.array([1.0])

        @property
        def Ag(self):
            return np.array([[0.0]] * 4 + [[H_now["H"]]])
    landing = Landing.__new__(Landing)
    landing.cfg, landing.ground = ControllerConfig(), SimpleNamespace(dyn=Dyn())
    landing.impact = None

    def desired(ref, tau, H_plan=-38.0, rate=20.0):
        d = Desired(np.array([H_plan]), np.array([rate]), np.array([0.0]))
        landing.scale_to_impact(d, ref, tau)
        return float(d.value[0]), float(d.d_value[0])

    plan, rebound = object(), object()
    assert desired(plan, 0.005) == (-38.0, 20.0)                     # during the impact: as solved
    k = 35.4 / 38.0
    assert desired(plan, 0.010) == pytest.approx((-38.0 * k, 20.0 * k))
    H_now["H"] = -30.0                                             # measured once: later ticks keep k
    assert desired(plan, 0.2, H_plan=-20.0, rate=30.0) == pytest.approx((-20.0 * k, 30.0 * k))
    H_now["H"] = -40.0                                             # a new plan (a rebound's re-solve)
    assert desired(rebound, 0.0) == (-38.0, 20.0)
    assert desired(rebound, 0.02) == (-38.0, 20.0)                   # more than planned: as solved
    H_now["H"] = 5.0
    assert desired(object(), 0.02) == (-38.0, 20.0)                 # the other sign: as solved
    landing.cfg = ControllerConfig(landing_impact_time=0.0)
    H_now["H"] = -35.4
    assert desired(object(), 0.02) == (-38.0, 20.0)                 # off


class _LandingWheel:
    """A controller through a somersault's FLIGHT into its LANDING under a tracked plan, fed flywheel
    speeds that follow the cap's own model: each tick's speed is the last one plus ``drift`` plus
    dt m.u, m the flywheel's row of M^-1 B, its response to the torques the controller sent (a still
    pelvis otherwise)."""
    dt = 0.0005

    def __init__(self, case="somersault"):
        self.sim = Simulator()
        self.fw = self.sim.model.jnt_dofadr[self.sim.model.joint("flywheel").id]
        self.ctl = Controller(export_mjcf(), track_hop_landing_reference=True,
                              landing_flywheel_speed_cap=(case != "off"))
        self.sc = StateConverter(self.ctl.dyn)
        self.t, self.w, self.u = 0.0, -300.0, None
        self.tick(self.w)
        self.ctl._somersault = case != "hop"
        self.ctl._enter(Domain.FLIGHT, self.t)

    def tick(self, w):
        self.sim.data.qvel[self.fw] = self.w = w
        q, v = self.sc.from_simulator(self.sim)
        self.u = self.ctl.compute(q, v, self.t)[0]
        self.t += self.dt
        return self.u

    def next(self, drift):
        """The speed the last tick's torques and ``drift`` make (the model's)."""
        d = self.ctl.dyn
        return self.w + drift + self.dt * float(d.Minv[d.flywheel_v, d.motor_v] @ self.u)

    def land(self):
        self.ctl._enter(Domain.LANDING, self.t)
        ts = np.linspace(0.0, 1.0, 11)
        self.ctl.set_reference(SampledReference(Domain.LANDING, ts, ["L"], np.full(11, 0.8), start_time=self.t))


@pytest.mark.parametrize("case", ["somersault", "off", "hop"])
def test_a_somersaults_tracked_landing_holds_the_flywheel_at_its_flights_peak(case):
    """``landing_flywheel_speed_cap``: in the LANDING under the tracked plan after a somersault the
    flywheel motor does not spin the flywheel past its flight's peak speed (302 rad/s here): with the
    body's motion speeding the wheel up by 0.3 rad/s a tick, from 301 the wheel is braked so that its next
    speed is the peak (the model's speeds: no miss, no guard).  Off, or after a hop, the QP's torque is
    left alone and the wheel goes past the peak."""
    r = _LandingWheel(case)
    r.tick(-302.0)                                   # the flight's peak
    r.land()
    r.tick(-301.0)                                   # its first tick sets the cap
    assert r.ctl.flywheel_cap == pytest.approx(302.0) or case != "somersault"
    for _ in range(6):
        r.tick(r.next(-0.3))
    after = abs(r.next(-0.3))
    assert r.ctl.domain == Domain.LANDING and r.ctl.refs.get(Domain.LANDING) is not None
    if case == "somersault":
        assert r.ctl.flywheel_cap_guard == pytest.approx(0.0, abs=1e-9)
        assert after == pytest.approx(302.0, abs=1e-9)
    else:
        assert after > 302.1, after


def test_a_touch_down_faster_than_the_flights_peak_is_held_at_its_speed():
    """The cap is the landing's first speed when that is above the flight's peak (the state the flight's
    last torque left, the touch-down's sample, which the flight's window counts too): the first tick's
    torque holds the next speed there against the drift the impact tick brought."""
    r = _LandingWheel()
    r.tick(-302.0)                                   # the flight's peak, spinning up
    u_flight = r.u.copy()
    r.land()
    r.tick(-302.5)                                   # the touch-down's tick, 0.5 past it
    d = r.ctl.dyn
    m = d.Minv[d.flywheel_v, d.motor_v]
    drift = -0.5 - r.dt * float(m @ u_flight)        # that tick's change less what the flight's torques did
    assert r.ctl.flywheel_cap == pytest.approx(302.5)
    assert abs(r.next(drift)) == pytest.approx(302.5, abs=1e-9)


@pytest.mark.parametrize("miss", [0.5, -0.5])
def test_the_landings_flywheel_cap_aims_below_its_peak_by_the_largest_miss_of_its_prediction(miss):
    """``Controller.flywheel_cap_guard``: a tick whose flywheel comes out 0.5 rad/s faster than the last
    tick's prediction lowers the cap's aim by 0.5: with that drift going on, the next speeds are braked
    to 0.5 under the flight's peak (302).  A wheel slower than predicted leaves the aim at the peak."""
    r = _LandingWheel()
    r.tick(-302.0)
    r.land()
    r.tick(-301.0)
    r.tick(r.next(-0.3))
    r.tick(r.next(-0.3))
    assert r.ctl.flywheel_cap_guard == pytest.approx(0.0, abs=1e-9)
    r.tick(r.next(-0.3) - miss)                      # |w| off the prediction by ``miss``
    assert r.ctl.flywheel_cap_guard == pytest.approx(max(miss, 0.0), abs=1e-9)
    if miss > 0.0:
        for _ in range(4):                           # the drift's change (the miss) goes on
            r.tick(r.next(-0.3 - miss))
        assert abs(r.next(-0.3 - miss)) == pytest.approx(302.0 - miss, abs=1e-9)
