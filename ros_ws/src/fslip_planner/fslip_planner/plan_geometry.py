"""A reference of the planner as geometry in the world frame (no ROS): the FSLIP's COM path and its
foot targets, for a viewer (planner_node publishes them as nav_msgs/Path ``/fslip/com_path`` and
visualization_msgs/MarkerArray ``/fslip/targets``), and the FSLIP's ground force (fig6.png).

Inputs are the fields of a flip_msgs/FlipReference as decoded (sample times, output names, values,
derivatives, parameters, the plan's figures) and where the robot was when the reference was made
(its COM, and the COM velocity at a lift-off), as the planner measured them.

The FSLIP (fslip.py) puts the COM at r (sin β, cos β) from the stance foot, r = L − ``leg_offset``
(a ground reference's ``L`` is the FSLIP leg length r plus that constant, ``plan.ground_reference``;
the reference carries it as parameter ``leg_offset``), β = ``phi_pitch``, and the world COM x is
``x_com``.  The path keeps the robot's own COM height at the reference's start (its COM sits ~8 cm
higher above the feet than the FSLIP's point mass) and moves it as the FSLIP's mass moves.

- JUMPING: the stance (x_com, z from r cos β), then the flight the plan predicts (ballistic from
  the lift-off velocity of the plan's figures, for its flight time); feet: the stance foot, and
  the touch-down point (the FSLIP lands with the lift-off leg mirrored: foot = COM − r (sin β⁺,
  cos β⁺), β⁺ = parameter ``beta_liftoff``, as ``FlipSession._touchdown_state`` predicts it).
- FLIGHT (made at the lift-off from the measured COM and its velocity): ballistic for
  ``flight_time``; feet: that touch-down point.
- LANDING: the stance from the touch-down; feet: the stance foot.
Pose orientation: the planned pelvis pitch (``phi_pitch``) about +y; the JUMPING path's flight part,
whose pitch the flight reference plans only at lift-off, holds the lift-off pitch.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Mapping, Optional, Sequence, Tuple

import numpy as np

G = 9.81
JUMPING, FLIGHT, LANDING = 1, 2, 3
#: sample spacing of the predicted flight in a JUMPING path (s; the references' own)
FLIGHT_DT = 0.002


@dataclass
class PlanGeometry:
    """A reference's COM path (world frame) and foot targets."""
    t: np.ndarray                     # sim time of each pose, s
    com: np.ndarray                   # (n, 3) COM, m
    pitch: np.ndarray                 # (n,) planned pelvis pitch about +y, rad
    feet: List[Tuple[str, np.ndarray]] = field(default_factory=list)   # (label, world point)

    def quaternions(self) -> np.ndarray:
        """(n, 4) pose orientations (x, y, z, w): the pitch about +y."""
        h = 0.5 * np.asarray(self.pitch, float)
        return np.column_stack([np.zeros_like(h), np.sin(h), np.zeros_like(h), np.cos(h)])


def _col(names: Sequence[str], value: np.ndarray, name: str) -> Optional[np.ndarray]:
    return value[:, list(names).index(name)] if name in names and value.ndim == 2 else None


def _ballistic(p0, v0, tau, g=G):
    """COM positions (n, 3) at times ``tau`` after leaving ``p0`` with velocity ``v0``."""
    tau = np.asarray(tau, float)[:, None]
    p = np.asarray(p0, float) + tau * np.asarray(v0, float)
    p[:, 2] -= 0.5 * g * tau[:, 0] ** 2
    return p


def reference_geometry(domain: int, start_time: float, t, output_names: Sequence[str], value,
                       parameters: Mapping[str, float], *, com, com_velocity=None, flight_time: float = 0.0,
                       liftoff_xdot: float = 0.0, liftoff_zdot: float = 0.0, foot_z: float = 0.0,
                       landing_foot_z: Optional[float] = None, g: float = G) -> PlanGeometry:
    """The COM path and foot targets of one reference (module doc).  ``value``: (len(t),
    len(output_names)); ``com``: the world COM at the reference's start; ``com_velocity``: at it
    (FLIGHT); ``flight_time``, ``liftoff_xdot``, ``liftoff_zdot``: the message's figures;
    ``foot_z``: height of the stance foot (the FSLIP's foot: the feet's contact-sphere centres),
    ``landing_foot_z``: of the predicted touch-down (default ``foot_z``)."""
    t = np.asarray(t, float)
    value = np.asarray(value, float).reshape(len(t), len(output_names)) if len(output_names) else np.zeros((len(t), 0))
    com = np.asarray(com, float)
    landing_foot_z = foot_z if landing_foot_z is None else landing_foot_z
    offset = float(parameters.get("leg_offset", 0.0))
    L, beta = _col(output_names, value, "L"), _col(output_names, value, "phi_pitch")
    beta_td = parameters.get("beta_liftoff")
    if domain in (JUMPING, LANDING):
        x = _col(output_names, value, "x_com")
        if x is None or L is None or beta is None:
            raise ValueError(f"a ground reference needs x_com, L and phi_pitch, not {list(output_names)}")
        r = L - offset
        z = com[2] + r * np.cos(beta) - r[0] * np.cos(beta[0])
        path = np.column_stack([x, np.full_like(x, com[1]), z])
        times, pitch = start_time + t, beta.copy()
        feet = [("stance", np.array([x[0] - r[0] * np.sin(beta[0]), com[1], foot_z]))]
        if domain == JUMPING and flight_time > 0:
            n = max(int(np.ceil(flight_time / FLIGHT_DT)), 1)
            tau = np.linspace(0.0, flight_time, n + 1)[1:]
            fly = _ballistic(path[-1], (liftoff_xdot, 0.0, liftoff_zdot), tau, g)
            path = np.vstack([path, fly])
            times = np.r_[times, times[-1] + tau]
            pitch = np.r_[pitch, np.full(len(tau), pitch[-1])]
            b = beta[-1] if beta_td is None else -float(beta_td)      # the lift-off lean, mirrored
            feet.append(("touchdown", np.array([fly[-1, 0] + r[-1] * np.sin(b), com[1], landing_foot_z])))
        return PlanGeometry(times, path, pitch, feet)
    if domain == FLIGHT:
        if com_velocity is None:
            raise ValueError("a flight reference's path needs the COM velocity at lift-off")
        T = float(flight_time) if flight_time > 0 else float(t[-1])
        tau = t[t <= T + 1e-12]
        path = _ballistic(com, com_velocity, tau, g)
        pitch = beta[:len(tau)] if beta is not None else np.zeros(len(tau))
        feet = []
        if L is not None and beta_td is not None:
            r = L[0] - offset
            end = _ballistic(com, com_velocity, [T], g)[0]
            feet.append(("touchdown", np.array([end[0] - r * np.sin(float(beta_td)), com[1], landing_foot_z])))
        return PlanGeometry(start_time + tau, path, pitch, feet)
    raise ValueError(f"no geometry for domain {domain}")


def ground_force(t, output_names: Sequence[str], value, d_value, dd_value, mass: float,
                 leg_offset: float = 0.0, g: float = G) -> Optional[Dict[str, np.ndarray]]:
    """The FSLIP's ground reaction force along a ground reference (its leg is massless: the force on
    the mass), {"t", "Fx", "Fz"} with Fx = m ẍ, Fz = m (z̈ + g), z = r cos β, r = L − leg_offset;
    None for a reference without x_com, L and phi_pitch (a flight)."""
    t = np.asarray(t, float)
    k = len(output_names)
    arr = [np.asarray(v, float).reshape(len(t), k) for v in (value, d_value, dd_value)]
    cols = {}
    for name in ("x_com", "L", "phi_pitch"):
        if name not in output_names:
            return None
        i = list(output_names).index(name)
        cols[name] = [a[:, i] for a in arr]
    _, _, xdd = cols["x_com"]
    L, rd, rdd = cols["L"]
    b, bd, bdd = cols["phi_pitch"]
    r = L - leg_offset
    c, s = np.cos(b), np.sin(b)
    zdd = rdd * c - 2.0 * rd * bd * s - r * (bd ** 2 * c + bdd * s)
    return {"t": t, "Fx": mass * xdd, "Fz": mass * (zdd + g)}
