"""Motor limits as on the robot: joint-side torque saturation and Cassie's published torque–speed
envelope (the paper's u_lb(q̇) ≤ u ≤ u_ub(q̇), eq. (power) / the Torque Limit row of the TSC QP).

Envelope per motor, joint side (τ_max = motor limit · gear, ω₀ = no-load rpm · 2π/60 / gear), as
Cassie's own simulators apply it (cassie-mujoco-sim ``motor()``, Agility's Gazebo plugin
``CassiePlugin::setMotor``): |τ| ≤ min(τ_max, 2 τ_max (1 − |ω|/ω₀)), clamped at 0, whatever the
sign of the torque — full torque up to half the no-load speed, none beyond it, driving or braking.
The flywheel has a constant 195 N·m limit (paper §V; ``flywheel_torque`` replaces it) and, optionally,
a maximum speed (no-load speed = that speed).  Order = contract motor order (architecture.md).

:func:`available_fraction` is the envelope's one Python form; ``native/motor_envelope.h`` its one
C++ form, which the simulator's torque clip (cassie_flip_sim native/step.cpp) and the controller's
bounds (tsc_controller native/limits.cpp) include, each tested bit for bit against this module.  The
planner's leg-force rows use :func:`planning_fraction`, an inner bound of it.
"""
from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, replace
from typing import Optional, Tuple

import numpy as np

from . import robot_params as P


def available_fraction(speed_ratio):
    """Share of a motor's torque limit available at |ω|/ω₀ = ``speed_ratio`` (either sign of the
    torque): min(1, 2 (1 − |ω|/ω₀)) clamped at 0 — Cassie's published curve.  numpy arrays; NaN
    stays NaN."""
    return np.minimum(np.maximum(2.0 * (1.0 - np.abs(speed_ratio)), 0.0), 1.0)


def planning_rows(speed_ratio):
    """The planner's leg-force rows (fslip_planner.jumping, paper §III-B actuation constraints):
    F ≤ F_max · each of (1 − r, 2 (1 + r)), besides F ≤ F_max, at the signed speed ratio r = ω/ω₀
    (r > 0: the motor drives the push).  Driving, the chord 1 − r of :func:`available_fraction` from
    stall to no-load: it leaves the controller the rest of the envelope to track the plan with.
    Braking, the envelope itself.  No min/max: CasADi expressions work as well as numbers."""
    return 1.0 - speed_ratio, 2.0 * (1.0 + speed_ratio)


def planning_fraction(speed_ratio):
    """min(1, :func:`planning_rows`): the share of the torque limit the planner's trajectories use
    at the signed speed ratio; never more than :func:`available_fraction` of its magnitude."""
    a, b = planning_rows(np.asarray(speed_ratio, float))
    return np.minimum(np.minimum(a, b), 1.0)


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
        """(lb, ub) of the joint-side torques at the given joint-side motor velocities (rad/s)."""
        w = np.asarray(motor_velocities, float)
        avail = self.torque_limit * available_fraction(w * self._inv_w0)
        return -avail, avail

    def clip(self, u, motor_velocities) -> np.ndarray:
        """Commanded torques saturated to the envelope."""
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
