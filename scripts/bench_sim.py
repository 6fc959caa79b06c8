#!/usr/bin/env python3
"""Benchmark of the cassie_flip_sim simulator: steps per second, printed as a table.

Part 1 (bare steps): raw ``mujoco.mj_step`` vs ``Simulator.step`` (motor-limit clipping +
foot-force readout + contact detector; with ``wrench=True`` the feet's wrenches too), standing on the
ground and in flight.
Part 2 (lockstep node round trip): :func:`bench_lockstep`, sim_node against echo_controller, each
its own process in a domain of its own (claimed like `flip` does; $FLIP_ROS_DOMAIN_ID if set), on
two CPUs or both pinned to one.

    .venv/bin/python scripts/bench_sim.py [--steps 4000] [--flywheel I]
"""
from __future__ import annotations

import argparse
import signal
import sys
import time
from pathlib import Path

import numpy as np

sys.path.append(str(Path(__file__).resolve().parents[1] / "ros_ws" / "src" / "cassie_flip_sim"))

import mujoco  # noqa: E402

from cassie_flip_sim.simulator import Simulator  # noqa: E402
from flip_tools.rosenv import claim_domain, node_env  # noqa: E402


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
    rows.append(("Simulator.step, standing, u = 0, the feet's wrenches too (foot_wrench)",
                 _rate(lambda: sim.step(u, wrench=True), steps)))
    sim.reset()
    rows.append(("Simulator.step, standing, random u (clipped)", _rate(lambda: sim.step(u_rand), steps)))
    q = sim.standing_qpos.copy()
    q[2] += 5.0
    sim.reset(q, in_contact=False)
    rows.append(("Simulator.step, flight (no contacts), u = 0", _rate(lambda: sim.step(u), steps)))
    sim.clip_torques = False
    sim.reset()
    rows.append(("Simulator.step, standing, clipping off", _rate(lambda: sim.step(u), steps)))
    ref = Simulator(flywheel, "flat", backend="python")       # the numpy reference of the compiled step
    rows.append(("Simulator.step, standing, u = 0, numpy", _rate(lambda: ref.step(u), steps)))
    ref.reset()
    rows.append(("Simulator.step, standing, random u, numpy", _rate(lambda: ref.step(u_rand), steps)))
    return rows


def bench_lockstep(steps: int, work_us: float = 0.0, pin_one_core: bool = False) -> float:
    """Lockstep sim_node <-> echo_controller, each its own process: real-time factor over the
    stepping loop (start-up excluded), as sim_node reports it."""
    import os
    import re
    import subprocess
    domain = os.environ.get("FLIP_ROS_DOMAIN_ID")
    claim = claim_domain(int(domain) if domain else None)
    env = node_env(claim.domain_id)
    env.pop("FLIP_LOCKSTEP_CPU", None)          # the pinning is taskset's here
    bindir = os.path.dirname(sys.executable)
    pin = ["taskset", "-c", "0"] if pin_one_core else []
    echo = subprocess.Popen(pin + [os.path.join(bindir, "echo_controller"), "--ros-args", "-p",
                                   f"work_us:={work_us}"], env=env, stderr=subprocess.DEVNULL,
                            stdout=subprocess.DEVNULL)
    try:
        out = subprocess.run(pin + [os.path.join(bindir, "sim_node"), "--ros-args", "-p",
                                    f"duration:={steps * 0.0005}"], env=env, capture_output=True,
                             text=True, timeout=600)
    finally:
        echo.send_signal(signal.SIGINT)
        echo.wait(timeout=10)
        claim.release()
    m = re.search(r"real-time factor ([0-9.]+)", out.stderr + out.stdout)
    if not m:
        raise RuntimeError("sim_node did not report its real-time factor:\n" + out.stderr[-2000:])
    return float(m.group(1))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=4000)
    ap.add_argument("--flywheel", default="I")
    ap.add_argument("--no-lockstep", dest="lockstep", action="store_false",
                    help="skip the two-process lockstep measurement")
    a = ap.parse_args()
    rows = bench_bare(a.steps, a.flywheel)
    dt = 0.0005
    w = max(len(r[0]) for r in rows)
    print(f"{'case':<{w}}  {'steps/s':>9}  {'us/step':>8}  {'x real time':>11}")
    for name, r in rows:
        print(f"{name:<{w}}  {r:9.0f}  {1e6 / r:8.1f}  {r * dt:11.1f}")
    if a.lockstep:
        print()
        print(f"lockstep sim_node <-> echo_controller, {a.steps} steps (real-time factor over the stepping loop)")
        print(f"{'controller work':>16}  {'cores':>9}  {'x real time':>11}")
        for work in (0.0, 100.0):
            for one in (False, True):
                rtf = bench_lockstep(a.steps, work, one)
                print(f"{work:13.0f} us  {'one' if one else 'two':>9}  {rtf:11.2f}")


if __name__ == "__main__":
    main()
