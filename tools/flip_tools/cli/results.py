"""A run's results: summary.json and plots from its bag, and their lines on the terminal."""
from __future__ import annotations

import json
from pathlib import Path
from typing import TYPE_CHECKING

from .common import json_default, log

if TYPE_CHECKING:
    from .graph import Graph


def finish(out: Path, graph: Graph | None, report: dict, extra: dict, kind: str | None,
           ground_z: float, takeoff_z: float = 0.0, plots: bool = True) -> dict:
    """summary.json + plots from the bag (read once for both)."""
    from flip_tools.bag import NOT_SUMMARIZED, load_bag
    from flip_tools.summary import summarize
    bag = out / "bag"
    summary = {"outcome": "no_bag"}
    data = None
    # a bag without metadata.yaml (its recorder died) is recovered by load_bag
    if bag.exists() and ((bag / "metadata.yaml").exists() or any(bag.glob("*.mcap"))):
        try:
            data = load_bag(bag, exclude=NOT_SUMMARIZED)
            summary = summarize(data, kind=kind, landing_ground_z=ground_z, takeoff_ground_z=takeoff_z)
        except Exception as e:  # noqa: BLE001
            summary = {"outcome": "error", "error": f"summary failed: {e!r}"}
        kept = summary.get("bag_recovered")
        if kept:
            ran = f" of the {graph.sim_time:.2f} s simulated" if graph is not None and graph.sim_time else ""
            log(f"the bag had no index or metadata.yaml (its recorder died): recovered {kept['messages']} "
                f"messages, sim time {summary.get('sim_duration_s')} s{ran} "
                f"({kept['bytes_dropped']} bytes of an unfinished chunk left out); index and metadata.yaml written")
    summary["processes"] = report
    summary["landing_fallbacks"] = landing_fallbacks(out / "logs" / "tsc.log")
    summary["landing_rebounds"] = landing_rebounds(out / "logs" / "tsc.log")
    summary.update(extra)   # a rejected request: outcome "rejected" whatever the bag shows
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=json_default))
    if plots and bag.exists() and (bag / "metadata.yaml").exists():
        try:
            from flip_tools.plots import plot_bag
            files = plot_bag(bag, out, data=data)
            summary["plots"] = [str(Path(f).name) for f in files]
            (out / "summary.json").write_text(json.dumps(summary, indent=2, default=json_default))
        except Exception as e:  # noqa: BLE001
            log(f"plots failed: {e!r}")
    return summary


def _log_matches(log_file: Path, pattern: str) -> list | None:
    """The regex matches of ``pattern`` in a node's log, in order; None without the log."""
    import re
    if not log_file.is_file():
        return None
    return list(re.finditer(pattern, log_file.read_text(errors="replace")))


def landing_fallbacks(log_file: Path) -> list | None:
    """The landings the controller's own landing did instead of the planner's tracked landing plan,
    from tsc_node's log: [{"t": s, "reason": "rebound" | "no landing plan"}]; None without the log."""
    found = _log_matches(log_file, r"landing fallback: own landing from t=([-0-9.]+) s \(([^)]*)\)")
    return None if found is None else [{"t": float(m.group(1)), "reason": m.group(2)} for m in found]


def landing_rebounds(log_file: Path) -> list | None:
    """The times (s) the feet left the ground under the tracked landing plan and the plan went on until
    the next touch-down's re-solve (tsc_node's 'rebound at t=' lines); None without the log."""
    found = _log_matches(log_file, r"rebound at t=([-0-9.]+) s")
    return None if found is None else [float(m.group(1)) for m in found]


def print_summary(summary: dict, keys=None) -> None:
    keys = keys or ["outcome", "verdict_notes", "net_rotation_deg", "apex_height_m", "forward_distance_m",
                    "flight_time_s", "touchdown_state", "touchdown_com_ahead_of_feet_m", "final_tilt_deg",
                    "final_height_above_ground_m", "at_rest",
                    "peak_flywheel_rpm", "flight_peak_flywheel_rpm", "landing_peak_flywheel_rpm", "tracking",
                    "landing_fallbacks", "landing_rebounds",
                    "tsc_tick_us", "sim_duration_s", "wall_time_s", "real_time_factor"]
    for k in keys:
        if k in summary:
            print(f"  {k}: {json.dumps(summary[k], default=json_default)}")
