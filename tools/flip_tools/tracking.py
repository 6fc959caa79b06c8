"""How well a run followed its plan: the measured outputs (flip_tools.measured, recomputed from the
bag) against the planner's references on /fslip/reference, per ground domain: RMS and largest
|measured - planned| of each output the reference plans and the bag lets us measure (the paper's Y1
and Y2 of the jumping and landing domains: H_pitch, L, x_com), over the part of the reference's span
the robot spent in that domain.  The landing is the paper's re-solve at touch-down (§III-C) and, after
a rebound, the re-solve of the next touch-down, each over its own span; the errors are against them
whether the controller tracked them or ran its own landing."""
from __future__ import annotations

import numpy as np

#: outputs compared (phi_pitch is planned too; its measured value is the pelvis pitch on /odom)
COMPARED = ("H_pitch", "L", "x_com")


def newest_reference(refs: list[dict], domain: int) -> dict | None:
    """The last reference of ``domain`` published (a re-solve replaces the plan's first landing)."""
    found = [r for r in refs if r["domain"] == domain]
    return found[-1] if found else None


def reference_span(ref: dict) -> tuple[float, float]:
    """Sim-time span a reference covers: its start time plus its time grid's ends."""
    t = np.asarray(ref["t"], float)
    return float(ref["start_time"] + t[0]), float(ref["start_time"] + t[-1])


def output_errors(measured: dict, ref: dict, t0: float, t1: float) -> dict | None:
    """{output: {"rms", "max", "n"}} of measured - planned over measured samples in [t0, t1] (the
    plan linearly interpolated at the measured times), plus "t0", "t1"; None without samples."""
    tm = np.asarray(measured["t"], float)
    r0, r1 = reference_span(ref)
    a, b = max(t0, r0), min(t1, r1)
    k = (tm >= a) & (tm <= b)
    if b <= a or not k.any():
        return None
    t_ref = ref["start_time"] + np.asarray(ref["t"], float)
    value = np.asarray(ref["value"], float)
    out: dict = {"t0": round(a, 4), "t1": round(b, 4)}
    for name in COMPARED:
        if name not in ref["output_names"] or name not in measured:
            continue
        planned = np.interp(tm[k], t_ref, value[:, ref["output_names"].index(name)])
        e = np.asarray(measured[name], float)[k] - planned
        out[name] = {"rms": round(float(np.sqrt(np.mean(e ** 2))), 4), "max": round(float(np.max(np.abs(e))), 4),
                     "n": int(k.sum())}
    return out


def errors_over_plans(measured: dict, refs: list[dict], t0: float, t1: float) -> dict | None:
    """:func:`output_errors` against a sequence of references of one domain (a landing and the re-solves
    of the touch-downs after its rebounds), each over its span until the next one starts (what the
    controller was given at each time), pooled: {output: {"rms", "max", "n"}}, "t0", "t1" and "plans"
    (how many references had samples); None without samples."""
    refs = sorted(refs, key=lambda r: float(r["start_time"]))
    parts = []
    for i, ref in enumerate(refs):
        end = min(t1, float(refs[i + 1]["start_time"])) if i + 1 < len(refs) else t1
        e = output_errors(measured, ref, t0, end)
        if e is not None:
            parts.append(e)
    if not parts:
        return None
    out: dict = {"t0": parts[0]["t0"], "t1": parts[-1]["t1"], "plans": len(parts)}
    for name in COMPARED:
        got = [p[name] for p in parts if name in p]
        if got:
            n = sum(g["n"] for g in got)
            out[name] = {"rms": round(float(np.sqrt(sum(g["n"] * g["rms"] ** 2 for g in got) / n)), 4),
                         "max": max(g["max"] for g in got), "n": n}
    return out


def peak_abs(t: np.ndarray, v: np.ndarray, t0: float, t1: float) -> float | None:
    """Largest |v| over samples with t in [t0, t1] (None without samples)."""
    k = (np.asarray(t) >= t0) & (np.asarray(t) <= t1)
    return float(np.nanmax(np.abs(np.asarray(v)[k]))) if k.any() else None
