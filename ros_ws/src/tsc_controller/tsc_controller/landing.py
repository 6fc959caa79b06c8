"""The LANDING domain: :class:`Landing`."""
from __future__ import annotations

from . import outputs as O
from .config import ControllerConfig
from .domain_outputs import _ground_outputs, _mk
from .ground_targets import GroundTargets
from .profiles import quintic
from .reference import Domain


class Landing:
    """LANDING: with a landing reference (after a somersault with ``track_landing_reference``, after a
    hop with ``track_hop_landing_reference``) the ground outputs with the landing gains
    (``landing_gains`` over ``gains``) track it over the standing targets; without one, the controller's
    own landing: the standing targets (leg catch, momentum removal, COM against the removal's CoP
    offset) with an H_pitch weight rising from
    ``landing_H_weight`` over ``landing_H_ramp``."""
    domain = Domain.LANDING

    def __init__(self, ground: GroundTargets, cfg: ControllerConfig):
        self.ground, self.cfg = ground, cfg
        self.o_H = _mk(O.CentroidalPitchMomentum, "H_pitch", cfg.gains)      # the own landing's; weight set per tick
        self.own_outputs = [self.o_H, ground.o_L, ground.o_com, ground.o_pel]
        self.plan_outputs = _ground_outputs({**cfg.gains, **cfg.landing_gains})

    def enter(self):
        self.ground.reanchor()            # re-anchor the standing targets at the current state

    def task(self, t, ref, t_enter):
        tau = 0.0 if ref is None else max(0.0, t - max(t_enter, ref.start_time))
        g = self.ground
        des = g.targets(t, True)
        if ref is not None:
            g.follow(des, ref.sample(tau))
            outs = self.plan_outputs
        else:
            cfg = self.cfg
            self.o_H.weight = float(quintic(cfg.landing_H_weight, g.o_H.weight, cfg.landing_H_ramp,
                                            t - g.stand["t0"])[0])
            outs = self.own_outputs
        return outs, [des[o.name] for o in outs]

    def done(self, t, ref):
        """The landing is over: its reference has ended or, without one, the own landing
        (:meth:`GroundTargets.landing_done`), not after blend_time: re-anchoring the standing targets
        mid-catch throws the robot."""
        return ref.start_time + ref.duration < t if ref is not None else self.ground.landing_done(t)
