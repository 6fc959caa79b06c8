"""pytest fixtures for ROS tests (see tests/ros_harness.py), and the test tiers.

- the tiers: every test lives in tests/unit, tests/offline or tests/graph and is marked with its
  folder's name (pytest.ini registers the markers: `pytest -m unit`); the helpers here in tests/
  are importable from all three.
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

TESTS = Path(__file__).resolve().parent
#: the test tiers: one folder under tests/ each, and a marker of the same name
TIERS = ("unit", "offline", "graph")


@pytest.hookimpl(tryfirst=True)
def pytest_collection_modifyitems(items):
    """Marks each test with its folder's tier, before `-m` selects; a test outside the tiers' folders
    is refused (it would run in no tier's selection)."""
    for item in items:
        tier = Path(item.path).resolve().relative_to(TESTS).parts[0]
        if tier not in TIERS:
            raise pytest.UsageError(f"{item.nodeid}: tests live in tests/{{{','.join(TIERS)}}}/")
        item.add_marker(tier)


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
