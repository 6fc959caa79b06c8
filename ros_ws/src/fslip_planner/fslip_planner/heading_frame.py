"""The jump's heading frame: the world turned by -ψ about the vertical through the pelvis at the
request, ψ the pelvis' heading then.  The plans' x is along that heading, as the controller, which
turns the robot the same way from the jump's start on (tsc_controller ``Controller._heading_frame``),
reads it: the FSLIP's sagittal plane is the plane the robot faces."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .plan_types import MeasuredState


def turn_xy(psi: float) -> np.ndarray:
    """2×2 rotation by -psi about the vertical."""
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, s], [-s, c]])


@dataclass(frozen=True)
class HeadingFrame:
    psi: float        # heading of the pelvis (rad, about the vertical)
    pivot: tuple      # (x, y) of the pelvis, m

    @classmethod
    def of_pelvis(cls, position, orientation_xyzw) -> "HeadingFrame":
        """The frame of a pelvis at ``position`` with ``orientation_xyzw`` (/odom's quaternion)."""
        x, y, z, w = (float(v) for v in orientation_xyzw)
        psi = math.atan2(2.0 * (x * y + z * w), 1.0 - 2.0 * (y * y + z * z))
        return cls(psi, (float(position[0]), float(position[1])))

    def point(self, p):
        """A world point (x, y, z) in this frame (None stays None)."""
        if p is None:
            return None
        p = np.array(p, float)
        P = np.asarray(self.pivot)
        p[:2] = P + turn_xy(self.psi) @ (p[:2] - P)
        return p

    def vector(self, v):
        """A world vector (x, y, z) in this frame."""
        v = np.array(v, float)
        v[:2] = turn_xy(self.psi) @ v[:2]
        return v

    def measured(self, state: MeasuredState) -> MeasuredState:
        """A contact event's state in this frame: positions and velocities turned, the pitch momentum
        about the heading's lateral axis taken as the world-y one over cos ψ (the contact event carries
        the world-y component only; a somersault's momentum has none along its heading).  Unchanged
        for ψ = 0."""
        if self.psi == 0.0:
            return state
        return MeasuredState(state.t, self.point(state.com), self.vector(state.com_velocity),
                             float(state.pitch_momentum) / math.cos(self.psi), state.pelvis_pitch,
                             state.pelvis_pitch_rate, self.point(state.support_center))
