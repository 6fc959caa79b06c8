"""`flip sweep --mode graph` (flip_tools.sweep_graph): each sample a `flip run` through the node graph
with its knobs given to sim_node only.  Two samples of flip A (1 m forward frontflip) of the
somersault robot, the robot's mass as built and x1.3 (offline, A lands from 15 of 15 start times as
built and fell x1.3 from each of 5 tried; the backflip, 12 of 15, fell in one CI graph run): the
records give the outcomes the same samples give offline (from the graph's own jump start, which the
request's latency sets, and the COM x its plan was anchored at), the heavier robot falls where the other lands, and sim_node built the
robot with the mass scaled (its log's total mass) while the planner and the controller were given
nothing of it."""
import json
import os
import re
import subprocess
import sys
from pathlib import Path

import pytest

from flip_tools import perturb as P
from flip_tools import sweep as S

REPO = Path(__file__).resolve().parents[2]
FLIP = REPO / "scripts" / "flip"


@pytest.fixture(scope="module")
def graph_sweep(tmp_path_factory):
    out = tmp_path_factory.mktemp("graph_sweep")
    env = {k: v for k, v in os.environ.items() if not k.startswith("RAY_")}
    r = subprocess.run([sys.executable, str(FLIP), "sweep", "--mode", "graph", "--flips", "A",
                        "--grid", "mass_scale=1.0,1.3", "--out", str(out), "--no-progress"],
                       capture_output=True, text=True, timeout=900, env=env, start_new_session=True)
    assert r.returncode == 0, r.stdout + r.stderr
    rows = {r["mass_scale"]: r for r in S.ResultStore(out).rows()}
    return out, rows


def test_graph_records_have_the_offline_outcomes(graph_sweep):
    out, rows = graph_sweep
    assert sorted(rows) == [1.0, 1.3]
    assert rows[1.0]["outcome"] == "landed" and rows[1.3]["outcome"] == "fell"
    for scale, row in rows.items():
        assert row["mode"] == "graph" and row["error"] is None
        assert row["jump_start_s"] > row["start"]          # the request's latency and the plan's lead
        # the offline twin: the same jump start, and the plan anchored where the graph's was (its
        # planner reads the robot when the plan goes out; from 1 cm behind, flip A fell where it landed)
        planner = json.loads((out / "runs" / row["sample_id"] / "summary.json").read_text())["planner"]
        offline = P.run_sample(P.Sample("A", {"mass_scale": scale, "start": row["jump_start_s"]}),
                               x_start=planner["x_start_m"], heading=planner["heading"])
        assert offline["outcome"] == row["outcome"], (scale, offline, row, planner)
    landed = rows[1.0]
    assert landed["net_rotation_deg"] == pytest.approx(360.0, abs=45.0)
    assert landed["touchdown_s"] > landed["jump_start_s"] and landed["sim_s"] == pytest.approx(9.0, abs=1e-3)


def test_the_mass_reaches_the_simulator_only(graph_sweep):
    out, rows = graph_sweep
    mass = {}
    for scale, row in rows.items():
        run = out / "runs" / row["sample_id"]
        info = json.loads((run / "run.json").read_text())
        assert json.loads(info["sim_params"]["plant"]) == {"mass_scale": scale}
        assert "plant" not in info["planner_params"] and "plant" not in info["tsc_params"]
        log = (run / "logs" / "sim.log").read_text()
        mass[scale] = float(re.search(r"plant perturbation: mass_scale [0-9.]+; total mass ([0-9.]+) kg", log)[1])
        assert not (run / "bag").exists()                 # deleted after the summary (no --keep-bags)
    assert mass[1.3] / mass[1.0] == pytest.approx(1.3, rel=1e-4)     # the log gives grams
