"""ament_python package tsc_controller: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv."""
from glob import glob

from setuptools import find_packages, setup

package_name = "tsc_controller"

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
    install_requires=["setuptools"],
    zip_safe=True,
    maintainer="somersault developers",
    maintainer_email="somersault@example.org",
    description="Momentum-included task space control (torque-only QP) at 2 kHz.",
    license="BSD-3-Clause",
    entry_points={"console_scripts": ["tsc_node = tsc_controller.tsc_node:main"]},
)
