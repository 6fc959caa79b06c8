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
        self.impact = None                # [reference, k]: the scale of its momentum, once measured

    def enter(self):
        self.ground.reanchor()            # re-anchor the standing targets at the current state
        self.impact = None

    def task(self, t, ref, t_enter):
        tau = 0.0 if ref is None else max(0.0, t - max(t_enter, ref.start_time))
        g = self.ground
        des = g.targets(t, True)
        if ref is not None:
            g.follow(des, ref.sample(tau))
            self.scale_to_impact(des["H_pitch"], ref, tau)
            outs = self.plan_outputs
        else:
            cfg = self.cfg
            self.o_H.weight = float(quintic(cfg.landing_H_weight, g.o_H.weight, cfg.landing_H_ramp,
                                            t - g.stand["t0"])[0])
            outs = self.own_outputs
        return outs, [des[o.name] for o in outs]

    def scale_to_impact(self, d, ref, tau):
        """Scale the plan's momentum (H_FSLIP of Y1, eq. (Y1)) by k = H / H_FSLIP measured
        ``landing_impact_time`` after its touch-down, 0 <= k <= 1 (1 where the signs differ or the plan
        holds under 1 kg m^2/s): the plan is solved from the touch-down's pre-impact state, and the
        impact takes momentum out within a few ms; tracked as solved, that momentum went back in."""
        t_i = self.cfg.landing_impact_time
        if t_i <= 0.0:
            return
        if self.impact is None or self.impact[0] is not ref:
            self.impact = [ref, None]             # a rebound's re-solve is scaled at its own impact
        k = self.impact[1]
        if k is None:
            if tau < t_i:
                return
            dyn = self.ground.dyn
            H, H_plan = float(dyn.Ag[4] @ dyn.v), float(d.value[0])
            k = min(max(H / H_plan, 0.0), 1.0) if abs(H_plan) > 1.0 and H * H_plan > 0.0 else 1.0
            self.impact[1] = k
        if k != 1.0:
            d.value[0] *= k
            d.d_value[0] *= k
            d.dd_value[0] *= k

    def done(self, t, ref):
        """The landing is over: its reference has ended or, without one, the own landing
        (:meth:`GroundTargets.landing_done`), not after blend_time: re-anchoring the standing targets
        mid-catch throws the robot."""
        return ref.start_time + ref.duration < t if ref is not None else self.ground.landing_done(t)
