#!/usr/bin/env python3
"""Landing rate of the somersaults without ROS: `flip_tools.offline` (simulator, planner and
controller wired as the node graph wires them, one process) from a set of start times, two flips at
a time.  Prints a table: per start time whether the flip landed (no body but the feet touched the
ground until the end, pelvis upright at +-2pi and above 0.8 m, and at rest as `flip run`'s verdict
has it: the pelvis' speed and angular speed below flip_tools.summary.LANDING_CRITERIA's over the
last 0.5 s), the touch-down state and the time of a fall; and the count per flip.  The start time is what differs between graph runs (the request
arrives while the robot stands), so the count is the offline estimate of a graph run's landing rate.

    .venv/bin/python scripts/bench_landings.py [--kinds backflip frontflip] [--starts 0.3 0.4 ...]
        [--seconds 9] [--controller JSON] [--motor-speed-scale 3] [--flywheel-torque 260] [--apex 1.3]
        [--distance 0] [--platform 0 | --ground-offset 0] [--noise 0] [--no-flight-check] [--knee-tangential] [--states]

(defaults: the somersault robot of the README and 30 start times).  A robot that has settled (from
~1.3 s on) repeats its run from every later start time to the bit, so the count over start times
weighs one run many times; ``--noise 1e-4`` (sensor noise, seeded per start time) makes the runs
independent.  Each row also gives
the planner's landing re-solve at touch-down (wall ms, IPOPT iterations, which attempt answered) and
whether the controller's own landing replaced the tracked plan (a rebound, or no plan); the summary
gives the stance the landed runs end in (one foot ahead of the other, the feet turned apart: what a
next flip in a row jumps from).
"""
from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor

from flip_tools.cli.options import flight_check_opt, knee_model_opt
from flip_tools.flip_request import request_distance
from flip_tools.perturb import add_noise_option
from flip_tools.offline import EXPECTED_TURN, at_rest, feet_apart, lift_off_touch_down, outcome  # noqa: F401
from flip_tools.summary import LANDING_CRITERIA, RPM_PER_RADPS  # noqa: F401
from flip_tools.tracking import peak_abs

#: start times of the jump (s): 0.3, 0.4, ..., 3.2 (the robot has stood that long; 30 of them)
START_TIMES = tuple(round(0.3 + 0.1 * i, 1) for i in range(30))
EXPECTED = EXPECTED_TURN


def one(kind: str, start: float, seconds: float, controller: str, scale: float, torque: float, apex: float,
        distance: float = 0.0, platform: float = 0.0, ground_offset: float = 0.0, x_start: float | None = None,
        heading: list | None = None, noise: float = 0.0, flight_check: bool = True,
        knee_tangential: bool = False) -> dict:
    import numpy as np

    from flip_tools import offline as of
    from cassie_model.model import Scenario, export_mjcf
    from cassie_flip_sim.simulator import Simulator
    from tsc_controller import Controller
    from tsc_controller.config import config_overrides
    scenario = (Scenario.platform(platform) if platform else
                Scenario.raised_landing(ground_offset) if ground_offset else Scenario.flat())
    sim = Simulator(scenario=scenario, motor_speed_scale=scale, flywheel_torque=torque)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=scale, flywheel_torque=torque,
                     **config_overrides(controller))
    plant = None
    if noise:                                  # seeded by the start time: a row re-runs alike
        from flip_tools.perturb import read_noise
        plant = read_noise(sim, noise, round(start * 1e4), start)
    r = of.run(kind, seconds=seconds, start=start, sim=sim, controller=ctl, every=10, apex_height=apex, x_start=x_start,
               heading=heading, plant=plant,
               forward_distance=distance, platform_height=platform, motor_speed_scale=scale, flywheel_torque=torque,
               flight_check=flight_check, knee_tangential=knee_tangential)
    lo, td = lift_off_touch_down(r["events"])
    out = {"kind": kind, "start": start, "fell_at": r["fell"], "flight_s": None, "td_rotation_deg": None,
           "td_axis_tilt_deg": None}
    if td is not None:
        i = min(int(np.searchsorted(r["t"], td)), len(r["t"]) - 1)
        out.update(flight_s=td - lo, td_rotation_deg=math.degrees(r["pitch"][i]),
                   td_axis_tilt_deg=math.degrees(r["axis_tilt"][i]))
    lo_plan = r["session"].result.lift_off if r["session"].result is not None else None
    lo_st = next((st for k, st in r["event_states"] if k == 0), None)
    td_st = next((st for k, st in r["event_states"] if k == 1 and lo_st is not None and st.t > lo_st.t), None)
    out["states"] = {"lift_off": _state_row(lo_st), "touch_down": _state_row(td_st),
                     "planned_lift_off": None if lo_plan is None else
                     {"com_ahead_of_feet": lo_plan["x"], "xdot": lo_plan["xdot"], "zdot": lo_plan["zdot"],
                      "H": lo_plan["momentum"]}}
    # the planner's landing re-solves at touch-down (paper §III-C): wall time, IPOPT iterations and
    # which attempt answered (0 warm, 1 cold, 2 momentum left free, 3 blend to standing)
    out["resolves"] = [{"ms": 1e3 * float(ref.figures.get("solve_time", math.nan)),
                        "iterations": int(ref.figures.get("iterations", -1)),
                        "fallback": int(ref.figures.get("fallback", -1))}
                       for _, ref in r["references"] if ref.domain == 3]
    # the landings the controller's own landing did instead of the tracked plan (reason each)
    out["own_landing"] = [why for _, why in r["ctl"].landing_fallbacks]
    # rebounds under the tracked plan (LIFT_OFFs in LANDING) and the re-solves of their touch-downs
    out["rebounds"] = len(r["ctl"].rebounds)
    # the flywheel's peak speed (rpm) in the flight and in the landing (issue 22: the landing's at most the flight's)
    out["fw_peak_rpm"] = None
    if td is not None:
        # over the same spans as summary.json's flight_/landing_peak_flywheel_rpm, from every step (as the
        # bag's /joint_states), not the log's samples: a flywheel still spinning up at the touch-down peaks
        # between them
        w = np.asarray(r["fw_step"]) * RPM_PER_RADPS
        ts = r["t_step"]
        out["fw_peak_rpm"] = (peak_abs(ts, w, lo, td), peak_abs(ts, w, td, float(ts[-1])))
    out["at_rest"] = at_rest(r["t"], r["speed"], r["ang_speed"])
    # the stance the run ends in (the next flip's, in a row): left foot ahead of the right, feet yaw apart
    out["feet_apart"] = feet_apart(sim)
    # the verdict on the true pitch where the controller reads a noisy one (as flip sweep's)
    out["landed"] = outcome(r, kind, pitch_end=None if plant is None else plant.pitch) == "landed"
    return out


def _state_row(st) -> dict | None:
    """A contact event's state as the table shows it: COM x ahead of the feet's centre (m), COM
    velocity x and z (m/s), centroidal pitch momentum (kg m^2/s)."""
    if st is None:
        return None
    ahead = None if st.support_center is None else float(st.com[0] - st.support_center[0])
    return {"com_ahead_of_feet": ahead, "xdot": float(st.com_velocity[0]), "zdot": float(st.com_velocity[2]),
            "H": float(st.pitch_momentum)}


def refusal(a) -> str | None:
    """Why the planner refuses one of the requests (``a``: the parsed arguments), or None."""
    from fslip_planner.plan import FlipSession, InfeasibleRequest
    for k in a.kinds:
        try:
            FlipSession(k, apex_height=a.apex, forward_distance=a.distance, platform_height=a.platform,
                        motor_speed_scale=a.motor_speed_scale, flywheel_torque=a.flywheel_torque,
                        flight_check=not a.no_flight_check,
                        knee_tangential=a.knee_tangential).jumping_reference()
        except InfeasibleRequest as e:
            return f"{k}: the planner refuses the request: {e}"
    return None


def faster_in_landing(rows) -> int:
    """How many runs' flywheel peaked higher in the landing than in the flight."""
    return sum(1 for r in rows if r["fw_peak_rpm"] and None not in r["fw_peak_rpm"]
               and r["fw_peak_rpm"][1] > r["fw_peak_rpm"][0])


def fw_cell(peaks) -> str:
    """'flight / landing' peak flywheel speeds (rpm), '-' where there was no touch-down."""
    if not peaks:
        return "-"
    return " / ".join("-" if p is None else f"{p:.0f}" for p in peaks)


def start_cell(start: float) -> str:
    """A start time with two decimals, or as many as it has up to the step's four (a graph run's start,
    e.g. 1.5555 s, to re-run it offline)."""
    text = f"{start:.4f}".rstrip("0")
    return text + "0" * max(0, 2 - len(text.split(".")[1]))


def numbers_attached(argv: list[str], options: dict) -> list[str]:
    """``argv`` with the numbers that follow each of ``options`` (name -> how many values) led by a space,
    so that a negative number in exponent form (a summary.json value such as -4.9e-06) is not taken for
    an option (argparse knows only -1 and -1.5 as negative numbers; float() ignores the space)."""
    out, i = [], 0
    while i < len(argv):
        n = options.get(argv[i])
        vals = argv[i + 1:i + 1 + n] if n else []
        if n and len(vals) == n and all(_is_float(v) for v in vals):
            out += [argv[i]] + [" " + v for v in vals]
            i += 1 + n
            continue
        out.append(argv[i])
        i += 1
    return out


def _is_float(text: str) -> bool:
    try:
        float(text)
        return True
    except ValueError:
        return False


def parse_args() -> argparse.Namespace:
    """The command line, checked (argparse exits 2 on a bad one)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kinds", nargs="+", default=["backflip", "frontflip"], choices=sorted(EXPECTED))
    ap.add_argument("--starts", nargs="+", type=float, default=list(START_TIMES))
    ap.add_argument("--seconds", type=float, default=9.0, help="sim time of each run (s)")
    ap.add_argument("--controller", default="", help="ControllerConfig overrides, JSON (as flip run --controller)")
    ap.add_argument("--motor-speed-scale", type=float, default=3.0)
    ap.add_argument("--flywheel-torque", type=float, default=260.0)
    ap.add_argument("--apex", type=float, default=1.3)
    ap.add_argument("--distance", type=float, default=None,
                    help="forward distance of the request (m; flip A: 1.0; default 0, or flip's 0.6 with --platform)")
    ap.add_argument("--platform", type=float, default=0.0, help="take off from a platform this high (m; flip C: 0.5)")
    ap.add_argument("--ground-offset", type=float, default=0.0,
                    help="landing ground this much higher than the planner is told (m; flip D: 0.1)")
    ap.add_argument("--x-start", type=float, default=None,
                    help="COM x the jump starts from (a run's summary.json planner.x_start_m; default: the initial one)")
    ap.add_argument("--heading", type=float, nargs=3, default=None, metavar=("PSI", "PIVOT_X", "PIVOT_Y"),
                    help="with --x-start: the heading frame the plans start in (a run's summary.json planner.heading)")
    add_noise_option(ap, "start time")
    flight_check_opt(ap)                         # --no-flight-check, as flip run's
    knee_model_opt(ap)                           # --knee-tangential, as flip run's
    ap.add_argument("--jobs", type=int, default=2)
    ap.add_argument("--states", action="store_true",
                    help="also the lift-off (measured / planned) and touch-down states: COM x ahead of the "
                         "feet, COM velocity x and z, pitch momentum; and the stance the run ends in")
    a = ap.parse_args(numbers_attached(sys.argv[1:], {"--x-start": 1, "--heading": 3}))
    if a.platform and a.ground_offset:
        ap.error("choose --platform or --ground-offset, not both")
    a.distance = request_distance(a)             # as `flip run`: a platform flip clears the edge
    return a


def main() -> int:
    a = parse_args()
    from tsc_controller.config import config_overrides
    config_overrides(a.controller)                     # refuse a bad setting before anything runs
    why = refusal(a)
    if why:                                             # a request the planner refuses: its reason, exit 4
        print(why, file=sys.stderr)
        return 4
    jobs = [(k, s) for k in a.kinds for s in a.starts]
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        futs = [pool.submit(one, k, s, a.seconds, a.controller, a.motor_speed_scale, a.flywheel_torque, a.apex,
                            a.distance, a.platform, a.ground_offset, a.x_start, a.heading, a.noise,
                            not a.no_flight_check, a.knee_tangential)
                for k, s in jobs]
        rows = [f.result() for f in futs]
    print(f"offline flips (flip_tools.offline): motor speed scale {a.motor_speed_scale}, flywheel "
          f"{a.flywheel_torque} N*m, apex {a.apex} m, distance {a.distance} m, platform {a.platform} m, "
          f"ground offset {a.ground_offset} m, {a.seconds} s each, controller {a.controller or '{}'}, "
          f"read noise {a.noise}" + (", planner's flight-torque check off" if a.no_flight_check else "")
          + (", knee torque of the tangential force planned" if a.knee_tangential else ""))
    print("| flip | start s | landed | at rest | fell at s | flight s | touch-down rotation deg | axis tilt deg "
          "| landing re-solve ms (iterations, attempt) | own landing | flywheel peak rpm: flight / landing |")
    print("|------|---------|--------|---------|-----------|----------|-------------------------|---------------"
          "|---|---|---|")
    f = lambda x, nd: "-" if x is None else f"{x:.{nd}f}"  # noqa: E731
    for r in rows:
        rs = ", ".join(f"{v['ms']:.1f} ({v['iterations']}, {v['fallback']})" for v in r["resolves"]) or "-"
        print(f"| {r['kind']} | {start_cell(r['start'])} | {'yes' if r['landed'] else 'no'} | "
              f"{'yes' if r['at_rest'] else 'no'} | {f(r['fell_at'], 3)} | "
              f"{f(r['flight_s'], 3)} | {f(r['td_rotation_deg'], 1)} | {f(r['td_axis_tilt_deg'], 2)} | {rs} | "
              f"{', '.join(r['own_landing']) or '-'} | {fw_cell(r['fw_peak_rpm'])} |")
    if a.states:
        print()
        print("| flip | start s | lift-off COM ahead of feet m (plan) | ẋ m/s (plan) | ż m/s (plan) | H kg m²/s (plan) "
              "| touch-down COM ahead of feet m | ẋ m/s | ż m/s | at the end: left foot ahead of right mm | feet yaw apart deg |")
        print("|---|---|---|---|---|---|---|---|---|---|---|")
        for r in rows:
            lo, pl, td = (r["states"][k] or {} for k in ("lift_off", "planned_lift_off", "touch_down"))
            g = lambda d, k, nd=3: f(d.get(k), nd)  # noqa: E731
            print(f"| {r['kind']} | {start_cell(r['start'])} | {g(lo, 'com_ahead_of_feet')} ({g(pl, 'com_ahead_of_feet')}) | "
                  f"{g(lo, 'xdot', 2)} ({g(pl, 'xdot', 2)}) | {g(lo, 'zdot', 2)} ({g(pl, 'zdot', 2)}) | "
                  f"{g(lo, 'H', 1)} ({g(pl, 'H', 1)}) | {g(td, 'com_ahead_of_feet')} | {g(td, 'xdot', 2)} | "
                  f"{g(td, 'zdot', 2)} | {1e3 * r['feet_apart'][0]:.1f} | {math.degrees(r['feet_apart'][1]):.2f} |")
    for k in a.kinds:
        n = [r["landed"] for r in rows if r["kind"] == k]
        print(f"{k}: landed from {sum(n)} of {len(n)} start times")
    first = [r["resolves"][0] for r in rows if r["resolves"]]
    if first:
        ms, its = [v["ms"] for v in first], [v["iterations"] for v in first]
        print(f"landing re-solve at the first touch-down: median {statistics.median(ms):.1f} ms, max {max(ms):.1f} ms; "
              f"IPOPT iterations median {statistics.median(its):.0f}, max {max(its)}; answered by a fallback "
              f"(cold / momentum free / blend) in {sum(v['fallback'] > 0 for v in first)} of {len(first)}")
    print(f"flywheel faster in the landing than in the flight in {faster_in_landing(rows)} of {len(rows)} runs")
    ends = [r["feet_apart"] for r in rows if r["landed"]]
    if ends:
        print(f"the stance the landed runs end in (the next flip's): one foot ahead of the other by up to "
              f"{1e3 * max(abs(e[0]) for e in ends):.1f} mm, the feet turned apart by up to "
              f"{max(abs(math.degrees(e[1])) for e in ends):.2f} deg")
    reb = [r for r in rows if r["rebounds"]]
    later = [v for r in rows for v in r["resolves"][1:]]
    print(f"rebounds under the tracked landing plan in {len(reb)} of {len(rows)} runs"
          + (f"; their touch-downs' re-solves: {len(later)}, answered by a fallback in "
             f"{sum(v['fallback'] > 0 for v in later)}" if later else ""))
    own = [r for r in rows if r["own_landing"]]
    print(f"own landing (the controller's fallback) in {len(own)} of {len(rows)} runs"
          + (f": {', '.join(sorted({w for r in own for w in r['own_landing']}))}" if own else ""))
    print(json.dumps({k: sum(r["landed"] for r in rows if r["kind"] == k) for k in a.kinds}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
