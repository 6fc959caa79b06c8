"""ament_python package cassie_flip_sim: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv.

The simulator's per-step work (cassie_flip_sim._native, native/step.cpp) is a pybind11 extension on
the MuJoCo C API: the headers and library of the mujoco wheel.  sim_node's per-step messages are
flip_transport's (flip_transport._rcl_io, on rcl's C API); its compiled stepping loop calls the step
through the C table of flip_transport's native/stepper_api.h, so flip_transport is installed first
(neither links the other's library)."""
import importlib.util
from glob import glob
from pathlib import Path

from pybind11.setup_helpers import Pybind11Extension, build_ext
from setuptools import find_packages, setup

# cassie_model/native: motor_envelope.h, the torque-speed envelope the step clips to (the sibling source
# package: colcon and pip build from ros_ws/src)
ENVELOPE_DIR = Path(__file__).resolve().parent.parent / "cassie_model" / "cassie_model" / "native"
package_name = "cassie_flip_sim"


def mujoco_dir() -> Path:
    """The mujoco wheel's package directory: include/mujoco/*.h and libmujoco.so.*."""
    spec = importlib.util.find_spec("mujoco")
    if spec is None or spec.origin is None:
        raise RuntimeError("cassie_flip_sim: the mujoco wheel must be installed to build the native step")
    d = Path(spec.origin).parent
    libs = sorted(d.glob("libmujoco.so.*"))
    if not (d / "include" / "mujoco" / "mujoco.h").is_file() or not libs:
        raise RuntimeError(f"cassie_flip_sim: no MuJoCo headers or library in {d}")
    return d


def stepper_api_dir() -> Path:
    """flip_transport's native/ directory: stepper_api.h, the C table its stepping loop calls."""
    spec = importlib.util.find_spec("flip_transport")
    if spec is None or not spec.submodule_search_locations:
        raise RuntimeError("cassie_flip_sim: flip_transport must be installed to build the native step")
    d = Path(list(spec.submodule_search_locations)[0]) / "native"
    if not (d / "stepper_api.h").is_file():
        raise RuntimeError(f"cassie_flip_sim: no stepper_api.h in {d}")
    return d


def native_extension():
    d = mujoco_dir()
    api = stepper_api_dir()
    lib = sorted(d.glob("libmujoco.so.*"))[-1].name
    return Pybind11Extension(
        f"{package_name}._native",
        ["cassie_flip_sim/native/step.cpp"],
        depends=[str(api / "stepper_api.h"), str(ENVELOPE_DIR / "motor_envelope.h")],
        include_dirs=[str(d / "include"), str(api), str(ENVELOPE_DIR)],
        library_dirs=[str(d)],
        # the library the mujoco module itself loads (same soname, one copy in the process)
        extra_link_args=[f"-l:{lib}", f"-Wl,-rpath,{d}"],
        # -ffp-contract=off: no fused multiply-adds the numpy reference does not make (bit-equal steps)
        extra_compile_args=["-O2", "-ffp-contract=off"],
        cxx_std=17,
    )


setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
        ("share/" + package_name + "/config", glob("config/*.yaml")),
    ],
    package_data={package_name: ["data/*.json"]},
    ext_modules=[native_extension()],
    cmdclass={"build_ext": build_ext},
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="somersault developers",
    maintainer_email="somersault@example.org",
    description="MuJoCo simulator of Cassie with a pelvis flywheel: deterministic 2 kHz lockstep node.",
    license="BSD-3-Clause",
    entry_points={"console_scripts": [
        "sim_node = cassie_flip_sim.sim_node:main",
        "state_publisher = cassie_flip_sim.state_publisher:main",
        "echo_controller = cassie_flip_sim.echo_controller:main",
    ]},
)
