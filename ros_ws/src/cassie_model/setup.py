"""ament_python package cassie_model: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv.

Plain Python, no ROS: the robot's parameters, its motor envelope and the MJCF / URDF builders that
the simulator, the planner and the controller all read."""
from setuptools import find_packages, setup

package_name = "cassie_model"

setup(
    name=package_name,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={package_name: ["native/*.h"]},      # motor_envelope.h: the simulator's and controller's builds include it
    data_files=[
        ("share/ament_index/resource_index/packages", ["resource/" + package_name]),
        ("share/" + package_name, ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="somersault developers",
    maintainer_email="somersault@example.org",
    description="Cassie with a pelvis flywheel: parameter table, flywheels, motor torque-speed envelope, MJCF and URDF builders.",
    license="BSD-3-Clause",
)
