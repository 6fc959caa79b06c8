"""Pre-checks with named, quantified reasons (before IPOPT), and IPOPT failures turned into the
most violated constraint (paper §III-B constraints)."""
from __future__ import annotations

import math

import numpy as np

from . import fslip as F

KINDS = ("backflip", "frontflip", "hop")
MAX_DISTANCE = 3.0      # m, |forward distance| accepted
MAX_PLATFORM = 2.0      # m
STANCE_T_MAX = 1.0      # s, upper bound of the jumping duration (jumping.JumpingProblem)


class InfeasibleRequest(ValueError):
    """A flip request the robot cannot do (or a malformed one); the message names the binding
    limit and by how much."""


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
            Fm *= max(0.0, 1.0 - float(p.dqknee_dL(L)) * v / p.knee_no_load_speed)
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
            f"apex ≈ {amax:.2f} m (lift-off ≈{vmax:.2f} m/s), over by {apex - amax:.2f} m")
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
                f"{H_need - H_cap:.0f} kg·m²/s")


def diagnose(err, p: F.FSLIPParams) -> str:
    """Most violated constraint at IPOPT's last iterate (``err.problem`` from jumping)."""
    from . import jumping as Jm
    prob = getattr(err, "problem", None)
    if prob is None:
        return str(err)
    dbg = prob.opti.debug
    try:
        X = np.array(dbg.value(prob.X)).T
        U = np.array(dbg.value(prob.U)).T
    except Exception:   # noqa: BLE001
        return str(err)
    worst, name = 0.0, "unknown"
    _, _, fg = Jm.knot_functions(p, prob.N)
    G = np.array(fg(X.T, U.T))
    scale = np.array([0.1, 0.1, p.m * p.g, p.m * p.g, p.m * p.g, p.m * p.g, 10, 10, 100, 100,
                      p.m * p.g, p.m * p.g])[:G.shape[0]]
    for i in range(G.shape[0]):
        v = float(-G[i].min()) / scale[i]
        if v > worst:
            worst, name = v, f"{Jm.PATH_ROWS[i]} (violated by {-G[i].min():.3g} at knot {int(G[i].argmin())})"
    for nm, e in prob.task_rows.items():
        v = abs(float(dbg.value(e)))
        if v > worst:
            worst, name = v, f"{nm} (residual {v:.3g})"
    return f"{err}; most violated constraint: {name}"
