"""flip_tools.offline.feet_apart: the stance a run ends in (what a next flip in a row jumps from)."""
import math

import numpy as np
import pytest

from cassie_flip_sim.simulator import Simulator
from flip_tools.offline import feet_apart

SITES = [f"{s}_foot_{k}" for s in ("left", "right") for k in ("toe", "heel")]


def _rot(psi):
    c, s = math.cos(psi), math.sin(psi)
    return np.array([[c, -s], [s, c]])


def test_feet_apart_reads_one_foot_ahead_or_turned():
    """Standing as built, the feet are side by side and parallel.  The left foot's sites moved 20 mm
    along the feet's heading read as 20 mm ahead and not turned; turned 5 deg about its centre instead,
    as 5 deg apart.  The whole stance turned 30 deg about the vertical reads the same."""
    sim = Simulator()
    m, d = sim.model, sim.data
    ids = {n: m.site(n).id for n in SITES}
    ahead, yaw = feet_apart(sim)
    assert abs(ahead) < 1e-3 and abs(yaw) < math.radians(0.1)
    xy0 = {n: d.site_xpos[i][:2].copy() for n, i in ids.items()}
    heading = xy0["right_foot_toe"] - xy0["right_foot_heel"]
    heading /= np.linalg.norm(heading)
    centre = 0.5 * (xy0["left_foot_toe"] + xy0["left_foot_heel"])
    stepped, turned = dict(xy0), dict(xy0)
    for k in ("toe", "heel"):
        n = f"left_foot_{k}"
        stepped[n] = xy0[n] + 0.02 * heading
        turned[n] = centre + _rot(math.radians(5.0)) @ (xy0[n] - centre)
    for psi in (0.0, math.radians(30.0)):
        for xy, want_ahead, want_yaw in ((stepped, 0.02, 0.0), (turned, None, 5.0)):
            for n, i in ids.items():
                d.site_xpos[i][:2] = _rot(psi) @ xy[n]
            ahead, yaw = feet_apart(sim)
            if want_ahead is not None:
                assert ahead == pytest.approx(want_ahead, abs=1e-4)
            assert math.degrees(yaw) == pytest.approx(want_yaw, abs=1e-6)
