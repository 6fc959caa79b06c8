#!/usr/bin/env python3
"""Flips in a row without ROS: from each start time, one simulator and one controller do N flips of a
kind, each asked 0.5 s after the previous run ends (``--seconds`` of sim time per flip), the pitch turns
carried as planner_node carries them (flip_tools.offline.run(turns=...)).  Prints each chain's outcomes
(a landed flip with the stance it left: one foot ahead of the other, the feet's yaw apart) and, per flip
number, how many landed (a chain stops at its first flip that does not land).

  .venv/bin/python scripts/bench_flips_in_a_row.py --kinds backflip frontflip --flips 3
"""
from __future__ import annotations

import argparse
import math
from concurrent.futures import ProcessPoolExecutor

#: start times of the first flip (s): the robot has stood that long
START_TIMES = (1.1, 1.2, 1.3, 1.4, 1.5, 1.6, 1.7, 1.8, 1.9, 2.0)
#: sim time between the end of one flip's run and the next one's jump (s)
GAP_S = 0.5


def chain(kind: str, start: float, flips: int, seconds: float, scale: float, torque: float, apex: float,
          controller: str = "", noise: float = 0.0) -> list[str]:
    """The outcomes (flip_tools.offline.outcome) of up to ``flips`` flips in a row from ``start``; a
    landed one with the stance it left (flip_tools.offline.feet_apart: one foot ahead of the other, mm;
    the feet's yaw apart, deg), the next flip's."""
    from cassie_flip_sim.simulator import Simulator
    from cassie_model.model import export_mjcf
    from flip_tools import offline as of
    from fslip_planner.feasibility import InfeasibleRequest
    from tsc_controller import Controller
    from tsc_controller.config import config_overrides
    sim = Simulator(motor_speed_scale=scale, flywheel_torque=torque)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=scale, flywheel_torque=torque,
                     **config_overrides(controller))
    turns, t, out = None, start, []
    for i in range(flips):
        plant = None
        if noise:                          # seeded by the chain's start and the flip's number
            from flip_tools.perturb import read_noise
            plant = read_noise(sim, noise, round(start * 1e4) * 100 + i, t)
        try:
            r = of.run(kind, seconds=t + seconds, start=t, sim=sim, controller=ctl, every=20, turns=turns,
                       plant=plant, apex_height=apex, motor_speed_scale=scale, flywheel_torque=torque)
        except InfeasibleRequest as e:
            out.append(f"rejected ({e.limit})")
            break
        turns = r["turns"]
        # judge this flip's own turn: the controller's pitch counts the flips before, the plant's true
        # pitch (with noise) counts from this run's start
        own = float(r["pitch"][-1]) - of.EXPECTED_TURN[kind] * i if plant is None else plant.pitch
        out.append(of.outcome(r, kind, pitch_end=own))
        if out[-1] != "landed":
            break
        ahead, yaw = of.feet_apart(sim)
        out[-1] += f" ({1e3 * ahead:+.1f} mm, {math.degrees(yaw):+.1f} deg)"
        t = sim.time + GAP_S
    return out


def main() -> int:
    from flip_tools.perturb import add_noise_option
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=["backflip", "frontflip"], choices=["backflip", "frontflip"])
    ap.add_argument("--flips", type=int, default=3, help="flips in a row from each start time")
    ap.add_argument("--starts", nargs="+", type=float, default=list(START_TIMES))
    ap.add_argument("--seconds", type=float, default=8.0, help="sim time of each flip's run (s)")
    ap.add_argument("--motor-speed-scale", type=float, default=3.0)
    ap.add_argument("--flywheel-torque", type=float, default=260.0)
    ap.add_argument("--apex", type=float, default=1.3)
    ap.add_argument("--controller", default="", help="ControllerConfig overrides, JSON (as flip run --controller)")
    add_noise_option(ap, "chain and flip")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    from tsc_controller.config import config_overrides
    config_overrides(a.controller)                     # refuse a bad setting before anything runs
    jobs = [(k, s) for k in a.kinds for s in a.starts]
    with ProcessPoolExecutor(a.jobs) as ex:
        futs = [ex.submit(chain, k, s, a.flips, a.seconds, a.motor_speed_scale, a.flywheel_torque, a.apex,
                          a.controller, a.noise)
                for k, s in jobs]
        results = [f.result() for f in futs]
    print("| kind | first start (s) | " + " | ".join(f"flip {i + 1}" for i in range(a.flips)) + " |")
    print("|---|---|" + "---|" * a.flips)
    for (kind, start), res in zip(jobs, results):
        cells = res + ["-"] * (a.flips - len(res))
        print(f"| {kind} | {start:.2f} | " + " | ".join(cells) + " |")
    for kind in a.kinds:
        rows = [res for (k, _), res in zip(jobs, results) if k == kind]
        tally = [f"flip {i + 1}: {sum(1 for r in rows if len(r) > i and r[i].startswith('landed'))} of "
                 f"{sum(1 for r in rows if len(r) > i)}" for i in range(a.flips)]
        print(f"{kind}: " + ", ".join(tally))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
