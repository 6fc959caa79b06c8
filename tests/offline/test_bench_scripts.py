"""The offline benchmark scripts (scripts/bench_landings.py, scripts/bench_landing_warm_start.py): each
runs its flips and reports them in the table its docs read, refuses a request the planner refuses, and
parses its arguments and verdicts as `flip run` does."""
import importlib.util
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

SCRIPTS = Path(__file__).resolve().parents[2] / "scripts"


def _bench_landings():
    """scripts/bench_landings.py as a module."""
    spec = importlib.util.spec_from_file_location("bench_landings", SCRIPTS / "bench_landings.py")
    bl = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(bl)
    return bl


@pytest.mark.parametrize("args, kind, flight_min, turn", [
    (("--states",), "backflip", 0.45, -360.0),
    # flip C: off a 0.5 m platform, `flip run`'s 0.6 m forward distance; the drop lengthens the flight (~0.54 s in place)
    (("--platform", "0.5", "--apex", "1.2"), "frontflip", 0.58, 349.0)])
def test_bench_landings_reports_a_flip(tmp_path, args, kind, flight_min, turn):
    """scripts/bench_landings.py (the offline landing-rate table) runs a flip and reports its touch-down."""
    script = SCRIPTS / "bench_landings.py"
    r = subprocess.run([sys.executable, str(script), "--kinds", kind, "--starts", "0.5", "--seconds", "2.45",
                        "--jobs", "1", *args], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    row = next(ln for ln in r.stdout.splitlines() if ln.startswith(f"| {kind} | 0.50 |"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[5]) > flight_min                             # the flight
    assert float(cells[6]) == pytest.approx(turn, abs=10.0)         # one turn at touch-down
    fw_flight, fw_landing = (float(x) for x in cells[10].split(" / "))   # the flywheel turns the body
    assert fw_flight > 2000.0 and fw_landing > 0.0
    # 2.45 s: the robot is still catching the landing, so not at rest, and so not landed yet
    assert cells[2:4] == ["no", "no"], row
    assert r.stdout.splitlines()[-1].startswith(f'{{"{kind}": ')
    if "--platform" in args:
        assert "distance 0.6 m, platform 0.5 m" in r.stdout
    if "--states" in args:
        # lift-off measured (planned) and touch-down: a backflip leaves with the COM behind its feet,
        # rising, with negative pitch momentum, and comes down falling
        srow = [ln for ln in r.stdout.splitlines() if ln.startswith(f"| {kind} | 0.50 |")][1]
        cells = [c.strip() for c in srow.strip("|").split("|")]
        lo_ahead, plan_ahead = (float(x.strip("()")) for x in cells[2].split())
        assert lo_ahead < 0.0 and plan_ahead < 0.0
        assert float(cells[4].split()[0]) > 2.0 and float(cells[5].split()[0]) < -30.0
        assert float(cells[8]) < -2.0
        # and the stance at the run's end (flip_tools.offline.feet_apart): the feet on the ground, not yet
        # settled at 2.45 s, but within a foot's length of each other and turned apart by a few degrees at most
        assert abs(float(cells[9])) < 100.0 and abs(float(cells[10])) < 20.0


def test_bench_landings_says_why_the_planner_refuses_a_request():
    """A request the planner refuses (here the published knees and a 1.3 m apex) gets the planner's
    reason and exit code 4, as `flip plan`, before any run (not a worker's traceback)."""
    script = SCRIPTS / "bench_landings.py"
    r = subprocess.run([sys.executable, str(script), "--kinds", "backflip", "--starts", "0.5", "--jobs", "1",
                        "--motor-speed-scale", "1", "--apex", "1.3"], capture_output=True, text=True, timeout=300)
    assert r.returncode == 4, r.stdout + r.stderr
    assert "the planner refuses the request" in r.stderr and "knee torque" in r.stderr
    assert "Traceback" not in r.stderr and "| backflip |" not in r.stdout


def test_bench_landings_at_rest_is_the_verdicts_check():
    """bench_landings' at-rest check is `flip run`'s (flip_tools.summary.LANDING_CRITERIA): the pelvis'
    speed and angular speed below their limits over the last 0.5 s, whatever came before."""
    bl = _bench_landings()
    t = np.arange(0.0, 3.0, 0.005)
    still, turning = np.full(t.size, 0.01), np.full(t.size, 0.1)
    assert bl.at_rest(t, still, turning)
    late = still.copy()
    late[t > 2.7] = 0.2                              # 0.2 m/s in the last 0.3 s (limit 0.15)
    assert not bl.at_rest(t, late, turning)
    early = still.copy()
    early[t < 2.4] = 2.0                             # before the window: does not count
    assert bl.at_rest(t, early, turning)
    spin = turning.copy()
    spin[-1] = 0.6                                   # angular speed 0.6 rad/s at the end (limit 0.5)
    assert not bl.at_rest(t, still, spin)
    assert bl.LANDING_CRITERIA["rest_window_s"] == 0.5
    assert [bl.start_cell(x) for x in (0.5, 0.98, 1.555, 1.5555, 3.0)] == ["0.50", "0.98", "1.555", "1.5555", "3.00"]


def test_bench_landings_takes_a_summarys_heading_and_x_start_as_written():
    """The re-run recipe of summary.json (``--x-start X --heading PSI PX PY``) takes negative numbers in
    exponent form as the values they are (argparse alone reads '-4.9e-06' as an option)."""
    bl = _bench_landings()
    argv = ["--kinds", "frontflip", "--x-start", "-1.1e-03", "--heading", "-4.9e-06", "0.0126", "-8.1e-05",
            "--starts", "1.97"]
    old = sys.argv
    try:
        sys.argv = ["bench_landings.py", *argv]
        a = bl.parse_args()
    finally:
        sys.argv = old
    assert a.x_start == pytest.approx(-1.1e-3) and a.heading == pytest.approx([-4.9e-6, 0.0126, -8.1e-5])
    assert a.starts == [1.97] and a.kinds == ["frontflip"]


def test_bench_landing_warm_start_replays_a_touch_down_under_each_strategy():
    """scripts/bench_landing_warm_start.py records a backflip's touch-down with its predictions and
    re-solves it under each warm start: every strategy answers, the blend in no more iterations than the
    nearest alone, and the strategies that retry failed predictions leave none failed."""
    script = SCRIPTS / "bench_landing_warm_start.py"
    r = subprocess.run([sys.executable, str(script), "--kinds", "backflip", "--starts", "0.5", "--seconds", "2.45",
                        "--jobs", "1", "--noise", "1e-4"], capture_output=True, text=True, timeout=600)
    assert r.returncode == 0, r.stdout + r.stderr
    assert "landing re-solves of 1 recorded touch-downs" in r.stdout
    rows = {c[0]: c[1:] for c in ([x.strip() for x in ln.strip("|").split("|")] for ln in r.stdout.splitlines()
                                  if ln.startswith("| ") and not ln.startswith("| strategy"))}
    assert set(rows) == {"nearest", "blend", "retry", "falls"}
    its = {k: int(v[0]) for k, v in rows.items()}
    assert all(0 < n < 60 for n in its.values()) and all(v[3] == "0" for v in rows.values())   # none failed
    assert its["blend"] <= its["nearest"]
    assert rows["retry"][6] == "0" and rows["falls"][6] == "0"
    assert int(rows["falls"][4]) > int(rows["blend"][4])           # three times the predictions' work
