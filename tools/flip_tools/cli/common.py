"""What every subcommand shares: exit codes, the log line, argument types, the run folder."""
from __future__ import annotations

import argparse
import math
import shutil
import sys
from pathlib import Path

# one code per meaning (README, "The flip tool"); 2 is argparse's own for a usage error
EXIT_OK, EXIT_NOT_LANDED, EXIT_USAGE, EXIT_INFRA, EXIT_REJECTED, EXIT_INTERRUPTED = 0, 1, 2, 3, 4, 130
#: RequestFlip's kind of each jump name
KINDS = {"backflip": 0, "frontflip": 1, "hop": 2}
#: how flip starts itself in a child process (its recorder, study's runs): this interpreter
FLIP_CMD = [sys.executable, "-m", "flip_tools.cli"]


def log(msg: str) -> None:
    print(f"[flip] {msg}", file=sys.stderr, flush=True)


def cpu_latency_arg(text: str) -> int | None:
    """argparse type of --cpu-dma-latency: microseconds or 'off' (None)."""
    from flip_tools.cpu_latency import parse_latency
    try:
        return parse_latency(text)
    except ValueError as e:
        raise argparse.ArgumentTypeError(str(e)) from None


def number(lo: float | None = None, hi: float | None = None, lo_open: bool = False):
    """argparse type: a finite number in [lo, hi] (``lo_open``: > lo), refused at parse time
    (exit 2) before anything is started or written."""
    def parse(text: str) -> float:
        try:
            v = float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
        if not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"{text} is not finite")
        if lo is not None and (v <= lo if lo_open else v < lo):
            raise argparse.ArgumentTypeError(f"{text} must be {'>' if lo_open else '>='} {lo:g}")
        if hi is not None and v > hi:
            raise argparse.ArgumentTypeError(f"{text} must be <= {hi:g}")
        return v
    return parse


POSITIVE, NONNEGATIVE, FINITE = number(0.0, lo_open=True), number(0.0), number()

#: what a run of this tool writes in its DIR (prepare_out clears these, and only these)
RUN_FILES = ("bag", "logs", "summary.json", "run.json", "record_stats.json", "*.png", "flip.mp4", "flip.gif")


def prepare_out(out: Path) -> None:
    """DIR for a run: a new or empty folder, or a previous run of this tool (it has run.json), whose
    own files (bag/, logs/, summary, plots) are cleared; anything else is refused (SystemExit), and
    nothing of what the tool did not write is ever deleted."""
    if out.exists() and not out.is_dir():
        raise SystemExit(f"--out {out}: exists and is not a folder")
    if out.is_dir() and any(out.iterdir()) and not (out / "run.json").is_file():
        raise SystemExit(f"--out {out}: a non-empty folder that is not a previous run of this tool "
                         f"(no run.json): choose another")
    try:
        out.mkdir(parents=True, exist_ok=True)
    except OSError as e:
        raise SystemExit(f"--out {out}: cannot create it ({e.strerror})") from None
    for name in ("bag", "logs"):
        if (out / name).exists():
            shutil.rmtree(out / name)
    for pat in RUN_FILES[2:]:
        for f in out.glob(pat):
            f.unlink()


def json_default(o):
    """json.dumps' fallback: NumPy scalars and arrays as Python numbers and lists, anything else as text."""
    try:
        import numpy as np
        if isinstance(o, np.generic):
            return o.item()
        if isinstance(o, np.ndarray):
            return o.tolist()
    except ImportError:
        pass
    return str(o)
