"""A Pinocchio model built joint by joint from a :class:`ModelDescription` (the reference of an MJCF or ball joints).

The description of an MJCF is MuJoCo's compiled model (engines/mujoco/description.py); Pinocchio's own MJCF
reader disagrees with it on real files (it ignores ``<default><geom mass=…>``: a dm_control-style
acrobot's arms weigh 8.38 kg, the capsules' volume × 1000, where MuJoCo's compiler says 1 kg). Each
moving joint is a 1-degree-of-freedom Pinocchio joint of its name (``JointModelRevoluteUnaligned`` for
revolute and continuous, ``JointModelPrismaticUnaligned``) at the joint's origin in its parent joint's
frame; a ball joint a ``JointModelSpherical`` there (q the quaternion x y z w, v the angular velocity in
the child's frame: xval's convention); a floating base is a ``JointModelFreeFlyer`` at the world's origin; a fixed joint's child is
appended to the body of the joint above it, as Pinocchio's readers do. Every link is a BODY frame.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engines.model.description import ModelDescription
from engines.model.kinematics import rpy_matrix

#: Pinocchio joint model per description joint type (the axis in the joint frame).
_MODELS = {"revolute": pin.JointModelRevoluteUnaligned, "continuous": pin.JointModelRevoluteUnaligned,
           "prismatic": pin.JointModelPrismaticUnaligned}


def build(description: ModelDescription) -> pin.Model:
    """The Pinocchio model of ``description`` (gravity and armature left at Pinocchio's defaults)."""
    model = pin.Model()
    model.name = description.name
    # Link name -> (the Pinocchio joint that carries it, the link frame in that joint's frame, its frame id).
    carried: dict[str, tuple[int, pin.SE3, int]] = {description.root: (0, pin.SE3.Identity(), 0)}
    for joint in description.joints:  # depth-first: the parent is placed before its children
        parent, above, previous = carried[joint.parent]
        origin = above * pin.SE3(rpy_matrix(joint.rpy), np.asarray(joint.xyz, dtype=float))
        inertial = description.body(joint.child).inertial
        inertia = pin.Inertia(inertial.mass, np.asarray(inertial.com, dtype=float), inertial.inertia_matrix)
        if joint.type == "fixed":
            model.appendBodyToJoint(parent, inertia, origin)
            frame = model.addBodyFrame(joint.child, parent, origin, previous)
            carried[joint.child] = (parent, origin, frame)
            continue
        if joint.type == "floating":
            kind = pin.JointModelFreeFlyer()
            origin = pin.SE3.Identity()  # the configuration is the base's pose in the world
        elif joint.type == "ball":
            kind = pin.JointModelSpherical()
        else:
            kind = _MODELS[joint.type](np.asarray(joint.axis, dtype=float))
        index = model.addJoint(parent, kind, origin, joint.name)
        model.appendBodyToJoint(index, inertia, pin.SE3.Identity())
        joint_frame = model.addJointFrame(index, previous)
        frame = model.addBodyFrame(joint.child, index, pin.SE3.Identity(), joint_frame)
        carried[joint.child] = (index, pin.SE3.Identity(), frame)
    return model
