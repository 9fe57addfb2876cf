"""ours on rigid bodies: Baraff's constrained dynamics in maximal coordinates (a library of its own).

Describe a :class:`Mechanism` of :class:`Body` and :class:`Joint` records (revolute, prismatic,
fixed, ball), build a state with :func:`initial_state` and :func:`simulate` it. Each body carries
its COM position, a unit quaternion, its COM velocity and its world angular velocity; joints are
constraint rows, and the solve eliminates along the tree in O(n). The compiled kernel
(``ours.rigid.kernel``, numba) is imported on the first run, not here.
"""

from ours.rigid.method import INTEGRATORS, METHODS, valid_pairs
from ours.rigid.model import DOFS, ROWS, Body, Joint, Mechanism
from ours.rigid.simulate import (
    RigidResult, angular_momentum, ball_coordinates, energy, frames, initial_state, joint_coordinates, joint_errors, pack, quaternion,
    rotation, rotation_of, simulate, Stepping, workspace,
)

__all__ = [
    "DOFS", "INTEGRATORS", "METHODS", "ROWS", "Body", "Joint", "Mechanism", "RigidResult", "angular_momentum",
    "ball_coordinates",
    "energy", "frames", "initial_state", "joint_coordinates", "joint_errors", "pack", "quaternion", "rotation",
    "rotation_of", "simulate", "Stepping", "valid_pairs", "workspace",
]
