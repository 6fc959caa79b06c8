"""A robot put in the air at a lift-off state, for flight and landing tests without a jump: pelvis
``h`` above standing, rising so that it is back at standing height after T, the whole body turning
at ±2π/T about the COM (rigid rotation); and the FLIGHT reference fslip_planner.flight would give it
(cubic pelvis pitch to ±2π with zero rate at T)."""
import math

import numpy as np

from tsc_controller import Domain, SampledReference


def launch(sim, sign, T, h):
    """Reset ``sim`` to the launched state; returns the pitch rate w (rad/s)."""
    qpos = sim.standing_qpos.copy()
    qpos[2] += h
    vz = (9.81 * T * T / 2 - h) / T
    w = sign * 2 * math.pi / T
    qvel = np.zeros(sim.model.nv)
    sim.reset(qpos, qvel, in_contact=False)
    c, p = sim.com_position(), sim.data.qpos[:3].copy()
    qvel[0:3] = np.array([0.0, 0.0, vz]) + np.cross([0.0, w, 0.0], p - c)   # rigid rotation about the COM
    qvel[4] = w                                                             # pelvis pitch rate (local y)
    sim.reset(qpos, qvel, in_contact=False)
    return w


def flight_reference(sign, w0, T):
    ts = np.linspace(0.0, T, 200)
    a2, a3 = np.linalg.solve([[T ** 2, T ** 3], [2 * T, 3 * T ** 2]], [sign * 2 * math.pi - w0 * T, -w0])
    th = w0 * ts + a2 * ts ** 2 + a3 * ts ** 3
    dth = w0 + 2 * a2 * ts + 3 * a3 * ts ** 2
    ddth = 2 * a2 + 6 * a3 * ts
    return SampledReference(Domain.FLIGHT, ts, ["phi_pitch"], th[:, None], dth[:, None], ddth[:, None],
                            parameters=dict(flight_time=T, T1=0.75 * T, beta_liftoff=0.0))
