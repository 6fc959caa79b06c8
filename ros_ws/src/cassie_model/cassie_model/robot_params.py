"""Parameter table of Cassie with a pelvis flywheel: numbers only, no file I/O.

The Cassie numbers are those of the published Agility Cassie model (MuJoCo Menagerie
``agility_cassie/cassie.xml``, MIT licence), written out here so the project never reads that
file at run time.  Names use ``_`` where the published model uses ``-``.  Angles are in degrees
exactly as published (``range``, ``ref``); frames are the published ``xyaxes``.
The flywheel follows paper §II and Table I (15 cm above the pelvis, 195 N·m).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Optional, Tuple, Union

Vec3 = Tuple[float, float, float]


@dataclass(frozen=True)
class Inertial:
    """Body mass, COM in the body frame and full inertia (ixx iyy izz ixy ixz iyz) about the COM."""
    mass: float
    pos: Vec3
    fullinertia: Tuple[float, float, float, float, float, float]


@dataclass(frozen=True)
class Joint:
    """A hinge (about the body's local z) or a ball joint.  Angles in degrees as published."""
    name: str
    type: str = "hinge"
    range_deg: Optional[Tuple[float, float]] = None
    ref_deg: float = 0.0
    stiffness: float = 0.0      # N·m/rad, spring rest at qpos = 0 (MuJoCo springref default 0)
    damping: float = 0.0        # N·m·s/rad
    armature: float = 0.0       # kg·m² (reflected rotor inertia)


@dataclass(frozen=True)
class Body:
    name: str
    parent: str
    pos: Vec3
    xyaxes: Optional[Tuple[float, float, float, float, float, float]]
    inertial: Inertial
    joint: Optional[Joint] = None


@dataclass(frozen=True)
class Connect:
    """Loop closure: point ``anchor`` (body1 frame) of body1 coincides with a point of body2,
    the constraint being satisfied at qpos0 (all hinges at ``ref``, balls at identity)."""
    body1: str
    body2: str
    anchor: Vec3


@dataclass(frozen=True)
class Motor:
    """Motor on ``joint``: gear ratio, motor-side torque limit (published ``ctrlrange``) and
    no-load motor speed in rpm (published ``user``)."""
    joint: str
    gear: float
    motor_torque_limit: float
    no_load_rpm: float

    @property
    def torque_limit(self) -> float:
        """Joint-side torque limit, N·m."""
        return self.motor_torque_limit * self.gear

    @property
    def no_load_speed(self) -> float:
        """Joint-side no-load speed, rad/s (= rpm·2π/60/gear)."""
        return self.no_load_rpm * 2.0 * math.pi / 60.0 / self.gear


# --------------------------------------------------------------------------------------------
# Cassie (published numbers)
# --------------------------------------------------------------------------------------------

PELVIS = Body(
    "pelvis", "world", (0.0, 0.0, 1.1), None,
    Inertial(10.33, (0.05066, 0.000346, 0.02841),
             (0.085821, 0.049222, 0.08626, 1.276e-05, -0.00016022, -0.000414)))

_HIP_ROLL_ARM = 0.038125
_PITCH_ARM = 0.09344
_FOOT_ARM = 0.01225

LEFT_LEG: Tuple[Body, ...] = (
    Body("left_hip_roll", "pelvis", (0.021, 0.135, 0.0), (0, 0, -1, 0, 1, 0),
         Inertial(1.82, (-0.01793, 0.0001, -0.04428),
                  (0.003431, 0.003793, 0.002135, -6.65e-07, -0.00084, 3.99e-06)),
         Joint("left_hip_roll", range_deg=(-15, 22.5), damping=1, armature=_HIP_ROLL_ARM)),
    Body("left_hip_yaw", "left_hip_roll", (0, 0, -0.07), (0, 0, 1, 0, 1, 0),
         Inertial(1.171, (0, -1e-05, -0.034277),
                  (0.002443, 0.002803, 0.000842, -4e-08, 2.462e-07, -2.71e-08)),
         Joint("left_hip_yaw", range_deg=(-22.5, 22.5), damping=1, armature=_HIP_ROLL_ARM)),
    Body("left_hip_pitch", "left_hip_yaw", (0, 0, -0.09), (0, 0, -1, 1, 0, 0),
         Inertial(5.52, (0.05946, 5e-05, -0.03581),
                  (0.010898, 0.029714, 0.030257, -0.0002669, -5.721e-05, 9.17e-06)),
         Joint("left_hip_pitch", range_deg=(-50, 80), damping=1, armature=_PITCH_ARM)),
    Body("left_achilles_rod", "left_hip_pitch", (0, 0, 0.045),
         (0.7922, -0.60599, -0.072096, 0.60349, 0.79547, -0.054922),
         Inertial(0.1567, (0.24719, 0, 0), (3.754e-06, 0.004487, 0.004488, -3.74e-08, -1.61e-08, 0)),
         Joint("left_achilles_rod", type="ball", damping=0.01)),
    Body("left_knee", "left_hip_pitch", (0.12, 0, 0.0045), (0.70711, -0.70711, 0, 0.70711, 0.70711, 0),
         Inertial(0.7578, (0.023, 0.03207, -0.002181),
                  (0.001376, 0.0010335, 0.0021637, -0.00039744, -4.085e-05, -5.374e-05)),
         Joint("left_knee", ref_deg=-45, range_deg=(-164, -37), damping=1, armature=_PITCH_ARM)),
    Body("left_knee_spring", "left_knee", (0.06068, 0.08241, 0), None,
         Inertial(0.186, (0.0836, 0.0034, 0), (5.215e-05, 0.00041205, 0.0003669, 6.87e-06, 0, 0))),
    Body("left_shin", "left_knee", (0.06068, 0.04741, 0), None,
         Inertial(0.577, (0.18338, 0.001169, 0.0002123),
                  (0.00035939, 0.014728, 0.014707, -0.00020981, 2.266e-05, -1.2e-07)),
         Joint("left_shin", range_deg=(-20, 20), stiffness=1500, damping=0.1)),
    Body("left_tarsus", "left_shin", (0.43476, 0.02, 0), (0.52992, 0.84805, 0, -0.84805, 0.52992, 0),
         Inertial(0.782, (0.11046, -0.03058, -0.00131),
                  (0.00039238, 0.013595, 0.013674, 0.00023651, -4.987e-05, -4.82e-06)),
         Joint("left_tarsus", ref_deg=58, range_deg=(50, 170), damping=0.1)),
    Body("left_heel_spring", "left_tarsus", (-0.01269, -0.03059, 0.00092),
         (-0.91211, 0.40829, 0.036948, -0.40992, -0.90952, -0.068841),
         Inertial(0.126, (0.081, 0.0022, 0), (2.959e-05, 0.00022231, 0.0002007, 7.15e-06, -6e-07, 1e-07)),
         Joint("left_heel_spring", stiffness=1250)),
    Body("left_foot_crank", "left_tarsus", (0.058, -0.034, 0.02275), None,
         Inertial(0.1261, (0.00493, 2e-05, -0.00215),
                  (2.6941e-05, 4.9621e-05, 6.3362e-05, -2.1e-09, -3.9623e-06, -1.09e-08)),
         Joint("left_foot_crank", range_deg=(-140, -30), damping=1)),
    Body("left_plantar_rod", "left_foot_crank", (0.055, 0, -0.00791), None,
         Inertial(0.1186, (0.17792, 0, 0), (2.779e-06, 0.001774, 0.001775, -2.34e-08, -8.1e-09, 0)),
         Joint("left_plantar_rod")),
    Body("left_foot", "left_tarsus", (0.408, -0.04, 0), None,
         Inertial(0.1498, (0.00474, 0.02748, -0.00014),
                  (0.00017388, 0.00016793, 0.00033261, 0.00011814, 1.36e-06, -4e-07)),
         Joint("left_foot", range_deg=(-140, -30), damping=1, armature=_FOOT_ARM)),
)

RIGHT_LEG: Tuple[Body, ...] = (
    Body("right_hip_roll", "pelvis", (0.021, -0.135, 0.0), (0, 0, -1, 0, 1, 0),
         Inertial(1.82, (-0.01793, 0.0001, -0.04428),
                  (0.003431, 0.003793, 0.002135, 6.65e-07, -0.00084, -3.99e-06)),
         Joint("right_hip_roll", range_deg=(-22.5, 15), damping=1, armature=_HIP_ROLL_ARM)),
    Body("right_hip_yaw", "right_hip_roll", (0, 0, -0.07), (0, 0, 1, 0, 1, 0),
         Inertial(1.171, (0, 1e-05, -0.034277),
                  (0.002443, 0.002803, 0.000842, 4e-08, 2.462e-07, 2.71e-08)),
         Joint("right_hip_yaw", range_deg=(-22.5, 22.5), damping=1, armature=_HIP_ROLL_ARM)),
    Body("right_hip_pitch", "right_hip_yaw", (0, 0, -0.09), (0, 0, -1, 1, 0, 0),
         Inertial(5.52, (0.05946, 5e-05, 0.03581),
                  (0.010898, 0.029714, 0.030257, -0.0002669, 5.721e-05, -9.17e-06)),
         Joint("right_hip_pitch", range_deg=(-50, 80), damping=1, armature=_PITCH_ARM)),
    Body("right_achilles_rod", "right_hip_pitch", (0, 0, -0.045),
         (0.7922, -0.60599, 0.072096, 0.60349, 0.79547, 0.054922),
         Inertial(0.1567, (0.24719, 0, 0), (3.754e-06, 0.004487, 0.004488, -3.74e-08, 1.61e-08, 0)),
         Joint("right_achilles_rod", type="ball", damping=0.01)),
    Body("right_knee", "right_hip_pitch", (0.12, 0, -0.0045), (0.70711, -0.70711, 0, 0.70711, 0.70711, 0),
         Inertial(0.7578, (0.023, 0.03207, 0.002181),
                  (0.001376, 0.0010335, 0.0021637, -0.00039744, 4.085e-05, 5.374e-05)),
         Joint("right_knee", ref_deg=-45, range_deg=(-164, -37), damping=1, armature=_PITCH_ARM)),
    Body("right_knee_spring", "right_knee", (0.06068, 0.08241, 0), None,
         Inertial(0.186, (0.0836, 0.0034, 0), (5.215e-05, 0.00041205, 0.0003669, 6.87e-06, 0, 0))),
    Body("right_shin", "right_knee", (0.06068, 0.04741, 0), None,
         Inertial(0.577, (0.18338, 0.001169, -0.0002123),
                  (0.00035939, 0.014728, 0.014707, -0.00020981, -2.266e-05, 1.2e-07)),
         Joint("right_shin", range_deg=(-20, 20), stiffness=1500, damping=0.1)),
    Body("right_tarsus", "right_shin", (0.43476, 0.02, 0), (0.52992, 0.84805, 0, -0.84805, 0.52992, 0),
         Inertial(0.782, (0.11046, -0.03058, 0.00131),
                  (0.00039238, 0.013595, 0.013674, 0.00023651, 4.987e-05, 4.82e-06)),
         Joint("right_tarsus", ref_deg=58, range_deg=(50, 170), damping=0.1)),
    Body("right_heel_spring", "right_tarsus", (-0.01269, -0.03059, -0.00092),
         (-0.91211, 0.40829, -0.036948, -0.40992, -0.90952, 0.068841),
         Inertial(0.126, (0.081, 0.0022, 0), (2.959e-05, 0.00022231, 0.0002007, 7.15e-06, 6e-07, -1e-07)),
         Joint("right_heel_spring", stiffness=1250)),
    Body("right_foot_crank", "right_tarsus", (0.058, -0.034, -0.02275), None,
         Inertial(0.1261, (0.00493, 2e-05, 0.00215),
                  (2.6941e-05, 4.9621e-05, 6.3362e-05, -2.1e-09, 3.9623e-06, 1.09e-08)),
         Joint("right_foot_crank", range_deg=(-140, -30), damping=1)),
    Body("right_plantar_rod", "right_foot_crank", (0.055, 0, 0.00791), None,
         Inertial(0.1186, (0.17792, 0, 0), (2.779e-06, 0.001774, 0.001775, -2.34e-08, 8.1e-09, 0)),
         Joint("right_plantar_rod")),
    Body("right_foot", "right_tarsus", (0.408, -0.04, 0), None,
         Inertial(0.1498, (0.00474, 0.02748, 0.00014),
                  (0.00017388, 0.00016793, 0.00033261, 0.00011814, -1.36e-06, 4e-07)),
         Joint("right_foot", range_deg=(-140, -30), damping=1, armature=_FOOT_ARM)),
)

BODIES: Tuple[Body, ...] = (PELVIS,) + LEFT_LEG + RIGHT_LEG

CONNECTS: Tuple[Connect, ...] = (
    Connect("left_plantar_rod", "left_foot", (0.35012, 0, 0)),
    Connect("left_achilles_rod", "left_heel_spring", (0.5012, 0, 0)),
    Connect("right_plantar_rod", "right_foot", (0.35012, 0, 0)),
    Connect("right_achilles_rod", "right_heel_spring", (0.5012, 0, 0)),
)

#: Cassie motors, in the published actuator order (= contract order without the flywheel).
CASSIE_MOTORS: Tuple[Motor, ...] = tuple(
    Motor(f"{side}_{j}", gear, lim, rpm)
    for side in ("left", "right")
    for j, gear, lim, rpm in (("hip_roll", 25, 4.5, 2900), ("hip_yaw", 25, 4.5, 2900),
                              ("hip_pitch", 16, 12.2, 1300), ("knee", 16, 12.2, 1300),
                              ("foot", 50, 0.9, 5500)))

#: Contract motor order (architecture.md): 10 Cassie motors then the flywheel.
MOTOR_NAMES: Tuple[str, ...] = tuple(m.joint for m in CASSIE_MOTORS) + ("flywheel",)

#: Published `home` keyframe (qpos, MuJoCo order, wxyz quaternions): leaves 0.6–1.9 mm loop gaps.
HOME_QPOS: Tuple[float, ...] = (
    0, 0, 1.0059301, 1, 0, 0, 0,
    0.00449956, 0, 0.497301, 0.97861, -0.0164104, 0.0177766, -0.204298, -1.1997, 0, 1.42671,
    -2.25907e-06, -1.52439, 1.50645, -1.59681,
    -0.00449956, 0, 0.497301, 0.97874, 0.0038687, -0.0151572, -0.204509, -1.1997, 0, 1.42671,
    0, -1.52439, 1.50645, -1.59681)

#: Spring joints (paper eq. (1): J_s^T tau_s with tau_s = -K (q - q_rest)); rest at q = 0 (MuJoCo).
SPRING_JOINTS: Tuple[str, ...] = ("left_shin", "left_heel_spring", "right_shin", "right_heel_spring")


def spring_params() -> dict:
    """{joint: (stiffness N·m/rad, rest position rad in MuJoCo qpos)} for the spring joints."""
    out = {}
    for b in BODIES:
        if b.joint is not None and b.joint.stiffness > 0:
            out[b.joint.name] = (b.joint.stiffness, 0.0)
    return out


# --------------------------------------------------------------------------------------------
# Options, contact, foot
# --------------------------------------------------------------------------------------------

TIMESTEP = 0.0005                 # s, published (2 kHz controller)
EQUALITY_SOLREF = (0.005, 1.0)    # published default for equality constraints
GEOM_SOLREF = (0.005, 1.0)        # published default geom solref (feet and ground)
FRICTION = (1.0, 0.005, 0.0001)   # MuJoCo default sliding/torsional/rolling friction
INTEGRATOR = "Euler"              # published model uses the default (Euler; damping implicit)
# Friction cone: elliptic, impratio 100 (MuJoCo's defaults: pyramidal, 1).  MuJoCo's soft contacts
# let a foot under a steady tangential load well inside the friction cone creep, at a rate that falls
# with impratio (the feet turning on the spot while standing: docs/measurements.md, Planner and
# robot-model values).
CONE = "elliptic"
IMPRATIO = 100.0

#: Foot contact points (foot-body frame): the two ends of the published foot collision capsule,
#: each a sphere of the capsule radius.  Flat-foot contact = both on the ground.  With the robot
#: facing +x, the first end is the toe (front) and the second the heel.
FOOT_TOE: Vec3 = (-0.052821, 0.092622, 0.0)
FOOT_HEEL: Vec3 = (0.069746, -0.010224, 0.0)
FOOT_RADIUS = 0.02
#: Foot length l (paper ZMP constraint, §III-B): distance between the two contact points.
FOOT_LENGTH = math.dist(FOOT_TOE, FOOT_HEEL)

CASSIE_MASS = sum(b.inertial.mass for b in BODIES)   # 33.3 kg approx.


# --------------------------------------------------------------------------------------------
# Flywheel (paper §II, Table I)
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Flywheel:
    """Aluminium disk 0.15 m above the pelvis origin, hinge about the pelvis y axis.

    ``inertia_pitch`` is the polar (spin) inertia; the transverse inertia is that of a solid
    cylinder with the radius/thickness implied by mass, inertia and ``density`` unless given.
    """
    inertia_pitch: float
    mass: float
    height: float = 0.15
    max_torque: float = 195.0
    max_speed_rpm: Optional[float] = None    # None: no speed limit (paper uses constant torque)
    transverse_inertia: Optional[float] = None
    density: float = 2700.0
    name: str = "custom"

    @property
    def radius(self) -> float:
        return math.sqrt(2.0 * self.inertia_pitch / self.mass)

    @property
    def thickness(self) -> float:
        return self.mass / (self.density * math.pi * self.radius ** 2)

    @property
    def inertia_transverse(self) -> float:
        if self.transverse_inertia is not None:
            return self.transverse_inertia
        return self.mass * (3.0 * self.radius ** 2 + self.thickness ** 2) / 12.0


#: Table I variants; ``w_max`` (rpm) in the table is the speed the paper's flip needed, not a limit.
FLYWHEELS = {
    "I": Flywheel(0.1074, 9.54, name="I"),
    "II": Flywheel(0.2148, 19.09, name="II"),
    "III": Flywheel(0.3222, 28.63, name="III"),
}
TABLE_I_W_MAX_RPM = {"I": 1645.0, "II": 812.0, "III": 573.0}


def flywheel(spec: Union[str, Flywheel, Tuple[float, float], None] = "I") -> Optional[Flywheel]:
    """Flywheel from a Table I name ("I", "II", "III"), an (inertia, mass) pair, a Flywheel, or None."""
    if spec is None or isinstance(spec, Flywheel):
        return spec
    if isinstance(spec, str):
        return FLYWHEELS[spec]
    inertia, mass = spec
    return Flywheel(float(inertia), float(mass))


def flywheel_motor(fw: Flywheel) -> Motor:
    """Flywheel motor as a Motor (gear 1, constant torque; no-load speed = max speed or inf)."""
    rpm = fw.max_speed_rpm if fw.max_speed_rpm is not None else math.inf
    return Motor("flywheel", 1.0, fw.max_torque, rpm)


@dataclass(frozen=True)
class Robot:
    """A named robot: Cassie (this module's tables) with a Table I flywheel, its design knobs set."""
    name: str
    flywheel: str = "I"
    motor_speed_scale: float = 1.0           # leg motors' no-load speeds × this
    flywheel_torque: float = 195.0           # flywheel motor's constant torque limit, N·m
    about: str = ""

    def params(self) -> dict:
        """The design parameters every node that models the robot takes (same names as theirs)."""
        return {"flywheel": self.flywheel, "motor_speed_scale": self.motor_speed_scale,
                "flywheel_torque": self.flywheel_torque}


#: The paper's robot (the default) and the design studies a user asks for by name (docs/robots.md
#: gives the evidence for each).
ROBOTS = {r.name: r for r in (
    Robot("cassie", about="Cassie as published (Agility's motors: gear, torque limit, no-load speed) "
                          "with flywheel I of Table I at 195 N*m: the paper's robot (Cassie's published torque-speed "
                          "curve, as its simulators apply it; docs/robots.md)"),
    Robot("cassie-legs3-fw260", motor_speed_scale=3.0, flywheel_torque=260.0,
          about="design study: leg motors' no-load speeds x3 and a 260 N*m flywheel motor (flywheel I)"),
)}
DEFAULT_ROBOT = "cassie"


def robot(name: str = DEFAULT_ROBOT) -> Robot:
    """The named robot; KeyError with the known names otherwise."""
    try:
        return ROBOTS[name]
    except KeyError:
        raise KeyError(f"unknown robot {name!r}; known: {', '.join(ROBOTS)}") from None
