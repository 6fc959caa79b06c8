"""pytest fixtures for ROS tests (see tests/ros_harness.py).

- ros_graph: an isolated graph (own ROS_DOMAIN_ID on loopback) + Launcher + lazy test node;
  on teardown every process is stopped (SIGINT, then SIGTERM/SIGKILL) and the test fails if an
  exit code is not the expected one (`ros_graph.expected_exit[name] = {...}`, default {0}) or
  anything is left running.
- test_node: shortcut for ros_graph.test_node.
"""
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path += [str(p) for p in sorted((Path(__file__).resolve().parents[1] / "ros_ws" / "src").iterdir()) if p.is_dir()]  # plain-Python packages without an install

from ros_harness import RosGraph, new_domain  # noqa: E402


@pytest.fixture
def ros_graph(tmp_path):
    g = RosGraph(new_domain(), tmp_path / "logs")
    yield g
    problems = g.teardown()
    if problems:
        pytest.fail("ROS graph teardown:\n" + "\n".join(problems), pytrace=False)


@pytest.fixture
def test_node(ros_graph):
    return ros_graph.test_node
