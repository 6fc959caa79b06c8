"""Foot contact: per-foot ground normal forces from MuJoCo contacts and the lift-off /
touch-down event detector (paper §II-B: jumping → flight when the normal forces reach zero,
flight → landing at foot strike)."""
from __future__ import annotations

from enum import IntEnum
from typing import NamedTuple, Optional, Tuple

import mujoco
import numpy as np
from cassie_model.model import FOOT_GEOMS


class FootForces:
    """Sums the normal forces of the foot-sphere contacts of each foot (N)."""

    def __init__(self, model: mujoco.MjModel):
        gid = lambda n: mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, n)
        self.side_of = {}
        for k, side in enumerate(("left", "right")):
            for g in FOOT_GEOMS[side]:
                self.side_of[gid(g)] = k
        self._f = np.zeros(6)

    def __call__(self, model: mujoco.MjModel, data: mujoco.MjData) -> Tuple[float, float]:
        """(left, right) normal forces of the contacts in ``data.contact`` with ``data.efc_force``."""
        out = [0.0, 0.0]
        for i in range(data.ncon):
            c = data.contact[i]
            side = self.side_of.get(c.geom1, self.side_of.get(c.geom2))
            if side is None or c.efc_address < 0:
                continue
            mujoco.mj_contactForce(model, data, i, self._f)
            out[side] += self._f[0]
        return out[0], out[1]

    def touching(self, data: mujoco.MjData) -> Tuple[bool, bool]:
        """Whether each foot has a (penetrating) contact in ``data.contact``."""
        out = [False, False]
        for i in range(data.ncon):
            c = data.contact[i]
            side = self.side_of.get(c.geom1, self.side_of.get(c.geom2))
            if side is not None:
                out[side] = True
        return out[0], out[1]


class Event(IntEnum):
    """Values of flip_msgs/ContactEvent.event."""
    LIFT_OFF = 0
    TOUCH_DOWN = 1


class ContactEvent(NamedTuple):
    kind: Event
    step: int            # step at which the condition started (forces reached zero / first contact)
    time: float
    detected_step: int   # step at which the event was confirmed and emitted
    left_force: float
    right_force: float


class ContactDetector:
    """Deterministic lift-off / touch-down detector with hysteresis.

    LIFT_OFF: in stance, both normal forces ≤ ``lift_off_force`` for ``lift_off_steps``
    consecutive steps.  TOUCH_DOWN: in flight (and at least ``min_flight_steps`` after lift-off),
    the first step where either normal force exceeds ``touch_down_force``.  Event step/time are
    those of the condition's onset.
    """

    def __init__(self, in_contact: bool = True, *, lift_off_force: float = 1e-9,
                 touch_down_force: float = 1.0, lift_off_steps: int = 20, min_flight_steps: int = 20):
        self.lift_off_force = lift_off_force
        self.touch_down_force = touch_down_force
        self.lift_off_steps = lift_off_steps
        self.min_flight_steps = min_flight_steps
        self.reset(in_contact)

    def reset(self, in_contact: bool = True) -> None:
        self.in_contact = in_contact
        self._zero_run = 0
        self._onset: Optional[Tuple[int, float]] = None
        self._flight_steps = 0 if in_contact else self.min_flight_steps

    def state(self) -> tuple:
        """(in_contact, zero_run, onset step (-1: none), onset time, flight steps, lift_off_force,
        touch_down_force, lift_off_steps, min_flight_steps): what the C++ copy of this detector in
        sim_node's compiled loop carries on from (flip_transport's native/stepper_api.h); ``set_state`` takes it back."""
        step, time = self._onset if self._onset is not None else (-1, 0.0)
        return (self.in_contact, self._zero_run, step, time, self._flight_steps, self.lift_off_force,
                self.touch_down_force, self.lift_off_steps, self.min_flight_steps)

    def set_state(self, state: tuple) -> None:
        (self.in_contact, self._zero_run, step, time, self._flight_steps, self.lift_off_force,
         self.touch_down_force, self.lift_off_steps, self.min_flight_steps) = state
        self._onset = (step, time) if step >= 0 else None

    @property
    def phase(self) -> str:
        return "stance" if self.in_contact else "flight"

    def update(self, step: int, time: float, left_force: float, right_force: float) -> Optional[ContactEvent]:
        """Feed the forces of one step; returns an event or None."""
        if self.in_contact:
            if left_force <= self.lift_off_force and right_force <= self.lift_off_force:
                if self._zero_run == 0:
                    self._onset = (step, time)
                self._zero_run += 1
                if self._zero_run >= self.lift_off_steps:
                    self.in_contact = False
                    self._zero_run = 0
                    self._flight_steps = 0
                    return ContactEvent(Event.LIFT_OFF, self._onset[0], self._onset[1], step,
                                        left_force, right_force)
            else:
                self._zero_run = 0
            return None
        self._flight_steps += 1
        if self._flight_steps > self.min_flight_steps and max(left_force, right_force) > self.touch_down_force:
            self.in_contact = True
            return ContactEvent(Event.TOUCH_DOWN, step, time, step, left_force, right_force)
        return None
