"""Whole flips on the full robot without ROS (tests/offline_flip.py wires simulator, planner and
controller as the node graph does): jump planned by the FSLIP planner, flight with the planned pelvis
pitch, landing, standing.  The robot is the somersault robot of the README: leg motors' no-load speeds
x3 and a 260 N*m flywheel motor, apex 1.3 m (0.52-0.58 s of flight).  With the published leg motors no
flip fits its flight time; with the 195 N*m flywheel the frontflip's planned turn does not (the
flywheel saturates and the body over-rotates or the legs fold).

Landing tallies (scripts/bench_landings.py) are in docs/measurements.md; the start time below lands
the backflip, the frontflip and flip A, and the tests guard that the pipeline keeps doing so."""
import math

import numpy as np
import pytest

import offline_flip as of
from cassie_model.model import export_mjcf
from cassie_flip_sim.simulator import Simulator
from tsc_controller import Controller

SCALE = 3.0
FLYWHEEL_TORQUE = 260.0


def robot():
    sim = Simulator(motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    return sim, ctl


@pytest.fixture(scope="module")
def backflip():
    sim, ctl = robot()
    z_stand = float(sim.standing_qpos[2])
    r = of.run("backflip", seconds=10.5, start=0.5, sim=sim, controller=ctl, every=10,
               apex_height=1.3, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    r["z_stand"] = z_stand
    return r


def test_backflip_touches_down_upright_after_one_turn(backflip):
    ev, t, pitch = backflip["events"], backflip["t"], backflip["pitch"]
    lo = next(tt for k, tt in ev if k == 0)
    td = next(tt for k, tt in ev if k == 1 and tt > lo)
    assert td - lo > 0.45                                   # the planned flight, not a stumble
    i = np.searchsorted(t, td)
    assert pitch[i] == pytest.approx(-2 * math.pi, abs=0.15)
    rate = (pitch[i] - pitch[i - 2]) / (t[i] - t[i - 2])
    assert abs(rate) < 2.5


def _axis_tilt_at_t1(r):
    """Degrees between the pelvis y axis and world y at the end of the tuck (T1 after lift-off)."""
    lo, ref = next((t, ref) for t, ref in r["references"] if ref.domain == 2)     # the FLIGHT reference
    T1 = ref.parameters["T1"]
    return math.degrees(r["axis_tilt"][np.searchsorted(r["t"], lo + T1)])


def _nudged_backflip(axis_weight=None):
    """The backflip up to 0.5 s after its lift-off, its pelvis given a roll impulse (1 N*m*s about
    world x over 20 ms) at the lift-off: the transverse disturbance the flight has to hold against."""
    sim, ctl = robot()
    if axis_weight is not None:
        ctl.flight.o_axis.weight = axis_weight
    pelvis = sim.model.body("pelvis").id
    st = {"lo": None}

    def nudge(sim, ctl, u, info):
        if st["lo"] is None and info["domain"] == 2:
            st["lo"] = sim.time
        on = st["lo"] is not None and sim.time < st["lo"] + 0.02
        sim.data.xfrc_applied[pelvis, 3] = 50.0 if on else 0.0

    return of.run("backflip", seconds=2.1, start=0.5, sim=sim, controller=ctl, every=10, on_step=nudge,
                  apex_height=1.3, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)


def test_flight_holds_the_flywheel_axis_through_the_tuck():
    """The somersault turns about the robot's intermediate principal axis with the flywheel spinning
    against the body: unstable.  After a roll impulse at the lift-off the flight's axis output keeps
    the pelvis y axis within a third of the tilt the same backflip has at T1 without it.  It turns the
    pelvis with the legs; since their hip pitch and knee are held equal (gains["leg_symmetry"]) it has
    less to turn it with: 2.8 deg at T1 before, ~14 now (docs/tuning.md, gains.leg_symmetry; the
    backflip falls after this impulse either way)."""
    held, loose = _axis_tilt_at_t1(_nudged_backflip()), _axis_tilt_at_t1(_nudged_backflip(axis_weight=0.0))
    assert held < 20.0 and held < 0.4 * loose, (held, loose)          # measured: 13.6 and 43.5 deg


def test_backflip_lands_and_stands(backflip):
    sim, ctl = backflip["sim"], backflip["ctl"]
    assert backflip["fell"] is None, f"body contact at t={backflip['fell']:.3f}"
    of.assert_stands(sim, ctl, backflip["z_stand"])                      # ... flywheel momentum out
    assert backflip["pitch"][-1] == pytest.approx(-2 * math.pi, abs=0.1)   # one whole turn, backwards


def _touch_down_lean_and_flywheel_peaks(r):
    """(COM x - feet x at the first touch-down after the lift-off, the flywheel's peak speed in the
    flight and in the landing, rad/s)."""
    lo, td = of.lift_off_touch_down(r["events"])
    st = next(s for k, s in r["event_states"] if k == 1)
    dom, fw = np.asarray(r["dom"]), np.abs(np.asarray(r["fw"]))
    return float(st.com[0] - st.support_center[0]), fw[dom == 2].max(), fw[dom == 3].max()


@pytest.mark.parametrize("preplaced", [False, True])
def test_backflip_legs_preplaced_touch_down_where_the_plan_puts_the_feet(backflip, preplaced):
    """Placed after T1 only, the backflip's legs swing while the flywheel stops the body at its torque
    limit and land ahead of the plan's placement (COM behind the feet, where the plan puts it ahead).
    The landing plan takes the momentum out through the feet' centre of pressure (landing.LANDING_COST),
    so the landing spins the flywheel less than 10 % above its flight peak (from this start 0.5 %, 7 %
    without ``landing_impact_time``; ~30 % above while the plan took it out with the flywheel torque
    alone).  Turned to their touch-down angle on the pelvis during
    the tuck's extension (``flight_legs_preplaced``) they touch down with the COM ahead of the feet."""
    if preplaced:
        sim, _ = robot()
        ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE,
                         flight_legs_preplaced=True)
        r = of.run("backflip", seconds=10.5, start=0.5, sim=sim, controller=ctl, every=10, apex_height=1.3,
                   motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
        assert of.outcome(r, "backflip") == "landed"
    else:
        r = backflip
    lean, fw_flight, fw_landing = _touch_down_lean_and_flywheel_peaks(r)
    mirrored = -r["session"].result.lift_off["x"]        # the plan's COM - foot at the touch-down
    assert mirrored > 0.0
    assert fw_landing < 1.10 * fw_flight, fw_landing / fw_flight
    if preplaced:
        assert lean == pytest.approx(mirrored, abs=0.06)
    else:
        assert lean < 0.0


def test_the_backflips_landing_spins_the_flywheel_no_faster_than_its_flight(backflip):
    """From this start the backflip touches down with its COM behind the feet and its landing plan grows
    the momentum (the feet's vertical force acts ahead of the COM); tracked, that went into the flywheel,
    3,660 rpm against 3,641 in the flight.  Under ``landing_flywheel_speed_cap`` the landing's flywheel
    is held just under the flight's peak (the rest goes into the body's pitch): at most the flight's peak,
    every step (measured 0.0041 rad/s under; 2 rad/s over without the cap, 0.0033 over with the first
    cap's prediction from the flywheel's torque alone); the robot lands and stands
    (test_backflip_lands_and_stands)."""
    lean = _touch_down_lean_and_flywheel_peaks(backflip)[0]
    assert lean < 0.0
    from flip_tools.tracking import peak_abs
    lo, td = of.lift_off_touch_down(backflip["events"])
    t, fw = backflip["t_step"], backflip["fw_step"]                      # every step, as bench_landings
    assert np.any(t == td)                  # stamped as the events: the touch-down's sample in both windows
    fw_flight, fw_landing = peak_abs(t, fw, lo, td), peak_abs(t, fw, td, float(t[-1]))
    assert fw_landing <= fw_flight, (fw_landing, fw_flight)


def test_the_landing_lets_go_of_the_flights_flywheel_torque(backflip):
    """The flight ends braking the body with the flywheel (~-170 N*m); under the tracked landing
    plan the QP smooths its torque at a tenth of the legs' (``flywheel_smoothing``), so that it stops within a
    few ticks of the touch-down: the flywheel gains less than 30 rpm in the 20 ms after it (fully
    smoothed it went on ~25 ms and gained ~90 rpm)."""
    from flip_tools.summary import RPM_PER_RADPS
    lo, td = of.lift_off_touch_down(backflip["events"])
    t, fw = np.asarray(backflip["t"]), np.abs(np.asarray(backflip["fw"])) * RPM_PER_RADPS
    i0, i1 = np.searchsorted(t, td), np.searchsorted(t, td + 0.02)
    assert fw[i0:i1 + 1].max() - fw[i0] < 30.0, fw[i0:i1 + 1]


def test_backflip_on_the_flywheel_momentum_output_touches_down_as_planned():
    """FLIGHT on eq. (momentumTrans)'s flywheel momentum, the paper's Y^F_1 (``flight_pitch_output``
    False), with its desired rate: the pelvis touches down within 3 deg of the flight plan's final pitch,
    the robot lands and stands, and the landing spins the flywheel at most 5 % faster than the flight.
    With the desired rate left at 0 the output's lag (kp 20 1/s) left the body turning: touch-down at
    -377 deg against the plan's -357 (bench_landings: 12,557 rpm in the landing against 3,653 in the
    flight, not at rest)."""
    sim, ctl = robot()
    ctl.cfg.flight_pitch_output = False
    z_stand = float(sim.standing_qpos[2])
    r = of.run("backflip", seconds=9.5, start=0.5, sim=sim, controller=ctl, every=10,
               apex_height=1.3, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    lo, td = of.lift_off_touch_down(r["events"])
    flight_ref = next(ref for _, ref in r["references"] if ref.domain == 2)
    planned = flight_ref.column("phi_pitch")[0][-1]
    i = np.searchsorted(r["t"], td)
    assert math.degrees(abs(r["pitch"][i] - planned)) < 3.0, (math.degrees(r["pitch"][i]), math.degrees(planned))
    assert r["fell"] is None
    of.assert_stands(sim, ctl, z_stand)
    fw = np.abs(r["fw"])
    assert fw[r["dom"] == 3].max() < 1.05 * fw[r["dom"] == 2].max()


def touch_down_state(r):
    lo = next(t for k, t in r["events"] if k == 0)
    return next(st for k, st in r["event_states"] if k == 1 and st.t > lo)


@pytest.mark.parametrize("psi", [-0.3, -0.2, 0.1, 0.2, 0.25, 0.3])
def test_backflip_of_a_robot_facing_another_way_lands_as_one_facing_x(backflip, psi):
    """The somersault is in the plane the robot faces (the controller's heading frame in JUMPING,
    FLIGHT and LANDING; the planner's plans along the heading it stood with): turned about the
    vertical, the same backflip lands with the feet as far ahead of the COM along its heading (with
    the jump and flight written in world x-z, 0.04 rad made it fall).  Turned 0.1, 0.25 or ±0.3 rad it
    touches down one foot first; it fell sideways 1.6 s later until the landing stopped turning the pelvis
    back to the feet's heading (config ``landing_yaw_stop``, docs/tuning.md)."""
    sim, ctl = robot()
    z_stand = float(sim.standing_qpos[2])
    q = sim.standing_qpos.copy()
    q[3:7] = [math.cos(psi / 2), 0.0, 0.0, math.sin(psi / 2)]
    sim.reset(q)
    r = of.run("backflip", seconds=10.5, start=0.5, sim=sim, controller=ctl, every=10,
               apex_height=1.3, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    of.assert_stands(sim, ctl, z_stand)
    assert r["pitch"][-1] == pytest.approx(-2 * math.pi, abs=0.1)
    ahead = lambda st, a: float((st.support_center - st.com)[:2] @ [math.cos(a), math.sin(a)])
    assert ahead(touch_down_state(r), psi) == pytest.approx(ahead(touch_down_state(backflip), 0.0), abs=0.02)
    assert ctl.landing_fallbacks == []                   # the landing plan tracked throughout


def test_frontflip_lands_and_stands():
    sim, ctl = robot()
    z_stand = float(sim.standing_qpos[2])
    r = of.run("frontflip", seconds=10.5, start=0.5, sim=sim, controller=ctl, every=10, apex_height=1.3,
               motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    ev, t, pitch = r["events"], r["t"], r["pitch"]
    lo = next(tt for k, tt in ev if k == 0)
    td = next(tt for k, tt in ev if k == 1 and tt > lo)
    assert td - lo > 0.45
    # one turn at touch-down; the pelvis may be past it (the foot placement outranks it late in the flight:
    # ControllerConfig.somersault_beta_weight), the feet are where the landing needs them
    assert pitch[np.searchsorted(t, td)] == pytest.approx(2 * math.pi, abs=0.25)
    st = next(st for k, st in r["event_states"] if k == 1 and st.t > lo)
    assert abs(st.com[0] - st.support_center[0]) < 0.14          # 0.16 m with the leg angles weighted as the pitch
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    of.assert_stands(sim, ctl, z_stand)
    assert pitch[-1] == pytest.approx(2 * math.pi, abs=0.1)                        # one whole turn, forwards


def test_forward_frontflip_lands_and_stands():
    """Flip A (1 m forward, apex 1.2 m): it touches down at ~1.2 m/s forward with its feet ~0.3 m
    ahead of the COM, and the tracked landing plan stops it over its feet (the controller's own
    landing let the COM run past the toes from 12 of 15 start times, the flywheel holding it there)."""
    sim, ctl = robot()
    z_stand = float(sim.standing_qpos[2])
    x0 = float(sim.com_position()[0])
    r = of.run("frontflip", seconds=12.0, start=0.5, sim=sim, controller=ctl, every=10, apex_height=1.2,
               forward_distance=1.0, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    ev, pitch = r["events"], r["pitch"]
    lo = next(tt for k, tt in ev if k == 0)
    td = next(tt for k, tt in ev if k == 1 and tt > lo)
    assert td - lo > 0.4
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert [k for k, tt in ev if tt > td] == []                     # no rebound off the ground
    of.assert_stands(sim, ctl, z_stand)
    assert pitch[-1] == pytest.approx(2 * math.pi, abs=0.1)
    assert float(sim.com_position()[0]) - x0 > 0.8                  # asked: 1.0 m


def test_a_backflip_that_touches_down_yawing_lands_and_stands():
    """A backflip whose flight ends with the pelvis yawing at ~1.2 rad/s (read noise of 1e-4 seeded as
    scripts/bench_landings.py --noise 1e-4 seeds its 0.9 s start) touches down with ~43 kg*m^2/s in the
    flywheel, where a pelvis yaw rate is a roll moment on the feet: the landing stops the yaw and leaves
    it there (``landing_yaw_stop``) and the robot lands and stands.  Turning the pelvis back to the feet's
    heading within the landing's 0.8 s blend, it unloaded one foot and fell sideways 1.5 s after the
    touch-down."""
    from flip_tools.perturb import read_noise
    sim, ctl = robot()
    # the case needs a flight that ends yawing: the legs' symmetry in the flight (gains["leg_symmetry"])
    # removes most of that yaw, so it is off here (the landing is what is tested)
    ctl.flight.o_sym.weight = 0.0
    z_stand = float(sim.standing_qpos[2])
    plant = read_noise(sim, 1e-4, round(0.9 * 1e4), 0.9)
    yaw_rate = {}

    def at_touch_down(sim, ctl, u, info):
        if info["domain"] == 3 and not yaw_rate:
            yaw_rate["td"] = float(sim.pelvis_twist("world")[1][2])

    r = of.run("backflip", seconds=9.0, start=0.9, sim=sim, controller=ctl, every=10, plant=plant,
               on_step=at_touch_down, apex_height=1.3, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    assert abs(yaw_rate["td"]) > 0.8, yaw_rate             # the case: it touches down yawing
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert of.outcome(r, "backflip", pitch_end=plant.pitch) == "landed"
    of.assert_stands(sim, ctl, z_stand)


def test_a_raised_ground_frontflip_that_rebounds_tracks_the_re_solve_of_its_next_touch_down():
    """Flip D (ground 0.1 m higher than the planner is told, 0.6 m forward, apex 1.2 m) with read noise
    seeded as scripts/bench_landings.py --noise 1e-4 seeds its 1.3 s start: the feet leave the ground
    again under the tracked landing plan (a rebound: with the plan's momentum scaled to what the impact
    left, ``landing_impact_time``, or the landing's flywheel held at its flight's peak speed,
    ``landing_flywheel_speed_cap``, none of the 30 start times rebounds, so the case is made with both
    off, as 1 of 30 did then).  The plan goes on,
    the planner re-solves the next touch-down from its measured state and the controller tracks that
    (paper §III-C): the own landing never runs, and the robot lands and stands.  (Flip C's 0.4 s start
    was the case while its landing plans took the momentum out with the flywheel torque alone; none of
    its 30 rebounds now.)"""
    from cassie_model.model import Scenario
    from flip_tools.perturb import read_noise
    sim = Simulator(scenario=Scenario.raised_landing(0.1), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE,
                     landing_impact_time=0.0, landing_flywheel_speed_cap=False)
    z_stand = float(sim.standing_qpos[2]) + 0.1            # on the raised landing area
    plant = read_noise(sim, 1e-4, round(1.3 * 1e4), 1.3)
    r = of.run("frontflip", seconds=10.3, start=1.3, sim=sim, controller=ctl, every=10, plant=plant,
               apex_height=1.2, forward_distance=0.6, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    assert ctl.rebounds, "the case: the feet leave the ground under the tracked landing plan"
    landings = [ref for _, ref in r["references"] if ref.domain == 3]
    assert len(landings) >= 2 and all(ref.figures["fallback"] == 0.0 for ref in landings)
    assert ctl.landing_fallbacks == []                   # the own landing never ran
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert of.outcome(r, "frontflip", pitch_end=plant.pitch) == "landed"
    of.assert_stands(sim, ctl, z_stand)


def test_a_platform_frontflip_planned_with_the_knees_tangential_load_lands_with_a_slower_flywheel():
    """Flip C with read noise seeded for its 0.7 s start, planned with
    ``knee_tangential`` (the knee torque of the tangential foot force counted): it lands on the tracked
    plans (no own landing, no fallback attempt) and its flywheel turns slower in the landing than in the
    flight (paper: the landing plan takes the momentum out through the ground; 2,924 / 2,475 rpm
    measured; with the share in the landing only, the default, 2,828 / 2,604; with the landing's H_pitch
    weight at 1 and the landing planned on the axial force alone it had peaked above its flight's,
    2,828 / 2,914)."""
    from cassie_model.model import Scenario
    from flip_tools.perturb import read_noise
    from flip_tools.summary import RPM_PER_RADPS
    from flip_tools.tracking import peak_abs
    sim = Simulator(scenario=Scenario.platform(0.5), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    z_stand = float(sim.standing_qpos[2]) - 0.5
    plant = read_noise(sim, 1e-4, round(0.7 * 1e4), 0.7)
    r = of.run("frontflip", seconds=11.0, start=0.7, sim=sim, controller=ctl, every=10, plant=plant,
               apex_height=1.2, forward_distance=0.6, platform_height=0.5, motor_speed_scale=SCALE,
               flywheel_torque=FLYWHEEL_TORQUE, knee_tangential=True)
    assert r["session"].robot.params.knee_tangential
    landings = [ref for _, ref in r["references"] if ref.domain == 3]
    assert landings and all(ref.figures["fallback"] == 0.0 for ref in landings)
    assert ctl.landing_fallbacks == []
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert of.outcome(r, "frontflip", pitch_end=plant.pitch) == "landed"
    of.assert_stands(sim, ctl, z_stand)
    lo, td = of.lift_off_touch_down(r["events"])
    w = np.asarray(r["fw"]) * RPM_PER_RADPS
    flight, landing = peak_abs(r["t"], w, lo, td), peak_abs(r["t"], w, td, float(r["t"][-1]))
    assert landing < 0.95 * flight, (flight, landing)


def backflip_from_a_stance_with_one_foot_ahead(start=1.5, shift=0.0024):
    """A backflip (read noise 1e-4 seeded by its start) of a robot that stood from the standing posture
    with its left hip pitch -``shift`` and its right +``shift`` rad: one foot ~4 mm ahead of the other, as
    a landing leaves them (docs/measurements.md, "The legs held symmetric in the flight").  Returns (run,
    plant, per-FLIGHT-tick hip-pitch difference of the legs, pelvis yaw rate at the first LANDING tick)."""
    from flip_tools.perturb import read_noise
    sim = Simulator(motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    m = sim.model
    q = sim.standing_qpos.copy()
    q[m.jnt_qposadr[m.joint("left_hip_pitch").id]] -= shift
    q[m.jnt_qposadr[m.joint("right_hip_pitch").id]] += shift
    sim.reset(q)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    plant = read_noise(sim, 1e-4, round(start * 1e4), start)
    apart, td = [], {}
    ql, qr = (m.jnt_qposadr[m.joint(f"{s}_hip_pitch").id] for s in ("left", "right"))

    def watch(sim, ctl, u, info):
        if info["domain"] == 2:
            apart.append(float(sim.data.qpos[ql] - sim.data.qpos[qr]))
        elif info["domain"] == 3 and not td:
            td["yaw_rate"] = float(sim.pelvis_twist("world")[1][2])

    r = of.run("backflip", seconds=start + 8.0, start=start, sim=sim, controller=ctl, every=10, plant=plant,
               on_step=watch, apex_height=1.3, motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    return r, plant, np.array(apart), td.get("yaw_rate")


def test_a_backflip_from_a_stance_with_one_foot_ahead_lands():
    """Issue 26, item 1 (a second flip falls): a first landing leaves one foot a few mm ahead of the
    other, and from such a stance backflips fell in their flight (6 of 6 start times, 1.5-2.0 s, with the
    legs left to their per-leg outputs: ``gains["leg_symmetry"]`` weight 0).  The push leaves the legs
    0.014 rad apart in hip pitch; the legs drifted further apart through the flight (0.13 rad by T1),
    the pelvis yawed, and the flywheel's momentum growing after T1 along the yawed pelvis axis turned
    into a yaw rate of 1.5-2 rad/s at the touch-down, which rolled the robot over.  With the legs' hip
    pitch and knee held equal in the flight, they stay within 0.03 rad of each other, the touch-down comes with
    little yaw rate, and the robot lands."""
    r, plant, apart, yaw_rate = backflip_from_a_stance_with_one_foot_ahead()
    assert apart.size > 0 and yaw_rate is not None
    assert np.abs(apart).max() < 0.03, np.abs(apart).max()
    assert abs(yaw_rate) < 0.8, yaw_rate
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    assert of.outcome(r, "backflip", pitch_end=plant.pitch) == "landed"



def test_the_backflips_landing_plan_is_scaled_to_what_the_impact_left(backflip):
    """The touch-down's impact takes part of the momentum out before the plan (solved from the
    pre-impact state) is tracked; 10 ms after it the plan's momentum is scaled to what is left
    (``landing_impact_time``), by less than 1 here, and the landing's flywheel then peaks within 2 % of
    its flight peak (measured 3,660 against 3,641 rpm with ``landing_flywheel_speed_cap`` off, 3,621 with it;
    3,901 without the scaling)."""
    k = backflip["ctl"].landing.impact[1]
    assert 0.8 < k < 1.0, k
    _, fw_flight, fw_landing = _touch_down_lean_and_flywheel_peaks(backflip)
    assert fw_landing < 1.02 * fw_flight, (fw_landing, fw_flight)
