"""The packages' import graph, read from their sources with ast (nothing is imported): the simulator
(cassie_flip_sim), the planner (fslip_planner) and the controller (tsc_controller) import none of
each other and share the robot model (cassie_model, no ROS) and the lockstep transport
(flip_transport); every node imports the transport; scripts/ and tools/ import no test module."""
from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

REPO = next(p for p in Path(__file__).resolve().parents if (p / "ros_ws" / "src").is_dir())
SRC = REPO / "ros_ws" / "src"
SIM, PLANNER, CONTROLLER = "cassie_flip_sim", "fslip_planner", "tsc_controller"
MODEL, TRANSPORT = "cassie_model", "flip_transport"
NODES = {SIM: ("sim_node",), PLANNER: ("planner_node",), CONTROLLER: ("tsc_node",)}


def _imports(path: Path, package: str | None = None) -> set[str]:
    """Modules imported anywhere in a file (function-level imports too); a relative import is
    resolved into ``package``."""
    tree = ast.parse(path.read_text(), filename=str(path))
    names = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                names.add(package + ("." + node.module if node.module else ""))
            else:
                names.add(node.module)
    return names


def _modules(package: str) -> dict[str, set[str]]:
    """{module file name: the top-level packages it imports} of one of ros_ws/src's packages."""
    files = sorted((SRC / package / package).rglob("*.py"))
    assert files, f"no sources of {package}"
    return {str(f.relative_to(SRC)): {n.split(".")[0] for n in _imports(f, package)} for f in files}


def test_simulator_planner_and_controller_import_none_of_each_other():
    three = {SIM, PLANNER, CONTROLLER}
    for package in three:
        for module, tops in _modules(package).items():
            assert not tops & (three - {package}), f"{module} imports {sorted(tops & (three - {package}))}"


def test_transport_and_model_import_none_of_the_nodes_packages():
    """flip_transport and cassie_model sit below the three; cassie_model imports no ROS."""
    above = {SIM, PLANNER, CONTROLLER}
    for module, tops in _modules(TRANSPORT).items():
        assert not tops & (above | {MODEL}), f"{module} imports {sorted(tops & (above | {MODEL}))}"
    for module, tops in _modules(MODEL).items():
        ros = {t for t in tops if t.startswith("rcl") or t.endswith("_msgs") or t == TRANSPORT}
        assert not tops & above and not ros, f"{module} imports {sorted(tops & above | ros)}"


def test_nodes_import_the_transport():
    for package, nodes in NODES.items():
        for node in nodes:
            path = SRC / package / package / f"{node}.py"
            assert any(n.split(".")[0] == TRANSPORT for n in _imports(path, package)), f"{path.name}"
    for package in (SIM, PLANNER, CONTROLLER):
        names = {m.stem for m in (SRC / package / package).rglob("*.py")}
        assert not names & {"lockstep", "cdr", "node_stop"}, f"{package} holds a copy of the transport"


def test_robot_parameters_read_without_mujoco_or_ros():
    """The parameter table and the motor envelope import neither MuJoCo nor ROS (a planner or a tool
    reads them without the simulator's runtime)."""
    code = ("import sys; from cassie_model import motor_limits, robot_params; "
            "robot_params.robot(); motor_limits.MotorLimits.from_flywheel('I').bounds([0.0] * 11); "
            "print(sorted(m for m in ('mujoco', 'rclpy', 'pinocchio', 'cassie_flip_sim') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_scripts_import_no_test_module():
    tests = REPO / "tests"
    test_names = {p.stem for p in tests.rglob("*.py")} | {p.name for p in tests.rglob("*") if p.is_dir()} | {"tests"}
    roots = [REPO / "scripts", REPO / "tools"]
    files = sorted(f for r in roots for f in r.rglob("*.py")) + [REPO / "scripts" / "flip"]
    script_names = {p.stem for p in files} | {p.name for r in roots for p in r.rglob("*") if p.is_dir()}
    assert any(f.parts[-2] == "cli" for f in files)          # the flip package is looked at
    for f in files:
        tops = {n.split(".")[0] for n in _imports(f, "flip_tools")}
        bad = tops & (test_names - script_names)
        assert not bad, f"{f.relative_to(REPO)} imports the test module(s) {sorted(bad)}"
