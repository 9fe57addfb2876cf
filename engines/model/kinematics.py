"""Link frames of a :class:`ModelDescription` at a configuration, computed from what the file says.

Poses are (R, p): R (3, 3) the link frame's axes in the world, p (3,) m its
origin. q : (nq,) the joints' configuration in the description's moving-joint order (rad or m; a ball
joint's quaternion x y z w), the floating base's pose left out.
"""

from __future__ import annotations

import numpy as np

from engines.model.description import ModelDescription


def rpy_matrix(rpy) -> np.ndarray:
    """URDF's fixed-axis roll, pitch, yaw (rad) as a rotation matrix Rz(yaw) Ry(pitch) Rx(roll)."""
    r, p, y = rpy
    cr, sr, cp, sp, cy, sy = np.cos(r), np.sin(r), np.cos(p), np.sin(p), np.cos(y), np.sin(y)
    return np.array([
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ])


def matrix_rpy(r: np.ndarray) -> tuple[float, float, float]:
    """Fixed-axis roll, pitch, yaw (rad) of a rotation matrix, the inverse of :func:`rpy_matrix`."""
    pitch = float(np.arcsin(-np.clip(r[2, 0], -1.0, 1.0)))
    if abs(r[2, 0]) < 1 - 1e-12:
        return float(np.arctan2(r[2, 1], r[2, 2])), pitch, float(np.arctan2(r[1, 0], r[0, 0]))
    return float(np.arctan2(-r[1, 2], r[1, 1])), pitch, 0.0


def axis_rotation(axis, angle: float) -> np.ndarray:
    """Rotation by ``angle`` (rad) about the unit ``axis`` (Rodrigues)."""
    k = np.asarray(axis, dtype=float)
    cross = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + np.sin(angle) * cross + (1 - np.cos(angle)) * cross @ cross


def quaternion_rotation(quaternion_xyzw) -> np.ndarray:
    """(3, 3) rotation of a quaternion (x, y, z, w), normalised first."""
    x, y, z, w = np.asarray(quaternion_xyzw, dtype=float) / np.linalg.norm(quaternion_xyzw)
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def link_poses(model: ModelDescription, q=None) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """Link name -> (R, p) in the world at ``q`` (zeros when None); the root at the world's origin."""
    q = model.neutral()[model.nconfig - model.nq:] if q is None else np.asarray(q, dtype=float)
    start = model.nconfig - model.nq  # the slots count the base's seven entries, which q leaves out
    values = {name: q[where.start - start:where.stop - start] for name, (where, _) in model.slots.items()}
    poses = {model.root: (np.eye(3), np.zeros(3))}
    for joint in model.joints:  # depth-first: the parent's pose is known
        r_parent, p_parent = poses[joint.parent]
        r = r_parent @ rpy_matrix(joint.rpy)
        p = p_parent + r_parent @ np.asarray(joint.xyz, dtype=float)
        if joint.type in ("revolute", "continuous"):
            r = r @ axis_rotation(joint.axis, values[joint.name][0])
        elif joint.type == "prismatic":
            p = p + r @ (np.asarray(joint.axis, dtype=float) * values[joint.name][0])
        elif joint.type == "ball":
            r = r @ quaternion_rotation(values[joint.name])
        poses[joint.child] = (r, p)
    return poses
