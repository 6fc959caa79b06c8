"""Module boundaries of tsc_controller (issue 25): the references (``reference``), the time profiles
(``profiles``) and the settings (``config``) are modules of their own that import no ROS, and
``domains`` defines none of their names again (a merge that brought back a copy of, say,
ControllerConfig or quintic into domains.py would have the Controller use one copy and tsc_node's
``config_overrides`` check against the other)."""
import ast
import subprocess
import sys
from pathlib import Path

import tsc_controller

PKG = Path(tsc_controller.__file__).parent
SPLIT = ("reference", "profiles", "config")
#: top-level packages of ROS 2 (rclpy and the generated message packages) and the graph's transport
#: modules (docs/architecture.md: the only ones besides the nodes that import ROS)
ROS = ("rclpy", "rcl_interfaces", "rosidl_runtime_py", "rosidl_parser", "builtin_interfaces", "std_msgs",
       "sensor_msgs", "nav_msgs", "rosgraph_msgs", "flip_msgs")
TRANSPORT = ("flip_transport.lockstep", "flip_transport._rcl_io", "tsc_controller.tsc_node")


def _defined(module: str) -> set:
    """Names a module of the package binds at its top level by def, class or assignment (not import)."""
    names = set()
    for n in ast.parse((PKG / f"{module}.py").read_text()).body:
        if isinstance(n, (ast.FunctionDef, ast.ClassDef)):
            names.add(n.name)
        elif isinstance(n, (ast.Assign, ast.AnnAssign)):
            for t in (n.targets if isinstance(n, ast.Assign) else [n.target]):
                names.update(e.id for e in ast.walk(t) if isinstance(e, ast.Name))
    return names


def test_reference_profiles_config_import_no_ros():
    code = ("import sys\n"
            + "".join(f"import tsc_controller.{m}\n" for m in SPLIT)
            + f"print(sorted(m for m in sys.modules if m.split('.')[0] in {ROS!r} or m in {TRANSPORT!r}))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]", out.stdout


def test_domains_defines_none_of_the_split_modules_names():
    ours = _defined("domains")
    for m in SPLIT:
        theirs = _defined(m)
        assert theirs, m
        assert not ours & theirs, f"domains.py defines {sorted(ours & theirs)} of tsc_controller.{m} again"
