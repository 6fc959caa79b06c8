"""The JUMPING domain: :class:`Jumping`."""
from __future__ import annotations

import numpy as np

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
        self._push = None                 # (reference, t of its deepest crouch, times, L from there)
        self._tau_push = -np.inf          # the push's last phase (it never goes back)

    def enter(self):
        self._push, self._tau_push = None, -np.inf  # the standing targets go on (in the heading frame)

    def task(self, t, ref):
        des = self.ground.targets(t, False)
        tau = t - ref.start_time
        if self.cfg.push_phase_from_leg and ref.has("L"):
            tau = self._push_phase(tau, ref)
        self.ground.follow(des, ref.sample(tau))
        return self.outputs, [des[o.name] for o in self.outputs]

    def _push_phase(self, tau, ref):
        """The reference's time in the push (after its deepest crouch): where its leg length (made
        non-decreasing) is the measured one, never going back; before it, ``tau`` (see
        ControllerConfig.push_phase_from_leg)."""
        if self._push is None or self._push[0] is not ref:
            L = ref.value[:, ref.names.index("L")]
            i0 = int(np.argmin(L))
            self._push = (ref, float(ref.t[i0]), ref.t[i0:], np.maximum.accumulate(L[i0:]))
            self._tau_push = -np.inf
        _, t0, tt, Lm = self._push
        if tau < t0:
            return tau
        L_now = float(self.ground.o_L.evaluate(self.ground.dyn)[0][0])
        k = int(np.searchsorted(Lm, L_now, side="right"))
        tp = float(tt[-1]) if k >= len(Lm) else (float(tt[0]) if k == 0 else
                                                float(np.interp(L_now, Lm[k - 1:k + 1], tt[k - 1:k + 1])))
        self._tau_push = max(self._tau_push, tp)
        return self._tau_push

    def push_over(self, t, t_end):
        """JUMPING has run past its reference without a lift-off: over after ``grace``, or after
        ``push_grace`` while the COM still rises faster than ``push_rising`` (see the config)."""
        late = t - t_end
        if late <= self.cfg.grace:
            return False
        dyn = self.ground.dyn
        rising = float(dyn.hg_lin[2]) / dyn.mass > self.cfg.push_rising
        return not rising or late > self.cfg.push_grace
