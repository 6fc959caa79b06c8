"""Perturbations of the simulated robot that the planner and controller are not told (robustness
sweeps): the landing ground's height, the terrain's friction, the masses, a payload, the motor
limits (edits of the simulator's model), a command delay and a push on the pelvis (per step).

One definition for both ways a sweep runs a flip: the offline runner (flip_tools.perturb builds a
:class:`PlantPerturbation` on its simulator) and sim_node (its ``plant`` parameter: these knobs as
JSON, its ``landing_height`` parameter: :func:`with_landing_offset` of a platform).
"""
from __future__ import annotations

import dataclasses
import json
import math
from collections import deque

import numpy as np

#: knob -> (default, meaning); a default of None leaves the model as it is
PLANT_KNOBS = {
    "friction": (None, "sliding friction coefficient of the terrain (default: the model's, 1.0)"),
    "mass_scale": (1.0, "every body's mass and inertia x this"),
    "com_offset": (0.0, "payload: the pelvis' centre of mass shifted along x (m)"),
    "torque_scale": (1.0, "the simulator's motor torque limits x this (the controller keeps its own)"),
    "delay_steps": (0, "commands applied this many whole steps late"),
    "push": (0.0, "impulse on the pelvis along world x (N*s), applied over 10 ms"),
    "push_phase": ("stance", "when the push comes: 'stance' (0.2 s after the jump's start) or 'flight' "
                             "(0.1 s after lift-off)"),
}
PUSH_DURATION = 0.01
PUSH_DELAY = {"stance": 0.2, "flight": 0.1}
#: the knobs that must be > 0
POSITIVE = ("friction", "mass_scale", "torque_scale")
#: where a landing area of another height starts, m ahead of the robot (Scenario.raised_landing's)
LANDING_START_X = 0.4


def with_landing_offset(base, height: float):
    """The terrain ``base`` (a cassie_model Scenario) with the ground from ``LANDING_START_X`` m ahead
    at ``height`` m (a slab, or lowered when negative): where a flip that travels comes down; ``base``
    itself for 0."""
    if height == 0.0:
        return base
    return dataclasses.replace(base, name="landing_offset", landing_height=height, landing_start_x=LANDING_START_X)


def check_knob(name: str, value):
    """A knob's value checked and normalised (a float, an int step count, a phase name; a knob that
    is not the plant's: a finite number); ValueError naming the knob."""
    if name == "push_phase":
        if value not in PUSH_DELAY:
            raise ValueError(f"push_phase must be one of {', '.join(PUSH_DELAY)}, not {value!r}")
        return value
    try:
        x = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"knob {name} must be a number, not {value!r}") from None
    if not math.isfinite(x):
        raise ValueError(f"knob {name} must be finite, not {value!r}")
    if name == "delay_steps":
        if x != int(x) or x < 0:
            raise ValueError(f"delay_steps must be a whole number >= 0, not {value!r}")
        return int(x)
    if name in POSITIVE and not x > 0:
        raise ValueError(f"knob {name} must be > 0, not {value!r}")
    return x


def parse_plant(text: str) -> dict:
    """sim_node's ``plant`` parameter (a JSON object of plant knobs; empty: none) -> checked knobs;
    ValueError for anything else."""
    if not text.strip():
        return {}
    try:
        knobs = json.loads(text)
    except json.JSONDecodeError as e:
        raise ValueError(f"plant: not JSON ({e})") from None
    if not isinstance(knobs, dict):
        raise ValueError(f"plant: a JSON object of knobs, not {text!r}")
    unknown = sorted(set(knobs) - set(PLANT_KNOBS))
    if unknown:
        raise ValueError(f"plant: unknown knob(s) {', '.join(unknown)}; plant knobs: {', '.join(PLANT_KNOBS)}")
    return {n: check_knob(n, v) for n, v in knobs.items()}


class PlantPerturbation:
    """The plant knobs applied to a built Simulator: its model edited at construction (friction,
    mass_scale, com_offset, torque_scale; the knobs at their defaults change nothing), then, step by
    step, the push's force set and the command delayed (:meth:`command`)."""

    def __init__(self, sim, knobs: dict):
        self.knobs = dict(knobs)
        self._edit_model(sim)
        self.delay = self.knob("delay_steps")
        self.buffer: deque = deque()
        self.dt = dt = sim.timestep
        self.push_steps = round(PUSH_DURATION / dt)
        self.push_force = self.knob("push") / (self.push_steps * dt)
        self.push_step = None               # first step of the push, once its phase's time is known
        self.pelvis = sim._pelvis

    def knob(self, name: str):
        return self.knobs.get(name, PLANT_KNOBS[name][0])

    @property
    def per_step(self) -> bool:
        """Whether :meth:`command` has work each step (a delay or a push)."""
        return bool(self.delay or self.push_force)

    def _edit_model(self, sim) -> None:
        import mujoco
        from cassie_model.model import TERRAIN_GEOMS
        from cassie_model.motor_limits import MotorLimits
        m = sim.model
        changed = False
        if self.knob("friction") is not None:
            for name in TERRAIN_GEOMS:
                g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
                if g >= 0:
                    # the terrain outranks the feet (friction 1.0), so its coefficient is the contact's
                    m.geom_priority[g] = 1
                    m.geom_friction[g, 0] = self.knob("friction")
            changed = True
        if self.knob("mass_scale") != 1.0:
            m.body_mass[1:] *= self.knob("mass_scale")
            m.body_inertia[1:] *= self.knob("mass_scale")
            changed = True
        if self.knob("com_offset") != 0.0:
            m.body_ipos[sim._pelvis, 0] += self.knob("com_offset")
            changed = True
        if self.knob("torque_scale") != 1.0:
            lim = sim.limits
            sim.limits = MotorLimits(lim.names, lim.torque_limit * self.knob("torque_scale"), lim.no_load_speed)
            if sim._native is not None:            # the compiled step holds a copy of the limits
                sim._native = sim._make_native()
            changed = True
        if changed:
            mujoco.mj_setConst(m, sim.data)
            sim.reset()

    def jump_started(self, t: float) -> None:
        """The jump starts at sim time ``t``: a stance push's time (the first jump's only)."""
        if self.push_force and self.push_step is None and self.knob("push_phase") == "stance":
            self.push_step = round((t + PUSH_DELAY["stance"]) / self.dt)

    def on_event(self, ev) -> None:
        """A contact event: the first lift-off sets a flight push's time (from the event's onset)."""
        if (int(ev.kind) == 0 and self.push_force and self.push_step is None
                and self.knob("push_phase") == "flight"):
            self.push_step = ev.step + round(PUSH_DELAY["flight"] / self.dt)

    def command(self, sim, u):
        """The command the simulator applies this step (``delay_steps`` late; ``u`` itself without a
        delay); the push's force set on the pelvis for the step."""
        if self.push_step is not None:
            k = sim.step_index - self.push_step
            sim.data.xfrc_applied[self.pelvis, 0] = self.push_force if 0 <= k < self.push_steps else 0.0
        if not self.delay:
            return u
        if not self.buffer:
            self.buffer.extend(np.array(u, float) for _ in range(self.delay))
        self.buffer.append(np.array(u, float))
        return self.buffer.popleft()

    def describe(self, sim) -> str:
        """The knobs set and the perturbed robot's total mass (sim_node's log line)."""
        knobs = ", ".join(f"{k} {v}" for k, v in sorted(self.knobs.items())) or "none"
        return f"plant perturbation: {knobs}; total mass {sim.total_mass():.3f} kg"
