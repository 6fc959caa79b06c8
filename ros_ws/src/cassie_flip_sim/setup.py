"""ament_python package cassie_flip_sim: `colcon build` on a ROS 2 Jazzy install, or `pip install -e` into the venv."""
from glob import glob

from setuptools import find_packages, setup

package_name = "cassie_flip_sim"

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
    description="MuJoCo simulator of Cassie with a pelvis flywheel: deterministic 2 kHz lockstep node.",
    license="BSD-3-Clause",
    entry_points={"console_scripts": [
        "sim_node = cassie_flip_sim.sim_node:main",
        "echo_controller = cassie_flip_sim.echo_controller:main",
    ]},
)
