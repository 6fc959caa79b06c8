"""flip stand: the simulator and the controller holding the standing pose, recorded (flip sim's graph
with the controller; exit 1 when the summary does not say standing)."""
from __future__ import annotations

from .sim import add_sim_parser


def add_parser(sub) -> None:
    add_sim_parser(sub, "stand", stand=True)
