"""Closed loop without ROS: landing after a full somersault (the fallback landing of tsc_controller;
and, at the end, a planned flip whose tracked landing plan the COM falls behind).

The robot is launched 0.1 m above standing height with the whole-body pitch rate of a 2π rotation in
T, runs FLIGHT with a cubic pelvis-pitch reference (momentum transmission into the flywheel), touches
down upright with 20–25 kg·m²/s of centroidal pitch momentum in the flywheel and a sink rate of
~3.3 m/s, and must land with no LANDING reference (fallback: leg catch, momentum removal at
``landing_moment`` with the COM shifted against the needed centre of pressure, per-foot contact) and
end standing: pelvis at its standing height, upright, nothing but the feet on the ground."""

import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from launched_flip import flight_reference, launch
import offline_flip as of
from offline_flip import assert_stands
from tsc_controller import Controller, Domain, StateConverter


# The launched somersaults land on the robot the somersaults are done with (docs/robots.md): with
# Cassie's published torque-speed curve the paper's robot's knees are back-driven past half their
# no-load speed by such a touch-down and give way (the launched backflip fell at 1.74 s)
ROBOT = dict(motor_speed_scale=3.0, flywheel_torque=260.0)


def run_flip(sign, T, t_end=6.0, axis_output=True, **config):
    sim = Simulator(**ROBOT)
    z_stand = float(sim.standing_qpos[2])
    ctl = Controller(export_mjcf(sim.flywheel), **ROBOT, **config)
    if not axis_output:
        ctl.flight.o_axis.weight = 0.0
    sc = StateConverter(ctl.dyn)
    ctl.compute(*sc.from_simulator(sim), 0.0)      # it has seen the robot standing (its standing leg length)
    w0 = launch(sim, sign, T, 0.1)
    ctl._enter(Domain.FLIGHT, 0.0)                  # as after a LIFT_OFF event
    ctl.set_reference(flight_reference(sign, w0, T))
    H_td, fell, trace = None, None, []
    for k in range(int(t_end / sim.timestep)):
        for ev in sim.pop_events():
            ctl.on_contact_event(int(ev.kind), ev.time)
            if H_td is None and int(ev.kind) == 1:
                H_td = sim.centroidal_pitch_momentum()
        q, v = sc.from_simulator(sim)
        u, _ = ctl.compute(q, v, sim.time)
        # (time, domain, H_pitch weight of the own landing, centroidal pitch momentum)
        trace.append((sim.time, int(ctl.domain), ctl.landing.o_H.weight, sim.centroidal_pitch_momentum()))
        sim.step(u)
        if k % 20 == 0 and sim.body_contacts():
            fell = sim.time
            break
    return dict(sim=sim, ctl=ctl, z_stand=z_stand, H_td=H_td, fell=fell, trace=trace)


# (on the somersaults' robot each of these lands with the default controller, and with the older
# landing settings — catch_decel 15 m/s², landing_moment 12 N·m, no flight axis output — as well)
@pytest.mark.parametrize("sign,T", [(-1, 0.7), (1, 0.6)], ids=["backflip_0.7s", "frontflip_0.6s"])
def test_flip_lands_and_stands(sign, T):
    r = run_flip(sign, T)
    sim, ctl = r["sim"], r["ctl"]
    assert r["H_td"] is not None and abs(r["H_td"]) > 15.0      # touched down with the flip's momentum
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert_stands(sim, ctl, r["z_stand"])                        # ... and the flywheel's momentum is gone


def test_own_landing_lets_the_flywheel_take_the_impact_then_removes_the_momentum():
    """The own landing starts with a light H_pitch weight (the flywheel may take the moment of the
    braking ground forces), back to its ``gains`` weight after ``landing_H_ramp``, and lasts until
    the momentum is below ``landing_H_done`` (the standing that follows removes it no slower).  The
    momentum comes out at ``landing_moment``, from ``landing_late_after`` on at ``landing_moment_late``."""
    r = run_flip(1, 0.6)
    ctl, tr = r["ctl"], r["trace"]
    cfg = ctl.cfg
    landing = [x for x in tr if x[1] == Domain.LANDING]
    assert landing, "never landed"
    t_td = landing[0][0]
    assert landing[0][2] == pytest.approx(cfg.landing_H_weight, abs=1e-3)
    assert all(x[2] >= cfg.landing_H_weight - 1e-9 for x in landing)
    late = [x[2] for x in landing if x[0] > t_td + cfg.landing_H_ramp]
    assert late and all(w == pytest.approx(cfg.gains["H_pitch"][0]) for w in late)
    end = next(i for i, x in enumerate(tr) if x[0] > t_td and x[1] == Domain.STANDING)
    assert abs(tr[end - 1][3]) <= cfg.landing_H_done + 0.5        # (sim and controller differ a little)
    assert r["fell"] is None

    def H_at(dt):
        return next(x[3] for x in tr if x[0] >= t_td + dt)
    # the momentum comes out at landing_moment, then (from landing_late_after) at landing_moment_late
    assert cfg.landing_moment_late > cfg.landing_moment
    early = (H_at(1.0) - H_at(1.75)) / 0.75
    late = (H_at(cfg.landing_late_after + 0.5) - H_at(cfg.landing_late_after + 1.0)) / 0.5
    assert early == pytest.approx(cfg.landing_moment, rel=0.1)
    assert late == pytest.approx(cfg.landing_moment_late, rel=0.1)


def _backflip_195(landing_gains=None):
    """The 195 N*m design study's backflip (the paper's flywheel motor, the flight on the flywheel
    momentum output, no flight-torque check) with read noise seeded as scripts/bench_landings.py
    --noise 1e-4 seeds its 0.3 s start; returns the run, the plant and the controller's COM x error
    (m) at every tick of the tracked landing plan."""
    from flip_tools.perturb import read_noise
    robot = dict(ROBOT, flywheel_torque=195.0)
    cfg = {} if landing_gains is None else {"landing_gains": landing_gains}
    sim = Simulator(**robot)
    ctl = Controller(export_mjcf(sim.flywheel), **robot, flight_pitch_output=False, **cfg)
    plant = read_noise(sim, 1e-4, round(0.3 * 1e4), 0.3)
    com_err = []

    def on_step(sim, ctl, u, info):
        if info["domain"] == Domain.LANDING and "errors" in info:
            com_err.append(float(np.ravel(info["errors"]["com"])[0]))
    r = of.run("backflip", seconds=6.0, start=0.3, sim=sim, controller=ctl, every=10, plant=plant,
               on_step=on_step, apex_height=1.3, flight_check=False, **robot)
    r["z_stand"] = float(sim.standing_qpos[2])
    return r, plant, np.array(com_err)


def test_the_landing_brings_a_com_that_lags_its_plan_back_over_the_feet():
    """The 195 N*m backflip from its 0.3 s start: late in the landing plan (the legs rising from the
    catch) the COM falls behind the plan and the centre of pressure reaches the heels.  Only a ground
    force whose moment changes H can then bring the COM forward; with the landing's H_pitch weight at
    its ground value 1 the QP kept H on the plan, the COM ran 0.18 m behind it, off the heels, and the
    robot fell backwards 1.8 s after its touch-down.  With ``landing_gains`` H_pitch weight 0.3 the COM
    stays within a few cm of the plan and the robot lands (docs/tuning.md, landing_gains)."""
    r, plant, com_err = _backflip_195()
    assert com_err.size > 1000, "the landing plan was tracked"
    assert np.abs(com_err).max() < 0.03, np.abs(com_err).max()
    landings = [ref for _, ref in r["references"] if ref.domain == 3]
    assert len(landings) == 1 and landings[0].figures["fallback"] == 0.0
    assert r["ctl"].landing_fallbacks == []
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert of.outcome(r, "backflip", pitch_end=plant.pitch) == "landed"
    assert_stands(r["sim"], r["ctl"], r["z_stand"])
