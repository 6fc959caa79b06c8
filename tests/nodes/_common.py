"""Shared bits of the stand-in nodes (test fixtures, not part of the product)."""
import signal

import rclpy
from rclpy.signals import SignalHandlerOptions

from flip_transport.node_stop import run_until_stopped


def run(node_factory, args=None) -> int:
    """Create the node, spin until SIGINT/SIGTERM (exit 0) or until the node calls
    `self.finished = True` (exit node.exit_code); ends the way the product's nodes do."""
    # a stop sets a flag the loop reads between spins, as sim_node's does: a KeyboardInterrupt raised
    # inside rclpy's take of a message surfaced as a RuntimeError and the stand-in exited 1
    rclpy.init(args=args, signal_handler_options=SignalHandlerOptions.NO)
    nodes, stop = [], []
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: stop.append(True))

    def loop():
        try:
            nodes.append(node_factory())
            while rclpy.ok() and not stop and not getattr(nodes[0], "finished", False):
                rclpy.spin_once(nodes[0], timeout_sec=0.1)
            return int(getattr(nodes[0], "exit_code", 0))
        except Exception:  # noqa: BLE001 - e.g. RCLError from a wait set after the signal shut rcl down
            if not rclpy.ok():
                return 0
            raise

    def close():
        for n in nodes:
            n.destroy_node()
        rclpy.try_shutdown()
    return run_until_stopped(loop, close)
