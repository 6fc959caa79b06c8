"""The touch-downs a lift-off predicts, solved during the flight as the warm starts of the touch-down's
landing re-solve (paper §III-C), and how long planner_node lets them run.

They are solved in their order (:data:`landing.PREDICTED_SHIFTS`), each warm from the nearest solved
(:meth:`LandingProblem.solve`), so each one's solution depends only on those before it.  The touch-down
solves those still missing up to the two its warm start uses and forgets the rest: its plan, and the
solutions a rebound's re-solve starts from, are the same to the bit however far the flight got.
"""
from __future__ import annotations

import numpy as np

from .landing import LandingProblem, SolveInterrupted, nearest_first


class Predictions:
    """The predicted touch-down states of one flight: all of them in order, and those not solved yet."""

    def __init__(self):
        self.states: list = []     # every touch-down predicted at the lift-off, in order
        self.pending: list = []    # (state, warm) not solved yet

    def start(self, states):
        self.states = list(states)
        self.pending = [(x0, True) for x0 in self.states]

    def solve(self, problem: LandingProblem, stop=None, needed_by=None, interrupt=None) -> int:
        """Solve the pending ones on ``problem``, in their order, until ``stop()``, or, with ``needed_by``
        (a touch-down state), until the two states nearest to it among the solved and the pending ones
        are solved (its warm start, ``landing._warm_start``); how many solves.  ``interrupt()``, asked at
        each IPOPT iteration, abandons the solve under way, which stays pending, and ends it.
        One whose warm solve fails is solved cold next (``stop()`` may leave that to the touch-down, which
        then does it as the lift-off would have): a touch-down near it then starts next to a solution,
        where a warm re-solve from a farther one may fail too."""
        n = 0
        problem.interrupt = interrupt
        try:
            while self.pending and not (stop is not None and stop()):
                if needed_by is not None and self._warm_start_solved(problem, needed_by):
                    break
                (x0, warm), n = self.pending.pop(0), n + 1
                try:
                    problem.solve(x0, warm=warm)
                except SolveInterrupted:
                    self.pending.insert(0, (x0, warm))
                    return n - 1
                except RuntimeError:
                    if warm:
                        self.pending.insert(0, (x0, False))
        finally:
            problem.interrupt = None
        return n

    def _warm_start_solved(self, problem: LandingProblem, x0) -> bool:
        """Are the two states nearest to x0 among the solved and the pending ones both solved?"""
        solved = problem.solved_states
        order = nearest_first(solved + [x for x, _ in self.pending], x0)[1]
        return all(i < len(solved) for i in order[:2])

    def drop_unneeded(self, problem: LandingProblem | None, x0):
        """At the touch-down x0: forget the pending ones, and drop from ``problem`` the solved ones after
        the last that x0's warm start uses, so that the landing's later re-solves (a rebound's) start
        from the same solutions however many the flight had time for."""
        states, self.states, self.pending = self.states, [], []
        if not states or problem is None or not problem.has_solutions:
            return
        solved = problem.solved_states
        index = [next((k for k, x in enumerate(states) if np.array_equal(x, solved[i])), -1)
                 for i in nearest_first(solved, x0)[1][:2]]
        problem.drop(states[max(index) + 1:])


class PredictionBudget:
    """``stop()`` for the lift-off's landing predictions: True once another solve, taking as much sim time
    as the last one did, would end after ``end`` (sim s), so that a touch-down near the planned one finds
    the planner free rather than inside a solve it may not need."""

    def __init__(self, sim_now, t_start: float, end: float):
        self.sim_now, self.last, self.end = sim_now, float(t_start), float(end)

    def __call__(self) -> bool:
        now = self.sim_now()
        took, self.last = now - self.last, now
        return now + max(took, 0.0) >= self.end
