"""Pinocchio's import of a model file: the reference of the parity check.

Import options: ``buildModelFromXML`` (URDF) or ``buildModelFromMJCF``
(MJCF, read from the self-contained text in a temporary file) with a fixed
base (no root joint), or a ``JointModelFreeFlyer`` root joint for a URDF read
with a floating base (an MJCF free joint is one already); links welded by fixed joints are merged into their
joint's body (Pinocchio keeps them as frames). Several joints in one MJCF
body are one composite joint (``Composite_<first>``) whose degrees of
freedom are the body's joints in file order: each is matched by name to the
description's chain.
Armature, damping and friction set to 0; gravity (0, 0, −9.81). M is
``crba`` (upper triangle, mirrored), the bias ``rnea(q, v, 0)``, the forward
dynamics ``aba``. A continuous joint is Pinocchio's (cos θ, sin θ): the
description's angle is converted on the way in.
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engines.model.description import ModelDescription
from engines.model.inertia import world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.source import ModelSource

NAME = "pinocchio"


def version() -> str:
    return pin.__version__


def load(source: ModelSource, description: ModelDescription) -> "PinocchioModel":
    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    try:
        if source.format == "urdf" and description.floating is not None:
            model = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
        elif source.format == "urdf":
            model = pin.buildModelFromXML(text)
        else:
            with source.engine_file() as path:
                model = pin.buildModelFromMJCF(path)
    except (RuntimeError, ValueError) as exc:
        raise Refused(" ".join(str(exc).split())) from None
    options = {"builder": "buildModelFromXML" if source.format == "urdf" else "buildModelFromMJCF",
               "root_joint": "none (fixed base)" if description.floating is None else "JointModelFreeFlyer"}
    return PinocchioModel(model, description, options, notes)


class PinocchioModel(LoadedModel):
    engine = NAME

    def __init__(self, model, description: ModelDescription, options: dict[str, str], notes=()):
        model.armature[:] = 0.0
        model.damping[:] = 0.0
        model.friction[:] = 0.0
        model.gravity.linear = np.array([0.0, 0.0, -GRAVITY])
        super().__init__(description, options, (*notes, "armature, damping and friction set to 0"))
        self.model, self.data = model, model.createData()
        # One entry per degree of freedom: (its name, Pinocchio joint, index within it).
        order = [j.name for j in description.moving_joints]
        names, slots = [], []
        base: list[int] = []
        for joint in range(1, model.njoints):
            name = model.names[joint]
            count = int(model.nvs[joint])
            if model.joints[joint].shortname() == "JointModelFreeFlyer" and description.floating is not None:
                base = [int(model.idx_vs[joint]) + k for k in range(6)]
                self.base_q = int(model.idx_qs[joint])
                continue
            if count > 1 and name.startswith("Composite_") and name[len("Composite_"):] in order:
                start = order.index(name[len("Composite_"):])
                parts = order[start:start + count]
            elif count == 1:
                parts = [name]
            else:
                raise Refused(f"only 1-degree-of-freedom joints are compared; pinocchio's {name} has {count}")
            names += parts
            slots += [(joint, k) for k in range(len(parts))]
        chosen = [slots[k] for k in index_map(description, names)]
        self.joint_ids = [joint for joint, _ in chosen]
        if description.floating is not None and not base:
            raise Refused("pinocchio's model has no free-flyer joint for the floating base")
        #: Pinocchio's velocity index of each of xval's (the base's six first, when floating).
        self.dof = np.array(base + [model.idx_vs[joint] + k for joint, k in chosen], dtype=int)
        # Where each coordinate sits in the configuration; continuous: (cos, sin), two numbers for one angle.
        self.qslot = [model.idx_qs[joint] + k for joint, k in chosen]
        self.circle = [model.nqs[joint] == 2 and model.nvs[joint] == 1 for joint, _ in chosen]

    def configuration(self, q) -> np.ndarray:
        """xval's configuration (nconfig,) as Pinocchio's (model.nq,): the base's pose as it is (the same
        convention), each continuous joint's angle as (cos, sin)."""
        config = pin.neutral(self.model)
        q = np.asarray(q, dtype=float)
        if self.description.floating is not None:
            config[self.base_q:self.base_q + 7] = np.concatenate([q[:3], q[3:7] / np.linalg.norm(q[3:7])])
            q = q[7:]
        for start, angle, circle in zip(self.qslot, q, self.circle):
            if circle:
                config[start:start + 2] = np.cos(angle), np.sin(angle)
            else:
                config[start] = angle
        return config

    def _vector(self, values) -> np.ndarray:
        full = np.zeros(self.model.nv)
        full[self.dof] = values
        return full

    def mass_matrix(self, q):
        upper = pin.crba(self.model, self.data, self.configuration(q))
        full = np.triu(upper) + np.triu(upper, 1).T
        return full[np.ix_(self.dof, self.dof)]

    def bias(self, q, v):
        return pin.rnea(self.model, self.data, self.configuration(q), self._vector(v), np.zeros(self.model.nv))[self.dof]

    def forward(self, q, v, tau):
        return pin.aba(self.model, self.data, self.configuration(q), self._vector(v), self._vector(tau))[self.dof].copy()

    def link_inertias(self):
        pin.forwardKinematics(self.model, self.data, self.configuration(self.description.neutral()))
        found = {}
        names = {joint: name for joint, name in zip(self.joint_ids, (j.name for j in self.description.moving_joints))}
        if self.description.floating is not None:
            names[next(j for j in range(1, self.model.njoints) if self.model.idx_vs[j] == self.dof[0])] = \
                self.description.floating.name
        for joint in range(1, self.model.njoints):
            # A joint's body is its child link with every link welded to it, in the joint frame (a composite
            # joint's body is the child of its last part).
            if joint not in names:
                continue
            inertia, pose = self.model.inertias[joint], self.data.oMi[joint]
            link = self.description.joint(names[joint]).child
            found[link] = world_inertia(inertia.mass, inertia.lever, inertia.inertia, pose.rotation, pose.translation)
        return found
