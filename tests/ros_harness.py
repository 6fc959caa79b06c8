"""launch_testing-style harness for pytest, on top of flip_tools (rclpy + subprocess).

Every test that uses `ros_graph` gets:
  - its own ROS_DOMAIN_ID (1..100), claimed with an flock so parallel pytest workers / other runs
    of this tool on the machine never share it, and ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST;
  - a Launcher: node processes (each its own OS process group, own env, log file under tmp_path);
  - a test node (rclpy, own Context in that domain) to publish/subscribe/call services;
  - readiness through the ROS graph (GraphWatcher: node names, services, pub/sub counts);
  - teardown that stops every process with SIGINT (then SIGTERM/SIGKILL), and asserts the exit
    codes the test declared acceptable and that no process (or process-group member) is left.
"""
from __future__ import annotations

import itertools
import os
import time
from pathlib import Path
from typing import Callable

from flip_tools.launcher import GraphWatcher, Launcher, ProcessDied, python_node_cmd, ros_args  # noqa: F401
from flip_tools.rosenv import DomainClaim, claim_domain, node_env, set_process_ros_env  # noqa: F401

set_process_ros_env()

REPO = Path(__file__).resolve().parents[1]

NODES_DIR = Path(__file__).resolve().parent / "nodes"
FLIP = REPO / "scripts" / "flip"
_counter = itertools.count()


def _worker_salt() -> int:
    w = os.environ.get("PYTEST_XDIST_WORKER", "gw0")
    digits = "".join(c for c in w if c.isdigit())
    return int(digits or 0) * 1000 + next(_counter)


def new_domain() -> DomainClaim:
    return claim_domain(salt=_worker_salt())


def stand_in(name: str) -> list[str]:
    """Command of a stand-in node script under tests/nodes/ (run with this interpreter)."""
    return python_node_cmd(NODES_DIR / name)


class TestNode:
    """An rclpy node in the test process, in the test's domain (own Context, no signal handlers)."""

    __test__ = False  # not a pytest test class

    def __init__(self, domain_id: int, name: str = "test_node"):
        import rclpy
        from rclpy.context import Context
        from rclpy.executors import SingleThreadedExecutor
        from rclpy.signals import SignalHandlerOptions
        self.context = Context()
        rclpy.init(context=self.context, domain_id=domain_id, signal_handler_options=SignalHandlerOptions.NO)
        self.node = rclpy.create_node(name, context=self.context)
        self.executor = SingleThreadedExecutor(context=self.context)
        self.executor.add_node(self.node)
        self.graph = GraphWatcher(node=self.node)

    def spin_until(self, pred: Callable[[], bool], timeout: float = 30.0, what: str = "condition") -> None:
        end = time.monotonic() + timeout
        while not pred():
            if time.monotonic() > end:
                raise TimeoutError(f"timed out after {timeout} s waiting for {what}")
            self.executor.spin_once(timeout_sec=0.05)

    def spin_for(self, seconds: float) -> None:
        end = time.monotonic() + seconds
        while time.monotonic() < end:
            self.executor.spin_once(timeout_sec=0.05)

    def collect(self, msg_type, topic: str, qos) -> list:
        """Subscribe and return the (growing) list of received messages."""
        got: list = []
        self.node.create_subscription(msg_type, topic, got.append, qos)
        return got

    def call(self, srv_type, name: str, request, timeout: float = 30.0):
        cli = self.node.create_client(srv_type, name)
        try:
            if not cli.wait_for_service(timeout_sec=timeout):
                raise TimeoutError(f"service {name} not available")
            fut = cli.call_async(request)
            self.spin_until(fut.done, timeout, f"response of {name}")
            return fut.result()
        finally:
            self.node.destroy_client(cli)

    def close(self) -> None:
        self.executor.shutdown()
        self.node.destroy_node()
        self.context.try_shutdown()


class RosGraph:
    """What the `ros_graph` fixture yields."""

    def __init__(self, domain: DomainClaim, log_dir: Path):
        self.domain_claim = domain
        self.domain_id = domain.domain_id
        self.log_dir = log_dir
        self.launcher = Launcher(self.domain_id, log_dir=log_dir)
        self._test_node: TestNode | None = None
        # exit codes a test accepts per process name when stopped (default: 0 only)
        self.expected_exit: dict[str, set[int]] = {}

    @property
    def env(self) -> dict:
        return node_env(self.domain_id)

    @property
    def test_node(self) -> TestNode:
        if self._test_node is None:
            self._test_node = TestNode(self.domain_id)
        return self._test_node

    def start(self, name: str, cmd: list[str], **kw):
        return self.launcher.start(name, cmd, **kw)

    def wait_ready(self, timeout: float = 60.0, **conds) -> float:
        """nodes=[...], services=[...], topics={topic: (min_pubs, min_subs)} — through the graph."""
        return self.test_node.graph.wait_ready(timeout=timeout, launcher=self.launcher, **conds)

    def stop_all(self) -> dict[str, dict]:
        return self.launcher.stop_all()

    def teardown(self) -> list[str]:
        """Stop everything; return a list of problems (bad exit codes, leftovers)."""
        problems = []
        try:
            report = self.launcher.stop_all()
            for name, r in report.items():
                ok = self.expected_exit.get(name, {0})
                if r["returncode"] not in ok:
                    problems.append(f"{name} exited {r['returncode']} ({r['stopped_by']}), expected {sorted(ok)}"
                                    f"\n--- {r['log']} ---\n{self.launcher.procs[name].log_tail()}")
            left = self.launcher.leftovers()
            if left:
                problems.append(f"processes left behind: {left}")
        finally:
            if self._test_node is not None:
                self._test_node.close()
            self.domain_claim.release()
        return problems
