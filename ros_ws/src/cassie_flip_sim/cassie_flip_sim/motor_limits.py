"""Motor limits as on the robot: joint-side torque saturation and the torque–speed envelope of
Cassie's published motor model (the paper's u_lb(q̇) ≤ u ≤ u_ub(q̇), eq. (power) / the Torque Limit
row of the TSC QP).

Envelope per motor, joint side (τ_max = motor limit · gear, ω₀ = no-load rpm · 2π/60 / gear), the
same in both directions (:func:`available_torque`, the one definition of it):

    tlim = clamp(2·τ_max·(1 − |ω|/ω₀), 0, τ_max),   −tlim ≤ u ≤ tlim

the full τ_max up to half the no-load speed, then falling linearly to 0 at |ω| = ω₀, motoring and
braking alike.  The flywheel has a constant 195 N·m limit (paper §V; ``flywheel_torque`` replaces
it; ω₀ = inf) and, optionally, a maximum speed (its no-load speed = that speed, the same envelope).
The compiled copies (cassie_flip_sim/native/step.cpp, the simulator's step; tsc_controller/native/
limits.cpp, the controller's QP bounds) implement this function operation for operation.
Order = contract motor order (architecture.md).
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace
from typing import Optional, Tuple

import numpy as np

from . import robot_params as P


def available_torque(w, tau_max, inv_w0):
    """Torque available to a motor at joint-side speed ``w`` (rad/s), the same for either sign of
    torque and of speed — Cassie's published motor model:

        tlim = clamp(2·τ_max·(1 − |ω|/ω₀), 0, τ_max)

    (``tau_max`` = τ_max, joint side; ``inv_w0`` = 1/ω₀, 0 for a motor without a speed limit, which
    keeps τ_max at any finite speed).  Full torque up to half the no-load speed, τ_max/2 at ¾ω₀, 0
    from ω₀ on.  Source: Agility Robotics' cassie-mujoco-sim (``motor()`` in src/cassiemujoco.c:
    ``tlim = 2 * tmax * (1 - fabs(w) / wmax); tlim = fmax(fmin(tlim, tmax), 0)``), Agility's Gazebo
    plugin (``CassiePlugin::setMotor``) and dairlib's Cassie motor model, which all saturate the
    command to ±tlim; the formula is the same motor side or joint side (τ and ω scale by the gear).

    Scalars or arrays (broadcast).  Order of operations (the compiled copies follow it, so their
    results are equal bit for bit): x = |ω|·(1/ω₀); t = ((1 − x)·2)·τ_max; min(t, τ_max); max(·, 0)
    (NaN in, NaN out; an infinite speed of a motor without a speed limit gives NaN, inf·0)."""
    t = (1.0 - np.abs(w) * inv_w0) * 2.0 * tau_max
    return np.maximum(np.minimum(t, tau_max), 0.0)


@dataclass(frozen=True)
class MotorLimits:
    names: Tuple[str, ...]
    torque_limit: np.ndarray     # joint side, N·m
    no_load_speed: np.ndarray    # joint side, rad/s (inf = no speed dependence)

    @staticmethod
    def from_flywheel(flywheel: P.Flywheel | str | tuple | None = "I",
                      speed_scale: float = 1.0, flywheel_torque: Optional[float] = None) -> "MotorLimits":
        """The robot's motors and the flywheel's.  ``speed_scale`` multiplies the no-load speeds of
        the ten leg motors (1 = the published Cassie motors; a design study of what a flip needs
        may raise it — the knee's 8.5 rad/s caps the lift-off speed near 1.6 m/s).
        ``flywheel_torque`` (N·m) replaces the flywheel's ``max_torque`` (None or 0: its own)."""
        if not (speed_scale > 0.0):
            raise ValueError(f"motor speed scale must be > 0, got {speed_scale}")
        fw = with_flywheel_torque(P.flywheel(flywheel), flywheel_torque)
        motors = list(P.CASSIE_MOTORS) + ([P.flywheel_motor(fw)] if fw is not None else [])
        w0 = np.array([m.no_load_speed for m in motors], float)
        w0[:len(P.CASSIE_MOTORS)] *= speed_scale
        return MotorLimits(tuple(m.joint for m in motors),
                           np.array([m.torque_limit for m in motors], float), w0)

    def __post_init__(self):
        # 1/ω₀, 0 where the no-load speed is inf: bounds() runs twice a step (simulator, controller)
        object.__setattr__(self, "_inv_w0", 1.0 / np.asarray(self.no_load_speed, float))

    @property
    def inv_no_load_speed(self) -> np.ndarray:
        """1/ω₀ per motor (0 for a motor without a speed limit), as :meth:`bounds` uses it."""
        return self._inv_w0

    def bounds(self, motor_velocities) -> Tuple[np.ndarray, np.ndarray]:
        """(lb, ub) = (−tlim, tlim) of the joint-side torques at the given joint-side motor velocities
        (rad/s), tlim = :func:`available_torque`."""
        t = available_torque(np.asarray(motor_velocities, float), self.torque_limit, self._inv_w0)
        return -t, t

    def clip(self, u, motor_velocities) -> np.ndarray:
        """Commanded torques saturated to the envelope: min(max(u, −tlim), tlim)."""
        lb, ub = self.bounds(motor_velocities)
        return np.minimum(np.maximum(np.asarray(u, float), lb), ub)


def flywheel_torque_override(torque) -> Optional[float]:
    """``torque`` checked: None for None or 0 (the flywheel's own limit), else the limit in N·m."""
    if torque is None:
        return None
    if not (isinstance(torque, numbers.Real) and math.isfinite(torque) and torque >= 0):
        raise ValueError(f"flywheel torque limit must be a finite number >= 0 N·m "
                         f"(0 = the flywheel's own), got {torque!r}")
    return float(torque) or None


def with_flywheel_torque(fw: Optional[P.Flywheel], torque=None) -> Optional[P.Flywheel]:
    """``fw`` with ``max_torque`` = ``torque`` N·m (None or 0: ``fw`` unchanged)."""
    t = flywheel_torque_override(torque)
    if t is None:
        return fw
    if fw is None:
        raise ValueError("a flywheel torque limit was given for a robot without a flywheel")
    return replace(fw, max_torque=t)


DEFAULT_LIMITS = MotorLimits.from_flywheel("I")


def torque_bounds(motor_velocities, limits: MotorLimits = DEFAULT_LIMITS) -> Tuple[np.ndarray, np.ndarray]:
    """(lb, ub) = (u_lb(q̇), u_ub(q̇)) for the 11 motors in contract order."""
    return limits.bounds(motor_velocities)
