"""Closed loop without ROS: cassie_flip_sim.Simulator (MuJoCo, 2 kHz) + tsc_controller.Controller
holding the standing pose (the vertical slice of the project)."""
import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from tsc_controller import Controller, Domain, StateConverter


def run_standing(seconds, controller=None, sim=None):
    sim = sim or Simulator()
    ctl = controller or Controller(export_mjcf())
    sc = StateConverter(ctl.dyn)
    z0 = sim.pelvis_pose()[0][2]
    n = int(round(seconds / sim.timestep))
    dz, statuses, grf_pred, grf_sim = np.zeros(n), {}, [], []
    for k in range(n):
        q, v = sc.from_simulator(sim)
        u, info = ctl.compute(q, v, sim.time)
        assert u.shape == (11,) and np.all(np.isfinite(u))
        statuses[info["qp_status"]] = statuses.get(info["qp_status"], 0) + 1
        sim.step(u)
        dz[k] = sim.pelvis_pose()[0][2] - z0
        grf_pred.append(sum(info["grf"]))
        grf_sim.append(sum(sim.foot_normal_forces()))
        if dz[k] < -0.2:
            break
    return dict(dz=dz[: k + 1], statuses=statuses, ctl=ctl, sim=sim, grf_pred=np.array(grf_pred),
                grf_sim=np.array(grf_sim))


@pytest.fixture(scope="module")
def standing_run():
    return run_standing(5.0)


def test_standing_holds_height_for_5s(standing_run):
    r = standing_run
    assert len(r["dz"]) == 10000, "fell"
    assert np.max(np.abs(r["dz"])) < 0.01, f"pelvis height drift {np.max(np.abs(r['dz'])):.4f} m"
    assert r["ctl"].domain == Domain.STANDING


def test_standing_stays_upright_and_in_place(standing_run):
    sim = standing_run["sim"]
    p, quat = sim.pelvis_pose()
    assert abs(p[0]) < 0.03 and abs(p[1]) < 0.03
    # pelvis tilt (angle of the body z axis from vertical) small
    w, x, y, z = quat
    zz = 1 - 2 * (x * x + y * y)
    assert np.degrees(np.arccos(np.clip(zz, -1, 1))) < 3.0
    assert np.linalg.norm(sim.pelvis_twist("world")[0]) < 0.01


def test_standing_qp_solves_and_predicts_weight(standing_run):
    r = standing_run
    n_ok = r["statuses"].get("solved", 0)
    assert n_ok >= 0.99 * len(r["dz"]), r["statuses"]
    # after settling, predicted total normal force = weight = simulated normal force
    w = r["sim"].total_mass() * 9.81
    pred, simf = r["grf_pred"][-2000:], r["grf_sim"][-2000:]
    assert np.allclose(pred, w, rtol=0.03)
    assert np.allclose(simf, w, rtol=0.03)


def _standing_with_load(seconds, load, controller=None):
    """Standing (somersault robot), with ``load(t) -> (force, torque)`` applied at the pelvis; returns
    per-step time, foot normal forces (left, right), feet heading (rad) and whether a body hit the ground."""
    sim = Simulator(motor_speed_scale=3.0, flywheel_torque=260.0)
    ctl = controller or Controller(export_mjcf(sim.flywheel), motor_speed_scale=3.0, flywheel_torque=260.0)
    sc = StateConverter(ctl.dyn)
    pelvis = sim.model.body("pelvis").id
    log = dict(t=[], fn=[], heading=[], fell=False)
    while sim.time < seconds:
        f, tau = load(sim.time)
        sim.data.xfrc_applied[pelvis, :3], sim.data.xfrc_applied[pelvis, 3:] = f, tau
        q, v = sc.from_simulator(sim)
        u, _ = ctl.compute(q, v, sim.time)
        sim.step(u)
        log["t"].append(sim.time)
        log["fn"].append(sim.foot_normal_forces())
        log["heading"].append(ctl.ground.feet()[1])
        if sim.body_contacts():
            log["fell"] = True
            break
    return {k: (np.asarray(v) if k != "fell" else v) for k, v in log.items()}


def test_standing_comes_to_rest_after_a_sideways_push():
    """A 75 N, 0.1 s sideways push at the pelvis (7.5 N*s): within 5 s the robot stands still on both
    feet.  (With the COM's kd 20 in STANDING it rocked from one foot to the other without end and fell.)"""
    push = lambda t: ((0.0, 75.0, 0.0) if 1.0 <= t < 1.1 else (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
    r = _standing_with_load(6.0, push)
    assert not r["fell"]
    last = r["t"] > 5.0
    diff = r["fn"][last, 0] - r["fn"][last, 1]
    assert np.std(diff) < 20.0, f"normal force difference left-right swings {np.std(diff):.0f} N (std)"
    assert np.min(r["fn"][last]) > 100.0, "a foot is (nearly) unloaded: still rocking"


def test_feet_do_not_creep_under_a_steady_twist():
    """A steady 15 N*m yaw torque at the pelvis, well inside what the feet's friction holds (~210 N on
    each foot, toe and heel 0.2 m apart, mu 1): the feet stay where they are.  (With MuJoCo's default
    pyramidal cone and impratio 1 the soft contacts let them turn by 49 deg in 3.5 s; 0.5 deg now.)"""
    twist = lambda t: ((0.0, 0.0, 0.0), (0.0, 0.0, 15.0) if t >= 0.5 else (0.0, 0.0, 0.0))
    r = _standing_with_load(4.0, twist)
    assert not r["fell"]
    turned = np.degrees(abs(r["heading"][-1] - r["heading"][int(0.5 / 0.0005)]))
    assert turned < 1.0, f"the feet turned {turned:.2f} deg on the ground"
