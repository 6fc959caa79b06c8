"""`flip sweep`: how often the flips land over perturbations of the simulated robot (flip_tools.perturb),
each sample an offline flip (flip_tools.offline) or, with ``--mode graph``, a `flip run` through the
node graph (flip_tools.sweep_graph) run as a Ray task.

Samples come from a grid (every combination of the knobs' levels, per flip) or are drawn at random
from ranges with a seed.  Ray runs embedded on this machine by default, bound to 127.0.0.1 with a
small object store, or joins a cluster (``--address``).  Results are written to ``DIR/results/``
(a Parquet dataset: one part file per batch of finished samples) as they come in; a rerun skips the
samples whose id (a hash of the record) is there.  At the end: the landing rate per knob level, the
failure modes and plots (flip_tools.sweep_report).
"""
from __future__ import annotations

import itertools
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from . import perturb as P

#: the folder flip_tools is in, put on the Ray workers' PYTHONPATH: the workers of a joined cluster
#: may run without this venv's editable install of it
TOOLS_DIR = Path(__file__).resolve().parents[1]
#: Ray's smallest object store: a sample's result is a few hundred bytes
OBJECT_STORE_BYTES = 80 * 1024 ** 2
#: results are written when this many are pending or this long after the last write (s)
FLUSH_ROWS, FLUSH_SECONDS = 8, 20.0


# ------------------------------------------------------------------ samples
def parse_assignments(items, what: str) -> dict:
    """``["name=value", ...]`` -> {name: value text}; SystemExit naming the bad item."""
    out = {}
    for item in items or ():
        name, sep, value = item.partition("=")
        if not sep or not name or not value:
            raise SystemExit(f"{what}: expected NAME=VALUE, got {item!r}")
        if name not in P.KNOBS:
            raise SystemExit(f"{what}: unknown knob {name!r}; known knobs: {', '.join(P.KNOBS)}")
        if name in out:
            raise SystemExit(f"{what}: knob {name} given twice")
        out[name] = value
    return out


def _checked(name: str, value):
    try:
        return P.check_knobs({name: value})[name]
    except ValueError as e:
        raise SystemExit(str(e)) from None


def grid_levels(items) -> dict:
    """``--grid name=v1,v2,...`` -> {name: [values]} (checked)."""
    return {n: [_checked(n, v) for v in text.split(",")] for n, text in parse_assignments(items, "--grid").items()}


def ranges(items) -> dict:
    """``--range name=lo:hi`` -> {name: (lo, hi)} (checked)."""
    out = {}
    for n, text in parse_assignments(items, "--range").items():
        lo, sep, hi = text.partition(":")
        if not sep or n == "push_phase":
            raise SystemExit(f"--range {n}: expected {n}=LO:HI with numbers")
        lo, hi = _checked(n, lo), _checked(n, hi)
        if not lo <= hi:
            raise SystemExit(f"--range {n}: {lo} > {hi}")
        out[n] = (lo, hi)
    return out


def _applicable(flip: str, knobs: dict) -> bool:
    try:
        P.Sample(flip, knobs)
        return True
    except ValueError:
        return False


def grid_samples(flips, levels: dict, fixed: dict, seed: int, repeats: int = 1) -> tuple[list, int]:
    """Every combination of the grid's levels for each flip (seeds ``seed`` .. ``seed + repeats - 1``:
    the same noise at every grid point); the samples that do not apply to a flip (ground_offset for
    a flip in place) are left out.  Returns (samples, how many were left out)."""
    names = list(levels)
    out, skipped = [], 0
    for flip in flips:
        for combo in itertools.product(*(levels[n] for n in names)):
            knobs = {**fixed, **dict(zip(names, combo))}
            if not _applicable(flip, knobs):
                skipped += repeats
                continue
            out += [P.Sample(flip, knobs, seed + r) for r in range(repeats)]
    return out, skipped


def random_samples(flips, bounds: dict, fixed: dict, n: int, seed: int) -> tuple[list, int]:
    """``n`` samples drawn uniformly from ``bounds`` (delay_steps: whole steps), the flips in turn,
    each with its own seed, all from ``seed``.  Draws that do not apply to their flip are left out."""
    rng = np.random.default_rng(seed)
    out, skipped = [], 0
    for i in range(n):
        knobs = dict(fixed)
        for name, (lo, hi) in bounds.items():
            knobs[name] = int(rng.integers(lo, hi + 1)) if name == "delay_steps" else float(rng.uniform(lo, hi))
        flip, s = flips[i % len(flips)], int(rng.integers(2 ** 31))
        if _applicable(flip, knobs):
            out.append(P.Sample(flip, knobs, s))
        else:
            skipped += 1
    return out, skipped


# ------------------------------------------------------------------ results on disk
def schema():
    """The results' Parquet schema (fixed, so that every part file reads alike)."""
    import pyarrow as pa
    f64, i64, s = pa.float64(), pa.int64(), pa.string()
    knob_types = {k: (i64 if k == "delay_steps" else s if k == "push_phase" else f64) for k in P.KNOBS}
    return pa.schema([("sample_id", s), ("flip", s), ("knobs", s), ("seed", i64), *knob_types.items(),
                      ("outcome", s), ("limit", s), ("error", s), ("net_rotation_deg", f64), ("fell_at_s", f64),
                      ("touchdown_s", f64), ("peak_flywheel_rpm", f64), ("sim_s", f64), ("wall_s", f64),
                      # added with --mode graph (older part files read them as null)
                      ("mode", s), ("jump_start_s", f64)])


class ResultStore:
    """``DIR/results/part-*.parquet``: finished samples, written in batches as they come in."""

    def __init__(self, out: Path):
        self.dir = Path(out) / "results"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.pending: list[dict] = []
        self.last_flush = time.monotonic()

    def rows(self) -> list[dict]:
        """Every stored result (the last one of a sample stored twice)."""
        import pyarrow.parquet as pq
        rows = {}
        for part in sorted(self.dir.glob("part-*.parquet")):
            for r in pq.read_table(part, schema=schema()).to_pylist():
                rows[r["sample_id"]] = r
        return list(rows.values())

    def done_ids(self) -> set:
        return {r["sample_id"] for r in self.rows()}

    def add(self, row: dict) -> None:
        self.pending.append(row)
        if len(self.pending) >= FLUSH_ROWS or time.monotonic() - self.last_flush > FLUSH_SECONDS:
            self.flush()

    def flush(self) -> None:
        """Write the pending results as a new part file (written aside, then renamed: a crash leaves
        no half-written part)."""
        import pyarrow as pa
        import pyarrow.parquet as pq
        self.last_flush = time.monotonic()
        if not self.pending:
            return
        n = len(list(self.dir.glob("part-*.parquet")))
        name = f"part-{n:05d}-{os.getpid()}-{time.time_ns()}.parquet"
        tmp = self.dir / f".{name}.tmp"
        pq.write_table(pa.Table.from_pylist(self.pending, schema=schema()), tmp)
        tmp.rename(self.dir / name)
        self.pending = []


# ------------------------------------------------------------------ Ray
def _run_remote(record: dict) -> dict:
    """A Ray task: one sample from its record."""
    return P.run_sample(P.Sample(**record))


def _run_graph_remote(record: dict, runs_dir: str, keep_bag: bool) -> dict:
    """A Ray task: one sample through the node graph (`flip run` in ``runs_dir``)."""
    from .sweep_graph import run_graph_sample
    return run_graph_sample(record, runs_dir, keep_bag)


def start_ray(address: str | None, workers: int | None) -> int:
    """``ray.init`` embedded on this machine (bound to 127.0.0.1, no dashboard, a small object store)
    or joined to the cluster at ``address``; returns the number of CPUs it offers."""
    os.environ.setdefault("RAY_USAGE_STATS_ENABLED", "0")
    if address is None:
        if "ray" in sys.modules:
            raise RuntimeError("start_ray: ray was imported before its environment was set")
        # a Linux node resolves 127.0.0.1 to its outward address and listens on every interface
        # unless Ray thinks multi-node clusters are off (then its servers bind to 127.0.0.1)
        os.environ["RAY_ENABLE_WINDOWS_OR_OSX_CLUSTER"] = "0"
    import logging

    import ray
    pythonpath = os.pathsep.join(p for p in (str(TOOLS_DIR), os.environ.get("PYTHONPATH")) if p)
    common = dict(runtime_env={"env_vars": {"PYTHONPATH": pythonpath}}, log_to_driver=False,
                  logging_level=logging.WARNING)
    if address is None:
        ray.init(num_cpus=workers or os.cpu_count(), include_dashboard=False, _node_ip_address="127.0.0.1",
                 object_store_memory=OBJECT_STORE_BYTES, **common)
    else:
        ray.init(address=address, **common)
    return int(ray.cluster_resources().get("CPU", 1))


def cluster_nodes() -> list[str]:
    """The alive nodes' addresses."""
    import ray
    return sorted(n["NodeManagerAddress"] for n in ray.nodes() if n["Alive"])


def execute(samples: list, workers: int, on_result, graph: dict | None = None) -> None:
    """Run the samples as Ray tasks, at most ``workers`` at a time, handing each result to
    ``on_result`` as it finishes (a task that died is an ``error`` result).  ``graph``: each
    through the node graph (``{"runs_dir": ..., "keep_bag": ...}``), a task taking GRAPH_CPUS."""
    import ray
    if graph is None:
        task, extra = ray.remote(num_cpus=1, max_retries=0)(_run_remote), ()
    else:
        from .sweep_graph import GRAPH_CPUS
        task = ray.remote(num_cpus=GRAPH_CPUS, max_retries=0)(_run_graph_remote)
        extra = (graph["runs_dir"], graph["keep_bag"])
    queue = list(reversed(samples))
    running = {}
    while queue or running:
        while queue and len(running) < workers:
            s = queue.pop()
            running[task.remote(s.to_dict(), *extra)] = s
        ready, _ = ray.wait(list(running), num_returns=1)
        for ref in ready:
            s = running.pop(ref)
            try:
                row = ray.get(ref)
            except Exception as e:  # noqa: BLE001 -- a worker that died: the sample's result says so
                row = P.failed_result(s, f"{type(e).__name__}: {e}", "offline" if graph is None else "graph")
            on_result(row)


def run_sweep(samples: list, out: Path, address: str | None = None, workers: int | None = None,
              progress: bool = True, log=print, graph: dict | None = None) -> list[dict]:
    """Run the samples not yet in ``out``'s results on Ray (``graph``: through the node graph,
    execute's); returns the results of all of them."""
    store = ResultStore(out)
    done = store.done_ids()
    todo = [s for s in samples if s.id not in done]
    log(f"sweep: {len(samples)} samples, {len(samples) - len(todo)} already in {store.dir}, {len(todo)} to run")
    if todo:
        per = 1
        if graph is not None:
            from .sweep_graph import GRAPH_CPUS
            per = GRAPH_CPUS
        # embedded: as many CPUs as the workers asked for take (a graph takes GRAPH_CPUS)
        cpus = start_ray(address, workers and workers * per)
        import ray
        try:
            nodes = cluster_nodes()
            fits = max(1, cpus // per)
            n = min(workers or fits, fits) if address else (workers or fits)
            log(f"ray {ray.__version__}: {len(nodes)} node(s) ({', '.join(sorted(set(nodes)))}), {cpus} CPU(s), "
                f"{n} sample(s) at a time" + (f", each a node graph of {per} CPUs" if graph is not None else ""))
            _execute_with_progress(todo, n, store, progress, graph)
        finally:
            store.flush()
            ray.shutdown()
    ids = {s.id for s in samples}
    return [r for r in store.rows() if r["sample_id"] in ids]


def _execute_with_progress(todo, workers, store, progress, graph=None) -> None:
    from tqdm import tqdm
    bar = tqdm(total=len(todo), file=sys.stderr, unit="sample", disable=not progress, smoothing=0.1)
    landed = 0

    def on_result(row):
        nonlocal landed
        store.add(row)
        landed += row["outcome"] == "landed"
        bar.set_postfix(landed=landed, refresh=False)
        bar.update(1)
    try:
        execute(todo, workers, on_result, graph)
    finally:
        bar.close()


def write_definition(out: Path, args_dict: dict, samples: list) -> None:
    """``DIR/sweep.json``: how the sweep was asked for and its sample ids."""
    Path(out).mkdir(parents=True, exist_ok=True)
    (Path(out) / "sweep.json").write_text(json.dumps({**args_dict, "robot": P.ROBOT, "samples": len(samples),
                                                      "sample_ids": [s.id for s in samples]}, indent=1) + "\n")


# ------------------------------------------------------------------ the command
def cmd_sweep(args, log=print) -> int:
    """`flip sweep`: the samples from the arguments, run (or resumed), reported; 0 when every sample
    has a result."""
    from . import sweep_report
    if args.workers is not None and args.workers < 1:
        raise SystemExit("--workers must be >= 1")
    fixed = {n: _checked(n, v) for n, v in parse_assignments(args.set, "--set").items()}
    if args.random is not None:
        if args.grid:
            raise SystemExit("choose --grid or --random, not both")
        bounds = ranges(args.range)
        if set(bounds) & set(fixed):
            raise SystemExit("a knob is both --set and --range")
        samples, skipped = random_samples(args.flips, bounds, fixed, args.random, args.seed)
    else:
        if args.range:
            raise SystemExit("--range needs --random N")
        levels = grid_levels(args.grid)
        if set(levels) & set(fixed):
            raise SystemExit("a knob is both --set and --grid")
        samples, skipped = grid_samples(args.flips, levels, fixed, args.seed, args.repeats)
    if skipped:
        log(f"sweep: {skipped} sample(s) left out: ground_offset applies to the flips that travel "
            f"({', '.join(P.TRAVELLING)}), not to a flip in place")
    if not samples:
        raise SystemExit("no samples to run")
    graph = None
    out = Path(args.out or f"runs/sweep-{time.strftime('%Y%m%d-%H%M%S')}")
    if args.mode == "graph":
        from .sweep_graph import refusal
        why = refusal(samples)
        if why:
            raise SystemExit(why)
        # each sample's `flip run` folder (summary.json, run.json, logs; the bag with --keep-bags)
        graph = {"runs_dir": str((out / "runs").resolve()), "keep_bag": args.keep_bags}
    write_definition(out, {k: v for k, v in vars(args).items() if k != "func"}, samples)
    t0 = time.monotonic()
    try:
        rows = run_sweep(samples, out, args.address, args.workers, progress=not args.no_progress, log=log,
                         graph=graph)
    except KeyboardInterrupt:
        log(f"sweep: interrupted; the finished samples are in {out / 'results'} (the same command resumes)")
        return 130
    log(f"sweep: {len(rows)} result(s) in {out / 'results'} ({time.monotonic() - t0:.1f} s)")
    text, files = sweep_report.report(rows, out)
    log(text)
    for f in files:
        log(f"plot: {f}")
    return 0 if len(rows) == len(samples) else 1
