"""Whole turns of the pelvis across flips.  The controller tracks a FLIGHT reference's phi_pitch
against its pelvis pitch unwrapped since it started (−2π after a backflip); the planner measures a
wrapped pitch at each contact event.  A flight plan is therefore shifted by the whole turns of the
flips before it, counted at each touch-down from where the last flight plan ended."""
from __future__ import annotations

import math


class PitchTurns:
    """2π × the somersaults turned so far, and the shift of the next flight plan."""

    def __init__(self, turns: float = 0.0):
        self.turns = float(turns)
        self._flight_end = None

    def shift_flight(self, ref) -> None:
        """Add the turns to a FLIGHT reference's phi_pitch column (in place) and remember its end."""
        if "phi_pitch" not in ref.names:
            return
        col = ref.names.index("phi_pitch")
        ref.value[:, col] += self.turns
        self._flight_end = float(ref.value[-1, col])

    def touch_down(self, measured_pitch: float) -> None:
        """At a touch-down after a flight plan: the whole turns that bring the measured (wrapped)
        pitch nearest to where that plan ended."""
        if self._flight_end is None:
            return
        self.turns = 2 * math.pi * round((self._flight_end - float(measured_pitch)) / (2 * math.pi))
        self._flight_end = None
