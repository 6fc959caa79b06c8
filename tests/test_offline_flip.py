"""Whole flips on the full robot without ROS (tests/offline_flip.py wires simulator, planner and
controller as the node graph does): jump planned by the FSLIP planner, flight with the planned pelvis
pitch, landing, standing.  The robot is the somersault robot of the README: leg motors' no-load speeds
x3 and a 260 N*m flywheel motor, apex 1.3 m (0.52-0.58 s of flight).  With the published leg motors no
flip fits its flight time; with the 195 N*m flywheel the frontflip's planned turn does not (the
flywheel saturates and the body over-rotates or the legs fold).

Measured offline (start times 0.3 ... 0.7 s): touch-down within 0.1 rad of -+2pi from every start time;
the backflip lands from 3 of 5, the frontflip from 1 of 5 (it falls 0.3-0.5 s after touch-down or
while the flywheel's momentum is taken out).  The start time below lands both; the tests guard that
the pipeline keeps doing so."""
import math

import numpy as np
import pytest

import offline_flip as of
from cassie_flip_sim.model import export_mjcf
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
    r = of.run("backflip", seconds=6.0, start=0.5, sim=sim, controller=ctl, every=10,
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


def test_backflip_lands_and_stands(backflip):
    sim, ctl = backflip["sim"], backflip["ctl"]
    assert backflip["fell"] is None, f"body contact at t={backflip['fell']:.3f}"
    of.assert_stands(sim, ctl, backflip["z_stand"])                      # ... flywheel momentum out
    assert backflip["pitch"][-1] == pytest.approx(-2 * math.pi, abs=0.1)   # one whole turn, backwards


def test_frontflip_lands_and_stands():
    sim, ctl = robot()
    z_stand = float(sim.standing_qpos[2])
    r = of.run("frontflip", seconds=6.5, start=0.5, sim=sim, controller=ctl, every=10, apex_height=1.3,
               motor_speed_scale=SCALE, flywheel_torque=FLYWHEEL_TORQUE)
    ev, t, pitch = r["events"], r["t"], r["pitch"]
    lo = next(tt for k, tt in ev if k == 0)
    td = next(tt for k, tt in ev if k == 1 and tt > lo)
    assert td - lo > 0.45
    assert pitch[np.searchsorted(t, td)] == pytest.approx(2 * math.pi, abs=0.15)   # upright at touch-down
    assert r["fell"] is None, f"body contact at t={r['fell']:.3f}"
    of.assert_stands(sim, ctl, z_stand)
    assert pitch[-1] == pytest.approx(2 * math.pi, abs=0.1)                        # one whole turn, forwards
