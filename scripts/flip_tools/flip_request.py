"""What a flip request asks for, from `flip run`'s (or a benchmark's) command line: the forward
distance, which a platform flip needs even when none is given."""
from __future__ import annotations

#: forward distance of a platform flip (--platform) when --distance is not given.  The robot stands
#: with its toes 0.05 m behind the platform's front edge (cassie_flip_sim Scenario.platform: edge at
#: x = 0.15 m, feet from -0.10 to +0.10 m), so a flip in place lands on the platform again, not on the
#: ground below (measured through the graph: the feet met the platform's front edge at touch-down).
#: Offline (tests/offline_flip.py, motor speed scale 3, 260 N*m, apex 1.2 m): with 0.4 m the left shin
#: struck the platform 0.1 s after touch-down; with 0.6 m the legs cleared it.
PLATFORM_FLIP_DISTANCE = 0.6


def request_distance(args) -> float:
    """Forward distance of the request: --distance, or PLATFORM_FLIP_DISTANCE for a platform flip."""
    if getattr(args, "distance", None) is not None:
        return float(args.distance)
    return PLATFORM_FLIP_DISTANCE if (getattr(args, "platform", None) or 0.0) > 0.0 else 0.0
