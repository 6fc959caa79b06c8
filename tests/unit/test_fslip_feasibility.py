"""Malformed and impossible requests give named, quantified reasons."""
import math
import re

import numpy as np
import pytest

from fslip_planner import plan as P
from fslip_planner.feasibility import InfeasibleRequest


def test_apex_6m_names_the_limit():
    with pytest.raises(InfeasibleRequest) as e:
        P.plan_flip("backflip", apex_height=6.0)
    msg = str(e.value)
    assert "apex 6.00 m" in msg and "envelope" in msg
    m = re.search(r"max reachable apex ≈ ([0-9.]+) m", msg)
    assert m and 1.0 < float(m.group(1)) < 1.5
    assert re.search(r"lift-off speed ≈([0-9.]+) m/s", msg)
    assert float(re.search(r"over by ([0-9.]+) m", msg).group(1)) == pytest.approx(6.0 - float(m.group(1)), abs=0.01)


@pytest.mark.parametrize("kw, match", [
    (dict(kind="backflip", apex_height=math.nan), "finite"),
    (dict(kind="backflip", apex_height=-1.0), "positive"),
    (dict(kind="cartwheel"), "unknown kind"),
    (dict(kind="frontflip", forward_distance=100.0), "outside"),
    (dict(kind="frontflip", forward_distance=math.inf), "finite"),
    (dict(kind="backflip", platform_height=-0.3), "platform_height"),
    (dict(kind="backflip", flywheel="IV"), "unknown flywheel"),
    (dict(kind="backflip", apex_height=0.5), "standing COM height"),
])
def test_malformed_rejected(kw, match):
    kind = kw.pop("kind")
    with pytest.raises(ValueError, match=match):
        P.plan_flip(kind, **kw)
    with pytest.raises(ValueError, match=match):
        P.FlipSession(kind, **kw).jumping_reference()


SOMERSAULT = dict(motor_speed_scale=3.0, flywheel_torque=260.0)


def test_a_request_beyond_the_limits_names_what_binds_with_numbers():
    # a 1.4 m apex with 1 m forward: past what the leg's force can do within the stance; the elastic
    # optimum says by how much and which limits hold it there
    with pytest.raises(InfeasibleRequest) as e:
        P.plan_flip("frontflip", apex_height=1.4, forward_distance=1.0, **SOMERSAULT)
    msg = str(e.value)
    short = re.search(r"apex ([0-9.]+) m short of the request", msg)
    assert short and float(short.group(1)) >= 0.005, msg        # far above IPOPT's tolerance
    assert "binding: " in msg and e.value.limit in msg
    assert "most violated" not in msg and "IPOPT" not in msg


def test_a_flight_the_flywheel_cannot_turn_is_rejected_with_the_torque_it_needs():
    # the paper's robot: its 195 N·m flywheel cannot turn the body 2π − 2β in the ~0.4 s flight that
    # the reachable apex leaves (the falls: frontflip --distance 1.0, backflip)
    for kind, d in (("frontflip", 1.0), ("backflip", 0.0)):
        with pytest.raises(InfeasibleRequest) as e:
            P.plan_flip(kind, forward_distance=d)
        assert e.value.limit == "flywheel torque (flight)", str(e.value)
        need = float(re.search(r"needs ≥([0-9]+) N·m", str(e.value)).group(1))
        assert need > 195.0 and "gives 195 N·m" in str(e.value)
    # a longer flight on a stronger flywheel passes: tucked, it needs less than the flywheel has (with
    # the planned, shallower tuck more; the plan's figures say both)
    r = P.plan_flip("backflip", apex_height=1.3, **SOMERSAULT)
    assert 0.0 < r.figures["flight_torque_needed_tucked"] <= 260.0
    assert r.figures["flight_torque_needed"] > r.figures["flight_torque_needed_tucked"]


def test_flight_torque_needed_is_the_bang_bang_torque():
    # constant inertia, from rest: the most a body turns in T with |torque| <= tau and ending at
    # rest is tau T² / (4 I), so turning D needs 4 I D / T²
    from fslip_planner import flight as Fl
    I, D, T = 2.5, 5.8, 0.45

    def inertia(t):
        return np.full(np.shape(t), I)
    assert Fl.flight_torque_needed(-D, 0.0, T, inertia) == pytest.approx(4 * I * D / T ** 2, rel=1e-3)
    # a head start in the turn's direction lowers it; one against raises it
    assert Fl.flight_torque_needed(D, 3.0, T, inertia) < 4 * I * D / T ** 2 < Fl.flight_torque_needed(D, -3.0, T, inertia)
    assert Fl.flight_torque_needed(D, 0.0, 1e-3, inertia) == math.inf


def test_the_ladder_restarts_from_the_elastic_optimum_when_ipopt_fails(monkeypatch):
    from fslip_planner import jumping as Jm
    robot = P._Robot.get("I", 3.0, 260.0)
    ref = P.plan_flip("backflip", apex_height=1.3, **SOMERSAULT)
    strict = Jm.problem(robot.params, robot.L0)
    real = strict.solve
    calls = []

    def fail_first(task, start=None):
        calls.append(start is not None)
        if start is None:
            raise RuntimeError("IPOPT: Error_In_Step_Computation")
        return real(task, start=start)
    monkeypatch.setattr(strict, "solve", fail_first)
    r = P.plan_flip("backflip", apex_height=1.3, **SOMERSAULT)
    assert calls == [False, True] and r.figures["attempt"] == 1
    np.testing.assert_allclose(r.solution.X[-1], ref.solution.X[-1], rtol=1e-4, atol=1e-4)


def test_a_flip_the_robot_could_not_land_is_refused_with_the_sink_it_can_take():
    """Flip C on the paper's robot (the platform's 0.5 m make a flight the flywheel turns) touches down
    sinking ~3.4 m/s, faster than the published knees brake: planned, it is refused with the largest sink a
    landing plan exists from, the envelope named (it was accepted and fell in its landing); the same flip
    on the somersault robot (3x leg speeds) keeps its landing plan, as flips A-D and the hop do."""
    from fslip_planner.feasibility import LANDING_SINK_STEPS
    for plan in (lambda: P.plan_flip("frontflip", platform_height=0.5, forward_distance=0.6),
                 lambda: P.FlipSession("frontflip", platform_height=0.5, forward_distance=0.6).jumping_reference()):
        with pytest.raises(InfeasibleRequest) as e:
            plan()
        msg = str(e.value)
        assert e.value.limit == "knee torque–speed envelope (landing)", msg
        sink = float(re.search(r"COM sink ([0-9.]+) m/s", msg).group(1))
        most = float(re.search(r"exists from at most ≈([0-9.]+) m/s of sink", msg).group(1))
        assert sink > 3.0 and 1.0 < most < sink - sink / 2 ** LANDING_SINK_STEPS, msg
    s = P.FlipSession("frontflip", platform_height=0.5, forward_distance=0.6, apex_height=1.2, **SOMERSAULT)
    s.jumping_reference()
    assert s.result is not None and s._landing.has_solutions     # the nominal landing, a warm start later
    P.plan_flip("hop")                                            # the paper's robot hops and lands
