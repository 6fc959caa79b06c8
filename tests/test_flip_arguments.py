"""`flip` checks every argument before it touches the output folder, and never deletes what it did
not write (issue: a refused argument wiped a copied run's folder)."""
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
    (["run", "backflip", "--platform", "0.5", "--ground-offset", "0.1"], "--platform or --ground-offset"),
    (["stand", "--duration", "0"], "must be > 0"),
    (["sim", "--duration", "-1"], "must be > 0"),
])
def test_a_refused_argument_leaves_the_output_folder_as_it_was(tmp_path, args, message):
    out = tmp_path / "copy"
    before = a_previous_run(out)
    r = flip(*args, "--out", str(out))
    assert r.returncode != 0 and message in r.stderr + r.stdout, r.stderr
    assert "Traceback" not in r.stderr
    assert sorted(p.relative_to(out) for p in out.rglob("*")) == before


def test_a_folder_that_is_no_run_of_flip_is_refused_and_kept(tmp_path):
    out = tmp_path / "mine"
    out.mkdir()
    (out / "thesis.tex").write_text("months of work")
    r = flip("stand", "--duration", "0.1", "--out", str(out))
    assert r.returncode != 0 and "not a previous run" in r.stderr, r.stderr
    assert (out / "thesis.tex").read_text() == "months of work" and len(list(out.iterdir())) == 1


def test_an_unwritable_out_is_an_error_not_a_traceback(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("x")
    r = flip("stand", "--duration", "0.1", "--out", str(blocker / "sub"))
    assert r.returncode != 0 and "--out" in r.stderr and "Traceback" not in r.stderr, r.stderr
