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
