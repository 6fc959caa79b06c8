"""`flip study flywheel` (paper Table I): flip C planned for flywheels I, II, III."""
import json
import subprocess
import sys

from ros_harness import FLIP


def test_study_flywheel_plans_flip_c_for_each_flywheel(tmp_path):
    r = subprocess.run([sys.executable, str(FLIP), "study", "flywheel", "--motor-speed-scale", "3",
                        "--out", str(tmp_path)], capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stdout + r.stderr
    doc = json.loads((tmp_path / "study.json").read_text())
    rows = {row["flywheel"]: row for row in doc["rows"]}
    assert list(rows) == ["I", "II", "III"] and doc["platform"] == 0.5 and doc["apex"] == 1.2
    rpm = [rows[k]["planned_rpm"] for k in ("I", "II", "III")]
    # as in the paper: a larger flywheel inertia needs a lower flywheel speed
    assert rpm[0] > rpm[1] > rpm[2] > 0
    assert "planned rpm" in r.stdout and "1645" in r.stdout


def test_study_flywheel_names_the_limit_when_flip_c_is_out_of_reach(tmp_path):
    # the published knee motor (8.5 rad/s no-load) cannot lift the robot to a 1.2 m apex
    r = subprocess.run([sys.executable, str(FLIP), "study", "flywheel", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 2, r.stdout + r.stderr
    rows = json.loads((tmp_path / "study.json").read_text())["rows"]
    assert all(row["planned_rpm"] is None and "knee" in row["reason"] for row in rows)
