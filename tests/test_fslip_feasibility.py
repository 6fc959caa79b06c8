"""Malformed and impossible requests give named, quantified reasons."""
import math
import re

import pytest

from fslip_planner import plan as P
from fslip_planner.feasibility import InfeasibleRequest


def test_apex_6m_names_the_limit():
    with pytest.raises(InfeasibleRequest) as e:
        P.plan_flip("backflip", apex_height=6.0)
    msg = str(e.value)
    assert "apex 6.00 m" in msg and "envelope" in msg
    m = re.search(r"max reachable apex ≈ ([0-9.]+) m", msg)
    assert m and 1.0 < float(m.group(1)) < 1.5
    assert re.search(r"lift-off speed ≈([0-9.]+) m/s", msg)
    assert float(re.search(r"over by ([0-9.]+) m", msg).group(1)) == pytest.approx(6.0 - float(m.group(1)), abs=0.01)


@pytest.mark.parametrize("kw, match", [
    (dict(kind="backflip", apex_height=math.nan), "finite"),
    (dict(kind="backflip", apex_height=-1.0), "positive"),
    (dict(kind="cartwheel"), "unknown kind"),
    (dict(kind="frontflip", forward_distance=100.0), "outside"),
    (dict(kind="frontflip", forward_distance=math.inf), "finite"),
    (dict(kind="backflip", platform_height=-0.3), "platform_height"),
    (dict(kind="backflip", flywheel="IV"), "unknown flywheel"),
    (dict(kind="backflip", apex_height=0.5), "standing COM height"),
])
def test_malformed_rejected(kw, match):
    kind = kw.pop("kind")
    with pytest.raises(ValueError, match=match):
        P.plan_flip(kind, **kw)
    with pytest.raises(ValueError, match=match):
        P.FlipSession(kind, **kw).jumping_reference()


def test_ipopt_failure_names_constraint():
    with pytest.raises(InfeasibleRequest, match="most violated constraint"):
        P.plan_flip("frontflip", apex_height=1.12, forward_distance=1.0)
