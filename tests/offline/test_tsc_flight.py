"""Closed loop without ROS: the flight phase (paper §IV-A, momentum transmission) and the fallback
landing of tsc_controller on the MuJoCo robot.

The robot is put in the air at a lift-off state (pelvis 0.4 m above standing, rising, whole body
pitching at 2π/T), with a FLIGHT reference whose pelvis pitch goes from 0 to ±2π with zero rate
at T (cubic), as fslip_planner.flight builds it.  The flywheel alone must turn the body: total
pitch momentum stays constant, the pelvis arrives at ±2π with a small rate, and the flywheel
ends up holding the momentum (eq. (momentumTrans))."""
import math

import mujoco
import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from launched_flip import flight_reference, launch
from tsc_controller import Controller, Domain, StateConverter
from tsc_controller.profiles import leg_catch

T_FLIGHT = 0.9


def run_flight(sign, pitch_output=True):
    sim = Simulator()
    w0 = launch(sim, sign, T_FLIGHT, 0.4)
    ctl = Controller(export_mjcf(), flight_pitch_output=pitch_output)
    sc = StateConverter(ctl.dyn)
    ctl._enter(Domain.FLIGHT, 0.0)                  # as after a LIFT_OFF event
    ctl.set_reference(flight_reference(sign, w0, T_FLIGHT))
    fw = sim.model.jnt_dofadr[mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_JOINT, "flywheel")]
    H, fw_speed = [], []
    while sim.time < 2 * T_FLIGHT:
        if sim.pop_events():                        # touch-down
            break
        q, v = sc.from_simulator(sim)
        u, info = ctl.compute(q, v, sim.time)
        sim.step(u)
        H.append(sim.centroidal_pitch_momentum())
        fw_speed.append(sim.data.qvel[fw])
    return dict(sim=sim, ctl=ctl, H=np.array(H), fw=np.array(fw_speed), t_td=sim.time)


@pytest.fixture(scope="module", params=[(1, True), (-1, True), (1, False), (-1, False)],
                ids=["frontflip", "backflip", "frontflip-momentum", "backflip-momentum"])
def flight(request):
    """Each turn with the pelvis pitch as FLIGHT's output and with eq. (momentumTrans)'s flywheel
    momentum (``flight_pitch_output`` False, the paper's Y^F_1)."""
    sign, pitch_output = request.param
    return sign, run_flight(sign, pitch_output)


def test_flight_turns_the_body_by_2pi(flight):
    sign, r = flight
    assert abs(r["t_td"] - T_FLIGHT) < 0.05                       # touched down when planned
    assert r["ctl"].pitch == pytest.approx(sign * 2 * math.pi, abs=0.25)   # unwrapped pelvis pitch
    w_pelvis = r["sim"].pelvis_twist("world")[1][1]
    assert abs(w_pelvis) < 0.5 * 2 * math.pi / T_FLIGHT           # slowed down for landing


def test_flight_conserves_momentum_and_stores_it_in_the_flywheel(flight):
    sign, r = flight
    H = r["H"][:-2]                                              # the last step is the impact
    assert np.ptp(H) < 0.01 * abs(H[0])                           # no external moment in the air
    # at touch-down the body has stopped turning: the flywheel holds most of the momentum
    I_fw = r["ctl"].flight.o_Hfw._I
    assert sign * r["fw"][-1] * I_fw > 0.6 * abs(H[0])
    assert np.max(np.abs(r["fw"])) < 400.0                        # rad/s: a physical flywheel speed


def test_leg_catch_profile():
    L0, v0, L1 = 0.86, -3.4, 0.86
    ts = np.linspace(0.0, 3.0, 3001)
    L, Ld, Ldd = (np.array(x) for x in zip(*[[float(a[0]) for a in leg_catch(L0, v0, L1, t)] for t in ts]))
    assert L[0] == pytest.approx(L0) and Ld[0] == pytest.approx(v0)
    assert L.min() >= 0.50 - 1e-9                                 # never below the leg's usable stroke
    assert np.max(np.abs(np.diff(L))) < 0.01                      # continuous
    assert np.max(np.abs(np.diff(Ld))) < 0.05
    assert L[-1] == pytest.approx(L1) and Ld[-1] == pytest.approx(0.0, abs=1e-9)
    assert Ldd.max() < 9.81 + 15.0 * 3 and Ldd[ts > 0.4].min() > -9.81   # never asks the feet to pull


def _drop(height, robot):
    """Drop the standing robot from ``height`` in FLIGHT with no reference (the fallback landing):
    (pelvis heights, z0, the time of a body contact or None, the controller)."""
    sim = Simulator(**robot)
    qpos = sim.standing_qpos.copy()
    z0 = qpos[2]
    qpos[2] += height
    sim.reset(qpos, None, in_contact=False)
    ctl = Controller(export_mjcf(sim.flywheel), **robot)
    sc = StateConverter(ctl.dyn)
    ctl._enter(Domain.FLIGHT, 0.0)
    zs = []
    while sim.time < 3.0:
        for ev in sim.pop_events():
            ctl.on_contact_event(int(ev.kind), ev.time)
        q, v = sc.from_simulator(sim)
        u, _ = ctl.compute(q, v, sim.time)
        sim.step(u)
        zs.append(sim.pelvis_pose()[0][2])
        if sim.body_contacts():
            return zs, z0, sim.time, ctl
    return zs, z0, None, ctl


@pytest.mark.parametrize("height, robot", [
    (0.3, dict(motor_speed_scale=3.0, flywheel_torque=260.0)),     # the somersaults' robot: 2.4 m/s
    (0.1, {}),                                                     # the paper's robot: 1.4 m/s
])
def test_drop_lands_and_stands(height, robot):
    """A drop in FLIGHT with no reference: the fallback landing catches it (the pelvis sinks less than
    0.3 m) and the robot ends standing at its height."""
    zs, z0, fell, ctl = _drop(height, robot)
    assert fell is None, f"fell at t={fell:.3f}"
    assert min(zs) > z0 - 0.3
    assert zs[-1] == pytest.approx(z0, abs=0.01)
    assert ctl.domain == Domain.STANDING


@pytest.mark.xfail(strict=True, reason="the paper's robot (Cassie's published torque-speed curve) falls from "
                   "a 0.2 m drop: its knees and feet are back-driven past half their no-load speeds, where "
                   "the curve's torque drops to zero (docs/robots.md)")
def test_paper_robot_catches_a_02_m_drop():
    zs, z0, fell, ctl = _drop(0.2, {})
    assert fell is None, f"fell at t={fell:.3f}"
    assert zs[-1] == pytest.approx(z0, abs=0.01)


def test_flight_reference_is_sampled_flight_lead_ahead():
    """The FLIGHT reference is tracked ``flight_lead`` ahead of the time since the lift-off event (the
    turn ends before the planned touch-down): the desired pelvis pitch at a tick is the reference's
    value at (t - t_lift_off + flight_lead)."""
    sim = Simulator()
    w0 = launch(sim, 1, T_FLIGHT, 0.4)
    ref = flight_reference(1, w0, T_FLIGHT)
    sc = None
    for lead in (0.0, 0.01, 0.05):
        ctl = Controller(export_mjcf(), flight_lead=lead)
        sc = sc or StateConverter(ctl.dyn)
        ctl._enter(Domain.FLIGHT, 0.0)
        ctl.set_reference(ref)
        q, v = sc.from_simulator(sim)
        ctl.dyn.update(q, v)
        ctl._update_pitch()
        t = 0.2
        _, outs, des = ctl._task(t)
        k = [o.name for o in outs].index("pitch")
        want = ref.sample(t + lead)["phi_pitch"]
        assert des[k].value[0] == pytest.approx(want[0]) and des[k].d_value[0] == pytest.approx(want[1])
    assert ref.sample(0.25)["phi_pitch"][0] != pytest.approx(ref.sample(0.2)["phi_pitch"][0])


def _wrapped(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


def _in_flight(sim, ref, **cfg):
    """A controller in FLIGHT from t = 0 under ``ref`` (no lead), its model at the simulator's state,
    as after a LIFT_OFF event; ``cfg``: ControllerConfig overrides."""
    ctl = Controller(export_mjcf(), flight_lead=0.0, **cfg)
    ctl._enter(Domain.FLIGHT, 0.0)
    ctl.set_reference(ref)
    q, v = StateConverter(ctl.dyn).from_simulator(sim)
    ctl.dyn.update(q, v)
    ctl._update_pitch()
    return ctl


@pytest.mark.parametrize("sign", [-1, 1])
def test_preplaced_legs_turn_to_their_touch_down_angle_on_the_pelvis_between_t1_half_and_t1(sign):
    """``flight_legs_preplaced``: the hip pitches leave the joint hold at T1/2 and each leg's angle
    follows a min-jerk from where it is then (no step) to the touch-down placement, which it reaches at
    T1 with the value and rate that the placement after T1 asks (no step there either); off, the hold
    runs to T1 as before."""
    sim = Simulator()
    w0 = launch(sim, sign, T_FLIGHT, 0.4)
    ref = flight_reference(sign, w0, T_FLIGHT)
    T1 = ref.parameters["T1"]
    for on in (True, False):
        ctl = _in_flight(sim, ref, flight_legs_preplaced=on)
        fl = ctl.flight

        def task(t):
            _, outs, des = ctl._task(t)
            return outs, des

        outs, _ = task(0.0)                                       # the lift-off posture is taken here
        assert fl.o_j_pre in outs and fl.o_beta[0] not in outs
        outs, des = task(0.5 * T1)
        if not on:
            assert fl.o_j_pre in outs and fl.o_beta[0] not in outs
            continue
        assert fl.o_j_mid in outs and fl.o_j_pre not in outs and "left_hip_pitch" not in fl.o_j_mid.joints
        k = outs.index(fl.o_beta[0])
        y = fl.o_beta[0].evaluate(ctl.dyn)[0][0]
        assert des[k].value[0] == pytest.approx(y, abs=1e-12)      # starts where the leg is
        _, end = task(T1 - 1e-9)
        outs_after, after = task(T1)
        ka = outs_after.index(fl.o_beta[0])
        assert fl.o_j_post in outs_after
        assert _wrapped(end[k].value[0] - after[ka].value[0]) == pytest.approx(0.0, abs=1e-6)
        assert end[k].d_value[0] == pytest.approx(after[ka].d_value[0], abs=1e-6)
        # and that placement is the touch-down's leg angle on the pelvis: beta + theta = -beta_liftoff + theta_T
        th_T = ref.sample(ref.duration)["phi_pitch"][0]
        assert _wrapped(after[ka].value[0] + ctl.pitch - (-ref.parameters["beta_liftoff"] + th_T)) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize("pitch_output", [True, False], ids=["pitch", "momentum"])
def test_past_the_plans_end_the_flight_holds_its_last_pitch_at_rest(pitch_output):
    """A touch-down later than planned (an in-place backflip's comes ~10 ms after its flight plan's end):
    past the FLIGHT reference's end the pelvis pitch is asked to stay at the plan's last value at rest.
    The last sample's acceleration is the plan's braking to rest; held on, it turned the pelvis back
    (+1.16 rad/s at a backflip's touch-down, against the turn) and spun the flywheel past what the
    turn needed, which the landing then had to take out."""
    sim = Simulator()
    w0 = launch(sim, -1, T_FLIGHT, 0.4)
    ref = flight_reference(-1, w0, T_FLIGHT)
    ctl = _in_flight(sim, ref, flight_pitch_output=pitch_output)
    fl = ctl.flight
    seen = {}
    orig = fl._momentum_transmission
    fl._momentum_transmission = lambda smp, pitch: seen.setdefault("smp", smp) and orig(smp, pitch)
    th, dth, ddth = (c[-1, 0] for c in (ref.value, ref.d_value, ref.dd_value))
    assert abs(ddth) > 1.0 and abs(dth) < 1e-9                  # the plan ends at rest, still braking

    def pitch_desired(t):
        seen.clear()
        _, outs, des = ctl._task(t)
        if pitch_output:
            d = des[outs.index(fl.o_pitch)]
            return d.value[0], d.d_value[0], d.dd_value[0]
        return seen["smp"]["phi_pitch"]

    v_end, d_end, dd_end = pitch_desired(ref.duration - 1e-9)
    assert dd_end == pytest.approx(ddth, rel=1e-6)
    for t in (ref.duration + 1e-3, ref.duration + 0.05):
        assert pitch_desired(t) == (pytest.approx(th, abs=1e-12), 0.0, 0.0)
