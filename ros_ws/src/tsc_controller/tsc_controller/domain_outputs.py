"""The outputs of the domains built from their gains ({name: (weight, kp, kd)}, config.DEFAULT_GAINS)."""
from __future__ import annotations

from . import outputs as O


def _mk(cls, name, gains, key=None, **kw):
    w, kp, kd = gains[key or name]
    return cls(name=name, weight=w, kp=kp, kd=kd, **kw)


def _ground_outputs(gains):
    """The outputs of a ground domain (paper §V-A): H_pitch, leg length, COM x/y, pelvis roll/pitch/yaw."""
    return [_mk(O.CentroidalPitchMomentum, "H_pitch", gains), _mk(O.LegLength, "L", gains),
            _mk(O.ComPosition, "com", gains, axes=(0, 1)),
            _mk(O.PelvisOrientation, "pelvis", gains, axes=("roll", "pitch", "yaw"))]

