"""What a flip request asks for, from `flip run`'s (or a benchmark's) command line: the forward
distance, which a platform flip and a flip onto the raised landing area need even when none is given."""
from __future__ import annotations

#: forward distance of a platform flip (--platform) when --distance is not given.  The robot stands
#: with its toes 0.05 m behind the platform's front edge (cassie_flip_sim Scenario.platform: edge at
#: x = 0.15 m, feet from -0.10 to +0.10 m), so a flip in place lands on the platform again, not on the
#: ground below (measured through the graph: the feet met the platform's front edge at touch-down).
#: Offline (tests/offline_flip.py, motor speed scale 3, 260 N*m, apex 1.2 m): with 0.4 m the left shin
#: struck the platform 0.1 s after touch-down; with 0.6 m the legs cleared it.
PLATFORM_FLIP_DISTANCE = 0.6


#: forward distance of a flip onto the raised landing area (--ground-offset, flip D) when --distance is
#: not given.  The area begins at x = 0.4 m (cassie_flip_sim Scenario.raised_landing), 0.3 m ahead of
#: the toes: a flip in place lands on the ground it took off from, below the area, and is not flip D
#: (measured: identical flights and touch-downs to the plain frontflip's).  After 0.6 m the heels come
#: down ~0.1 m past the area's edge.
RAISED_FLIP_DISTANCE = 0.6


def request_distance(args) -> float:
    """Forward distance of the request: --distance, or PLATFORM_FLIP_DISTANCE for a platform flip,
    RAISED_FLIP_DISTANCE for a flip onto the raised landing area (--ground-offset)."""
    if getattr(args, "distance", None) is not None:
        return float(args.distance)
    if (getattr(args, "platform", None) or 0.0) > 0.0:
        return PLATFORM_FLIP_DISTANCE
    return RAISED_FLIP_DISTANCE if (getattr(args, "ground_offset", None) or 0.0) > 0.0 else 0.0
