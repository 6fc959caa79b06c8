"""The services flip calls on a graph: /request_flip (flip_msgs RequestFlip) and std_srvs Trigger."""
from __future__ import annotations


def call_request_flip(watcher, kind: int, apex: float, distance: float, platform: float, timeout: float):
    from flip_msgs.srv import RequestFlip
    node = watcher.node
    cli = node.create_client(RequestFlip, "/request_flip")
    try:
        if not cli.wait_for_service(timeout_sec=timeout):
            raise TimeoutError("/request_flip not available")
        req = RequestFlip.Request(kind=kind, apex_height=float(apex), forward_distance=float(distance),
                                  platform_height=float(platform))
        fut = cli.call_async(req)
        try:
            watcher.spin_until(fut.done, timeout, "the /request_flip response")
        except TimeoutError:
            raise TimeoutError(f"/request_flip did not answer in {timeout:.0f} s") from None
        return fut.result()
    finally:
        node.destroy_client(cli)


def call_trigger(watcher, service: str, timeout: float) -> str:
    """Call a std_srvs/Trigger service; its message (RuntimeError when it reports no success)."""
    from std_srvs.srv import Trigger
    cli = watcher.node.create_client(Trigger, service)
    try:
        if not cli.wait_for_service(timeout_sec=timeout):
            raise TimeoutError(f"{service} not available")
        fut = cli.call_async(Trigger.Request())
        watcher.spin_until(fut.done, timeout, f"the {service} response")
        r = fut.result()
        if not r.success:
            raise RuntimeError(f"{service}: {r.message}")
        return r.message
    finally:
        watcher.node.destroy_client(cli)


def response_dict(r) -> dict:
    return {k: getattr(r, k) for k in ("accepted", "reason", "plan_id", "liftoff_zdot", "liftoff_xdot",
                                       "liftoff_pitch_rate", "flight_time", "peak_flywheel_speed",
                                       "solve_time")}
