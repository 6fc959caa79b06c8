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
    # twist: the linear part R^T v summed in index order, as native/step.cpp does, without BLAS ...
    R, lin = b.data.xmat[b._pelvis].reshape(3, 3).tolist(), b.data.qvel[0:3].tolist()
    twist = [R[0][i] * lin[0] + R[1][i] * lin[1] + R[2][i] * lin[2] for i in range(3)] + b.data.qvel[3:6].tolist()
    assert np.array_equal(got[4], twist)
    # ... and the numpy form's (pelvis_twist: R.T @ v, BLAS, whose kernel (OPENBLAS_CORETYPE) sums with or
    # without fused multiply-adds): within a few ulps of |v| (measured: up to 1.5 ulps, 0 under some kernels)
    np.testing.assert_allclose(ref[4], twist, rtol=0, atol=4 * np.finfo(float).eps * max(1.0, np.abs(lin).max()))
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


def test_compiled_loops_detector_follows_the_contact_detector():
    """_native.Detector (the contact detector sim_node's compiled loop runs, native/stepper_api.h)
    against contacts.ContactDetector on the forces of a robot pushed about until it falls: the same
    events (lift-offs and touch-downs, their onset steps and times, forces) and the same state after
    every step; the state handed back and forth (ContactDetector.state / set_state), as between the
    loop's calls, changes nothing."""
    from cassie_flip_sim import _native
    from cassie_flip_sim.contacts import ContactDetector
    sim = Simulator(motor_speed_scale=3.0, flywheel_torque=260.0)
    ref = ContactDetector(True)
    lim = ref.state()[5:]
    cpp = _native.Detector(*lim)
    rng = np.random.default_rng(0)
    kinds = []
    for k in range(3000):
        u = rng.normal(0.0, 60.0, 11) if k % 400 < 150 else np.zeros(11)
        t = sim.data.time
        sim.step(u)
        want = ref.update(k, t, *sim.forces)
        got = cpp.update(k, t, *sim.forces)
        assert (got is None) == (want is None), k
        if want is not None:
            assert got == (int(want.kind), want.step, want.time, want.detected_step, want.left_force,
                           want.right_force), k
            kinds.append(want.kind)
        state = (cpp.in_contact, cpp.zero_run, cpp.onset_step, cpp.onset_time, cpp.flight_steps)
        assert state + lim == ref.state(), k
        if k % 7 == 0:                                   # a hand-over: Python's state back and forth
            ref.set_state(ref.state())
            assert ref.state() == state + lim
    assert len(kinds) >= 4 and set(kinds) == {0, 1}      # lift-offs and touch-downs


def test_native_loop_parts_only_for_the_native_step_and_the_contact_detector():
    from cassie_flip_sim.contacts import ContactDetector

    class Other(ContactDetector):
        pass
    assert Simulator().native_loop_parts() is not None
    assert Simulator(backend="python").native_loop_parts() is None
    assert Simulator(detector=Other()).native_loop_parts() is None
