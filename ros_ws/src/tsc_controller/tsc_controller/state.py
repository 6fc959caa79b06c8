"""Contract state (sensor_msgs/JointState + nav_msgs/Odometry arrays) -> Pinocchio (q, v).

docs/architecture.md: /joint_states has one entry per DOF — hinges under their joint name, each ball
joint (achilles rods) as ``<name>_x/_y/_z`` with the rotation vector (log map of the joint's quaternion)
as position and the local angular velocity as velocity.  /odom: pelvis pose in the world
(quaternion x, y, z, w) and twist in the pelvis (child) frame, REP 105 — which is exactly
Pinocchio's free-flyer velocity (linear and angular, both local).
"""
from __future__ import annotations

import math

import numpy as np
import pinocchio as pin


class StateConverter:
    """Builds (q, v) for a :class:`~tsc_controller.dynamics.Dynamics` model from contract arrays.

    With the Dynamics' native backend the conversion runs compiled (``_native.StateMap``: the same
    Pinocchio exp3 and Eigen quaternion as ``pin.exp3`` / ``pin.Quaternion``); ``backend="python"``
    is the reference (tests/unit/test_tsc_state.py compares them)."""

    def __init__(self, dyn, backend: str | None = None):
        self.dyn = dyn
        m = dyn.model
        self.base_q = m.idx_qs[dyn.base_jid]
        self.base_v = m.idx_vs[dyn.base_jid]
        self._names = None
        self._names_seen = None     # the names object last checked against self._names
        self.backend = backend or ("native" if getattr(dyn, "native", None) is not None else "python")
        if self.backend not in ("native", "python"):
            raise ValueError(f"backend must be 'native' or 'python', not {self.backend!r}")
        self._map = None

    def _index(self, names):
        m = self.dyn.model
        pos = {n: i for i, n in enumerate(names)}
        hq, hv, hs, balls = [], [], [], []
        for jid in range(1, m.njoints):
            if jid == self.dyn.base_jid:
                continue
            name = m.names[jid].replace("-", "_")
            nq, nv = m.nqs[jid], m.nvs[jid]
            if nq == 1:
                if name not in pos:
                    raise KeyError(f"joint {name} missing from JointState")
                hq.append(m.idx_qs[jid])
                hv.append(m.idx_vs[jid])
                hs.append(pos[name])
            elif nq == 4 and nv == 3:
                k = [pos[f"{name}_{a}"] for a in "xyz"]
                balls.append((m.idx_qs[jid], m.idx_vs[jid], k))
            else:
                raise NotImplementedError(f"joint {name}: nq={nq}")
        self._names = list(names)
        self._hq, self._hv, self._hs = np.array(hq), np.array(hv), np.array(hs)
        self._balls = balls
        if self.backend == "native":
            from . import _native
            self._map = _native.StateMap(
                self.dyn.nq, self.dyn.nv, self.base_q, self.base_v, len(names), self._hq, self._hv, self._hs,
                np.array([b[0] for b in balls], int), np.array([b[1] for b in balls], int),
                np.array([k for b in balls for k in b[2]], int))

    def from_ros(self, names, position, velocity, base_position, base_quat_xyzw, lin_vel_local, ang_vel_local):
        """(q, v) from JointState (names, position, velocity) and Odometry (pose, child-frame twist).
        ``names`` is compared with the last list only when it is another object: a list changed in
        place is not seen (pass a new list for other names, as a message reader does)."""
        if names is not self._names_seen:         # (a message reader hands the same list while it holds)
            if self._names is None or list(names) != self._names:
                self._index(names)
            self._names_seen = names
        if self._map is not None:
            quat = np.asarray(base_quat_xyzw, float)
            # |quat| as np.linalg.norm computes it (sqrt of x.dot(x)), without its Python layers
            return self._map.convert(position, velocity, base_position, quat / math.sqrt(quat.dot(quat)),
                                     lin_vel_local, ang_vel_local)
        position = np.asarray(position, float)
        velocity = np.asarray(velocity, float)
        q = np.empty(self.dyn.nq)
        v = np.empty(self.dyn.nv)
        b, bv = self.base_q, self.base_v
        q[b:b + 3] = base_position
        quat = np.asarray(base_quat_xyzw, float)
        q[b + 3:b + 7] = quat / np.linalg.norm(quat)
        v[bv:bv + 3] = lin_vel_local
        v[bv + 3:bv + 6] = ang_vel_local
        q[self._hq] = position[self._hs]
        v[self._hv] = velocity[self._hs]
        for iq, iv, k in self._balls:
            R = pin.exp3(position[k])
            q[iq:iq + 4] = pin.Quaternion(R).coeffs()   # x, y, z, w
            v[iv:iv + 3] = velocity[k]
        return q, v

    def use_cdr_layout(self, js_layout, odom_layout):
        """Let :meth:`from_cdr` read serialized messages of this layout: ``js_layout`` and ``odom_layout``
        are ``(size, runs, offsets)`` (``flip_transport.cdr.MessageReader.layout``) of a
        /joint_states whose names :meth:`from_ros` has indexed and of an /odom.  Native backend only
        (a no-op with the Python one)."""
        if self._map is None:
            return
        (js_size, js_runs, js_off), (od_size, od_runs, od_off) = js_layout, odom_layout
        self._map.set_cdr_layout(js_size, list(js_runs), js_off["position"], js_off["velocity"],
                                 od_size, list(od_runs), od_off["pose"], od_off["twist"])

    def from_cdr(self, js_buf, odom_buf):
        """(q, v) straight from a serialized /joint_states and /odom (compiled: no numpy views, the
        quaternion normalised in C++ as numpy's dot rounds), or None when no layout has been given
        (:meth:`use_cdr_layout`), the backend is Python, or a message has another layout (other
        names, frame ids or lengths): then read them with :meth:`from_ros`."""
        if self._map is None:
            return None
        return self._map.convert_cdr(js_buf, odom_buf)

    def from_simulator(self, sim):
        """(q, v) from a ``cassie_flip_sim.simulator.Simulator`` through the contract arrays, the very
        numbers ``sim_node`` publishes (``Simulator.state_into``, which fills its messages): a run without
        ROS then gives the controller the state the node would read, to the bit."""
        n = len(sim.joint_names)
        pos, vel, eff, pose, twist = np.empty(n), np.empty(n), np.empty(n), np.empty(7), np.empty(6)
        sim.state_into(pos, vel, eff, pose, twist)
        return self.from_ros(sim.joint_names, pos, vel, pose[:3], pose[3:], twist[:3], twist[3:])


def state_from_ros(converter: StateConverter, js, odom):
    """(q, v) from sensor_msgs/JointState and nav_msgs/Odometry messages (duck-typed, no ROS import)."""
    p, o = odom.pose.pose.position, odom.pose.pose.orientation
    lin, ang = odom.twist.twist.linear, odom.twist.twist.angular
    return converter.from_ros(js.name, js.position, js.velocity, (p.x, p.y, p.z), (o.x, o.y, o.z, o.w),
                              (lin.x, lin.y, lin.z), (ang.x, ang.y, ang.z))
