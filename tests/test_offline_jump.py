"""The planned jump on the full robot, without ROS (tests/offline_flip.py wires simulator, planner and
controller as the node graph does): the robot follows the FSLIP jumping plan to its end — lift-off
when the plan ends, not earlier (the torque-only QP chattering against the leaf springs used to
unload the feet 0.1 s into the push) — and, for a backflip, turns backwards through most of a
somersault in the air.  (With the published motors its flight is too short to land; see
test_offline_flip.py for the somersault robot, which lands.)"""
import pytest

import offline_flip as of


@pytest.fixture(scope="module")
def backflip():
    return of.run("backflip", seconds=2.75, start=1.1525)


def test_backflip_lifts_off_when_the_jumping_plan_ends(backflip):
    plan_end = backflip["session"].t_start + backflip["session"].result.solution.T
    lo = [t for k, t in backflip["events"] if k == 0]
    assert lo and lo[0] == pytest.approx(plan_end, abs=0.03)


def test_backflip_turns_backwards_in_the_air(backflip):
    ev = backflip["events"]
    lo = next(t for k, t in ev if k == 0)
    td = next((t for k, t in ev if k == 1 and t > lo), None)
    assert td is not None and td - lo > 0.3
    pitch_at_td = backflip["pitch"][backflip["t"] <= td][-1]
    assert pitch_at_td < -4.7                  # more than 270° backwards (rad, unwrapped pelvis pitch)
