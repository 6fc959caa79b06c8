"""`flip` checks every argument before it touches the output folder, and never deletes what it did
not write (issue: a refused argument wiped a copied run's folder)."""
import json
import subprocess
import sys

import pytest

from ros_harness import FLIP


def flip(*args):
    return subprocess.run([sys.executable, str(FLIP), *args], capture_output=True, text=True, timeout=120)


def a_previous_run(path):
    """A folder as `flip run` leaves it (run.json, a bag, a summary), plus a file of the user's."""
    (path / "bag").mkdir(parents=True)
    (path / "bag" / "bag_0.mcap").write_bytes(b"mcap")
    for name in ("run.json", "summary.json", "fig6.png", "notes.txt"):
        (path / name).write_text(name)
    return sorted(p.relative_to(path) for p in path.rglob("*"))


@pytest.mark.parametrize("args, message", [
    (["run", "backflip", "--motor-speed-scale", "0"], "must be > 0"),
    (["run", "backflip", "--flywheel-torque", "-1"], "must be > 0"),
    (["run", "backflip", "--settle", "-5"], "must be >= 0"),
    (["run", "backflip", "--duration", "0"], "must be > 0"),
    (["run", "backflip", "--platform", "-0.5"], "must be >= 0"),
    (["run", "backflip", "--apex", "nan"], "not finite"),
    (["run", "backflip", "--plant", "friction=0"], "friction must be > 0"),
    (["run", "backflip", "--plant", "mass=1.1"], "--plant: expected KNOB=VALUE"),
    (["run", "backflip", "--plant", "delay_steps=1.5"], "whole number"),
    (["stand", "--duration", "0"], "must be > 0"),
    (["sim", "--duration", "-1"], "must be > 0"),
])
def test_a_refused_argument_leaves_the_output_folder_as_it_was(tmp_path, args, message):
    out = tmp_path / "copy"
    before = a_previous_run(out)
    r = flip(*args, "--out", str(out))
    assert r.returncode == 2 and message in r.stderr + r.stdout, r.stderr      # usage error
    assert "Traceback" not in r.stderr
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before


def test_a_folder_that_is_no_run_of_flip_is_refused_and_kept(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("months of work")
    r = flip("stand", "--duration", "0.1", "--out", str(out))
    assert r.returncode == 2 and "not a previous run" in r.stderr, r.stderr
    assert (out / "thesis.tex").read_text() == "months of work" and len(list(out.iterdir())) == 1


def test_an_unwritable_out_is_an_error_not_a_traceback(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = flip("stand", "--duration", "0.1", "--out", str(blocker / "sub"))
    assert r.returncode == 2 and "--out" in r.stderr and "Traceback" not in r.stderr, r.stderr


# ---------------------------------------------------------------------------------------------
# exit codes: one per meaning, as README's table says (issue 26, item 6)
def readme_exit_codes() -> dict[int, str]:
    """The exit-code table of README's `flip` section: {code: meaning}."""
    text = (FLIP.parents[1] / "README.md").read_text()
    table = text[text.index("| exit code |"):].split("\n\n")[0]
    rows = [r.split("|")[1:3] for r in table.splitlines()[2:]]
    return {int(code.strip().strip("`")): meaning.strip() for code, meaning in rows}


def test_exit_codes_are_distinct_and_documented():
    from flip_tools.cli import common
    codes = {k: getattr(common, k) for k in dir(common) if k.startswith("EXIT_")}
    assert len(set(codes.values())) == len(codes), codes
    assert codes["EXIT_USAGE"] == 2                      # argparse's own
    assert sorted(readme_exit_codes()) == sorted(codes.values())
    doc = readme_exit_codes()
    for name, words in (("EXIT_OK", "landed"), ("EXIT_NOT_LANDED", "did not land"), ("EXIT_USAGE", "argument"),
                        ("EXIT_INFRA", "infrastructure"), ("EXIT_REJECTED", "rejected"),
                        ("EXIT_INTERRUPTED", "interrupted")):
        assert words in doc[codes[name]], (name, doc)


def test_usage_rejected_and_not_landed_exit_differently(tmp_path):
    """2: a refused argument (argparse's, or one flip checks itself); 4: a request the planner
    refuses (`flip plan`, no ROS); 1: a run whose bag shows no landing (`flip summarize`); 0: landed."""
    assert flip("plan", "backflip", "--apex", "oops", "--out", str(tmp_path / "p")).returncode == 2
    assert flip("run", "backflip", "--plant", "torque_scale=-1").returncode == 2
    # the request carries no robot: the running graph's is the one that flips
    r = flip("request", "backflip", "--robot", "cassie-legs3-fw260", "--domain", "99")
    assert r.returncode == 2 and "--robot" in r.stderr, r.stderr
    r = flip("plan", "backflip", "--apex", "6", "--out", str(tmp_path / "p"))
    assert r.returncode == 4 and "apex" in r.stderr, r.stderr
    from synthetic_bag import write_flip_bag
    write_flip_bag(tmp_path / "fell" / "bag", rotation_deg=360.0, final_z=0.3, final_tilt_deg=80.0)
    write_flip_bag(tmp_path / "landed" / "bag", rotation_deg=360.0, final_z=0.9)
    assert flip("summarize", str(tmp_path / "fell"), "--kind", "frontflip").returncode == 1
    assert flip("summarize", str(tmp_path / "landed"), "--kind", "frontflip").returncode == 0


def test_infrastructure_failure_exits_3(tmp_path):
    """A node that dies before the graph is ready: exit 3, not a verdict on the flip."""
    r = flip("run", "hop", "--out", str(tmp_path / "run"), "--ready-timeout", "60",
             "--exe", f"sim={sys.executable} -c raise(SystemExit(5))")
    assert r.returncode == 3, r.stdout + r.stderr


def test_a_named_robot_reaches_the_planner_and_its_flags_replace_one_parameter(tmp_path):
    """--robot sets every design parameter (the request the planner gets says so); a flag replaces
    just its own; the default is the paper's robot; an unknown name is a usage error."""
    r = flip("plan", "backflip", "--apex", "1.3", "--robot", "cassie-legs3-fw260", "--out", str(tmp_path / "a"))
    assert r.returncode == 0, r.stderr
    req = json.loads((tmp_path / "a" / "plan.json").read_text())["request"]
    assert (req["flywheel"], req["motor_speed_scale"], req["flywheel_torque"]) == ("I", 3.0, 260.0)
    r = flip("plan", "backflip", "--apex", "1.3", "--robot", "cassie-legs3-fw260", "--flywheel-torque", "300",
             "--out", str(tmp_path / "b"))
    req = json.loads((tmp_path / "b" / "plan.json").read_text())["request"]
    assert (req["motor_speed_scale"], req["flywheel_torque"]) == (3.0, 300.0)
    r = flip("plan", "backflip", "--apex", "1.3", "--out", str(tmp_path / "c"))
    req = json.loads((tmp_path / "c" / "plan.json").read_text())["request"]
    assert (req["flywheel"], req["motor_speed_scale"], req["flywheel_torque"]) == ("I", 1.0, 195.0)
    r = flip("plan", "backflip", "--robot", "no-such-robot", "--out", str(tmp_path / "d"))
    assert r.returncode == 2 and "cassie" in r.stderr
