"""End to end through the real node graph (sim_node, planner_node, tsc_node, recorder, each its own
process, lockstep), judged from the recorded bag: `scripts/flip run`.

* A hop (a FlipRequest with zero flip momentum) lands and stands (issue: the TSC from standing to
  flight and landing).
* A backflip: the planned jump is executed, the robot leaves the ground turning backwards, and the
  bag carries the verdict (computed from /odom, not from the controller).  It does NOT land yet.
  (Deterministic checks of the same jump without ROS: tests/test_offline_jump.py.)"""
import json
import subprocess
import sys

import pytest

from ros_harness import FLIP  # noqa: F401  (puts scripts/ on sys.path)


def run_flip(tmp_path, kind, *args):
    out = tmp_path / kind
    r = subprocess.run([sys.executable, str(FLIP), "run", kind, "--out", str(out), *args],
                       capture_output=True, text=True, timeout=900)
    summary = json.loads((out / "summary.json").read_text())
    return r, summary, out


def events(summary, name):
    return [e["t"] for e in summary["contact_events"] if e["event"] == name]


def test_hop_lands_through_the_graph(tmp_path):
    r, s, out = run_flip(tmp_path, "hop")
    assert r.returncode == 0, r.stdout + r.stderr
    assert s["outcome"] == "landed" and s["response"]["accepted"] is True
    lo, td = events(s, "LIFT_OFF"), events(s, "TOUCH_DOWN")
    assert len(lo) == 1 and len(td) == 1 and td[0] - lo[0] > 0.1        # one flight, and a real one
    assert s["apex_rise_m"] > 0.08
    assert abs(s["net_rotation_deg"]) < 5 and s["final_tilt_deg"] < 3
    assert s["at_rest"] is True and not events(s, "BODY_CONTACT")
    assert {n: p["returncode"] for n, p in s["processes"].items()} == {"recorder": 0, "sim": 0, "planner": 0,
                                                                      "tsc": 0}
    assert (out / "bag" / "metadata.yaml").exists() and (out / "fig6.png").exists()


def test_backflip_runs_through_the_graph_and_the_bag_tells(tmp_path):
    """The jump starts at the sim time the request arrives (+ a lead), which depends on wall-clock
    timing, so the run is not bit-reproducible; what it must always show: the planned jump is
    executed and leaves the ground backwards, every node ends cleanly, and the verdict comes from
    the bag.  The deterministic version of the jump is tests/test_offline_jump.py."""
    from flip_tools.bag import load_bag
    r, s, out = run_flip(tmp_path, "backflip")
    assert r.returncode in (0, 1), r.stdout + r.stderr                # a verdict, not an infrastructure failure
    assert s["response"]["accepted"] is True and s["response"]["liftoff_pitch_rate"] < 0
    assert all(p["returncode"] == 0 for p in s["processes"].values())
    refs = load_bag(out / "bag", ["/fslip/reference"])["/fslip/reference"]["refs"]
    assert [x["domain"] for x in refs][:3] == [1, 2, 3]                # jumping, flight at lift-off, landing
    jump = refs[0]
    lo = events(s, "LIFT_OFF")
    assert lo and lo[0] > jump["start_time"]
    assert s["net_rotation_deg"] < -90                                  # turned backwards
    assert s["outcome"] in ("landed", "fell", "body_contact", "under_rotated", "over_rotated", "not_at_rest")
