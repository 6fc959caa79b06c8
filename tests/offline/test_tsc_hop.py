"""Closed loop without ROS: a vertical hop with zero flip momentum — push up (JUMPING), flight with the
feet off the ground (FLIGHT), land (LANDING) and stand (STANDING).

The JUMPING reference is hand made (fslip_planner.plan is not available yet): leg length dips 8 cm
with a min-jerk profile, holds, then a quintic push reaching 0.9 m/s leg extension rate with -g
acceleration at its end; H_pitch = 0.  No FLIGHT / LANDING reference is sent, so the controller's
fallbacks are exercised: flight holds the lift-off posture and keeps the pelvis level through the
flywheel (momentum transmission, eq. (momentumTrans)); landing/standing blend to the stand pose.
"""
import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from tsc_controller import Controller, Domain, SampledReference, StateConverter


def _quintic_coeffs(T, x0, v0, a0, x1, v1, a1):
    A = np.array([[0, 0, 0, 0, 0, 1], [0, 0, 0, 0, 1, 0], [0, 0, 0, 2, 0, 0],
                  [T ** 5, T ** 4, T ** 3, T ** 2, T, 1], [5 * T ** 4, 4 * T ** 3, 3 * T ** 2, 2 * T, 1, 0],
                  [20 * T ** 3, 12 * T ** 2, 6 * T, 2, 0, 0]])
    return np.linalg.solve(A, [x0, v0, a0, x1, v1, a1])


def hop_reference(L_stand, t0, dip=0.08, push=0.22, v_to=0.9, T_dip=0.5, T_hold=0.1, dt=0.002):
    ts = np.arange(0.0, T_dip + T_hold + push + 1e-9, dt)
    L, dL, ddL = [], [], []
    c = _quintic_coeffs(push, L_stand - dip, 0, 0, L_stand - dip + 0.55 * push * v_to, v_to, -9.81)
    for t in ts:
        if t < T_dip:
            x = t / T_dip
            L.append(L_stand - dip * (10 * x ** 3 - 15 * x ** 4 + 6 * x ** 5))
            dL.append(-dip * (30 * x ** 2 - 60 * x ** 3 + 30 * x ** 4) / T_dip)
            ddL.append(-dip * (60 * x - 180 * x ** 2 + 120 * x ** 3) / T_dip ** 2)
        elif t < T_dip + T_hold:
            L.append(L_stand - dip), dL.append(0.0), ddL.append(0.0)
        else:
            s = t - T_dip - T_hold
            L.append(np.polyval(c, s)), dL.append(np.polyval(np.polyder(c), s))
            ddL.append(np.polyval(np.polyder(c, 2), s))
    n = len(ts)
    z = np.zeros(n)
    return SampledReference(Domain.JUMPING, ts, ["L", "H_pitch"], np.c_[L, z], np.c_[dL, z], np.c_[ddL, z],
                            start_time=t0, plan_id=1)


@pytest.fixture(scope="module")
def hop_run():
    sim = Simulator()
    ctl = Controller(export_mjcf())
    sc = StateConverter(ctl.dyn)
    z0 = sim.pelvis_pose()[0][2]
    log = dict(t=[], z=[], dom=[], fn=[], events=[])
    for k in range(int(5.5 / sim.timestep)):
        if k == int(0.8 / sim.timestep):      # the reference arrives ahead of its start time
            ctl.set_reference(hop_reference(ctl.cfg.L_stand, 1.0))
        for ev in sim.pop_events():
            log["events"].append((int(ev.kind), ev.time))
            ctl.on_contact_event(int(ev.kind), ev.time)
        q, v = sc.from_simulator(sim)
        u, info = ctl.compute(q, v, sim.time)
        sim.step(u)
        log["t"].append(sim.time)
        log["z"].append(sim.pelvis_pose()[0][2] - z0)
        log["dom"].append(info["domain"])
        log["fn"].append(sum(sim.foot_normal_forces()))
        if log["z"][-1] < -0.3:
            break
    log = {k: np.array(v) for k, v in log.items()}
    log.update(sim=sim, ctl=ctl)
    return log


def test_hop_goes_through_all_domains(hop_run):
    doms = hop_run["dom"]
    order = [int(d) for i, d in enumerate(doms) if i == 0 or doms[i - 1] != d]
    assert order[:4] == [Domain.STANDING, Domain.JUMPING, Domain.FLIGHT, Domain.LANDING], order
    assert order[-1] == Domain.STANDING
    ev = hop_run["events"]
    assert ev[0][0] == 0 and ev[1][0] == 1, ev        # LIFT_OFF then TOUCH_DOWN


def test_hop_flight_has_feet_off(hop_run):
    dom, fn, t = hop_run["dom"], hop_run["fn"], hop_run["t"]
    flight = dom == Domain.FLIGHT
    assert t[flight].max() - t[flight].min() > 0.1          # > 0.1 s airborne
    assert np.all(fn[flight][2:-2] == 0.0)                # (event latency: first and last steps)
    assert hop_run["z"].max() > 0.04                        # pelvis rose


def test_hop_lands_and_stands(hop_run):
    sim = hop_run["sim"]
    assert len(hop_run["z"]) == int(5.5 / sim.timestep), "fell"
    assert abs(hop_run["z"][-1]) < 0.01
    p, (w, x, y, z) = sim.pelvis_pose()
    tilt = np.degrees(np.arccos(np.clip(1 - 2 * (x * x + y * y), -1, 1)))
    assert tilt < 3.0
    assert np.linalg.norm(sim.pelvis_twist("world")[0]) < 0.02
    assert hop_run["ctl"].domain == Domain.STANDING
