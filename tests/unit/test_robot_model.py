"""cassie_model: the figures a planner takes of the standing robot (standing_figures) are the
simulator's own at its start, bit for bit, without building a simulator."""
import numpy as np
import pytest
from cassie_model import robot_params as P
from cassie_model.model import standing_figures

from cassie_flip_sim.simulator import Simulator


@pytest.mark.parametrize("flywheel", ["I", "III"])
def test_standing_figures_are_the_simulators_start(flywheel):
    st = standing_figures(flywheel)
    sim = Simulator(flywheel)
    p, q = sim.pelvis_pose()
    assert st.mass == sim.total_mass()
    np.testing.assert_array_equal(st.com, sim.com_position())
    np.testing.assert_array_equal(st.pelvis_position, p)
    np.testing.assert_array_equal(st.pelvis_quaternion, q)
    d = sim.data
    legs = [np.linalg.norm(d.joint(f"{s}_foot").xanchor - d.joint(f"{s}_hip_pitch").xanchor) for s in ("left", "right")]
    assert st.leg_length == float(np.mean(legs))
    assert st.mass == pytest.approx(P.CASSIE_MASS + P.flywheel(flywheel).mass)
    assert 0.8 < st.leg_length < 0.9          # hip pitch axis to foot joint, standing
