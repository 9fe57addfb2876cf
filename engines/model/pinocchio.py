"""Pinocchio's import of a model file: the reference of the parity check.

Import options: ``buildModelFromXML`` (URDF) or ``buildModelFromMJCF``
(MJCF) with a fixed base (no root joint); links welded by fixed joints
are merged into their joint's body (Pinocchio keeps them as frames).
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
        if source.format == "urdf":
            model = pin.buildModelFromXML(text)
        else:
            model = pin.buildModelFromMJCF(str(source.path))
    except (RuntimeError, ValueError) as exc:
        raise Refused(" ".join(str(exc).split())) from None
    options = {"builder": "buildModelFromXML" if source.format == "urdf" else "buildModelFromMJCF",
               "root_joint": "none (fixed base)"}
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
        joints = list(model.names)[1:]
        self.joint_ids = [int(k) + 1 for k in index_map(description, joints)]
        if any(model.nvs[j] != 1 for j in range(1, model.njoints)):
            raise Refused("only 1-degree-of-freedom joints are compared")
        self.dof = np.array([model.idx_vs[j] for j in self.joint_ids])
        self.circle = [model.nqs[j] == 2 for j in self.joint_ids]  # continuous: (cos, sin)

    def configuration(self, q) -> np.ndarray:
        """The description's q (nq,) as Pinocchio's configuration (model.nq,)."""
        config = pin.neutral(self.model)
        for joint, angle, circle in zip(self.joint_ids, q, self.circle):
            start = self.model.idx_qs[joint]
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
        pin.forwardKinematics(self.model, self.data, self.configuration(np.zeros(len(self.dof))))
        found = {}
        for joint in range(1, self.model.njoints):
            # A joint's body is its child link with every link welded to it, in the joint frame.
            inertia, pose = self.model.inertias[joint], self.data.oMi[joint]
            link = self.description.joint(self.model.names[joint]).child
            found[link] = world_inertia(inertia.mass, inertia.lever, inertia.inertia, pose.rotation, pose.translation)
        return found
