"""What a sweep found (flip_tools.sweep): the landing rate per knob level, the failure modes with
their share, and plots (matplotlib Agg): the landing rate against each knob the sweep varied, and a
heat map when it varied two."""
from __future__ import annotations

import textwrap
from collections import Counter
from pathlib import Path

import numpy as np

from .perturb import KNOBS, OUTCOMES

#: a knob with more distinct values than this (a random sweep's) is shown in this many bins
MAX_LEVELS = 8
BINS = 5


def varied_knobs(rows: list[dict]) -> list[str]:
    """The knobs that take more than one value among the rows."""
    return [k for k in KNOBS if len({r[k] for r in rows}) > 1]


def levels(rows: list[dict], knob: str) -> list[tuple]:
    """[(label, x, predicate)] of a knob: its values, or ``BINS`` equal bins of a knob with many."""
    values = sorted({r[knob] for r in rows}, key=lambda v: (v is None, v))
    if len(values) <= MAX_LEVELS or isinstance(values[0], str) or None in values:
        return [(_fmt(v), v, (lambda r, v=v: r[knob] == v)) for v in values]
    edges = np.linspace(values[0], values[-1], BINS + 1)
    out = []
    for i, (lo, hi) in enumerate(zip(edges[:-1], edges[1:])):
        last = i == BINS - 1
        out.append((f"[{lo:.4g}, {hi:.4g}{']' if last else ')'}", 0.5 * (lo + hi),
                    (lambda r, lo=lo, hi=hi, last=last: lo <= r[knob] < hi or (last and r[knob] == hi))))
    return out


def _fmt(v) -> str:
    return "default" if v is None else f"{v:g}" if isinstance(v, float) else str(v)


def _rate(rows) -> tuple[int, int]:
    return sum(r["outcome"] == "landed" for r in rows), len(rows)


def _fraction(rows) -> float:
    landed, n = _rate(rows)
    return landed / n if n else np.nan


def _cell(rows) -> str:
    landed, n = _rate(rows)
    return "-" if not n else f"{landed}/{n} ({100.0 * landed / n:.0f}%)"


def rate_table(rows: list[dict]) -> str:
    """Markdown: per varied knob and level, landed / samples over all flips and per flip."""
    flips = sorted({r["flip"] for r in rows})
    knobs = varied_knobs(rows)
    head = "| knob | level | all | " + " | ".join(flips) + " |"
    lines = ["landing rate per knob level (landed/samples)", head, "|" + "---|" * (3 + len(flips))]
    lines.append("| (all) | | " + _cell(rows) + " | "
                 + " | ".join(_cell([r for r in rows if r["flip"] == f]) for f in flips) + " |")
    for k in knobs:
        for label, _, pick in levels(rows, k):
            sel = [r for r in rows if pick(r)]
            lines.append(f"| {k} | {label} | {_cell(sel)} | "
                         + " | ".join(_cell([r for r in sel if r["flip"] == f]) for f in flips) + " |")
    return "\n".join(lines)


def outcome_table(rows: list[dict]) -> str:
    """Markdown: each outcome's count and share; a rejected request's limits, an error's message."""
    counts = Counter(r["outcome"] for r in rows)
    lines = ["outcomes", "| outcome | samples | share |", "|---|---|---|"]
    for o in OUTCOMES:
        if counts.get(o):
            lines.append(f"| {o} | {counts[o]} | {100.0 * counts[o] / len(rows):.1f}% |")
    for what, key in (("rejected", "limit"), ("error", "error")):
        detail = Counter(r[key] for r in rows if r["outcome"] == what)
        for text, n in detail.most_common(5):
            lines.append(f"{what} ({n}): {text}")
    return "\n".join(lines)


def report(rows: list[dict], out: Path) -> tuple[str, list[Path]]:
    """(the tables as text, the plot files), also written to ``out/summary.md``."""
    if not rows:
        return "no results", []
    text = rate_table(rows) + "\n\n" + outcome_table(rows)
    out = Path(out)
    (out / "summary.md").write_text(text + "\n")
    files = [rate_plot(rows, k, out / f"landing_rate_{k}.png") for k in varied_knobs(rows)]
    knobs = varied_knobs(rows)
    if len(knobs) == 2 and all(len(levels(rows, k)) <= MAX_LEVELS for k in knobs):
        files.append(heat_map(rows, knobs, out / f"heatmap_{knobs[0]}_{knobs[1]}.png"))
    return text, files


def _pyplot():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    return plt


def rate_plot(rows: list[dict], knob: str, path: Path) -> Path:
    """Landing rate against one knob: all flips and each flip."""
    plt = _pyplot()
    lv = levels(rows, knob)
    numeric = all(isinstance(x, (int, float)) for _, x, _ in lv)
    xs = [x for _, x, _ in lv] if numeric else list(range(len(lv)))
    fig, ax = plt.subplots(figsize=(6, 4))
    for flip in [None] + sorted({r["flip"] for r in rows}):
        sel = [r for r in rows if flip is None or r["flip"] == flip]
        rate = [_fraction([r for r in sel if pick(r)]) for _, _, pick in lv]
        ax.plot(xs, rate, "o-", lw=2.5 if flip is None else 1.2, color="k" if flip is None else None,
                label="all" if flip is None else f"flip {flip}")
    if not numeric:
        ax.set_xticks(xs, [label for label, _, _ in lv])
    ax.set_xlabel(knob)
    ax.set_title(textwrap.fill(KNOBS[knob][1], 80), fontsize=8)
    ax.set_ylabel("landing rate")
    ax.set_ylim(-0.05, 1.05)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path


def heat_map(rows: list[dict], knobs: list[str], path: Path) -> Path:
    """Landing rate over two knobs' levels (all flips), each cell annotated landed/samples."""
    plt = _pyplot()
    (kx, ky), lx, ly = knobs, levels(rows, knobs[0]), levels(rows, knobs[1])
    rate = np.full((len(ly), len(lx)), np.nan)
    fig, ax = plt.subplots(figsize=(1.2 * len(lx) + 2.5, 0.9 * len(ly) + 2))
    for j, (_, _, py) in enumerate(ly):
        for i, (_, _, px) in enumerate(lx):
            landed, n = _rate([r for r in rows if px(r) and py(r)])
            if n:
                rate[j, i] = landed / n
                ax.text(i, j, f"{landed}/{n}", ha="center", va="center", fontsize=8)
    im = ax.imshow(rate, origin="lower", vmin=0.0, vmax=1.0, cmap="RdYlGn", aspect="auto")
    ax.set_xticks(range(len(lx)), [label for label, _, _ in lx])
    ax.set_yticks(range(len(ly)), [label for label, _, _ in ly])
    ax.set_xlabel(kx)
    ax.set_ylabel(ky)
    fig.colorbar(im, ax=ax, label="landing rate")
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return path
