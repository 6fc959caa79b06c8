"""`flip study flywheel` (paper Table I): flip C planned for flywheels I, II, III."""
import json
import subprocess
import sys

from ros_harness import FLIP


def test_study_flywheel_plans_flip_c_for_each_flywheel(tmp_path):
    r = subprocess.run([sys.executable, str(FLIP), "study", "flywheel", "--motor-speed-scale", "3",
                        "--out", str(tmp_path)], capture_output=True, text=True, timeout=300)
    # exit 4 when a flywheel's flip is rejected: III's 28.6 kg shorten the flight until the 195 N·m
    # motor cannot turn the body in it (the planner's flight check names it)
    assert r.returncode in (0, 4), r.stdout + r.stderr
    doc = json.loads((tmp_path / "study.json").read_text())
    rows = {row["flywheel"]: row for row in doc["rows"]}
    assert list(rows) == ["I", "II", "III"] and doc["platform"] == 0.5 and doc["apex"] == 1.2
    rpm = [rows[k]["planned_rpm"] for k in ("I", "II", "III")]
    # as in the paper: a larger flywheel inertia needs a lower flywheel speed
    assert rpm[0] > rpm[1] > 0
    assert (rpm[2] is not None and rpm[1] > rpm[2] > 0) or "flywheel torque" in rows["III"]["reason"]
    assert (r.returncode == 0) == (rpm[2] is not None)
    assert "planned rpm" in r.stdout and "1645" in r.stdout


def test_study_flywheel_names_the_limit_when_flip_c_is_out_of_reach(tmp_path):
    # the published knee motor (8.5 rad/s no-load) cannot lift the robot to a 1.2 m apex
    r = subprocess.run([sys.executable, str(FLIP), "study", "flywheel", "--out", str(tmp_path)],
                       capture_output=True, text=True, timeout=300)
    assert r.returncode == 4, r.stdout + r.stderr
    rows = json.loads((tmp_path / "study.json").read_text())["rows"]
    assert all(row["planned_rpm"] is None and "knee" in row["reason"] for row in rows)


def test_platform_flip_lands_beyond_the_platform_unless_told_otherwise(tmp_path):
    """Flip C as the issue words it (no --distance): the robot stands 0.05 m behind the platform's
    edge, so a flip in place would land on the platform; the request gets a forward distance that puts
    the whole foot (heel 0.10 m behind the foot point) past the edge with room for the shins."""
    from cassie_model.model import Scenario

    def plan(*extra):
        out = tmp_path / ("p" + "_".join(extra))
        r = subprocess.run([sys.executable, str(FLIP), "plan", "frontflip", "--platform", "0.5", "--apex", "1.2",
                            "--motor-speed-scale", "3", "--out", str(out), *extra],
                           capture_output=True, text=True, timeout=300)
        assert r.returncode == 0, r.stdout + r.stderr
        return json.loads((out / "plan.json").read_text())["request"]["forward_distance"]
    edge = Scenario.platform(0.5).platform_edge_x
    assert plan() - 0.10 > edge + 0.2
    assert plan("--distance", "0") == 0.0


def test_the_simulated_table_prints_a_refused_flywheel(capsys):
    """--simulate runs only the flywheels whose flip C plans: a refused one (flywheel III on the
    design-study robot: no landing from its sink) has no measured speed and is printed, not a crash."""
    from argparse import Namespace
    from flip_tools.cli.study import print_study
    rows = [{"flywheel": "I", "I_pitch": 0.1074, "mass": 9.54, "paper_rpm": 1645.0, "planned_rpm": 2362.8,
             "run_exit": 0, "outcome": "landed", "measured_rpm": 2845.2},
            {"flywheel": "III", "I_pitch": 0.3222, "mass": 28.63, "paper_rpm": 573.0, "planned_rpm": None,
             "reason": "no landing plan from the touch-down this jump leads to"}]
    print_study(Namespace(platform=0.5, apex=1.2, simulate=True, robot="cassie-legs3-fw260"), rows,
                {"flywheel_torque": 260.0, "motor_speed_scale": 3.0}, 0.6)
    out = capsys.readouterr().out.splitlines()
    assert out[2].split()[-2:] == ["2845", "landed"]
    assert out[3].split()[-3:] == ["infeasible", "-", "-"] and "no landing plan" in out[4]
