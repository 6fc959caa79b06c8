"""tsc_node holds its answer to a contact event's step until the planner's reference for the domain
entered has come, as sim_node holds that step (lockstep): the reference and the state are two topics with
no order between them, and a state that came first was answered without the plan (a graph backflip's
touch-down command then differed from its offline reproduction: test_graph_flips)."""
import json
import subprocess
import sys
from pathlib import Path

from ros_harness import new_domain, node_env

PROBE = Path(__file__).resolve().parents[1] / "nodes" / "reference_hold_probe.py"


def _probe(*args):
    with new_domain() as claim:
        r = subprocess.run([sys.executable, str(PROBE), *args], env=node_env(claim.domain_id),
                           capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    return json.loads(r.stdout.strip().splitlines()[-1])


def test_the_contact_events_step_waits_for_its_reference():
    out = _probe("hold")
    assert out["standing"] == [0, 1, 2]
    assert out["event_step"] == [0, 1, 2] and out["sent_again"] == [0, 1, 2] and out["held"] is True
    assert out["after_reference"] == [0, 1, 2, 3] and out["next"] == [0, 1, 2, 3, 4]


def test_without_the_hold_or_past_its_timeout_the_step_is_answered():
    """``hold_for_reference`` false (realtime mode: the simulator steps on): answered at once; held, the
    step is answered without the reference once REFERENCE_HOLD_TIMEOUT_S has passed."""
    out = _probe("nohold")
    assert out["event_step"] == [0, 1, 2, 3] and out["held"] is False
    out = _probe("hold", "0.05")
    assert out["event_step"] == [0, 1, 2] and out["sent_again"] == [0, 1, 2, 3] and out["held"] is False
