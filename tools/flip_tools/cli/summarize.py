"""flip summarize: DIR/summary.json and plots recomputed from DIR/bag (exit 0 when it shows a landing)."""
from __future__ import annotations

import json
from pathlib import Path

from .common import EXIT_NOT_LANDED, EXIT_OK
from .results import finish, print_summary


def add_parser(sub) -> None:
    sp = sub.add_parser("summarize", help="recompute DIR/summary.json and plots from DIR/bag")
    sp.add_argument("dir")
    sp.add_argument("--kind", choices=["backflip", "frontflip", "hop", "stand", "sim"])
    sp.add_argument("--ground-z", type=float)
    sp.set_defaults(func=cmd_summarize)


def cmd_summarize(args) -> int:
    out = Path(args.dir)
    run_info = {}
    if (out / "run.json").exists():
        run_info = json.loads((out / "run.json").read_text())
    kind = args.kind or run_info.get("kind")
    ground = args.ground_z if args.ground_z is not None else run_info.get("landing_ground_z", 0.0)
    prev = json.loads((out / "summary.json").read_text()) if (out / "summary.json").exists() else {}
    extra = {k: prev[k] for k in ("processes", "run", "response", "error") if k in prev}
    summary = finish(out, None, prev.get("processes", {}), extra, kind, ground,
                     run_info.get("takeoff_ground_z", 0.0))
    print_summary(summary)
    return EXIT_OK if summary.get("outcome") == "landed" else EXIT_NOT_LANDED
