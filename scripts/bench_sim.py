#!/usr/bin/env python3
"""Benchmark of the cassie_flip_sim simulator: steps per second, printed as a table.

Part 1 (bare steps, here): raw ``mujoco.mj_step`` vs ``Simulator.step`` (motor-limit clipping +
foot-force readout + contact detector), standing on the ground and in flight.
Part 2 (lockstep node round trip): :func:`bench_lockstep`, to be filled in with the ROS node.

    .venv/bin/python scripts/bench_sim.py [--steps 4000] [--flywheel I]
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1] / "ros_ws" / "src" / "cassie_flip_sim"))

import mujoco  # noqa: E402

from cassie_flip_sim.simulator import Simulator  # noqa: E402


def _rate(fn, steps: int) -> float:
    t = time.perf_counter()
    for _ in range(steps):
        fn()
    return steps / (time.perf_counter() - t)


def bench_bare(steps: int, flywheel: str = "I") -> list[tuple[str, float]]:
    """[(case, steps/s)] for the in-process simulator step."""
    sim = Simulator(flywheel, "flat")
    rows = []
    u = np.zeros(sim.model.nu)
    rng = np.random.default_rng(0)
    u_rand = rng.normal(scale=50.0, size=sim.model.nu)

    sim.reset()
    rows.append(("mujoco.mj_step, standing (no limits)", _rate(lambda: mujoco.mj_step(sim.model, sim.data), steps)))
    sim.reset()
    rows.append(("Simulator.step, standing, u = 0", _rate(lambda: sim.step(u), steps)))
    sim.reset()
    rows.append(("Simulator.step, standing, random u (clipped)", _rate(lambda: sim.step(u_rand), steps)))
    q = sim.standing_qpos.copy()
    q[2] += 5.0
    sim.reset(q, in_contact=False)
    rows.append(("Simulator.step, flight (no contacts), u = 0", _rate(lambda: sim.step(u), steps)))
    sim.clip_torques = False
    sim.reset()
    rows.append(("Simulator.step, standing, clipping off", _rate(lambda: sim.step(u), steps)))
    return rows


def bench_lockstep(steps: int) -> list[tuple[str, float]]:
    """Lockstep sim_node <-> controller round trip (steps/s).  To be written with the ROS node."""
    raise NotImplementedError


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--flywheel", default="I")
    a = ap.parse_args()
    rows = bench_bare(a.steps, a.flywheel)
    dt = 0.0005
    w = max(len(r[0]) for r in rows)
    print(f"{'case':<{w}}  {'steps/s':>9}  {'us/step':>8}  {'x real time':>11}")
    for name, r in rows:
        print(f"{name:<{w}}  {r:9.0f}  {1e6 / r:8.1f}  {r * dt:11.1f}")


if __name__ == "__main__":
    main()
