"""flip_tools.perturb: each knob changes the simulated robot (and only it) as specified; a sample's
record gives the same result every time; unknown knobs and misplaced values are refused."""
import mujoco
import numpy as np
import pinocchio as pin
import pytest

from cassie_flip_sim.contacts import ContactEvent, Event
from flip_tools import offline
from flip_tools import perturb as P


def built(flip="A", **knobs):
    return P.build(P.Sample(flip, knobs))


def geom(sim, name):
    return mujoco.mj_name2id(sim.model, mujoco.mjtObj.mjOBJ_GEOM, name)


def same_controller(ctl, ref):
    """The controller's model and limits are those of an unperturbed robot's controller."""
    m, r = ctl.dyn.model, ref.dyn.model
    assert pin.computeTotalMass(m) == pin.computeTotalMass(r)
    for a, b in zip(m.inertias, r.inertias):
        assert np.array_equal(a.lever, b.lever) and a.mass == b.mass
    assert np.array_equal(ctl.limits.tau_max, ref.limits.tau_max)


@pytest.fixture(scope="module")
def reference():
    return built()


@pytest.mark.parametrize("offset", [0.1, -0.1])
def test_ground_offset_moves_the_landing_ground_only(reference, offset):
    sim, ctl, _ = built(ground_offset=offset)
    m = sim.model
    top = {n: m.geom_pos[geom(sim, n)][2] + (m.geom_size[geom(sim, n)][2] if n != "ground" else 0.0)
           for n in ("ground", "landing_slab", "takeoff_slab") if geom(sim, n) >= 0}
    if offset > 0:
        assert top == pytest.approx({"ground": 0.0, "landing_slab": offset})
        g = geom(sim, "landing_slab")
        assert m.geom_pos[g][0] - m.geom_size[g][0] == pytest.approx(0.4)             # from x = 0.4 on
    else:
        assert top == pytest.approx({"ground": offset, "takeoff_slab": 0.0})
        g = geom(sim, "takeoff_slab")
        assert m.geom_pos[g][0] + m.geom_size[g][0] == pytest.approx(0.4)             # up to x = 0.4
    assert np.array_equal(sim.standing_qpos, reference[0].standing_qpos)     # stands on the same ground
    same_controller(ctl, reference[1])


def test_ground_offset_adds_to_flip_d_and_is_refused_for_a_flip_in_place():
    assert P.scenario(P.FLIPS["D"], 0.05).landing_height == pytest.approx(0.15)
    assert P.scenario(P.FLIPS["D"], -0.1).name == "flat"
    with pytest.raises(ValueError, match="flip B lands where it took off"):
        P.Sample("B", {"ground_offset": 0.1})


def test_friction_is_the_terrains_in_every_contact(reference):
    sim, ctl, _ = built(friction=0.4)
    g = geom(sim, "ground")
    assert sim.model.geom_friction[g, 0] == 0.4 and reference[0].model.geom_friction[g, 0] == 1.0
    d = sim.data
    assert d.ncon > 0 and np.all(d.contact.friction[:d.ncon, 0] == 0.4)     # the feet standing on it
    same_controller(ctl, reference[1])


def test_mass_scale_and_com_offset_edit_the_simulators_bodies(reference):
    base = reference[0].model
    sim, ctl, _ = built(mass_scale=1.1, com_offset=0.03)
    m = sim.model
    assert np.allclose(m.body_mass, base.body_mass * 1.1, rtol=1e-15)
    assert np.allclose(m.body_inertia, base.body_inertia * 1.1, rtol=1e-15)
    assert mujoco.mj_getTotalmass(m) == pytest.approx(1.1 * mujoco.mj_getTotalmass(base))
    shift = m.body_ipos - base.body_ipos
    assert shift[sim._pelvis, 0] == pytest.approx(0.03)
    shift[sim._pelvis, 0] = 0.0
    assert not shift.any()
    assert m.body_subtreemass[0] == pytest.approx(1.1 * base.body_subtreemass[0])   # constants recomputed
    same_controller(ctl, reference[1])


def test_torque_scale_derates_the_simulators_motors_only(reference):
    sim, ctl, _ = built(torque_scale=0.8)
    lim = reference[0].limits.torque_limit
    assert np.array_equal(sim.limits.torque_limit, lim * 0.8)
    sim.step(np.full(len(lim), 1e4))               # the compiled step clips with the derated limits
    assert np.allclose(sim.last_command, lim * 0.8)
    same_controller(ctl, reference[1])


def test_delay_applies_each_command_whole_steps_late():
    sim, _, plant = built(delay_steps=3)
    out = [plant.command(sim, np.full(2, float(k)))[0] for k in range(6)]
    assert out == [0.0, 0.0, 0.0, 0.0, 1.0, 2.0]     # the first command held until the delay has passed
    sim, _, plant = built()
    u = np.ones(2)
    assert plant.command(sim, u) is u                # no delay: the command itself


@pytest.mark.parametrize("knob", ["joint_noise", "imu_noise"])
def test_noise_is_on_what_the_controller_reads(knob):
    sim, ctl, plant = built(**{knob: 0.01})
    sc = offline.StateConverter(ctl.dyn)
    q0, v0 = sc.from_simulator(sim)
    q, v = plant.state_reader(sc.from_simulator, sc, sim)(sim)
    dq, dv = q - q0, v - v0
    base = np.r_[0:7]                                  # pinocchio's free flyer: position, quaternion
    if knob == "joint_noise":
        assert not dq[base].any() and not dv[:6].any()
        assert 0.003 < np.std(dv[6:]) < 0.03 and np.abs(dq[7:]).max() > 1e-3
    else:
        assert not dq[7:].any() and not dv[6:].any() and not dq[:3].any() and not dv[:3].any()
        assert np.abs(dq[3:7]).max() > 1e-4 and np.abs(dv[3:6]).max() > 1e-3
    assert np.array_equal(sim.data.qpos, built()[0].data.qpos)        # the plant's state untouched
    sim2, _, plant2 = built(**{knob: 0.01})
    assert np.array_equal(plant2.state_reader(sc.from_simulator, sc, sim2)(sim2)[1], v)    # seeded
    _, _, quiet = built()
    assert quiet.state_reader(sc.from_simulator, sc, sim) == sc.from_simulator


def test_read_noise_alone_is_seeded_on_joints_and_imu_and_leaves_the_plant_as_it_is():
    """perturb.read_noise (bench_landings.py --noise): noise on both readings, drawn from its seed,
    nothing else of the plant changed (no push, no delay: the command passes as it is)."""
    sim, ctl, _ = built("B")
    sc = offline.StateConverter(ctl.dyn)
    q0, v0 = sc.from_simulator(sim)
    read = lambda seed: P.read_noise(sim, 1e-3, seed, 0.5).state_reader(sc.from_simulator, sc, sim)(sim)  # noqa: E731
    q, v = read(3)
    assert np.abs(v[6:] - v0[6:]).max() > 1e-4 and np.abs(v[3:6] - v0[3:6]).max() > 1e-4
    assert np.abs(q[3:7] - q0[3:7]).max() > 1e-5 and not (q[:3] - q0[:3]).any()
    assert np.array_equal(read(3)[1], v) and not np.array_equal(read(4)[1], v)
    u = np.arange(11.0)
    assert np.array_equal(P.read_noise(sim, 1e-3, 3, 0.5).command(sim, u), u)
    assert P.read_noise(sim, 0.0, 3, 0.5).state_reader(sc.from_simulator, sc, sim) == sc.from_simulator


@pytest.mark.parametrize("phase", ["stance", "flight"])
def test_push_is_the_impulse_over_10_ms_at_its_phase(phase):
    sim, _, plant = built(push=6.0, push_phase=phase, start=0.1)
    if phase == "flight":
        plant.on_event(ContactEvent(Event(0), 100, 0.05, 120, 0.0, 0.0))
    first = 100 + 200 if phase == "flight" else round(0.3 / sim.timestep)
    force = []
    for _ in range(first + 30):
        plant.command(sim, np.zeros(len(sim.motor_names)))
        force.append(sim.data.xfrc_applied[sim._pelvis].copy())
        sim.step(np.zeros(len(sim.motor_names)))
    force = np.array(force)
    pushed = np.flatnonzero(force[:, 0])
    assert pushed[0] == first and len(pushed) == 20 and pushed[-1] == first + 19
    assert force[:, 0].sum() * sim.timestep == pytest.approx(6.0)
    assert not force[:, 1:].any()


def test_unknown_knobs_and_bad_values_are_refused():
    with pytest.raises(ValueError, match="unknown knob 'frictoin'; known knobs: ground_offset, friction"):
        P.Sample("A", {"frictoin": 0.5})
    with pytest.raises(ValueError, match="unknown flip 'E'"):
        P.Sample("E")
    for knobs, msg in (({"delay_steps": 1.5}, "whole number"), ({"mass_scale": 0}, "> 0"),
                       ({"push_phase": "air"}, "push_phase must be one of"), ({"friction": "x"}, "a number")):
        with pytest.raises(ValueError, match=msg):
            P.Sample("A", knobs)


def test_a_sample_is_its_record():
    s = P.Sample("B", {"joint_noise": 0.01, "imu_noise": 0.005, "delay_steps": 1, "push": 3.0, "start": 0.2,
                       "seconds": 0.6}, seed=7)
    assert s.id == P.Sample("B", {"seconds": "0.6", "start": 0.2, "push": 3, "delay_steps": 1.0,
                                  "imu_noise": 0.005, "joint_noise": 0.01}, seed=7).id
    a, b = P.run_sample(s), P.run_sample(s)
    a.pop("wall_s"), b.pop("wall_s")
    assert a == b and a["outcome"] != "error" and a["sim_s"] == pytest.approx(0.6, abs=1e-3)
    c = P.run_sample(P.Sample("B", s.knobs, seed=8))
    assert c["net_rotation_deg"] != a["net_rotation_deg"]              # the seed draws the noise


def test_no_knob_is_the_unperturbed_run():
    """A sample with no knob set runs the flip as flip_tools.offline does without a plant, to the bit."""
    s = P.Sample("C", {"seconds": 1.2, "start": 0.3})
    sim, ctl, plant = P.build(s)
    f = P.FLIPS["C"]
    req = dict(apex_height=f.apex, forward_distance=f.distance, platform_height=f.platform, **P.robot_request())
    r = offline.run(f.kind, seconds=1.2, start=0.3, sim=sim, controller=ctl, every=10, plant=plant, **req)
    sim0, ctl0, _ = P.build(s)
    r0 = offline.run(f.kind, seconds=1.2, start=0.3, sim=sim0, controller=ctl0, every=10, **req)
    assert np.array_equal(sim.data.qpos, sim0.data.qpos) and np.array_equal(r["pitch"], r0["pitch"])


def test_the_models_own_friction_is_the_unperturbed_run():
    """friction 1.0 (the model's own) edits the model (terrain priority, constants recomputed) and
    changes nothing else: the run is the unperturbed one to the bit."""
    f = P.FLIPS["B"]
    req = dict(apex_height=f.apex, forward_distance=f.distance, platform_height=f.platform, **P.robot_request())
    qpos = []
    for knobs in ({}, {"friction": 1.0}):
        sim, ctl, plant = P.build(P.Sample("B", knobs))
        offline.run(f.kind, seconds=1.2, start=0.3, sim=sim, controller=ctl, every=10, plant=plant, **req)
        qpos.append(sim.data.qpos.copy())
    assert sim.model.geom_priority[geom(sim, "ground")] == 1
    assert np.array_equal(qpos[0], qpos[1])


def test_a_request_the_planner_refuses_is_rejected_with_its_limit(monkeypatch):
    monkeypatch.setitem(P.FLIPS, "X", P.Flip("backflip", 3.0))      # an apex the knees cannot reach
    r = P.run_sample(P.Sample("X", {"seconds": 1.0}))
    assert r["outcome"] == "rejected" and r["limit"] == "knee torque–speed envelope"
    assert "apex 3.00 m" in r["error"] and r["sim_s"] is None
