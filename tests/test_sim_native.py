"""The simulator's compiled step (cassie_flip_sim._native) against its numpy reference
(Simulator(backend="python")): the same trajectory bit for bit, the same state messages."""
import numpy as np
import pytest

from cassie_flip_sim.simulator import Simulator


def _pair(**kw):
    return Simulator(backend="native", **kw), Simulator(backend="python", **kw)


def test_native_step_follows_the_numpy_step_bit_for_bit():
    """Standing, pushed about by random torques (clipped at the envelope) until it falls: contacts
    come and go, lift-off / touch-down events and body contacts happen."""
    a, b = _pair(motor_speed_scale=3.0, flywheel_torque=260.0)
    rng = np.random.default_rng(0)
    saw_clip = saw_body = False
    for k in range(3000):
        u = rng.normal(0.0, 60.0, 11) if k % 400 < 150 else np.zeros(11)
        a.step(u)
        b.step(u)
        assert np.array_equal(a.data.qpos, b.data.qpos) and np.array_equal(a.data.qvel, b.data.qvel), k
        assert a.forces == b.forces and np.array_equal(a.last_command, b.last_command), k
        assert a.body_contacts() == b.body_contacts(), k
        saw_clip |= not np.array_equal(a.last_command, u)
        saw_body |= bool(a.body_contacts())
    assert [e.kind for e in a.pop_events()] == [e.kind for e in b.pop_events()]
    assert saw_clip and saw_body                     # the run covers clipping and a fall


def test_native_state_matches_the_accessors_into_unaligned_views():
    """sim_node writes the state into numpy views of serialized messages, whose float64 fields sit
    4 bytes off an 8-byte boundary."""
    a, b = _pair()
    rng = np.random.default_rng(1)
    for _ in range(300):
        u = rng.normal(0.0, 30.0, 11)
        a.step(u)
        b.step(u)
    n = len(a.joint_names)

    def views(sim):
        buf = bytearray(4 + 8 * (3 * n + 13))
        arrs = [np.frombuffer(buf, "<f8", k, 4 + 8 * off)
                for k, off in ((n, 0), (n, n), (n, 2 * n), (7, 3 * n), (6, 3 * n + 7))]
        sim.state_into(*arrs)
        return arrs
    got, ref = views(a), views(b)
    assert not got[0].flags.aligned
    for x, y in zip(got[:4], ref[:4]):                # joints, pose: the same numbers
        assert np.array_equal(x, y)
    # twist: R^T v summed in index order (numpy's matmul may round the last bit differently)
    np.testing.assert_allclose(got[4], ref[4], rtol=0, atol=1e-12)
    pos, quat = a.pelvis_pose()
    assert np.array_equal(got[3], np.r_[pos, quat[1:], quat[0]])
    assert np.array_equal(got[0], a.joint_positions()) and np.array_equal(got[2], a.joint_efforts())


def test_native_refuses_arrays_that_do_not_fit():
    sim = Simulator()
    n = len(sim.joint_names)
    with pytest.raises(ValueError):
        sim.step(np.zeros(10))
    with pytest.raises(ValueError):
        sim.state_into(np.zeros(n), np.zeros(n), np.zeros(n), np.zeros(7), np.zeros(5))
    with pytest.raises(ValueError):
        sim.state_into(np.zeros(n, np.float32), np.zeros(n), np.zeros(n), np.zeros(7), np.zeros(6))
    with pytest.raises(ValueError):
        Simulator(backend="cuda")


def test_native_step_without_clipping_applies_the_torques_as_given():
    a, b = _pair()
    a.clip_torques = b.clip_torques = False          # (bench_sim's "clipping off" row)
    rng = np.random.default_rng(2)
    for k in range(300):
        u = rng.normal(0.0, 300.0, 11)
        a.step(u)
        b.step(u)
        assert np.array_equal(a.last_command, u) and np.array_equal(a.data.qvel, b.data.qvel), k
