"""The planner's verdicts do not depend on the BLAS kernel: the grid of scripts/bench_planner_grid.py
(backflip/frontflip × apex 1.00–1.40 m × distance 0/0.5/1 m × platform 0/0.5 m) for the somersault
robot (leg motors x3, 260 N·m flywheel: both verdicts and both kinds of rejection occur) and the
default robot
planned in one process per OpenBLAS kernel (CasADi's IPOPT factorises with MUMPS on the OpenBLAS it
ships, which reads OPENBLAS_CORETYPE when it loads)."""
import json
import os
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import pytest

GRID = Path(__file__).resolve().parents[2] / "scripts" / "bench_planner_grid.py"
KERNELS = ("default", "Haswell", "Prescott")
#: what a rejection may name: physical limits (and the modelling limits of the transcription)
LIMITS = {"knee torque–speed envelope", "knee torque", "leg force limit", "flywheel torque (flight)",
          "flywheel torque (stance)", "flywheel torque", "friction cone", "ZMP inside the foot",
          "leg length range", "unilateral leg force", "unilateral ground contact", "leg force rate",
          "flywheel torque rate", "foot torque rate", "feet loaded until the push-off",
          "stance duration bounds", "lift-off vertical speed >= 0.3 m/s", "mass height >= 0.3 m",
          "knee torque–speed envelope (landing)", "landing"}


ROBOTS = {"somersault": ["--motor-speed-scale", "3", "--flywheel-torque", "260"], "default": []}


def grid_under(kernel, robot):
    env = dict(os.environ)
    env.pop("OPENBLAS_CORETYPE", None)
    env.pop("OPENBLAS_L2_SIZE", None)
    if kernel != "default":
        env["OPENBLAS_CORETYPE"] = kernel
    r = subprocess.run([sys.executable, str(GRID), "--worker", *ROBOTS[robot]], env=env, capture_output=True, text=True,
                       timeout=600)
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout)


@pytest.fixture(scope="module")
def grids():
    # one worker process per (kernel, robot), two at a time (the machine's cores)
    keys = [(k, robot) for k in KERNELS for robot in ROBOTS]
    with ThreadPoolExecutor(max_workers=2) as pool:
        return dict(zip(keys, pool.map(lambda key: grid_under(*key), keys)))


@pytest.mark.parametrize("robot", list(ROBOTS))
def test_same_request_same_verdict_under_every_kernel(grids, robot):
    base = grids["default", robot]
    if robot == "somersault":
        accepted = [r for r in base if r["verdict"] == "accepted"]
        assert 0 < len(accepted) < len(base)             # the grid has both sides of the limits
        assert {"flywheel torque (flight)"} < {r["limit"] for r in base if r["verdict"] == "rejected"}
    for kernel in KERNELS[1:]:
        other = grids[kernel, robot]
        assert [(r["kind"], r["apex"], r["distance"], r["platform"], r["verdict"]) for r in other] == \
               [(r["kind"], r["apex"], r["distance"], r["platform"], r["verdict"]) for r in base], kernel
        for a, b in zip(base, other):
            if a["verdict"] == "accepted":          # the same plan, up to the solver's tolerance
                for k, v in a["lift_off"].items():
                    assert b["lift_off"][k] == pytest.approx(v, rel=1e-4, abs=1e-5), (kernel, a, k)
            else:
                assert a["limit"] == b["limit"], (kernel, a["reason"], b["reason"])


def test_every_rejection_names_a_limit(grids):
    for key, recs in grids.items():
        for r in recs:
            if r["verdict"] == "rejected":
                assert r["limit"] in LIMITS, (key, r["reason"])
                assert "most violated" not in r["reason"] and "optimiser" not in r["reason"]
