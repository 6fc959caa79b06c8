"""fslip_planner.pitch_turns: a flight plan in the controller's unwrapped pitch, after earlier flips
(planner_node and the offline runner share it)."""
import math

import numpy as np
import pytest

from fslip_planner.pitch_turns import PitchTurns



class _Ref:
    def __init__(self, first, last):
        self.names = ["phi_pitch", "L"]
        self.value = np.array([[first, 0.9], [0.5 * (first + last), 0.6], [last, 0.9]])


def test_turns_count_at_each_touch_down_from_where_the_flight_plan_ended():
    t = PitchTurns()
    first = _Ref(0.02, -2 * math.pi + 0.06)            # a backflip's flight plan from the wrapped pitch
    t.shift_flight(first)
    assert first.value[0, 0] == 0.02                    # nothing turned before it
    t.touch_down(-0.05)                                 # measured (wrapped) at its touch-down
    assert t.turns == pytest.approx(-2 * math.pi)
    second = _Ref(0.03, -2 * math.pi + 0.06)
    t.shift_flight(second)
    assert second.value[0, 0] == pytest.approx(0.03 - 2 * math.pi) and second.value[0, 1] == 0.9
    t.touch_down(0.1)
    assert t.turns == pytest.approx(-4 * math.pi)
    t.touch_down(3.0)                                   # a touch-down without a flight plan: no change
    assert t.turns == pytest.approx(-4 * math.pi)


def test_offline_second_flip_is_planned_in_the_controllers_pitch():
    """Two backflips on one simulator and controller, as `flip request` on a running graph: the second
    flight plan starts at the controller's unwrapped pitch (-2pi), as planner_node sends it."""
    from cassie_model.model import export_mjcf
    from cassie_flip_sim.simulator import Simulator
    from flip_tools import offline as of
    from tsc_controller import Controller
    robot = dict(motor_speed_scale=3.0, flywheel_torque=260.0)
    sim = Simulator(**robot)
    ctl = Controller(export_mjcf(sim.flywheel), **robot)
    r1 = of.run("backflip", seconds=10.1, start=1.1, sim=sim, controller=ctl, every=50, apex_height=1.3, **robot)
    assert of.outcome(r1, "backflip") == "landed"
    assert r1["turns"].turns == pytest.approx(-2 * math.pi) and ctl.pitch == pytest.approx(-2 * math.pi, abs=0.05)
    t2 = sim.time + 0.5
    r2 = of.run("backflip", seconds=t2 + 1.3, start=t2, sim=sim, controller=ctl, every=50, turns=r1["turns"],
                apex_height=1.3, **robot)
    flight = [ref for _, ref in r2["references"] if ref.domain == 2]
    assert flight, r2["events"]
    phi = flight[0].value[:, flight[0].names.index("phi_pitch")]
    assert phi[0] == pytest.approx(-2 * math.pi, abs=0.15)                   # where the controller's pitch is
    assert phi[-1] - phi[0] == pytest.approx(-2 * math.pi, abs=0.3)          # one more backward turn
