"""cassie_flip_sim.perturbation: sim_node's ``plant`` parameter is checked as the sweep's knobs are,
and sim_node builds the same perturbed robot and terrain the offline sweep does (flip_tools.perturb)."""
import numpy as np
import pytest

from cassie_flip_sim.perturbation import PlantPerturbation, parse_plant
from cassie_flip_sim.sim_node import make_scenario
from cassie_flip_sim.simulator import Simulator
from flip_tools import perturb as P


def test_plant_parameter_is_checked():
    assert parse_plant("") == {}
    knobs = parse_plant('{"friction": 0.5, "delay_steps": 2.0, "push_phase": "flight"}')
    assert knobs == {"friction": 0.5, "delay_steps": 2, "push_phase": "flight"}
    assert type(knobs["delay_steps"]) is int
    for text, msg in (("[1]", "JSON object"), ("{", "not JSON"), ('{"mass": 1}', "unknown knob(s) mass"),
                      ('{"friction": 0}', "must be > 0"), ('{"delay_steps": 1.5}', "whole number"),
                      ('{"push_phase": "air"}', "push_phase must be one of")):
        with pytest.raises(ValueError, match=msg.replace("(", r"\(").replace(")", r"\)")):
            parse_plant(text)


@pytest.mark.parametrize("flip, offset, params", [
    ("C", 0.05, ("platform", 0.5, 0.1, 0.05)),         # `flip run --platform 0.5 --ground-offset 0.05`
    ("D", -0.05, ("raised", 0.5, 0.05, 0.0)),          # `flip run --ground-offset 0.05`
    ("A", -0.05, ("raised", 0.5, -0.05, 0.0)),
])
def test_sim_node_builds_the_offline_terrain(flip, offset, params):
    a = Simulator("I", make_scenario(*params))
    b = Simulator("I", P.scenario(P.FLIPS[flip], offset))
    for field in ("geom_size", "geom_pos", "geom_type"):
        assert np.array_equal(getattr(a.model, field), getattr(b.model, field)), field


def test_model_knobs_edit_the_model_and_per_step_knobs_ask_for_the_python_loop():
    base = Simulator("I")
    sim = Simulator("I")
    p = PlantPerturbation(sim, {"mass_scale": 1.2, "friction": 0.6})
    assert not p.per_step
    assert sim.total_mass() == pytest.approx(1.2 * base.total_mass())
    assert "mass_scale 1.2" in p.describe(sim) and f"{sim.total_mass():.3f} kg" in p.describe(sim)
    assert PlantPerturbation(Simulator("I"), {"delay_steps": 1}).per_step
    assert PlantPerturbation(Simulator("I"), {"push": 2.0}).per_step
