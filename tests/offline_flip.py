"""The offline flip runner for the tests: flip_tools.offline (simulator, planner and
controller wired as the node graph wires them, in one process), re-exported under its old name, plus
the tests' own check of a landed flip's end (:func:`assert_stands`)."""
from __future__ import annotations

import numpy as np

from flip_tools.offline import *  # noqa: F401,F403
from flip_tools.offline import (REQUEST_LEAD, NodeStateReader, measured, pelvis_state, run, stamp,  # noqa: F401
                                to_sampled)


def assert_stands(sim, ctl, z_stand):
    """The end of a landed flip: STANDING, pelvis at standing height, upright, flywheel momentum out."""
    from tsc_controller import Domain
    assert ctl.domain == Domain.STANDING
    p, (w, x, y, z) = sim.pelvis_pose()
    assert abs(p[2] - z_stand) < 0.03
    tilt = np.degrees(np.arccos(np.clip(1 - 2 * (x * x + y * y), -1, 1)))
    assert tilt < 10.0
    assert abs(sim.centroidal_pitch_momentum()) < 1.0
