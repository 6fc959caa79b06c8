"""`flip sweep` (flip_tools.sweep): samples run as Ray tasks give the records the same samples give
run one by one without Ray, on Ray embedded on this machine and on a two-node cluster; a rerun skips
the samples already done; the report's tables and plots.  Short samples (1 s of simulation from a
jump started at 0.3 s) keep it to a couple of minutes."""
import ast
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
from flip_tools import perturb as P
from flip_tools import sweep as S
from flip_tools import sweep_report as R

FLIP = REPO / "scripts" / "flip"
# B and C, with and without joint noise (seed 5): 4 short samples
ARGS = ["--flips", "B", "C", "--set", "seconds=1.0", "start=0.3", "--seed", "5", "--no-progress"]
GRID = ["--grid", "joint_noise=0,0.01"]


def sweep(out, *args, timeout=600, prefix=()):
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    r = subprocess.run([*prefix, sys.executable, str(FLIP), "sweep", "--out", str(out), *ARGS, *args],
                       capture_output=True, text=True, timeout=timeout, env=env, start_new_session=True)
    assert r.returncode == 0, r.stdout + r.stderr
    return r.stdout


def samples():
    return S.grid_samples(["B", "C"], {"joint_noise": [0.0, 0.01]}, {"seconds": 1.0, "start": 0.3}, 5)[0]


@pytest.fixture(scope="module")
def one_by_one():
    """The 4 samples run in this process, without Ray."""
    out = {}
    for s in samples():
        row = P.run_sample(s)
        row.pop("wall_s")
        out[s.id] = row
    return out


def stored(out) -> dict:
    rows = {r["sample_id"]: r for r in S.ResultStore(out).rows()}
    for r in rows.values():
        r.pop("wall_s")
    return rows


@pytest.fixture(scope="module")
def local_sweep(tmp_path_factory):
    """Half the grid, then the whole grid into the same directory (a resumed sweep)."""
    out = tmp_path_factory.mktemp("sweep")
    first = sweep(out, "--grid", "joint_noise=0", "--workers", "2")
    half = S.ResultStore(out).rows()
    second = sweep(out, *GRID, "--workers", "2")
    return out, first, half, second


def test_local_sweep_gives_the_records_of_one_by_one_runs(local_sweep, one_by_one):
    out, first, _, second = local_sweep
    assert "1 node(s) (127.0.0.1)" in first                  # embedded, bound to the loopback address
    assert stored(out) == one_by_one
    assert len({r["outcome"] for r in one_by_one.values()}) >= 1
    assert "| joint_noise | 0.01 |" in second and "outcomes" in second
    assert (out / "summary.md").exists() and (out / "landing_rate_joint_noise.png").stat().st_size > 1000


LISTENERS = r"""
import os, re, subprocess, sys
from flip_tools import sweep
sweep.start_ray(None, 1)
import ray
ray.get(ray.remote(lambda: 1).remote())          # a worker up too


def ours(pid):
    while pid > 1:
        if pid == os.getpid():
            return True
        pid = int(open(f"/proc/{pid}/stat").read().rsplit(")", 1)[1].split()[1])
    return False


out = subprocess.run(["ss", "-ltnpH"], capture_output=True, text=True).stdout
mine = [(ln.split()[3], int(m)) for ln in out.splitlines() for m in re.findall(r"pid=(\d+)", ln) if ours(int(m))]
ray.shutdown()
print(mine)
"""


def test_embedded_ray_listens_on_127_0_0_1_only():
    """Every socket that the embedded Ray's processes listen on is bound to 127.0.0.1."""
    if shutil.which("ss") is None:
        pytest.skip("ss (iproute2, which scripts/install_system_deps.sh installs) is not on PATH: "
                    "cannot list the listening sockets")
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    r = subprocess.run([sys.executable, "-c", LISTENERS], capture_output=True, text=True,
                       timeout=300, env=env)
    assert r.returncode == 0, r.stderr
    listening = ast.literal_eval(r.stdout.strip().splitlines()[-1])
    assert len(listening) >= 3                                  # GCS, raylet, driver, worker
    assert all(addr.rsplit(":", 1)[0] in ("127.0.0.1", "[::ffff:127.0.0.1]") for addr, _ in listening), listening


def test_a_rerun_skips_the_samples_done(local_sweep):
    out, first, half, second = local_sweep
    assert "2 samples, 0 already in" in first
    assert "4 samples, 2 already in" in second and "2 to run" in second
    again = sweep(out, *GRID)
    assert "4 samples, 4 already in" in again and "0 to run" in again and "ray " not in again
    kept = {r["sample_id"]: r["wall_s"] for r in S.ResultStore(out).rows()}
    assert all(kept[r["sample_id"]] == r["wall_s"] for r in half)         # not run again


def test_sweep_on_a_two_node_cluster(one_by_one):
    """`ray start` head + a second node on this machine (a network namespace with only the loopback
    interface: tests/ray_cluster.py), and the sweep joined to it with --address."""
    unshare = shutil.which("unshare")
    if unshare is None or subprocess.run([unshare, "-n", "true"]).returncode != 0:
        pytest.skip("this machine does not let an unprivileged process make a network namespace "
                    "(`unshare -n true` failed): no loopback-only second Ray node to join")
    temp = Path(tempfile.mkdtemp(prefix="rsw", dir="/tmp"))        # short: Ray's socket paths
    try:
        text = sweep(temp / "out", *GRID, "--address", "{address}", timeout=900,
                     prefix=(unshare, "-n", sys.executable, str(REPO / "tests" / "ray_cluster.py"), str(temp), "--"))
        assert "2 node(s) (127.0.0.1), 2 CPU(s), 2 sample(s) at a time" in text
        assert stored(temp / "out") == one_by_one
    finally:
        shutil.rmtree(temp, ignore_errors=True)


def test_graph_mode_noise_and_bad_arguments_are_refused(tmp_path):
    for args, msg in ((["--mode", "graph", *GRID], "--mode graph cannot apply joint_noise"),
                      (["--grid", "frictoin=0.5"], "unknown knob 'frictoin'"),
                      (["--random", "4", "--range", "mass_scale=1.1:0.9"], "1.1 > 0.9"),
                      (["--grid", "delay_steps=0.5"], "whole number")):
        r = subprocess.run([sys.executable, str(FLIP), "sweep", "--out", str(tmp_path), *ARGS, *args],
                           capture_output=True, text=True, timeout=120)
        assert r.returncode == 2 and msg in r.stderr, r.stdout + r.stderr
    assert not (tmp_path / "results").exists()


def test_samples_of_a_grid_and_of_random_draws():
    grid, skipped = S.grid_samples(["A", "B"], {"ground_offset": [-0.1, 0.0], "friction": [0.5, 0.8]}, {}, 0)
    assert len(grid) == 6 and skipped == 2                     # B has no landing area to move
    assert len({s.id for s in grid}) == 6
    draws, _ = S.random_samples(["A", "C"], {"mass_scale": (0.9, 1.1), "delay_steps": (0, 3)}, {}, 10, seed=3)
    again, _ = S.random_samples(["A", "C"], {"mass_scale": (0.9, 1.1), "delay_steps": (0, 3)}, {}, 10, seed=3)
    assert [s.id for s in draws] == [s.id for s in again]
    assert all(0.9 <= s.knob("mass_scale") <= 1.1 and s.knob("delay_steps") in range(4) for s in draws)
    assert [s.flip for s in draws[:4]] == ["A", "C", "A", "C"]
    assert [s.id for s in S.random_samples(["A"], {"mass_scale": (0.9, 1.1)}, {}, 3, seed=4)[0]] != \
        [s.id for s in S.random_samples(["A"], {"mass_scale": (0.9, 1.1)}, {}, 3, seed=3)[0]]


def test_report_tables_and_heat_map(tmp_path):
    rows = []
    for i, (g, f, outcome) in enumerate([(-0.1, 0.5, "fell"), (-0.1, 0.8, "landed"), (0.1, 0.5, "rejected"),
                                         (0.1, 0.8, "landed"), (0.1, 0.8, "not_at_rest")]):
        s = P.Sample("A", {"ground_offset": g, "friction": f}, i)
        rows.append({**P.failed_result(s, None), "outcome": outcome,
                     "limit": "knee torque-speed envelope" if outcome == "rejected" else None})
    text, files = R.report(rows, tmp_path)
    assert "| ground_offset | 0.1 | 1/3 (33%) | 1/3 (33%) |" in text
    assert "| friction | 0.8 | 2/3 (67%) |" in text
    assert "| landed | 2 | 40.0% |" in text and "rejected (1): knee torque-speed envelope" in text
    assert {f.name for f in files} == {"landing_rate_ground_offset.png", "landing_rate_friction.png",
                                       "heatmap_ground_offset_friction.png"}
    binned = [{**r, "mass_scale": 0.9 + 0.01 * i, "outcome": "landed" if i % 2 else "fell"}
              for i, r in enumerate(rows * 3)]
    assert len(R.levels(binned, "mass_scale")) == R.BINS

