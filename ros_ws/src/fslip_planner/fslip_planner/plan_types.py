"""The planner's data: the measured states it plans from (:class:`MeasuredState` at a contact event,
:class:`PelvisState` from ``/odom``) and the sampled references it returns (:class:`Reference`)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional

import numpy as np


@dataclass
class MeasuredState:
    """Floating-base state at a contact event (world frame, SI units); ``support_center`` is the
    centre of the feet's contact points (the FSLIP's foot), None where it is not known."""
    t: float
    com: np.ndarray
    com_velocity: np.ndarray
    pitch_momentum: float
    pelvis_pitch: float
    pelvis_pitch_rate: float
    support_center: Optional[np.ndarray] = None


@dataclass
class PelvisState:
    """The pelvis as ``/odom`` carries it: world position, orientation quaternion (x, y, z, w), and
    linear and angular velocity in the pelvis frame (REP 105); with the flywheel's speed."""
    t: float
    position: np.ndarray
    orientation: np.ndarray
    linear_velocity: np.ndarray
    angular_velocity: np.ndarray
    #: the flywheel joint's speed (rad/s, /joint_states); None: not measured
    flywheel_speed: float | None = None


@dataclass
class Reference:
    """Sampled reference for the controller: ``value``/``d_value``/``dd_value`` are (n, k)."""
    domain: int
    t: np.ndarray
    names: List[str]
    value: np.ndarray
    d_value: np.ndarray
    dd_value: np.ndarray
    parameters: Dict[str, float] = field(default_factory=dict)
    figures: Dict[str, float] = field(default_factory=dict)

    @property
    def duration(self):
        return float(self.t[-1])

    def column(self, name):
        i = self.names.index(name)
        return self.value[:, i], self.d_value[:, i], self.dd_value[:, i]
