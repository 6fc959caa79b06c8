"""fslip_planner.plan_geometry (no ROS): a reference's COM path and foot targets in the world frame,
and the FSLIP's ground force, from the fields a FlipReference carries."""
import math

import numpy as np
import pytest

from fslip_planner.plan_geometry import FLIGHT, JUMPING, LANDING, G, ground_force, reference_geometry


def synthetic_ground(n=101, T=0.2):
    """A ground reference: leg L = 0.9 → 1.0 m, lean β 0 → 0.2 rad, the COM over a foot at x = 0.3 m
    (r = L − 0.02, the leg_offset the tests give)."""
    t = np.linspace(0.0, T, n)
    L, beta = 0.9 + 0.5 * t, np.linspace(0.0, 0.2, n)
    x = 0.3 + (L - 0.02) * np.sin(beta)
    names = ["H_pitch", "L", "x_com", "phi_pitch"]
    return t, names, np.column_stack([np.zeros(n), L, x, beta])


def test_ground_reference_path_keeps_the_start_com_and_finds_the_stance_foot():
    t, names, value = synthetic_ground()
    com = np.array([0.3, 0.05, 0.95])
    g = reference_geometry(LANDING, 10.0, t, names, value, {"leg_offset": 0.02}, com=com, foot_z=0.02)
    np.testing.assert_allclose(g.t, 10.0 + t)
    np.testing.assert_allclose(g.com[0], com)                              # starts at the robot's COM
    np.testing.assert_allclose(g.com[:, 0], value[:, 2])                   # x is the reference's x_com
    assert np.all(g.com[:, 1] == com[1])
    r = value[:, 1] - 0.02
    np.testing.assert_allclose(g.com[:, 2] - com[2], r * np.cos(value[:, 3]) - r[0], atol=1e-12)
    np.testing.assert_allclose(g.pitch, value[:, 3])
    (label, foot), = g.feet
    assert label == "stance"
    np.testing.assert_allclose(foot, [0.3, 0.05, 0.02])
    q = g.quaternions()[-1]                                                # pitch about +y
    assert q[0] == q[2] == 0.0 and math.isclose(2 * math.atan2(q[1], q[3]), 0.2)


def test_jumping_path_continues_with_the_planned_flight_to_its_touch_down():
    """After the stance: ballistic from the lift-off velocity of the plan's figures for its flight
    time (apex ż²/2g above the lift-off), then the touch-down foot, the lift-off lean mirrored."""
    t, names, value = synthetic_ground()
    com = np.array([0.3, 0.0, 0.95])
    T, xd, zd = 0.5, 0.4, 2.45
    g = reference_geometry(JUMPING, 1.0, t, names, value, {"leg_offset": 0.02, "beta_liftoff": -0.2},
                           com=com, flight_time=T, liftoff_xdot=xd, liftoff_zdot=zd, foot_z=0.52,
                           landing_foot_z=0.02)
    n = len(t)
    lo = g.com[n - 1]
    assert g.t[-1] == pytest.approx(1.0 + t[-1] + T) and np.all(np.diff(g.t) > 0)
    assert g.com[:, 2].max() == pytest.approx(lo[2] + zd ** 2 / (2 * G), abs=1e-4)
    end = g.com[-1]
    np.testing.assert_allclose(end, lo + [xd * T, 0.0, zd * T - 0.5 * G * T * T])
    assert np.all(g.pitch[n:] == g.pitch[n - 1])                          # no pitch planned yet: held
    feet = dict(g.feet)
    np.testing.assert_allclose(feet["stance"], [0.3, 0.0, 0.52])
    r_lo = value[-1, 1] - 0.02
    np.testing.assert_allclose(feet["touchdown"], [end[0] + r_lo * math.sin(0.2), 0.0, 0.02])


def test_flight_path_is_ballistic_from_the_measured_lift_off():
    n, T = 60, 0.45
    t = np.linspace(0.0, T + 0.02, n)                                    # samples beyond the flight time
    names = ["phi_pitch", "L"]
    value = np.column_stack([np.linspace(0.1, -6.0, n), np.full(n, 0.95)])
    com, v = np.array([0.1, 0.0, 1.1]), np.array([0.3, 0.0, 2.2])
    g = reference_geometry(FLIGHT, 3.0, t, names, value, {"beta_liftoff": 0.15, "leg_offset": 0.02},
                           com=com, com_velocity=v, flight_time=T, landing_foot_z=0.02)
    assert g.t[-1] <= 3.0 + T + 1e-12 and len(g.t) == np.count_nonzero(t <= T)
    tau = g.t - 3.0
    np.testing.assert_allclose(g.com[:, 0], com[0] + v[0] * tau)
    np.testing.assert_allclose(g.com[:, 2], com[2] + v[2] * tau - 0.5 * G * tau ** 2)
    np.testing.assert_allclose(g.pitch, value[:len(tau), 0])
    (label, foot), = g.feet
    x_end = com[0] + v[0] * T
    assert label == "touchdown"
    np.testing.assert_allclose(foot, [x_end - 0.93 * math.sin(0.15), 0.0, 0.02])
    with pytest.raises(ValueError):
        reference_geometry(FLIGHT, 3.0, t, names, value, {}, com=com)     # no lift-off velocity


@pytest.fixture(scope="module")
def frontflip_plan():
    """The somersault robot's frontflip A (1 m forward), planned offline, as its message carries it."""
    from fslip_planner.plan import FlipSession
    s = FlipSession("frontflip", apex_height=1.2, forward_distance=1.0, motor_speed_scale=3.0,
                    flywheel_torque=260.0)
    return s, s.jumping_reference()


def test_planned_frontflip_touches_down_where_the_plan_lands(frontflip_plan):
    """The jumping reference's own numbers put the touch-down foot 1 m ahead of the stance foot
    (where FlipSession predicts the touch-down), and the path's apex above the lift-off as its
    lift-off ż gives it."""
    s, ref = frontflip_plan
    f = ref.figures
    com0 = np.array([ref.parameters["x_start"], 0.0, 0.94])
    g = reference_geometry(JUMPING, 0.75, ref.t, ref.names, ref.value, ref.parameters, com=com0,
                           flight_time=f["flight_time"], liftoff_xdot=f["liftoff_xdot"],
                           liftoff_zdot=f["liftoff_zdot"], foot_z=0.02)
    feet = dict(g.feet)
    assert feet["stance"][0] == pytest.approx(ref.parameters["x_start"], abs=1e-9)
    td = s._touchdown_state(None)                    # the planner's own prediction: COM − foot at touch-down
    assert feet["touchdown"][0] - g.com[-1, 0] == pytest.approx(-td[0], abs=1e-9)
    assert feet["touchdown"][0] - feet["stance"][0] == pytest.approx(1.0, abs=0.02)
    n = len(ref.t)
    assert g.com[:, 2].max() - g.com[n - 1, 2] == pytest.approx(f["liftoff_zdot"] ** 2 / (2 * G), abs=1e-3)


def test_fslip_ground_force_carries_the_weight_then_the_jumps_momentum(frontflip_plan):
    """Fz = m g at the standing start and the impulse of the stance is the lift-off momentum:
    ∫(Fz − m g) dt = m ż, ∫Fx dt = m ẋ (the plan's figures), within 1 %."""
    _, ref = frontflip_plan
    m = ref.parameters["fslip_mass"]
    f = ground_force(ref.t, ref.names, ref.value, ref.d_value, ref.dd_value, m, ref.parameters["leg_offset"])
    assert f["Fz"][0] == pytest.approx(m * G, rel=1e-3)
    assert f["Fz"].max() > 1.5 * m * G                                     # the push-off
    zd = np.trapezoid(f["Fz"] - m * G, f["t"]) / m
    xd = np.trapezoid(f["Fx"], f["t"]) / m
    assert zd == pytest.approx(ref.figures["liftoff_zdot"], rel=0.01)
    assert xd == pytest.approx(ref.figures["liftoff_xdot"], rel=0.01, abs=0.01)
    flight = ground_force([0.0, 0.1], ["phi_pitch", "L"], np.zeros((2, 2)), np.zeros((2, 2)),
                          np.zeros((2, 2)), m)
    assert flight is None
