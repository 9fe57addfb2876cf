"""The description of an MJCF file: what MuJoCo's compiler makes of it (MJCF is MuJoCo's own format).

MJCF's meaning depends on its compiler: defaults classes, angle units,
inertias from geoms (``inertiafromgeom``), frames given as quat, euler or
axisangle. Rather than re-implement those rules, the description of an MJCF
file is read from MuJoCo's compiled model (``MjModel.from_xml_path``, as
written): each body a link, its one joint (hinge: revolute, or continuous
when unlimited; slide: prismatic; none: fixed). A link frame sits at its
joint's anchor (a hinge may pass through any point of its body). Refused:
ball and free joints, and several joints in one body.
"""

from __future__ import annotations

import numpy as np

from engines.model.description import Body, Inertial, Joint, Limits, ModelDescription, ModelError
from engines.model.source import ModelSource

KINDS = {2: "prismatic", 3: "revolute"}  # mjJNT_SLIDE, mjJNT_HINGE


def read(source: ModelSource) -> ModelDescription:
    from engines.mujoco.library import mujoco

    try:
        m = mujoco.MjModel.from_xml_path(str(source.path))
    except ValueError as exc:
        raise ModelError(f"model {source.label}: MuJoCo cannot compile it ({' '.join(str(exc).split())}); fix the file") from None
    names = [m.body(k).name or f"body{k}" for k in range(m.nbody)]
    anchor = np.zeros((m.nbody, 3))  # each link frame's offset from its body frame (the joint's pos)
    bodies, joints = [Body(names[0], None)], []
    for k in range(1, m.nbody):
        count = m.body_jntnum[k]
        if count > 1:
            raise ModelError(f"body {names[k]}: {count} joints in one body are not supported; "
                             f"give each joint a body of its own")
        joint_id = m.body_jntadr[k] if count else -1
        if joint_id >= 0 and m.jnt_type[joint_id] not in KINDS:
            kind = {0: "free", 1: "ball"}.get(int(m.jnt_type[joint_id]), str(m.jnt_type[joint_id]))
            fix = "the base is welded to the world; remove the freejoint" if kind == "free" else \
                "use hinge or slide joints"
            raise ModelError(f"joint {m.joint(joint_id).name or names[k]}: type {kind!r} is not supported; {fix}")
        if joint_id >= 0:
            anchor[k] = m.jnt_pos[joint_id]
        parent = m.body_parentid[k]
        rotation = _quat_matrix(m.body_quat[k])
        xyz = m.body_pos[k] + rotation @ anchor[k] - anchor[parent]
        inertia_axes = _quat_matrix(m.body_iquat[k])
        inertial = Inertial(mass=float(m.body_mass[k]), com=tuple(m.body_ipos[k] - anchor[k]),
                            inertia=tuple(map(tuple, inertia_axes @ np.diag(m.body_inertia[k]) @ inertia_axes.T)),
                            rotated=not np.allclose(m.body_iquat[k], (1, 0, 0, 0)))
        name = m.joint(joint_id).name if joint_id >= 0 else f"{names[parent]}_to_{names[k]}"
        if joint_id >= 0:
            hinge = m.jnt_type[joint_id] == 3
            limited = bool(m.jnt_limited[joint_id])
            kind = "prismatic" if not hinge else ("revolute" if limited else "continuous")
            lo, hi = (float(x) for x in m.jnt_range[joint_id]) if limited else (None, None)
            joint = Joint(name, kind, names[parent], names[k], tuple(m.jnt_axis[joint_id]), tuple(xyz),
                          _rpy(rotation), Limits(lo, hi), float(m.dof_damping[m.jnt_dofadr[joint_id]]))
        else:
            joint = Joint(name, "fixed", names[parent], names[k], xyz=tuple(xyz), rpy=_rpy(rotation))
        bodies.append(Body(names[k], name, inertial))
        joints.append(joint)
    return ModelDescription(name=m.names[:m.names.index(b"\0")].decode() or source.path.stem, source=source.label,
                            format="mjcf", root=names[0], bodies=tuple(bodies), joints=tuple(joints),
                            notes=("the description of an MJCF file is MuJoCo's compiled model",))


def _quat_matrix(quat) -> np.ndarray:
    from engines.mujoco.library import mujoco

    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quat, dtype=float))
    return matrix.reshape(3, 3)


def _rpy(r: np.ndarray) -> tuple[float, float, float]:
    """Fixed-axis roll, pitch, yaw of a rotation matrix (R = Rz Ry Rx)."""
    pitch = float(np.arcsin(-np.clip(r[2, 0], -1.0, 1.0)))
    if abs(r[2, 0]) < 1 - 1e-12:
        return float(np.arctan2(r[2, 1], r[2, 2])), pitch, float(np.arctan2(r[1, 0], r[0, 0]))
    return float(np.arctan2(-r[1, 2], r[1, 1])), pitch, 0.0
