"""Perturbed flips for robustness sweeps: named, seeded knobs applied to the simulated robot only.

The planner and the controller are built as for an unperturbed flip and are not told: the knobs
change the simulator's model (terrain, friction, masses, payload, motor limits) or sit between
simulator and controller in the offline runner (:mod:`flip_tools.offline`): a command delay,
sensor noise on what the controller reads, a push on the pelvis.  The plant's knobs (all but the
noise, the start and the length) are applied by cassie_flip_sim.perturbation, as sim_node applies
them in a graph run (`flip sweep --mode graph`, flip_tools.sweep_graph).

A sample is a record (flip, knobs, seed); :func:`run_sample` gives the same result for the same
record on any worker (one seeded numpy Generator per sample; the simulator is deterministic).
"""
from __future__ import annotations

import hashlib
import json
import math
import time
from dataclasses import dataclass, field

import numpy as np
from cassie_flip_sim.perturbation import PLANT_KNOBS, PlantPerturbation, check_knob, with_landing_offset

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

#: knob -> (default, meaning); a default of None leaves the model as it is.  The plant's own
#: (terrain friction, masses, motors, delay, push) are the simulator package's (PLANT_KNOBS)
KNOBS = {
    "ground_offset": (0.0, "landing ground this much higher (m) than the planner believes (added to D's 0.1)"),
    **{k: PLANT_KNOBS[k] for k in ("friction", "mass_scale", "com_offset", "torque_scale", "delay_steps")},
    "joint_noise": (0.0, "std of Gaussian noise on the joint positions (rad) and velocities (rad/s) read"),
    "imu_noise": (0.0, "std of Gaussian noise on the pelvis orientation (rad) and angular velocity (rad/s) read"),
    **{k: PLANT_KNOBS[k] for k in ("push", "push_phase")},
    "start": (0.5, "the jump's start time (s)"),
    "seconds": (9.0, "simulated time (s)"),
}
#: the outcomes of a sample; off_landing_ground is a graph run's alone (flip_tools.summary: the feet
#: came down elsewhere than on the landing ground; the offline verdict does not look)
OUTCOMES = ("landed", "fell", "not_at_rest", "wrong_rotation", "off_landing_ground", "rejected", "error")


def check_knobs(knobs: dict) -> dict:
    """The knobs with their values checked and normalised (floats, an int step count); ValueError
    naming the knob for an unknown knob or a bad value."""
    out = {}
    for name, value in knobs.items():
        if name not in KNOBS:
            raise ValueError(f"unknown knob {name!r}; known knobs: {', '.join(KNOBS)}")
        x = check_knob(name, value)
        if name == "seconds" and not x > 0:
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
    """The terrain of a flip with its landing ground ``ground_offset`` m off what it has
    (cassie_flip_sim.perturbation.with_landing_offset: from 0.4 m ahead of the robot, where a flip
    that travels comes down)."""
    from cassie_model.model import Scenario
    base = Scenario.platform(flip.platform) if flip.platform else Scenario.flat()
    return with_landing_offset(base, flip.ground_offset + ground_offset)


def plant_knobs(sample: Sample) -> dict:
    """The sample's knobs that the simulator's plant applies (cassie_flip_sim.perturbation)."""
    return {k: v for k, v in sample.knobs.items() if k in PLANT_KNOBS}


# ------------------------------------------------------------------ between simulator and controller
class Plant:
    """The offline runner's plant hook (flip_tools.offline.run ``plant``): the simulator's plant
    perturbation (cassie_flip_sim.perturbation: a command delay, a push on the pelvis; its model
    edits made when it was built), sensor noise on the state the controller reads; and the true
    pelvis pitch, unwrapped every step (the verdict's, not the controller's noisy estimate)."""

    def __init__(self, rng: np.random.Generator, sim, perturbation: PlantPerturbation, start: float,
                 joint_noise: float = 0.0, imu_noise: float = 0.0):
        """``start``: the jump's start time (s); ``joint_noise``, ``imu_noise``: the knobs' read noise."""
        self.rng = rng
        self.perturbation = perturbation
        self.joint_noise, self.imu_noise = joint_noise, imu_noise
        perturbation.jump_started(start)
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
        """A contact event (a flight push's time: PlantPerturbation.on_event)."""
        self.perturbation.on_event(ev)

    def command(self, sim, u):
        """The command the simulator applies this step (PlantPerturbation.command: ``delay_steps``
        late, the push's force set); the true pitch followed."""
        R = sim.data.xmat[self.pelvis]
        raw = math.atan2(-R[6], R[0])
        self.pitch = raw if self._raw is None else self.pitch + (raw - self._raw + math.pi) % (2 * math.pi) - math.pi
        self._raw = raw
        return self.perturbation.command(sim, u)


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
    perturbation = PlantPerturbation(sim, plant_knobs(sample))
    ctl = Controller(export_mjcf(sim.flywheel), motor_speed_scale=p["motor_speed_scale"],
                     flywheel_torque=p["flywheel_torque"])
    return sim, ctl, Plant(np.random.default_rng(sample.seed), sim, perturbation, sample.knob("start"),
                           sample.knob("joint_noise"), sample.knob("imu_noise"))


def read_noise(sim, std: float, seed: int, start: float) -> Plant:
    """A plant that only adds Gaussian noise of ``std`` (rad, rad/s) to what the controller reads of
    the joints and the IMU (the ``joint_noise`` and ``imu_noise`` knobs), seeded: without it, runs of
    a settled robot from different start times repeat each other to the bit, and a tally over start
    times counts one run many times (scripts/bench_landings.py --noise)."""
    return Plant(np.random.default_rng(seed), sim, PlantPerturbation(sim, {}), start, std, std)


def add_noise_option(ap, seeded: str) -> None:
    """The benches' ``--noise STD`` (scripts/bench_landings.py, bench_flips_in_a_row.py): :func:`read_noise`'s
    std, checked as the sweep checks its ``joint_noise`` and ``imu_noise`` knobs (argparse exits 2 on a bad
    one); ``seeded``: what each run's seed is drawn from, for the help."""
    import argparse

    def std(text: str) -> float:
        try:
            return check_knobs({"joint_noise": float(text)})["joint_noise"]
        except ValueError as e:
            raise argparse.ArgumentTypeError(str(e)) from None
    ap.add_argument("--noise", type=std, default=0.0, metavar="STD",
                    help="std of Gaussian noise on the joints and IMU the controller reads (rad, rad/s; flip sweep's "
                         f"joint_noise and imu_noise), seeded per {seeded}: independent runs where a settled robot "
                         "would repeat one run (e.g. 1e-4)")


def failed_result(sample: Sample, error: str | None, mode: str = "offline") -> dict:
    """A sample's result before (or without) a run: the record, outcome ``error``; ``mode``: how it
    runs (offline, or graph: flip_tools.sweep_graph)."""
    return {"sample_id": sample.id, "flip": sample.flip, "knobs": json.dumps(sample.knobs, sort_keys=True),
            "seed": sample.seed, **{k: sample.knob(k) for k in KNOBS},
            "outcome": "error", "limit": None, "error": error, "net_rotation_deg": None, "fell_at_s": None,
            "touchdown_s": None, "peak_flywheel_rpm": None, "sim_s": None, "wall_s": 0.0,
            "mode": mode, "jump_start_s": None}


def run_sample(sample: Sample, x_start: float | None = None, heading=None) -> dict:
    """Run a sample offline; its result: the record's fields, ``outcome`` (one of OUTCOMES),
    ``limit`` (a rejected request's), ``error``, net rotation (deg), fall and touch-down times (s),
    peak flywheel speed (rpm), simulated and wall seconds, the jump's start (s: the ``start`` knob).
    ``x_start``, ``heading``: where the jump plan starts (a graph run's summary.json ``planner.x_start_m``
    and ``planner.heading``; flip_tools.offline.run), None: measured as planner_node measures it."""
    from fslip_planner.feasibility import InfeasibleRequest

    from . import offline
    from .summary import RPM_PER_RADPS
    t0 = time.perf_counter()
    res = failed_result(sample, None)
    flip = FLIPS[sample.flip]
    try:
        sim, ctl, plant = build(sample)
        r = offline.run(flip.kind, seconds=sample.knob("seconds"), start=sample.knob("start"), sim=sim,
                        controller=ctl, every=10, plant=plant, x_start=x_start, heading=heading,
                        apex_height=flip.apex,
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
                   sim_s=sim.time, jump_start_s=sample.knob("start"))
    res["wall_s"] = time.perf_counter() - t0
    return res
