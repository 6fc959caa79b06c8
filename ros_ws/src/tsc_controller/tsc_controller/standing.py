"""The STANDING domain: :class:`Standing`."""
from __future__ import annotations

from .config import ControllerConfig
from .domain_outputs import _ground_outputs
from .ground_targets import GroundTargets
from .reference import Domain


class Standing:
    """STANDING: the ground outputs with the standing gains, held at the standing targets; the H_pitch
    weight gives way while the COM is off the feet (:meth:`H_weight`)."""
    domain = Domain.STANDING

    def __init__(self, ground: GroundTargets, cfg: ControllerConfig):
        self.ground = ground
        self.outputs = _ground_outputs({**cfg.gains, **cfg.standing_gains})
        self.H_w0 = self.outputs[0].weight       # see H_weight

    def enter(self):
        self.ground.reanchor()            # re-anchor the standing targets at the current state

    def task(self, t):
        des = self.ground.targets(t, False)
        self.H_weight()
        return self.outputs, [des[o.name] for o in self.outputs]

    def H_weight(self):
        """The STANDING H_pitch weight: its ``standing_gains`` value while the COM is over the span of
        the feet on the ground (along their heading); past its front or back, falling linearly to
        ``standing_H_edge_weight`` of it at ``standing_H_edge`` beyond and further out.

        Why: with the COM off the feet the ground cannot give the moment that brings it back, and the
        H_pitch output's momentum removal asks for the opposite moment; at full weight it costs the QP
        more than the COM error saves, so the COM stays off the feet and the flywheel takes the
        toppling moment.  Back over the feet, the removal needs no COM error and the weight is back.
        The measurements: docs/tuning.md, ``standing_H_edge``."""
        self.outputs[0].weight = self.ground.standing_H_weight(self.H_w0)
