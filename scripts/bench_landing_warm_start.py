#!/usr/bin/env python3
"""IPOPT iterations of the landing re-solve at touch-down (paper §III-C) by how its warm start is made.

Runs the offline flips of ``scripts/bench_landings.py`` (same options), records each first touch-down's
FSLIP state together with the touch-downs its lift-off predicted (``landing.predicted_touchdowns``) and
the plan's nominal one, then re-solves every recorded touch-down under each strategy, from the same
predictions solved the same way the planner solves them.  Iterations do not depend on the machine or
its load (the time does: ~1.6-2.3 ms an iteration on the machines measured), so the table compares
strategies run by run:

    .venv/bin/python scripts/bench_landing_warm_start.py [bench_landings.py options, e.g. --kinds
        frontflip --platform 0.5 --apex 1.2 --noise 1e-4] [--strategies nearest blend ...]

Strategies (how the touch-down starts; what is predicted):
  nearest  the nearest solved state's solution alone (the planner before the blend)
  blend    ``landing._warm_start``: the nearest moved towards the second-nearest (the planner's)
  retry    blend, and a prediction whose warm solve fails is solved cold
  falls    retry, and the same predictions for falls 0.05 and 0.1 m shorter (15 kept as warm starts)
The prediction columns give what each strategy spends in the flight (iterations, failed solves).
"""
from __future__ import annotations

import argparse
import statistics
import sys
from concurrent.futures import ProcessPoolExecutor

import numpy as np

import bench_landings as bl

STRATEGIES = ("nearest", "blend", "retry", "falls")
#: the shorter falls the "falls" strategy predicts for as well (m)
FALL_SHORTER = (0.05, 0.1)
_RECORDS: list = []


def _record_touch_downs():
    """Wrap FlipSession.landing_reference (in this process) to keep each first touch-down's state, the
    plan's nominal touch-down and the lift-off's predicted ones in _RECORDS."""
    from fslip_planner import plan as P
    if getattr(P.FlipSession.landing_reference, "recording", False):
        return
    predict, resolve, last = P.predicted_touchdowns, P.FlipSession.landing_reference, {}

    def predicted_touchdowns(*a, **k):
        out = predict(*a, **k)
        last["predictions"] = [np.asarray(x, float) for x in out]
        return out

    def landing_reference(self, state):
        nominal = (self._touchdown_state(None) if self.result is not None and self.t_liftoff is not None
                   else None)
        ref = resolve(self, state)
        predictions = last.pop("predictions", None)
        if ref is not None and nominal is not None and predictions:
            st = self.heading.measured(state) if self.heading is not None else state
            _RECORDS.append({"x0": self._touchdown_state(st), "nominal": nominal, "predictions": predictions})
        return ref
    landing_reference.recording = True
    P.predicted_touchdowns = predicted_touchdowns
    P.FlipSession.landing_reference = landing_reference


def _touch_downs(*args) -> list:
    _record_touch_downs()
    _RECORDS.clear()
    bl.one(*args)
    return list(_RECORDS)


def _shorter_fall(x, dh):
    """The touch-down state ``x`` after a fall ``dh`` shorter (ż from the same flight)."""
    from fslip_planner.fslip import touchdown_zdot
    x = np.array(x, float)
    x[3] = touchdown_zdot(x[3], -dh)
    return x


def _iterations(prob) -> int:
    solver = {"near": prob.warm_near, "far": prob.warm, "cold": prob.cold}[prob.last_start]
    return int(solver.stats()["iter_count"])


def resolve(prob, rec: dict, strategy: str) -> dict:
    """Re-solve one recorded touch-down: the nominal landing cold, the predictions warm in their order
    (as FlipSession.predict_landing), then the touch-down as FlipSession.landing_reference's first attempt."""
    from fslip_planner.landing import WARM_NEAR
    prob.forget()
    predictions = list(rec["predictions"])
    if strategy == "falls":
        predictions += [_shorter_fall(x, dh) for dh in FALL_SHORTER for x in rec["predictions"]]
    spent, failed = 0, 0
    for i, x in enumerate([rec["nominal"]] + predictions):
        for warm in ((False,) if i == 0 else (True, False) if strategy in ("retry", "falls") else (True,)):
            try:
                prob.solve(x, warm=warm)
                spent += _iterations(prob)
                break
            except RuntimeError:
                spent += _iterations(prob)
        else:
            failed += 1
    try:
        prob.solve(rec["x0"], warm=True, near=WARM_NEAR, blend=strategy != "nearest")
        its = _iterations(prob)
    except RuntimeError:
        its = None
    return {"iterations": its, "spent": spent, "failed": failed}


def main() -> int:
    extra = argparse.ArgumentParser(add_help=False)
    extra.add_argument("--strategies", nargs="+", default=list(STRATEGIES), choices=STRATEGIES)
    mine, rest = extra.parse_known_args()
    sys.argv = sys.argv[:1] + rest
    a = bl.parse_args()
    why = bl.refusal(a)
    if why:
        print(why, file=sys.stderr)
        return 4
    with ProcessPoolExecutor(max_workers=a.jobs) as pool:
        futs = [pool.submit(_touch_downs, k, s, a.seconds, a.controller, a.motor_speed_scale, a.flywheel_torque,
                            a.apex, a.distance, a.platform, a.ground_offset, a.x_start, a.heading, a.noise,
                            not a.no_flight_check, a.knee_tangential) for k in a.kinds for s in a.starts]
        records = [r for f in futs for r in f.result()]
    if not records:
        print("no touch-down after a predicted landing in these runs (longer --seconds?)", file=sys.stderr)
        return 1
    from fslip_planner import landing as Ld
    from fslip_planner.plan import FlipSession
    Ld.WARM_POINTS = max(Ld.WARM_POINTS, 1 + len(records[0]["predictions"]) * (1 + len(FALL_SHORTER)))
    robot = FlipSession(a.kinds[0], apex_height=a.apex, motor_speed_scale=a.motor_speed_scale,
                        flywheel_torque=a.flywheel_torque, knee_tangential=a.knee_tangential).robot
    prob = Ld.LandingProblem(robot.params, robot.L0, near_start=True)
    print(f"landing re-solves of {len(records)} recorded touch-downs ({', '.join(a.kinds)}; apex {a.apex} m, "
          f"distance {a.distance} m, platform {a.platform} m, ground offset {a.ground_offset} m, read noise "
          f"{a.noise}, {a.seconds} s each)")
    print("| strategy | touch-down iterations median | p90 | max | failed | prediction iterations median | max "
          "| predictions failed |")
    print("|---|---|---|---|---|---|---|---|")
    for strategy in mine.strategies:
        out = [resolve(prob, r, strategy) for r in records]
        its = [o["iterations"] for o in out if o["iterations"] is not None]
        spent = [o["spent"] for o in out]
        cells = (f"{statistics.median(its):.0f} | {np.percentile(its, 90):.0f} | {max(its)}" if its else "- | - | -")
        print(f"| {strategy} | {cells} | {len(out) - len(its)} | {statistics.median(spent):.0f} | {max(spent)} | "
              f"{sum(o['failed'] for o in out)} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
