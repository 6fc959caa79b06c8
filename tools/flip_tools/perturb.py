"""Perturbed flips for robustness sweeps: named, seeded knobs applied to the simulated robot only.

The planner and the controller are built as for an unperturbed flip and are not told: the knobs
change the simulator's model (terrain, friction, masses, payload, motor limits) or sit between
simulator and controller in the offline runner (:mod:`flip_tools.offline`): a command delay,
sensor noise on what the controller reads, a push on the pelvis.

A sample is a record (flip, knobs, seed); :func:`run_sample` gives the same result for the same
record on any worker (one seeded numpy Generator per sample; the simulator is deterministic).
"""
from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from collections import deque
from dataclasses import dataclass, field

import numpy as np

#: the robot the named flips run on (cassie_model.robot_params.ROBOTS)
ROBOT = "cassie-legs3-fw260"


@dataclass(frozen=True)
class Flip:
    """A flip request as `flip run` sends it, and the true ground offset the planner is not told."""
    kind: str
    apex: float
    distance: float = 0.0
    platform: float = 0.0
    ground_offset: float = 0.0


#: the paper's four flips (README Results; distances as `flip run` fills them in, flip_request)
FLIPS = {
    "A": Flip("frontflip", 1.2, distance=1.0),
    "B": Flip("backflip", 1.3),
    "C": Flip("frontflip", 1.2, distance=0.6, platform=0.5),
    "D": Flip("frontflip", 1.2, distance=0.6, ground_offset=0.1),
}

#: the flips that come down on a landing area ahead of the take-off ground (ground_offset's)
TRAVELLING = tuple(name for name, f in FLIPS.items() if f.distance)

#: knob -> (default, meaning); a default of None leaves the model as it is
KNOBS = {
    "ground_offset": (0.0, "landing ground this much higher (m) than the planner believes (added to D's 0.1)"),
    "friction": (None, "sliding friction coefficient of the terrain (default: the model's, 1.0)"),
    "mass_scale": (1.0, "every body's mass and inertia x this"),
    "com_offset": (0.0, "payload: the pelvis' centre of mass shifted along x (m)"),
    "torque_scale": (1.0, "the simulator's motor torque limits x this (the controller keeps its own)"),
    "delay_steps": (0, "commands applied this many whole steps late"),
    "joint_noise": (0.0, "std of Gaussian noise on the joint positions (rad) and velocities (rad/s) read"),
    "imu_noise": (0.0, "std of Gaussian noise on the pelvis orientation (rad) and angular velocity (rad/s) read"),
    "push": (0.0, "impulse on the pelvis along world x (N*s), applied over 10 ms"),
    "push_phase": ("stance", "when the push comes: 'stance' (0.2 s after the jump's start) or 'flight' "
                             "(0.1 s after lift-off)"),
    "start": (0.5, "the jump's start time (s)"),
    "seconds": (9.0, "simulated time (s)"),
}
PUSH_DURATION = 0.01
PUSH_DELAY = {"stance": 0.2, "flight": 0.1}
OUTCOMES = ("landed", "fell", "not_at_rest", "wrong_rotation", "rejected", "error")


def check_knobs(knobs: dict) -> dict:
    """The knobs with their values checked and normalised (floats, an int step count); ValueError
    naming the knob for an unknown knob or a bad value."""
    out = {}
    for name, value in knobs.items():
        if name not in KNOBS:
            raise ValueError(f"unknown knob {name!r}; known knobs: {', '.join(KNOBS)}")
        if name == "push_phase":
            if value not in PUSH_DELAY:
                raise ValueError(f"push_phase must be one of {', '.join(PUSH_DELAY)}, not {value!r}")
            out[name] = value
            continue
        try:
            x = float(value)
        except (TypeError, ValueError):
            raise ValueError(f"knob {name} must be a number, not {value!r}") from None
        if not math.isfinite(x):
            raise ValueError(f"knob {name} must be finite, not {value!r}")
        if name == "delay_steps":
            if x != int(x) or x < 0:
                raise ValueError(f"delay_steps must be a whole number >= 0, not {value!r}")
            x = int(x)
        elif name in ("friction", "mass_scale", "torque_scale", "seconds") and not x > 0:
            raise ValueError(f"knob {name} must be > 0, not {value!r}")
        elif name in ("joint_noise", "imu_noise", "start") and x < 0:
            raise ValueError(f"knob {name} must be >= 0, not {value!r}")
        out[name] = x
    return out


@dataclass(frozen=True)
class Sample:
    """One run of a sweep: a named flip, the knobs set (the others at their defaults), a seed."""
    flip: str
    knobs: dict = field(default_factory=dict)
    seed: int = 0

    def __post_init__(self):
        if self.flip not in FLIPS:
            raise ValueError(f"unknown flip {self.flip!r}; known flips: {', '.join(FLIPS)}")
        object.__setattr__(self, "knobs", check_knobs(self.knobs))
        if self.knobs.get("ground_offset", 0.0) and not FLIPS[self.flip].distance:
            raise ValueError(f"ground_offset applies to the flips that travel ({', '.join(TRAVELLING)}): "
                             f"flip {self.flip} lands where it took off")
        object.__setattr__(self, "seed", int(self.seed))

    def knob(self, name: str):
        return self.knobs.get(name, KNOBS[name][0])

    @property
    def id(self) -> str:
        """A hash of the record: the same (flip, knobs, seed) has the same id on every machine."""
        text = json.dumps({"flip": self.flip, "knobs": self.knobs, "seed": self.seed}, sort_keys=True)
        return hashlib.sha256(text.encode()).hexdigest()[:16]

    def to_dict(self) -> dict:
        return {"flip": self.flip, "knobs": dict(self.knobs), "seed": self.seed}


# ------------------------------------------------------------------ the plant's model
def scenario(flip: Flip, ground_offset: float = 0.0):
    """The terrain of a flip with its landing ground ``ground_offset`` m off what it has: the
    landing area starts 0.4 m ahead of the robot (Scenario.raised_landing's), where a flip that
    travels comes down."""
    from cassie_model.model import Scenario
    h = flip.ground_offset + ground_offset
    base = Scenario.platform(flip.platform) if flip.platform else Scenario.flat()
    if h == 0.0:
        return base
    return dataclasses.replace(base, name="landing_offset", landing_height=h, landing_start_x=0.4)


def perturb_model(sim, sample: Sample) -> None:
    """Edit a built simulator's model for the sample's friction, mass_scale, com_offset and
    torque_scale knobs (the knobs left at their defaults change nothing), then reset it."""
    import mujoco
    from cassie_model.model import TERRAIN_GEOMS
    from cassie_model.motor_limits import MotorLimits
    m = sim.model
    changed = False
    if sample.knob("friction") is not None:
        for name in TERRAIN_GEOMS:
            g = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_GEOM, name)
            if g >= 0:
                # the terrain outranks the feet (friction 1.0), so its coefficient is the contact's
                m.geom_priority[g] = 1
                m.geom_friction[g, 0] = sample.knob("friction")
        changed = True
    if sample.knob("mass_scale") != 1.0:
        m.body_mass[1:] *= sample.knob("mass_scale")
        m.body_inertia[1:] *= sample.knob("mass_scale")
        changed = True
    if sample.knob("com_offset") != 0.0:
        m.body_ipos[sim._pelvis, 0] += sample.knob("com_offset")
        changed = True
    if sample.knob("torque_scale") != 1.0:
        lim = sim.limits
        sim.limits = MotorLimits(lim.names, lim.torque_limit * sample.knob("torque_scale"), lim.no_load_speed)
        if sim._native is not None:            # the compiled step holds a copy of the limits
            sim._native = sim._make_native()
        changed = True
    if changed:
        mujoco.mj_setConst(m, sim.data)
        sim.reset()


# ------------------------------------------------------------------ between simulator and controller
class Plant:
    """The offline runner's plant hook (flip_tools.offline.run ``plant``): sensor noise on the state
    the controller reads, a command delay, a push on the pelvis; and the true pelvis pitch, unwrapped
    every step (the verdict's, not the controller's noisy estimate)."""

    def __init__(self, sample: Sample, rng: np.random.Generator, sim):
        self.sample, self.rng = sample, rng
        self.delay = sample.knob("delay_steps")
        self.buffer: deque = deque()
        self.joint_noise, self.imu_noise = sample.knob("joint_noise"), sample.knob("imu_noise")
        self.dt = dt = sim.timestep
        self.push_steps = round(PUSH_DURATION / dt)
        self.push_force = sample.knob("push") / (self.push_steps * dt)
        self.push_step = None               # first step of the push, once its phase is known
        if self.push_force and sample.knob("push_phase") == "stance":
            self.push_step = round((sample.knob("start") + PUSH_DELAY["stance"]) / dt)
        self.pelvis = sim._pelvis
        self.pitch, self._raw = 0.0, None

    def state_reader(self, read_state, sc, sim):
        """``read_state`` itself, or with noise: the contract arrays as sim_node fills them, noise
        added, converted as tsc_node converts them."""
        if not (self.joint_noise or self.imu_noise):
            return read_state
        n = len(sim.joint_names)
        pos, vel, eff, pose, twist = np.empty(n), np.empty(n), np.empty(n), np.empty(7), np.empty(6)

        def read(sim):
            sim.state_into(pos, vel, eff, pose, twist)
            if self.joint_noise:
                pos[:] += self.rng.normal(0.0, self.joint_noise, n)
                vel[:] += self.rng.normal(0.0, self.joint_noise, n)
            if self.imu_noise:
                pose[3:] = _rotate_xyzw(pose[3:], self.rng.normal(0.0, self.imu_noise, 3))
                twist[3:] += self.rng.normal(0.0, self.imu_noise, 3)
            return sc.from_ros(sim.joint_names, pos, vel, pose[:3], pose[3:], twist[:3], twist[3:])
        return read

    def on_event(self, ev) -> None:
        """A contact event: the first lift-off sets a flight push's time (from the event's onset)."""
        if (int(ev.kind) == 0 and self.push_force and self.push_step is None
                and self.sample.knob("push_phase") == "flight"):
            self.push_step = ev.step + round(PUSH_DELAY["flight"] / self.dt)

    def command(self, sim, u):
        """The command the simulator applies this step (``delay_steps`` late); the push's force set."""
        R = sim.data.xmat[self.pelvis]
        raw = math.atan2(-R[6], R[0])
        self.pitch = raw if self._raw is None else self.pitch + (raw - self._raw + math.pi) % (2 * math.pi) - math.pi
        self._raw = raw
        if self.push_step is not None:
            k = sim.step_index - self.push_step
            sim.data.xfrc_applied[self.pelvis, 0] = self.push_force if 0 <= k < self.push_steps else 0.0
        if not self.delay:
            return u
        if not self.buffer:
            self.buffer.extend(np.array(u, float) for _ in range(self.delay))
        self.buffer.append(np.array(u, float))
        return self.buffer.popleft()


def _rotate_xyzw(q, rotvec) -> np.ndarray:
    """Quaternion (x, y, z, w) times the rotation of ``rotvec`` (body axes)."""
    angle = float(np.linalg.norm(rotvec))
    if angle == 0.0:
        return np.asarray(q, float)
    ax = np.asarray(rotvec) / angle
    s, c = math.sin(angle / 2), math.cos(angle / 2)
    bx, by, bz, bw = ax[0] * s, ax[1] * s, ax[2] * s, c
    x, y, z, w = q
    return np.array([w * bx + x * bw + y * bz - z * by, w * by - x * bz + y * bw + z * bx,
                     w * bz + x * by - y * bx + z * bw, w * bw - x * bx - y * by - z * bz])


# ------------------------------------------------------------------ one sample
def robot_params() -> dict:
    """The design parameters of ``ROBOT`` (flywheel, motor speed scale, flywheel torque)."""
    from cassie_model.robot_params import robot
    return robot(ROBOT).params()


def robot_request() -> dict:
    """The robot's parameters a flip request carries (as planner_node passes them)."""
    p = robot_params()
    return {"motor_speed_scale": p["motor_speed_scale"], "flywheel_torque": p["flywheel_torque"]}


def build(sample: Sample):
    """(simulator, controller, plant) of a sample: the simulator perturbed, the controller as for
    the unperturbed robot (its model, limits and settings from the robot alone)."""
    from cassie_model.model import export_mjcf
    from cassie_flip_sim.simulator import Simulator
    from tsc_controller import Controller
    p = robot_params()
    flip = FLIPS[sample.flip]
    sim = Simulator(p["flywheel"], scenario(flip, sample.knob("ground_offset")),
                    motor_speed_scale=p["motor_speed_scale"], flywheel_torque=p["flywheel_torque"])
    perturb_model(sim, sample)
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=p["motor_speed_scale"],
                     flywheel_torque=p["flywheel_torque"])
    return sim, ctl, Plant(sample, np.random.default_rng(sample.seed), sim)


def failed_result(sample: Sample, error: str | None) -> dict:
    """A sample's result before (or without) a run: the record, outcome ``error``."""
    return {"sample_id": sample.id, "flip": sample.flip, "knobs": json.dumps(sample.knobs, sort_keys=True),
            "seed": sample.seed, **{k: sample.knob(k) for k in KNOBS},
            "outcome": "error", "limit": None, "error": error, "net_rotation_deg": None, "fell_at_s": None,
            "touchdown_s": None, "peak_flywheel_rpm": None, "sim_s": None, "wall_s": 0.0}


def run_sample(sample: Sample) -> dict:
    """Run a sample offline; its result: the record's fields, ``outcome`` (one of OUTCOMES),
    ``limit`` (a rejected request's), ``error``, net rotation (deg), fall and touch-down times (s),
    peak flywheel speed (rpm), simulated and wall seconds."""
    from fslip_planner.feasibility import InfeasibleRequest

    from . import offline
    from .summary import RPM_PER_RADPS
    t0 = time.perf_counter()
    res = failed_result(sample, None)
    flip = FLIPS[sample.flip]
    try:
        sim, ctl, plant = build(sample)
        r = offline.run(flip.kind, seconds=sample.knob("seconds"), start=sample.knob("start"), sim=sim,
                        controller=ctl, every=10, plant=plant, apex_height=flip.apex,
                        forward_distance=flip.distance, platform_height=flip.platform,
                        **robot_request())
    except InfeasibleRequest as e:
        res.update(outcome="rejected", limit=e.limit, error=str(e))
    except Exception as e:  # noqa: BLE001 -- a sweep reports a crashed sample and goes on
        res.update(error=f"{type(e).__name__}: {e}")
    else:
        ground = flip.ground_offset + sample.knob("ground_offset")
        res.update(outcome=offline.outcome(r, flip.kind, ground, plant.pitch),
                   net_rotation_deg=math.degrees(plant.pitch), fell_at_s=r["fell"],
                   touchdown_s=offline.lift_off_touch_down(r["events"])[1],
                   peak_flywheel_rpm=float(np.max(np.abs(r["fw"]))) * RPM_PER_RADPS if len(r["fw"]) else 0.0,
                   sim_s=sim.time)
    res["wall_s"] = time.perf_counter() - t0
    return res
