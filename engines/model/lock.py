"""Joints welded at their initial value (a suite's ``lock = ["JOINT", …]``, ``--lock JOINT``), in the text.

Every engine reads the file itself, so a lock is made in the text they all
load: a URDF joint becomes ``type="fixed"`` with its motion at the locked
value folded into its ``<origin>`` (a revolute joint's rotation about its
axis, a prismatic one's slide along it); an MJCF ``<joint>`` is removed with
every element that names it (actuators, tendons, equalities, sensors),
which welds its body where the joint's zero puts it (an MJCF lock is
refused at any other value: turning a body about a joint's anchor is
MuJoCo's compiler's business). ModelError for a name that is not a moving
joint.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET

import numpy as np

from engines.model.description import ModelError
from engines.model.kinematics import axis_rotation, matrix_rpy, rpy_matrix

#: MJCF attributes that name a joint (actuators, tendons, equalities, sensors).
JOINT_REFERENCES = ("joint", "joint1", "joint2", "jointinparent")


def lock_urdf(text: str, values: dict[str, float]) -> str:
    """The URDF ``text`` with each joint of ``values`` (name -> rad or m) fixed at that value."""
    robot = ET.fromstring(text)
    found = set()
    for joint in robot.iter("joint"):
        name = joint.get("name", "")
        if name not in values or joint.get("type") not in ("revolute", "continuous", "prismatic"):
            continue
        found.add(name)
        origin = joint.find("origin")
        if origin is None:
            origin = ET.SubElement(joint, "origin")
        xyz = np.array([float(x) for x in origin.get("xyz", "0 0 0").split()])
        rotation = rpy_matrix([float(x) for x in origin.get("rpy", "0 0 0").split()])
        axis_element = joint.find("axis")
        axis = np.array([float(x) for x in (axis_element.get("xyz", "1 0 0") if axis_element is not None
                                            else "1 0 0").split()])
        axis = axis / np.linalg.norm(axis)
        if joint.get("type") == "prismatic":
            xyz = xyz + rotation @ axis * values[name]
        else:
            rotation = rotation @ axis_rotation(axis, values[name])
        origin.set("xyz", " ".join(repr(float(x)) for x in xyz))
        origin.set("rpy", " ".join(repr(float(x)) for x in matrix_rpy(rotation)))
        joint.set("type", "fixed")
        for child in list(joint):
            if child.tag in ("axis", "limit", "dynamics", "mimic", "safety_controller", "calibration"):
                joint.remove(child)
    _require_found(values, found)
    return ET.tostring(robot, encoding="unicode")


def lock_mjcf(text: str, values: dict[str, float]) -> str:
    """The MJCF ``text`` (self-contained) with each joint of ``values`` removed, and what names it."""
    root = ET.fromstring(text)
    turned = [name for name, value in values.items() if value != 0.0]
    if turned:
        raise ModelError(f"lock: joint {turned[0]} of an MJCF is welded at 0 only; give it q0 = 0 or unlock it")
    found = set()
    for parent in root.iter():
        for child in list(parent):
            if child.tag == "joint" and child.get("name") in values and parent.tag == "body":
                found.add(child.get("name", ""))
                parent.remove(child)
            elif any(child.get(a) in values for a in JOINT_REFERENCES) and child.tag != "body":
                parent.remove(child)
    _require_found(values, found)
    return ET.tostring(root, encoding="unicode")


def _require_found(values: dict[str, float], found: set[str]) -> None:
    missing = [name for name in values if name not in found]
    if missing:
        raise ModelError(f"lock: {', '.join(missing)} is not a moving joint of the model; name a hinge, slide, "
                         f"revolute, continuous or prismatic joint")
