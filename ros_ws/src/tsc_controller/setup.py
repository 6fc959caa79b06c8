"""ament_python package tsc_controller: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv.

The compiled tick (tsc_controller._native, native/tick.cpp) is a pybind11 extension on the Pinocchio,
Eigen and Boost headers of the pip wheels (pin, cmeel-eigen, cmeel-boost: the cmeel.prefix tree)."""
import importlib.util
import os
import sys
from glob import glob
from pathlib import Path

from pybind11.setup_helpers import ParallelCompile, Pybind11Extension, build_ext, naive_recompile
from setuptools import find_packages, setup

# cassie_model/native: motor_envelope.h, the torque-speed envelope of the QP bounds (the sibling source
# package: colcon and pip build from ros_ws/src)
ENVELOPE_DIR = Path(__file__).resolve().parent.parent / "cassie_model" / "cassie_model" / "native"
package_name = "tsc_controller"
# tick.cpp (Pinocchio) beside the small files; `python setup.py build_ext --inplace` here rebuilds only
# the files changed since its last build (its build/ tree; pip's builds start afresh)
ParallelCompile("TSC_NATIVE_BUILD_JOBS", default=2, needs_recompile=naive_recompile).install()


def cmeel_prefix() -> Path:
    """The cmeel.prefix tree that holds pinocchio's Python package (and its C++ headers, libraries)."""
    spec = importlib.util.find_spec("pinocchio")
    if spec is None or spec.origin is None:
        raise RuntimeError("tsc_controller: the pin wheel (pinocchio) must be installed to build the native tick")
    prefix = Path(spec.origin).resolve().parents[4]
    if not (prefix / "include" / "eigen3").is_dir():
        raise RuntimeError(f"tsc_controller: no Eigen headers in {prefix}/include (pip install cmeel-eigen)")
    return prefix


def native_extension():
    prefix = cmeel_prefix()
    lib = str(prefix / "lib")
    # -march=native with Eigen's alignment held at 16 bytes: the Model/Data layout and the heap
    # alignment Eigen assumes stay those of the pinocchio wheel (built for plain x86-64), see
    # Eigen's EIGEN_MAX_ALIGN_BYTES.  TSC_NATIVE_MARCH= (empty) builds for plain x86-64.
    march = os.environ.get("TSC_NATIVE_MARCH", "native")
    # -ffp-contract=off: no fused multiply-adds the numpy reference does not make (limits.py's bounds
    # are then equal bit for bit)
    flags = ["-O3", "-DNDEBUG", "-DEIGEN_MAX_ALIGN_BYTES=16", "-DEIGEN_MAX_STATIC_ALIGN_BYTES=16",
             "-ffp-contract=off", "-Wno-deprecated-declarations"]
    if march:
        flags.append(f"-march={march}")
    return Pybind11Extension(
        f"{package_name}._native",
        ["tsc_controller/native/tick.cpp", "tsc_controller/native/task.cpp",
         "tsc_controller/native/limits.cpp", "tsc_controller/native/state.cpp",
         "tsc_controller/native/ground.cpp"],
        include_dirs=[str(prefix / "include"), str(prefix / "include" / "eigen3"), str(ENVELOPE_DIR)],
        depends=[str(ENVELOPE_DIR / "motor_envelope.h")],
        # PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION: the algorithms the pin wheel's libpinocchio_default
        # instantiates (for double, Eigen::Ref arguments) are linked from it, not compiled again here
        define_macros=[("BOOST_MPL_LIMIT_LIST_SIZE", "30"), ("BOOST_MPL_LIMIT_VECTOR_SIZE", "30"),
                       ("BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", None), ("BOOST_FUSION_INVOKE_MAX_ARITY", "12"),
                       ("PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION", None)],
        library_dirs=[lib],
        libraries=[f"boost_python{sys.version_info.major}{sys.version_info.minor}", "pinocchio_default"],
        runtime_library_dirs=[lib],
        extra_compile_args=flags,
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
    description="Momentum-included task space control (torque-only QP) at 2 kHz.",
    license="BSD-3-Clause",
    entry_points={"console_scripts": ["tsc_node = tsc_controller.tsc_node:main"]},
)
