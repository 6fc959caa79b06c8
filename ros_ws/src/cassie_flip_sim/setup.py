"""ament_python package cassie_flip_sim: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv.

The simulator's per-step work (cassie_flip_sim._native, native/step.cpp) is a pybind11 extension on
the MuJoCo C API: the headers and library of the mujoco wheel.  sim_node's per-step messages
(cassie_flip_sim._rcl_io, native/rcl_io.cpp) are one on rcl's C API: the headers and libraries of
the ROS wheels in the venv (or of the ROS install on AMENT_PREFIX_PATH); its compiled stepping loop
calls the first through the C table of native/stepper_api.h (neither links the other's library)."""
import importlib.util
import os
import sys
from glob import glob
from pathlib import Path

from pybind11.setup_helpers import Pybind11Extension, build_ext
from setuptools import find_packages, setup

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


def native_extension():
    d = mujoco_dir()
    lib = sorted(d.glob("libmujoco.so.*"))[-1].name
    return Pybind11Extension(
        f"{package_name}._native",
        ["cassie_flip_sim/native/step.cpp"],
        depends=["cassie_flip_sim/native/stepper_api.h"],
        include_dirs=[str(d / "include")],
        library_dirs=[str(d)],
        # the library the mujoco module itself loads (same soname, one copy in the process)
        extra_link_args=[f"-l:{lib}", f"-Wl,-rpath,{d}"],
        # -ffp-contract=off: no fused multiply-adds the numpy reference does not make (bit-equal steps)
        extra_compile_args=["-O2", "-ffp-contract=off"],
        cxx_std=17,
    )


def ros_prefix() -> Path:
    """The prefix holding rcl's headers and library: the venv (ROS wheels) or a ROS install."""
    for p in [sys.prefix] + os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if p and (Path(p) / "include" / "rcl" / "rcl" / "rcl.h").is_file() and (Path(p) / "lib" / "librcl.so").is_file():
            return Path(p)
    raise RuntimeError("cassie_flip_sim: no rcl headers and library (include/rcl/rcl/rcl.h, lib/librcl.so) "
                       f"in {sys.prefix} or on AMENT_PREFIX_PATH")


def rcl_extension():
    p = ros_prefix()
    # Jazzy's layout: include/<package>/<package>/*.h
    inc = [str(d) for d in sorted((p / "include").iterdir())
           if d.is_dir() and (d / d.name).is_dir() and not d.name.startswith("python")]
    return Pybind11Extension(
        f"{package_name}._rcl_io",
        ["cassie_flip_sim/native/rcl_io.cpp"],
        depends=["cassie_flip_sim/native/stepper_api.h"],
        include_dirs=inc,
        library_dirs=[str(p / "lib")],
        libraries=["rcl", "rmw", "rcutils"],
        extra_link_args=[f"-Wl,-rpath,{p / 'lib'}"],
        extra_compile_args=["-O2"],
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
    ext_modules=[native_extension(), rcl_extension()],
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
