"""The description of an MJCF file: what MuJoCo's compiler makes of it (MJCF is MuJoCo's own format).

MJCF's meaning depends on its compiler (defaults classes, angle units, inertias from geoms, frames as quat,
euler or axisangle), so the description is read from MuJoCo's compiled model of the self-contained text
(``ModelSource.engine_text``): each body a link, its one joint (hinge: revolute, or continuous when unlimited;
slide: prismatic; none: fixed). A link frame sits at its
joint's anchor (a hinge may pass through any point of its body). A body
with several joints (a planar root: slide x, slide z, hinge y) becomes a
chain: one massless link per joint but the last, named ``BODY/JOINT``
(marked ``virtual``), the body itself the child of its last joint; MuJoCo
applies a body's joints in that order, each in the frame the previous ones
moved. A free joint is the floating base (type "floating", from the world;
it has no anchor); a ball joint is a ball (its quaternion turns the link
about its anchor; MuJoCo's qpos w x y z, xval's x y z w).
"""

from __future__ import annotations

import numpy as np

from engines.model.description import Body, Inertial, Joint, Limits, ModelDescription, ModelError
from engines.model.kinematics import matrix_rpy
from engines.model.source import ModelSource

KINDS = {0: "floating", 1: "ball", 2: "prismatic", 3: "revolute"}  # mjJNT_FREE, _BALL, _SLIDE, _HINGE


def read(source: ModelSource) -> ModelDescription:
    from engines.mujoco.library import mujoco  # for cost: the library loads on first use

    text, _ = source.engine_text()
    try:
        m = mujoco.MjModel.from_xml_string(text)
    except ValueError as exc:
        raise ModelError(f"model {source.label}: MuJoCo cannot compile it ({' '.join(str(exc).split())}); fix the file") from None
    names = [m.body(k).name or f"body{k}" for k in range(m.nbody)]
    anchor = np.zeros((m.nbody, 3))  # each link frame's offset from its body frame (the joint's pos)
    bodies, joints = [Body(names[0], None)], []
    for k in range(1, m.nbody):
        count = int(m.body_jntnum[k])
        ids = list(range(m.body_jntadr[k], m.body_jntadr[k] + count))
        parent = m.body_parentid[k]
        rotation = _quat_matrix(m.body_quat[k])
        anchors = [np.asarray(m.jnt_pos[j], dtype=float) for j in ids] or [np.zeros(3)]
        anchor[k] = anchors[-1]
        # The first link frame: the body frame moved to the first joint's anchor; each next one the previous
        # anchor moved to its own (the joints share the body's axes, so no rotation between them).
        offsets = [m.body_pos[k] + rotation @ anchors[0] - anchor[parent]] + \
            [anchors[i] - anchors[i - 1] for i in range(1, len(anchors))]
        inertia_axes = _quat_matrix(m.body_iquat[k])
        inertial = Inertial(mass=float(m.body_mass[k]), com=tuple(m.body_ipos[k] - anchor[k]),
                            inertia=tuple(map(tuple, inertia_axes @ np.diag(m.body_inertia[k]) @ inertia_axes.T)),
                            rotated=not np.allclose(m.body_iquat[k], (1, 0, 0, 0)))
        if not ids:
            name = f"{names[parent]}_to_{names[k]}"
            joints.append(Joint(name, "fixed", names[parent], names[k], xyz=tuple(offsets[0]), rpy=matrix_rpy(rotation)))
            bodies.append(Body(names[k], name, inertial))
            continue
        links = [f"{names[k]}/{m.joint(j).name}" for j in ids[:-1]] + [names[k]]
        above = names[parent]
        for i, (joint_id, link) in enumerate(zip(ids, links)):
            hinge = m.jnt_type[joint_id] == 3
            limited = bool(m.jnt_limited[joint_id]) and m.jnt_type[joint_id] > 1  # a free or ball joint has no range
            kind = KINDS[int(m.jnt_type[joint_id])] if not hinge else ("revolute" if limited else "continuous")
            lo, hi = (float(x) for x in m.jnt_range[joint_id]) if limited else (None, None)
            name = m.joint(joint_id).name or f"{names[k]}_joint{i}"
            if kind == "floating":  # the configuration is the base's pose in the world (MuJoCo's qpos, Pinocchio's q)
                joints.append(Joint(name, kind, above, link))
            else:
                joints.append(Joint(name, kind, above, link, tuple(m.jnt_axis[joint_id]), tuple(offsets[i]),
                                    matrix_rpy(rotation) if i == 0 else (0.0, 0.0, 0.0), Limits(lo, hi),
                                    float(m.dof_damping[m.jnt_dofadr[joint_id]])))
            last = link == names[k]
            bodies.append(Body(link, name, inertial if last else Inertial(), virtual=not last))
            above = link
    return ModelDescription(name=m.names[:m.names.index(b"\0")].decode() or source.path.stem, source=source.label,
                            format="mjcf", root=names[0], bodies=tuple(bodies), joints=tuple(joints),
                            notes=("the description of an MJCF file is MuJoCo's compiled model",))


def _quat_matrix(quat) -> np.ndarray:
    from engines.mujoco.library import mujoco

    matrix = np.zeros(9)
    mujoco.mju_quat2Mat(matrix, np.asarray(quat, dtype=float))
    return matrix.reshape(3, 3)
