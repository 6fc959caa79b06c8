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


def test_the_flywheel_of_a_published_description_is_read_back():
    """cassie_model.description.flywheel_inertial: the flywheel body's mass and diagonal inertia from
    an MJCF string (planner_node compares the simulator's with its own), None without a flywheel body,
    ValueError for text that is not XML."""
    import pytest

    from cassie_model.description import flywheel_inertial
    from cassie_model.model import export_mjcf
    from cassie_model.robot_params import flywheel
    for name in ("I", "III"):
        mass, diag = flywheel_inertial(export_mjcf(name))
        assert mass == pytest.approx(flywheel(name).mass) and diag[1] == pytest.approx(flywheel(name).inertia_pitch)
    assert flywheel_inertial("<mujoco><worldbody><body name='pelvis'/></worldbody></mujoco>") is None
    with pytest.raises(ValueError):
        flywheel_inertial("not xml")
