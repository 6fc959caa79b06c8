"""ament_python package fslip_planner: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv."""
from glob import glob

from setuptools import find_packages, setup

package_name = "fslip_planner"

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
    description="Flywheel-SLIP planner: regression, jumping and landing trajectory optimisation, momentum-transmission flight plan.",
    license="BSD-3-Clause",
    entry_points={"console_scripts": ["planner_node = fslip_planner.planner_node:main"]},
)
