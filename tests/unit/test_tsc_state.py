"""State conversion of tsc_controller (no ROS): StateConverter against Pinocchio's map, its compiled
path against its numpy one, and the serialized-message path against the numpy reading."""
import math
from fractions import Fraction
from types import SimpleNamespace

import numpy as np
import pytest

from cassie_model.model import export_mjcf
from cassie_model.pinocchio_map import PinocchioMap
from cassie_flip_sim.simulator import Simulator
from tsc_controller import StateConverter, state_from_ros
from tsc_controller.dynamics import Dynamics


def test_state_converter_matches_pinocchio_map():
    sim = Simulator()
    dyn = Dynamics(export_mjcf())
    rng = np.random.default_rng(0)
    sim.data.qvel[:] = rng.normal(0, 0.5, sim.model.nv)
    sim.data.qpos[3:7] = [0.9, 0.1, -0.2, 0.3]
    sim.data.qpos[3:7] /= np.linalg.norm(sim.data.qpos[3:7])
    import mujoco
    mujoco.mj_forward(sim.model, sim.data)
    q, v = StateConverter(dyn).from_simulator(sim)
    q_ref, v_ref = PinocchioMap(sim.model, dyn.model).to_pin(sim.data.qpos, sim.data.qvel)
    assert np.allclose(v, v_ref, atol=1e-12)
    for jid in range(1, dyn.model.njoints):   # quaternions up to sign
        a, n = dyn.model.idx_qs[jid], dyn.model.nqs[jid]
        assert np.allclose(q[a:a + n], q_ref[a:a + n], atol=1e-9) or np.allclose(q[a:a + n], -q_ref[a:a + n], atol=1e-9)
    # the message adapter (duck-typed JointState / Odometry)
    p, quat = sim.pelvis_pose()
    lin, ang = sim.pelvis_twist("local")
    vec = lambda x: SimpleNamespace(x=x[0], y=x[1], z=x[2])  # noqa: E731
    odom = SimpleNamespace(pose=SimpleNamespace(pose=SimpleNamespace(
        position=vec(p), orientation=SimpleNamespace(x=quat[1], y=quat[2], z=quat[3], w=quat[0]))),
        twist=SimpleNamespace(twist=SimpleNamespace(linear=vec(lin), angular=vec(ang))))
    js = SimpleNamespace(name=sim.joint_names, position=list(sim.joint_positions()), velocity=list(sim.joint_velocities()))
    q2, v2 = state_from_ros(StateConverter(dyn), js, odom)
    assert np.allclose(q2, q) and np.allclose(v2, v)


def test_compiled_state_conversion_equals_the_numpy_one():
    """StateConverter's compiled conversion (the controller's default) gives the (q, v) of its numpy
    reference bit for bit, ball joints included, over states of a robot pushed about until it falls."""
    sim = Simulator()
    dyn = Dynamics(export_mjcf())
    native, ref = StateConverter(dyn), StateConverter(dyn, backend="python")
    assert native.backend == "native"
    rng = np.random.default_rng(3)
    for k in range(1500):
        sim.step(rng.normal(0.0, 40.0, 11) if k % 300 < 100 else np.zeros(11))
        (q1, v1), (q2, v2) = native.from_simulator(sim), ref.from_simulator(sim)
        assert np.array_equal(q1, q2) and np.array_equal(v1, v2), k
    with pytest.raises(ValueError):
        StateConverter(dyn, backend="gpu")


def _fma(a, b, c):
    """a * b + c rounded once, as std::fma (Python 3.11 has no math.fma): exact in fractions, then
    rounded to the nearest double."""
    return float(Fraction(a) * Fraction(b) + Fraction(c))


def _unit_quaternion(x):
    """x / |x| in the operations of StateMap.convert_cdr (native/state.cpp): |x|^2 = x0 x0, then
    fused multiply-adds of x1, x2, x3; no BLAS (numpy's dot sums in the order, and with or without
    the fused multiply-adds, of the OpenBLAS kernel it runs on)."""
    x = [float(c) for c in x]
    n = math.sqrt(_fma(x[3], x[3], _fma(x[2], x[2], _fma(x[1], x[1], x[0] * x[0]))))
    return np.array([c / n for c in x])


#: |from_ros's base quaternion - convert_cdr's|: from_ros normalises with numpy's dot (BLAS ddot),
#: which sums x.x in the order of the OpenBLAS kernel (OPENBLAS_CORETYPE): the fused chain of
#: convert_cdr under SkylakeX and this AMD CPU's own, plain left to right under Haswell, two
#: accumulators under Prescott.  |x|^2 then differs by an ulp or two and the unit components (<= 1)
#: by at most 1 ulp of 1 (2.2e-16, measured over these 1,200 states under the four); 4 ulps of 1 is
#: the bound, a quaternion off by 1e-6 (not normalised, or the old state's) is far outside it.
QUAT_ATOL = 4 * np.finfo(float).eps


def test_state_from_serialized_messages_equals_the_numpy_reading():
    """StateConverter.from_cdr (the controller node's per-step path: (q, v) compiled straight from the
    serialized /joint_states and /odom) gives what the numpy views + from_ros give, to the bit, the
    quaternion's normalisation included (not quite unit, as a message may carry it: here compared
    with its normalisation in convert_cdr's operations, as from_ros's numpy dot rounds x.x by the
    BLAS kernel's summation; from_ros's own within QUAT_ATOL); a message of another layout (here a
    longer frame id) is not read (None) until that layout is handed on."""
    from flip_transport.lockstep import MessageReader, RawMessage, joint_state_layout, odometry_layout
    from nav_msgs.msg import Odometry
    from sensor_msgs.msg import JointState
    sim = Simulator()
    conv = StateConverter(Dynamics(export_mjcf()))
    n = len(sim.joint_names)
    quat = slice(conv.base_q + 3, conv.base_q + 7)            # x, y, z, w as /odom's pose[3:]

    def messages(frame):
        js = RawMessage(JointState(name=list(sim.joint_names), position=[0.0] * n, velocity=[0.0] * n,
                                   effort=[0.0] * n), joint_state_layout)
        od = Odometry(child_frame_id="pelvis")
        od.header.frame_id = frame
        return js, RawMessage(od, odometry_layout)
    js, od = messages("world")
    read_js, read_od = MessageReader(joint_state_layout), MessageReader(odometry_layout)
    assert conv.from_cdr(bytes(js.buf), bytes(od.buf)) is None            # no layout yet
    rng = np.random.default_rng(5)

    def step(js, od, k):
        """The serialized messages of the next state, and their numpy reading: from_ros's (q, v) with
        the base quaternion normalised as convert_cdr does (from_ros's own checked against it)."""
        sim.step(rng.normal(0.0, 40.0, 11) if k % 300 < 100 else np.zeros(11))
        f, o = js.fields, od.fields
        sim.state_into(f["position"], f["velocity"], f["effort"], o["pose"], o["twist"])
        o["pose"][3:] *= 1.0 + rng.normal(0.0, 1e-6)
        jb, ob = bytes(js.buf), bytes(od.buf)
        a, b = read_js(jb), read_od(ob)
        q_ros, v_ref = conv.from_ros(read_js.names[0], a["position"], a["velocity"], b["pose"][:3], b["pose"][3:],
                                     b["twist"][:3], b["twist"][3:])
        q_ref = q_ros.copy()
        q_ref[quat] = _unit_quaternion(b["pose"][3:])
        np.testing.assert_allclose(q_ros, q_ref, rtol=0.0, atol=QUAT_ATOL, err_msg=str(k))
        return jb, ob, (q_ref, v_ref)
    for k in range(1200):
        jb, ob, (q_ref, v_ref) = step(js, od, k)
        if k == 0:
            conv.use_cdr_layout(read_js.layout(), read_od.layout())
        q, v = conv.from_cdr(jb, ob)
        assert np.array_equal(q, q_ref) and np.array_equal(v, v_ref), k
    js2, od2 = messages("world_frame")
    jb, ob, (q_ref, _) = step(js2, od2, 0)
    assert conv.from_cdr(jb, ob) is None
    conv.use_cdr_layout(read_js.layout(), read_od.layout())
    assert np.array_equal(conv.from_cdr(jb, ob)[0], q_ref)
    assert conv.from_cdr(bytes(js.buf), bytes(od.buf)) is None            # the old layout is gone
    assert StateConverter(Dynamics(export_mjcf()), backend="python").from_cdr(jb, ob) is None
