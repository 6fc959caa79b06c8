"""Deterministic MuJoCo simulator of Cassie + flywheel (no ROS).

Stepping: between steps the data holds ``mj_step1`` of the current state (kinematics, contacts,
passive forces).  ``step(u)`` clips u with the motor limits, runs ``mj_step2`` (forces with u,
Euler integration), records the foot normal forces that acted during that step (and, with
``wrench=True``, each foot's contact wrench: ``foot_wrench``), then runs ``mj_step1`` of the new
state.  Same sequence as ``mj_step``; bit-for-bit repeatable.

``backend="native"`` (default) runs that step, the state of ``state_into`` and the body-contact test
in C++ on the MuJoCo C API (``cassie_flip_sim._native``, native/step.cpp); ``"python"`` is the numpy
reference.  The two step bit for bit alike (tests/unit/test_sim_native.py).  sim_node's compiled loop
steps the native one from C++ (``native_loop_parts``, then ``note_native_steps``).
"""
from __future__ import annotations

from typing import List, Optional, Tuple, Union

import mujoco
import numpy as np
from cassie_model import model as M
from cassie_model import robot_params as P
from cassie_model.motor_limits import MotorLimits, with_flywheel_torque

from . import _native
from .contacts import ContactDetector, ContactEvent, Event, FootForces
from .foot_wrench import FootWrenches


class Simulator:
    """MuJoCo simulation of one scenario.  Joint-side torques in, state out."""

    def __init__(self, flywheel: M.FlywheelSpec = "I", scenario: Union[str, M.Scenario, None] = None, *,
                 clip_torques: bool = True, detector: Optional[ContactDetector] = None,
                 motor_speed_scale: float = 1.0, flywheel_torque: Optional[float] = None,
                 backend: str = "native"):
        # flywheel_torque (N·m): the flywheel motor's limit (None or 0: the flywheel's max_torque)
        self.flywheel = with_flywheel_torque(P.flywheel(flywheel), flywheel_torque)
        self.scenario = M.scenario(scenario)
        self.model = M.build_model(self.flywheel, self.scenario)
        self.data = mujoco.MjData(self.model)
        self.limits = MotorLimits.from_flywheel(self.flywheel, motor_speed_scale, flywheel_torque)
        self.clip_torques = clip_torques
        self.detector = detector if detector is not None else ContactDetector(True)
        self.motor_names = self.limits.names
        m = self.model
        jid = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_JOINT, n) for n in self.motor_names]
        self._motor_dof = np.array([m.jnt_dofadr[j] for j in jid])
        self._act_ids = np.array([mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_ACTUATOR, n) for n in self.motor_names])
        self._pelvis = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, "pelvis")
        self._foot_geoms = [mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, g)
                            for side in ("left", "right") for g in M.FOOT_GEOMS[side]]
        self._foot_forces = FootForces(m)
        self._foot_wrenches = FootWrenches(m)
        #: the feet's wrenches (foot_wrench: left, right; force, torque in the foot's frame) of the
        #: state of step ``wrench_step``, from the last ``step(u, wrench=True)``
        self.wrenches = np.zeros((2, 6))
        self.wrench_step = -1
        self._build_joint_table()
        if backend not in ("native", "python"):
            raise ValueError(f"backend must be 'native' or 'python', not {backend!r}")
        self.backend = backend
        self._native = self._make_native() if backend == "native" else None
        self._u_applied = np.zeros(len(self.motor_names))
        self.standing_qpos, _ = M.standing_state(m, self.scenario)
        self.reset()

    # ---------------------------------------------------------------- state control
    def reset(self, qpos=None, qvel=None, *, in_contact: Optional[bool] = None) -> None:
        """Reset to (qpos, qvel) (default: the standing state), time 0, step 0."""
        m, d = self.model, self.data
        mujoco.mj_resetData(m, d)
        d.qpos[:] = self.standing_qpos if qpos is None else qpos
        d.qvel[:] = 0.0 if qvel is None else qvel
        mujoco.mj_forward(m, d)
        self._step = 0
        self.last_command = np.zeros(m.nu)
        self.forces = self._foot_forces(m, d)      # with zero torque at the initial state
        if in_contact is None:
            in_contact = any(self._foot_forces.touching(d))
        self.detector.reset(in_contact)
        self.events: List[ContactEvent] = []

    def _make_native(self):
        m = self.model
        side = np.full(m.ngeom, -1)
        for g, k in self._foot_forces.side_of.items():
            side[g] = k
        return _native.Stepper(
            m._address, self.data._address, self._motor_dof, self._act_ids, self.limits.torque_limit,
            self.limits.inv_no_load_speed, side, self._jq, self._jv,
            np.array([qa for _, qa in self._balls], int), np.array([i for i, _ in self._balls], int),
            self._pelvis, (m.geom_contype == M.BODY_CONTYPE).astype(int), self._foot_wrenches.bodies)

    def step(self, u, wrench: bool = False) -> None:
        """Advance one timestep with joint-side torques u (contract motor order), clipped to the
        torque–speed envelope.  ``wrench``: also the feet's contact wrenches of the state stepped
        from, into ``wrenches`` (``wrench_step`` = its step)."""
        if wrench:
            self.wrench_step = self._step
        if self._native is not None:
            t = self.data.time
            self.forces = self._native.step(u, self._u_applied, self.clip_torques,
                                            self.wrenches if wrench else None)
            self.last_command = self._u_applied.copy()
            ev = self.detector.update(self._step, t, *self.forces)
            if ev is not None:
                self.events.append(ev)
            self._step += 1
            return
        m, d = self.model, self.data
        u = np.asarray(u, float)
        if self.clip_torques:
            u = self.limits.clip(u, d.qvel[self._motor_dof])
        self.last_command = u
        d.ctrl[self._act_ids] = u
        t = d.time
        mujoco.mj_step2(m, d)
        self.forces = self._foot_forces(m, d)
        if wrench:
            self._foot_wrenches(m, d, out=self.wrenches)
        ev = self.detector.update(self._step, t, *self.forces)
        if ev is not None:
            self.events.append(ev)
        mujoco.mj_step1(m, d)
        self._step += 1

    def native_loop_parts(self):
        """(the compiled step's C table (a capsule, flip_transport's native/stepper_api.h), the applied-torque buffer
        it writes) for a loop that steps this simulator from C++ (flip_transport._rcl_io.SimLoop) as ``step`` does,
        or None where it cannot: the numpy backend, or a detector other than ContactDetector (the loop
        runs a C++ copy of that one)."""
        if self._native is None or type(self.detector) is not ContactDetector:
            return None
        return self._native._api(), self._u_applied

    def note_native_steps(self, steps: int, forces, detector_state: tuple, event) -> None:
        """After ``steps`` steps of such a loop: what ``step`` keeps (step count, forces, applied
        torques, the detector's state as the loop left it (ContactDetector.set_state), its event as
        a (kind, step, time, detected_step, left_force, right_force) tuple or None)."""
        self.detector.set_state(detector_state)
        if steps:
            self._step += steps
            self.forces = forces
            self.last_command = self._u_applied.copy()
        if event is not None:
            kind, step, t, detected, fl, fr = event
            self.events.append(ContactEvent(Event(kind), step, t, detected, fl, fr))

    def pop_events(self) -> List[ContactEvent]:
        ev, self.events = self.events, []
        return ev

    # ---------------------------------------------------------------- accessors
    @property
    def time(self) -> float:
        return float(self.data.time)

    @property
    def step_index(self) -> int:
        """Number of steps taken since reset (the state is that of step ``step_index``)."""
        return self._step

    @property
    def timestep(self) -> float:
        return float(self.model.opt.timestep)

    def _build_joint_table(self):
        m = self.model
        names, qadr, vadr, ball = [], [], [], []
        for j in range(m.njnt):
            t = m.jnt_type[j]
            if t == mujoco.mjtJoint.mjJNT_FREE:
                continue
            n = m.joint(j).name
            if t == mujoco.mjtJoint.mjJNT_BALL:
                names += [f"{n}_x", f"{n}_y", f"{n}_z"]
                ball.append((len(vadr), m.jnt_qposadr[j]))
                qadr += [-1, -1, -1]
                vadr += [m.jnt_dofadr[j] + k for k in range(3)]
            else:
                names.append(n)
                qadr.append(m.jnt_qposadr[j])
                vadr.append(m.jnt_dofadr[j])
        self.joint_names: List[str] = names
        self._jq, self._jv, self._balls = np.array(qadr), np.array(vadr), ball

    def joint_positions(self) -> np.ndarray:
        """Per ``joint_names`` entry: hinge angle (MuJoCo qpos), ball = rotation vector (parent frame)."""
        q = self.data.qpos[np.maximum(self._jq, 0)].copy()
        rv = np.zeros(3)
        for i, qa in self._balls:
            mujoco.mju_quat2Vel(rv, self.data.qpos[qa:qa + 4], 1.0)
            q[i:i + 3] = rv
        return q

    def joint_velocities(self) -> np.ndarray:
        """Per ``joint_names`` entry: qvel (balls: local angular velocity)."""
        return self.data.qvel[self._jv].copy()

    def joint_efforts(self) -> np.ndarray:
        """Per ``joint_names`` entry: applied motor torque (last command, after clipping) plus
        joint spring torque -K q at the current state; damping not included."""
        d = self.data
        return (d.qfrc_actuator[self._jv] + d.qfrc_spring[self._jv]).copy()

    def motor_velocities(self) -> np.ndarray:
        """Joint-side velocities of the 11 motors (contract order)."""
        return self.data.qvel[self._motor_dof].copy()

    def motor_positions(self) -> np.ndarray:
        m = self.model
        return np.array([self.data.qpos[m.jnt_qposadr[m.dof_jntid[v]]] for v in self._motor_dof])

    def pelvis_pose(self) -> Tuple[np.ndarray, np.ndarray]:
        """(position (3,), quaternion **wxyz** (4,)) of the pelvis frame in the world."""
        return self.data.qpos[0:3].copy(), self.data.qpos[3:7].copy()

    def pelvis_twist(self, frame: str = "world") -> Tuple[np.ndarray, np.ndarray]:
        """(linear velocity of the pelvis origin, angular velocity).

        frame="world": both in world axes (flip_msgs/ContactEvent);  "local": both in pelvis axes
        (nav_msgs/Odometry, REP 105);  "mujoco": MuJoCo's qvel (linear world, angular local)."""
        R = self.data.xmat[self._pelvis].reshape(3, 3)
        lin_w, ang_b = self.data.qvel[0:3].copy(), self.data.qvel[3:6].copy()
        if frame == "world":
            return lin_w, R @ ang_b
        if frame == "local":
            return R.T @ lin_w, ang_b
        if frame == "mujoco":
            return lin_w, ang_b
        raise ValueError(frame)

    def com_position(self) -> np.ndarray:
        """Whole-robot COM, world frame."""
        return self.data.subtree_com[self._pelvis].copy()

    def com_velocity(self) -> np.ndarray:
        """Whole-robot COM velocity, world frame."""
        mujoco.mj_subtreeVel(self.model, self.data)
        return self.data.subtree_linvel[self._pelvis].copy()

    def centroidal_angular_momentum(self) -> np.ndarray:
        """Whole-body angular momentum about the COM, world axes (kg·m²/s)."""
        mujoco.mj_subtreeVel(self.model, self.data)
        return self.data.subtree_angmom[self._pelvis].copy()

    def centroidal_pitch_momentum(self) -> float:
        """H_pitch (paper eq. (8)): world-y component of the angular momentum about the COM."""
        return float(self.centroidal_angular_momentum()[1])

    def foot_normal_forces(self) -> Tuple[float, float]:
        """(left, right) ground normal forces (N) that acted during the last step."""
        return self.forces

    def support_center(self) -> np.ndarray:
        """Centre of the four foot contact spheres (toe and heel of each foot), world frame: where
        the FSLIP's foot is, whether or not the feet touch the ground."""
        return self.data.geom_xpos[self._foot_geoms].mean(axis=0)

    def state_into(self, position, velocity, effort, pose, twist) -> None:
        """Write the state into float64 arrays (e.g. views of a serialized message): per
        ``joint_names`` entry :meth:`joint_positions`, :meth:`joint_velocities`,
        :meth:`joint_efforts`; ``pose`` = pelvis position and quaternion x, y, z, w (7); ``twist`` =
        :meth:`pelvis_twist` ``("local")`` (6)."""
        if self._native is not None:
            self._native.state(position, velocity, effort, pose, twist)
            return
        pos, quat = self.pelvis_pose()
        pose[:3], pose[3:6], pose[6] = pos, quat[1:], quat[0]
        twist[:3], twist[3:] = self.pelvis_twist("local")
        position[:] = self.joint_positions()
        velocity[:] = self.joint_velocities()
        effort[:] = self.joint_efforts()

    def body_contacts(self) -> List[str]:
        """Names of the bodies other than the feet touching the terrain now (a fall)."""
        m, d = self.model, self.data
        if d.ncon == 0 or (self._native is not None and not self._native.body_contact()):
            return []
        g = d.contact.geom[:d.ncon].ravel()
        g = g[m.geom_contype[g] == M.BODY_CONTYPE]
        return sorted({m.body(b).name for b in m.geom_bodyid[g]}) if g.size else []

    def total_mass(self) -> float:
        return float(mujoco.mj_getTotalmass(self.model))
