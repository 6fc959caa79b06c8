"""What a published robot description says about the robot, read without building it: the flywheel's
inertial (the part a design study changes) and the motors' torque limits (their actuators' ctrlrange)
from an MJCF string such as sim_node's ``/robot_description_mjcf``."""
from __future__ import annotations

import xml.etree.ElementTree as ET


def _root(mjcf: str):
    try:
        return ET.fromstring(mjcf)
    except ET.ParseError as e:
        raise ValueError(f"not an MJCF document: {e}") from None


def motor_torque_limits(mjcf: str) -> dict[str, float]:
    """{joint: torque limit} of the MJCF's ``<motor>`` actuators (gear 1: the upper end of ctrlrange)."""
    return {m.get("joint"): float(m.get("ctrlrange").split()[1])
            for m in _root(mjcf).iter("motor") if m.get("ctrlrange")}


def flywheel_inertial(mjcf: str) -> tuple[float, tuple[float, float, float]] | None:
    """(mass, diagonal inertia) of the body named ``flywheel`` in an MJCF string; None when it has
    none (a robot without a flywheel, or no ``<inertial>``).  ValueError for text that is not XML."""
    body = _root(mjcf).find(".//body[@name='flywheel']")
    inertial = body.find("inertial") if body is not None else None
    if inertial is None:
        return None
    diag = tuple(float(x) for x in inertial.get("diaginertia", "0 0 0").split())
    return float(inertial.get("mass", "0")), diag
