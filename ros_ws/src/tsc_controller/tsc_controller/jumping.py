"""The JUMPING domain: :class:`Jumping`."""
from __future__ import annotations

from .config import ControllerConfig
from .domain_outputs import _ground_outputs
from .ground_targets import GroundTargets
from .reference import Domain


class Jumping:
    """JUMPING: the ground outputs with the jumping gains, tracking the planner's jumping reference
    (eq. Y^{J/L}) over the standing targets STANDING began (names the reference lacks keep them)."""
    domain = Domain.JUMPING

    def __init__(self, ground: GroundTargets, cfg: ControllerConfig):
        self.ground, self.cfg = ground, cfg
        self.outputs = _ground_outputs({**cfg.gains, **cfg.jumping_gains})

    def enter(self):
        pass                              # the standing targets go on (turned into the heading frame)

    def task(self, t, ref):
        des = self.ground.targets(t, False)
        self.ground.follow(des, ref.sample(t - ref.start_time))
        return self.outputs, [des[o.name] for o in self.outputs]

    def push_over(self, t, t_end):
        """JUMPING has run past its reference without a lift-off: over after ``grace``, or after
        ``push_grace`` while the COM still rises faster than ``push_rising`` (see the config)."""
        late = t - t_end
        if late <= self.cfg.grace:
            return False
        dyn = self.ground.dyn
        rising = float(dyn.hg_lin[2]) / dyn.mass > self.cfg.push_rising
        return not rising or late > self.cfg.push_grace
