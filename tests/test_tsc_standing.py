"""Closed loop without ROS: cassie_flip_sim.Simulator (MuJoCo, 2 kHz) + tsc_controller.Controller
holding the standing pose (the vertical slice of the project)."""
import numpy as np
import pytest

from cassie_flip_sim.model import export_mjcf
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
