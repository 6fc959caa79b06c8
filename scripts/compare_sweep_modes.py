#!/usr/bin/env python3
"""Spot check of `flip sweep --mode graph` against offline: each sample of a graph sweep's results
(DIR/results) run offline (flip_tools.perturb.run_sample) from the sweep's start time and from the
graph run's own jump start (the graph's request latency and plan lead set it; ``jump_start_s``).
Prints a table (outcome per mode, wall seconds per sample) and the agreement counts.

    .venv/bin/python scripts/compare_sweep_modes.py DIR
"""
from __future__ import annotations

import argparse
import json
import statistics
from concurrent.futures import ProcessPoolExecutor

from flip_tools import perturb as P
from flip_tools import sweep as S


def offline(args):
    flip, knobs, seed, start = args
    return P.run_sample(P.Sample(flip, {**knobs, "start": start}, seed))


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dir", help="a `flip sweep --mode graph` output folder")
    ap.add_argument("--jobs", type=int, default=2)
    a = ap.parse_args()
    rows = sorted((r for r in S.ResultStore(a.dir).rows() if r["mode"] == "graph"),
                  key=lambda r: (r["flip"], r["knobs"]))
    if not rows:
        raise SystemExit(f"{a.dir}: no graph-mode results")
    jobs = []
    for r in rows:
        knobs = json.loads(r["knobs"])
        jobs.append((r["flip"], knobs, r["seed"], knobs.get("start", P.KNOBS["start"][0])))
        jobs.append((r["flip"], knobs, r["seed"], r["jump_start_s"] if r["jump_start_s"] is not None
                     else jobs[-1][3]))
    with ProcessPoolExecutor(a.jobs) as ex:
        res = list(ex.map(offline, jobs))
    print("| flip | knobs | graph (jump start s) | offline, sweep's start | offline, graph's jump start | "
          "wall s graph | wall s offline |")
    print("|---|---|---|---|---|---|---|")
    same_nominal = same_start = 0
    for r, nominal, at_start in zip(rows, res[0::2], res[1::2]):
        same_nominal += nominal["outcome"] == r["outcome"]
        same_start += at_start["outcome"] == r["outcome"]
        js = f"{r['jump_start_s']:.2f}" if r["jump_start_s"] is not None else "-"
        print(f"| {r['flip']} | {r['knobs']} | {r['outcome']} ({js}) | {nominal['outcome']} | "
              f"{at_start['outcome']} | {r['wall_s']:.1f} | {at_start['wall_s']:.1f} |")
    n = len(rows)
    print(f"\nagreement: {same_start}/{n} with offline from the graph's jump start, "
          f"{same_nominal}/{n} from the sweep's start")
    print(f"wall s per sample: graph median {statistics.median(r['wall_s'] for r in rows):.1f}, offline median "
          f"{statistics.median(x['wall_s'] for x in res):.1f} (offline: {a.jobs} at a time on this machine)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
