"""ament_python package flip_transport: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv.

The lockstep's per-step messages on rcl's C API (flip_transport._rcl_io, native/rcl_io.cpp) are a
pybind11 extension on the headers and libraries of the ROS wheels in the venv (or of the ROS install
on AMENT_PREFIX_PATH).  Its compiled stepping loop calls a simulator's step through the C table of
native/stepper_api.h, installed with the package for the simulator's build (cassie_flip_sim)."""
import os
import sys
from pathlib import Path

from pybind11.setup_helpers import Pybind11Extension, build_ext
from setuptools import find_packages, setup

package_name = "flip_transport"


def ros_prefix() -> Path:
    """The prefix holding rcl's headers and library: the venv (ROS wheels) or a ROS install."""
    for p in [sys.prefix] + os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if p and (Path(p) / "include" / "rcl" / "rcl" / "rcl.h").is_file() and (Path(p) / "lib" / "librcl.so").is_file():
            return Path(p)
    raise RuntimeError("flip_transport: no rcl headers and library (include/rcl/rcl/rcl.h, lib/librcl.so) "
                       f"in {sys.prefix} or on AMENT_PREFIX_PATH")


def rcl_extension():
    p = ros_prefix()
    # Jazzy's layout: include/<package>/<package>/*.h
    inc = [str(d) for d in sorted((p / "include").iterdir())
           if d.is_dir() and (d / d.name).is_dir() and not d.name.startswith("python")]
    return Pybind11Extension(
        f"{package_name}._rcl_io",
        ["flip_transport/native/rcl_io.cpp"],
        depends=sorted(str(p) for p in Path("flip_transport/native").glob("*.h")),  # stepper_api.h and rcl_io.cpp's parts
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
    ],
    package_data={package_name: ["native/*.h"]},
    ext_modules=[rcl_extension()],
    cmdclass={"build_ext": build_ext},
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="somersault developers",
    maintainer_email="somersault@example.org",
    description="Lockstep message transport of the flip graph: serialized per-step messages, wait sets, rcl's C API.",
    license="BSD-3-Clause",
)
