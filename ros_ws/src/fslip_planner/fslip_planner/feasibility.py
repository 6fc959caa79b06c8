"""Named, quantified reasons for a rejection: pre-checks before IPOPT (malformed requests, the apex the
knees can reach, the momentum the stance can build), the limits that bind the elastic optimum of a
task beyond reach (paper §III-B constraints), and the flight the plan leaves (momentum transmission,
§IV-A: can the flywheel turn the body in that time?)."""
from __future__ import annotations

import math

import numpy as np
from cassie_model.motor_limits import planning_fraction

from . import fslip as F

KINDS = ("backflip", "frontflip", "hop")
MAX_DISTANCE = 3.0      # m, |forward distance| accepted
MAX_PLATFORM = 2.0      # m
STANCE_T_MAX = 1.0      # s, upper bound of the jumping duration (jumping.JumpingProblem)


class InfeasibleRequest(ValueError):
    """A flip request the robot cannot do (or a malformed one); the message names the binding
    limit and by how much, ``limit`` names it alone (e.g. "knee torque–speed envelope")."""

    def __init__(self, message, limit="malformed request"):
        super().__init__(message)
        self.limit = limit


def _finite(name, v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        raise InfeasibleRequest(f"{name} must be a number, got {v!r}") from None
    if not math.isfinite(v):
        raise InfeasibleRequest(f"{name} must be finite, got {v}")
    return v


def validate_inputs(kind, apex, distance, platform, flywheel):
    """Type/range checks of a request; returns the cleaned (apex, distance, platform)."""
    if kind not in KINDS:
        raise InfeasibleRequest(f"unknown kind {kind!r}: expected one of {', '.join(KINDS)}")
    if flywheel not in ("I", "II", "III"):
        raise InfeasibleRequest(f"unknown flywheel {flywheel!r}: expected I, II or III")
    distance = _finite("forward_distance", distance)
    platform = _finite("platform_height", platform)
    if apex is not None:
        apex = _finite("apex_height", apex)
        if apex <= 0:
            raise InfeasibleRequest(f"apex_height must be positive, got {apex} m")
    if abs(distance) > MAX_DISTANCE:
        raise InfeasibleRequest(f"forward_distance {distance} m is outside ±{MAX_DISTANCE} m")
    if platform < 0 or platform > MAX_PLATFORM:
        raise InfeasibleRequest(f"platform_height {platform} m is outside [0, {MAX_PLATFORM}] m")
    if kind == "hop" and abs(distance) > 1.0:
        raise InfeasibleRequest(f"hop forward_distance {distance} m exceeds 1.0 m")
    return apex, distance, platform


def max_vertical_jump(p: F.FSLIPParams, dt=5e-4):
    """Upper estimate of the reachable COM apex (m above the ground) and lift-off speed: a vertical
    push from rest in the deepest crouch (L_min) with the largest leg force the knees allow
    (F_max(L) and the torque–speed envelope), releasing where z + ż²/2g is largest."""
    L, v = p.L_min, 0.0
    com_h = float(p.reg("com_h", p.L_max))
    best = (L + com_h, 0.0)
    while L < p.L_max:
        Fm = float(p.F_max(L))
        if math.isfinite(p.knee_no_load_speed):
            Fm *= max(0.0, float(planning_fraction(float(p.dqknee_dL(L)) * v / p.knee_no_load_speed)))
        a = Fm / p.m - p.g
        v += a * dt
        L += v * dt
        if v <= 0:
            break
        apex = L + v * v / (2 * p.g) + com_h
        if apex > best[0]:
            best = (apex, v)
    return best


def precheck(kind, apex, distance, platform, p: F.FSLIPParams, L0: float):
    """Named, quantified reasons before IPOPT."""
    com_h = float(p.reg("com_h", L0))
    stand = L0 + com_h
    if apex < stand + 0.02:
        raise InfeasibleRequest(
            f"apex {apex:.2f} m is not above the standing COM height {stand:.2f} m: no flight phase")
    amax, vmax = max_vertical_jump(p)
    z_lo = p.L_max - 0.05
    need = math.sqrt(max(2 * p.g * (apex - com_h - z_lo), 0.0))
    if apex > amax:
        lim = "knee torque–speed envelope" if math.isfinite(p.knee_no_load_speed) else "leg force limit"
        raise InfeasibleRequest(
            f"apex {apex:.2f} m needs lift-off speed ≈{need:.2f} m/s; {lim} reached: max reachable "
            f"apex ≈ {amax:.2f} m (lift-off ≈{vmax:.2f} m/s), over by {apex - amax:.2f} m", lim)
    if kind != "hop":
        # conservative: the longest flight this apex allows (lift-off from a low, 0.75 m, mass height)
        zd = math.sqrt(max(2 * p.g * (apex - com_h - 0.75), 0.01))
        T = float(F.flight_time(zd, platform, p.g))
        H_need = float(p.I(p.L_max)) * 1.5 * math.pi / T    # ≥ ¾ turn must come from the stance
        H_cap = p.tau_max * STANCE_T_MAX
        if H_need > H_cap:
            raise InfeasibleRequest(
                f"{kind}: flight {T:.2f} s needs pitch momentum ≥{H_need:.0f} kg·m²/s; flywheel torque "
                f"{p.tau_max:.0f} N·m over ≤{STANCE_T_MAX:.1f} s stance gives {H_cap:.0f}: over by "
                f"{H_need - H_cap:.0f} kg·m²/s", "flywheel torque (stance)")


def _limit_names():
    """The physical limit each path-constraint family (``jumping.PATH_ROWS``) stands for."""
    from .jumping import PATH_ROWS
    limits = ("leg length range", "leg length range", "unilateral leg force", "unilateral ground contact",
              "friction cone", "friction cone", "ZMP inside the foot", "ZMP inside the foot",
              "flywheel torque", "flywheel torque", "knee torque", "knee torque–speed envelope",
              "knee torque–speed envelope")
    return dict(zip(PATH_ROWS, limits))


TASK_NAMES = {"flip encoding (thetadot*T_flight = ±2π − 2β)": "rotation",
              "apex height": "apex", "forward distance": "forward distance"}


def unreachable_message(err, p: F.FSLIPParams):
    """(message, limit) of a :class:`fslip_planner.jumping.TaskUnreachable`: what the closest plan
    within every limit reaches, and the limits that hold it there (by multiplier share)."""
    limit_of = _limit_names()
    parts = []
    for k, v in err.residuals.items():
        if abs(v) < 1e-4:
            continue
        if TASK_NAMES[k] == "rotation":
            parts.append(f"the rotation it leaves for the flight is off by {math.degrees(v):+.1f}°")
        else:
            parts.append(f"{TASK_NAMES[k]} {abs(v):.3f} m {'beyond' if v > 0 else 'short of'} the request")
    named = ", ".join(f"{limit_of.get(n, n)} ({100 * s:.0f} %"
                      + (f", {w[0]:.2f}–{w[1]:.2f} s into the push" if w else "") + ")"
                      for n, s, w in err.binding[:3])
    top = next((limit_of.get(n, n) for n, _, _ in err.binding), "unknown")
    return (f"beyond the robot's limits: the closest plan within them has "
            f"{'; '.join(parts) or 'task residuals below 1e-4'}; binding: {named}", top)


def flight_requirement(kind, lift_off, omega0, T, p: F.FSLIPParams, I_fw, L_land, tucked=False):
    """Least flywheel torque (N·m) that turns the body without the flywheel by ±2π − 2β in the
    planned flight and brings it to rest (momentum transmission, eq. momentumTrans); ``omega0`` the
    body's lift-off rate (the pelvis tracks β on the ground: β̇).  The body's inertia I(L) − I_flywheel
    along the planned tuck, or (``tucked``) at the deepest tuck the whole flight: the least any
    flight of this duration can need."""
    from . import flight as Fl
    sign = Fl.SIGN[kind]
    if sign == 0.0:
        return 0.0
    turn = sign * 2 * math.pi - 2 * lift_off["beta"]
    T1, L_tuck = Fl.tuck_timing(kind, T, lift_off["L"])

    def inertia(t):
        t = np.asarray(t, float)
        if tucked:
            return np.full(t.shape, float(p.I(Fl.TUCK_LENGTH)) - I_fw)
        L = Fl.leg_profile(lift_off["L"], L_tuck, L_land, T1, t)[0]
        return np.array([float(p.I(v)) for v in np.ravel(L)]) - I_fw
    return Fl.flight_torque_needed(turn, omega0, T, inertia)


def check_flight(kind, lift_off, omega0, T, p: F.FSLIPParams, I_fw, L_land):
    """The flight the plan leaves must be turnable with the flywheel's torque: InfeasibleRequest
    with the numbers when even a body tucked to its shortest legs for the whole flight needs more
    torque than the flywheel motor gives (a necessary condition; the robot has flown longer than
    its plan, by ~0.1 m of apex as the paper reports, so the planned tuck's figure is no verdict).
    Returns (needed with the planned tuck, needed fully tucked)."""
    from . import flight as Fl
    need_tucked = flight_requirement(kind, lift_off, omega0, T, p, I_fw, L_land, tucked=True)
    if need_tucked > p.tau_max:
        turn = math.degrees(abs(Fl.SIGN[kind] * 2 * math.pi - 2 * lift_off["beta"]))
        raise InfeasibleRequest(
            f"{kind}: the {T:.2f} s flight this plan leaves needs ≥{need_tucked:.0f} N·m of flywheel "
            f"torque to turn the body {turn:.0f}° and stop it (momentum transmission, legs tucked to "
            f"{Fl.TUCK_LENGTH:.2f} m the whole flight); the flywheel motor gives {p.tau_max:.0f} N·m: "
            f"over by {need_tucked - p.tau_max:.0f} N·m (a higher apex gives a longer flight)",
            "flywheel torque (flight)")
    return flight_requirement(kind, lift_off, omega0, T, p, I_fw, L_land), need_tucked


#: halvings of the touch-down sink speed searched for the largest one a landing plan exists from, when
#: none exists from the predicted touch-down (each a landing solve, warm from the nearest solved)
LANDING_SINK_STEPS = 5


def _lands(problem, x0, zdot) -> bool:
    """Does ``problem`` (a ``LandingProblem``) solve from ``x0`` with the sink speed ``zdot``: warm from the
    nearest state it solved (a homotopy in the sink speed), else cold."""
    x = np.r_[np.asarray(x0, float)[:3], zdot, float(x0[4])]
    for warm in ((True, False) if problem.has_solutions else (False,)):
        try:
            problem.solve(x, warm=warm)
            return True
        except RuntimeError:
            continue
    return False


def check_landing(x0, rest, L_stand: float):
    """The landing (paper §III-C) from the touch-down ``x0`` a jumping plan predicts
    (``landing.mirrored_touchdown``): ``rest`` (a ``LandingProblem``) solved cold, that solution.  When it
    has none, the largest touch-down sink speed from which a landing plan with the momentum left free
    exists (bisection, each solve warm from the nearest solved): None when a landing exists from within
    a bisection step of the predicted sink, or from none at all (an optimiser failure, not a verdict: a
    landing without sink exists), else the robot could not land the flip it would jump: InfeasibleRequest
    with that sink against the predicted one, naming the knee torque–speed envelope when the landing
    exists without it."""
    from .landing import shared_problem
    p = rest.p
    try:
        return rest.solve(x0, warm=False)
    except RuntimeError:
        pass
    x0 = np.asarray(x0, float)
    sink = -float(x0[3])
    free, unbounded = (shared_problem(p, L_stand, name) for name in ("free", "unbounded"))
    free.forget()
    unbounded.forget()
    lo, hi = 0.0, sink
    for _ in range(LANDING_SINK_STEPS):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if _lands(free, x0, -mid) else (lo, mid)
    if hi == sink or lo == 0.0:
        return None
    what = (f"no landing plan from the touch-down this jump leads to (COM sink {sink:.2f} m/s, "
            f"{abs(float(x0[4])):.0f} kg·m²/s of pitch momentum, COM {abs(float(x0[0])):.2f} m "
            f"{'ahead of' if x0[0] >= 0 else 'behind'} the feet): "
            f"a landing plan exists from at most ≈{lo:.2f} m/s of sink (over by {sink - lo:.2f} m/s; a lower "
            f"apex or platform sinks slower)")
    if math.isfinite(p.knee_no_load_speed) and _lands(unbounded, x0, -0.5 * sink) and _lands(unbounded, x0, -sink):
        raise InfeasibleRequest(
            f"{what}; the knees' torque–speed envelope binds (full torque up to half the no-load speed, "
            f"{0.5 * p.knee_no_load_speed:.2f} rad/s; without it the landing exists)",
            "knee torque–speed envelope (landing)")
    raise InfeasibleRequest(f"{what}; it does not exist without the knee torque–speed envelope either "
                            f"(leg force, leg length range, friction, ZMP, flywheel torque)", "landing")


# ------------------------------------------------------------------------------- standing
#: how near the standing state at rest the measured pelvis must be for a flip to be planned from it
#: (InfeasibleRequest "not_standing" otherwise): tilt of its z axis, height above the take-off ground
#: against the standing pose's, speed, angular rate, and the momentum its flywheel still holds (kg m^2/s:
#: a jump plan starts from zero pitch momentum; after a somersault the controller's landing takes the
#: flywheel's out over seconds with the pelvis already still; its own bound is landing_H_done, 2)
STAND_MAX_TILT = math.radians(10.0)
STAND_HEIGHT_TOL = 0.05
STAND_MAX_SPEED = 0.2
STAND_MAX_RATE = 0.5
STAND_MAX_FLYWHEEL_MOMENTUM = 2.0


def rotation_xyzw(q):
    """Rotation matrix of a quaternion (x, y, z, w), normalised (scipy's)."""
    from scipy.spatial.transform import Rotation
    return Rotation.from_quat(np.asarray(q, float)).as_matrix()


def standing_com_x(state, robot, ground_z: float = 0.0) -> float:
    """World COM x of a robot standing at ``state`` (a ``plan.PelvisState``: the standing pose's COM
    of ``robot``, a ``plan._Robot``, carried by the measured pelvis), where a jump plan starts;
    InfeasibleRequest (limit "not_standing") unless the pelvis is
    near the standing state at rest on the take-off ground at ``ground_z``: tilt, height above it,
    speed and angular rate within the STAND_* bounds, and (when ``state.flywheel_speed`` is measured)
    the flywheel's momentum."""
    vals = np.r_[state.t, np.ravel(state.position), np.ravel(state.orientation),
                 np.ravel(state.linear_velocity), np.ravel(state.angular_velocity)]
    if vals.size != 14 or not np.all(np.isfinite(vals)) or np.linalg.norm(state.orientation) < 1e-9:
        raise InfeasibleRequest(f"not_standing: malformed measured pelvis state {state}", "not_standing")
    R = rotation_xyzw(state.orientation)
    tilt = math.acos(max(-1.0, min(1.0, R[2, 2])))
    height = float(state.position[2]) - ground_z
    stand = float(robot.pelvis0[2])
    speed = float(np.linalg.norm(state.linear_velocity))
    rate = float(np.linalg.norm(state.angular_velocity))
    off = []
    if tilt > STAND_MAX_TILT:
        off.append(f"pelvis tilted {math.degrees(tilt):.1f} deg (at most {math.degrees(STAND_MAX_TILT):.0f})")
    if abs(height - stand) > STAND_HEIGHT_TOL:
        off.append(f"pelvis {height:.3f} m above the take-off ground at z = {ground_z:g} m "
                   f"(standing: {stand:.3f} +- {STAND_HEIGHT_TOL:g})")
    if speed > STAND_MAX_SPEED:
        off.append(f"pelvis moving at {speed:.2f} m/s (at most {STAND_MAX_SPEED:g})")
    if rate > STAND_MAX_RATE:
        off.append(f"pelvis turning at {rate:.2f} rad/s (at most {STAND_MAX_RATE:g})")
    w_fw = getattr(state, "flywheel_speed", None)
    if w_fw is not None and not abs(robot.I_fw * w_fw) <= STAND_MAX_FLYWHEEL_MOMENTUM:
        off.append(f"flywheel spinning at {abs(w_fw) * 30 / math.pi:.0f} rpm, {abs(robot.I_fw * w_fw):.1f} kg m^2/s "
                   f"(at most {STAND_MAX_FLYWHEEL_MOMENTUM:g}): the landing is still taking its momentum out")
    if off:
        raise InfeasibleRequest(f"not_standing: the robot is not standing at rest at sim t = {state.t:.3f} s: "
                                + "; ".join(off), "not_standing")
    return float(com_of_standing(state, robot)[0])


def com_of_standing(state, robot):
    """World COM of the robot standing with its pelvis at ``state`` (a ``plan.PelvisState``): its standing
    COM in the pelvis frame carried by the measured pelvis, as the jumping plan's x_start is found."""
    return np.asarray(state.position, float) + rotation_xyzw(state.orientation) @ robot.com_in_pelvis
