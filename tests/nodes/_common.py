"""Shared bits of the stand-in nodes (test fixtures, not part of the product)."""
import rclpy
from rclpy.executors import ExternalShutdownException


def run(node_factory, args=None) -> int:
    """Create the node, spin until SIGINT/SIGTERM (exit 0) or until the node calls
    `self.finished = True` (exit node.exit_code)."""
    rclpy.init(args=args)
    node = None
    try:
        node = node_factory()
        while rclpy.ok() and not getattr(node, "finished", False):
            rclpy.spin_once(node, timeout_sec=0.1)
        return int(getattr(node, "exit_code", 0))
    except (KeyboardInterrupt, ExternalShutdownException):
        return 0
    except Exception:  # noqa: BLE001 - e.g. RCLError from a wait set after the signal shut rcl down
        if not rclpy.ok():
            return 0
        raise
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
