"""Pinocchio's model of a file: the reference of the parity check and of model scenes.

A URDF is read by Pinocchio's own reader (``buildModelFromXML``, no geometry), with no root joint or a
``JointModelFreeFlyer`` for ``--base floating``; welded links merged into their joint's body; a URDF with
``spherical`` joints (which Pinocchio's reader, urdfdom, does not know) is built like an MJCF's. An MJCF's
reference is built joint by joint from the description, MuJoCo's compiled model
(engines/model/pinocchio_tree.py: MuJoCo's compiler says what its format means, and Pinocchio's
``buildModelFromMJCF`` ignores ``<default>`` geom masses). Pinocchio's algorithms are the independent
dynamics: M is ``crba`` (mirrored), the bias ``rnea(q, v, 0)``, the forward dynamics ``aba``; armature,
damping and friction 0, gravity (0, 0, −9.81). A URDF's continuous joint is Pinocchio's (cos θ, sin θ).
"""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from engines.model.description import ModelDescription
from engines.model.inertia import world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.pinocchio_tree import build
from engines.model.source import ModelSource

NAME = "pinocchio"


def version() -> str:
    return pin.__version__


def load(source: ModelSource, description: ModelDescription) -> "PinocchioModel":
    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    try:
        if source.format == "urdf" and description.balls:  # Pinocchio's URDF reader has no spherical joint
            model = build(description)
            notes = (*notes, BALL_NOTE)
        elif source.format == "urdf" and description.floating is not None:
            model = pin.buildModelFromXML(text, pin.JointModelFreeFlyer())
        elif source.format == "urdf":
            model = pin.buildModelFromXML(text)
        else:
            model = build(description)
            notes = (*notes, MJCF_NOTE)
    except (RuntimeError, ValueError) as exc:
        raise Refused(" ".join(str(exc).split())) from None
    builder = "buildModelFromXML" if source.format == "urdf" and not description.balls else \
        "joint by joint from the description" if source.format == "urdf" else "joint by joint from MuJoCo's compiled model"
    options = {"builder": builder,
               "root_joint": "none (fixed base)" if description.floating is None else "JointModelFreeFlyer"}
    return PinocchioModel(model, description, options, notes)


#: What the reference of an MJCF is, in the check's notes.
MJCF_NOTE = ("the reference's model of an MJCF is MuJoCo's compiled model (MJCF is MuJoCo's format; Pinocchio's "
             "own MJCF reader ignores <default> geom masses) built joint by joint; Pinocchio's crba, rnea and aba "
             "compute its dynamics")


#: What the reference of a URDF with spherical joints is, in the check's notes.
BALL_NOTE = ("the reference's model of a URDF with spherical joints is built joint by joint from xval's reading of "
             "the file (Pinocchio's URDF reader, urdfdom, has no spherical joint): JointModelSpherical for each")


class PinocchioModel(LoadedModel):
    engine = NAME

    def __init__(self, model, description: ModelDescription, options: dict[str, str], notes=()):
        model.armature[:] = 0.0
        model.damping[:] = 0.0
        model.friction[:] = 0.0
        model.gravity.linear = np.array([0.0, 0.0, -GRAVITY])
        super().__init__(description, options, (*notes, "armature, damping and friction set to 0"))
        self.model, self.data = model, model.createData()
        # Per moving joint: its Pinocchio joint (the description's slots say where xval keeps its entries).
        names, ids = [], []
        base: list[int] = []
        for joint in range(1, model.njoints):
            name = model.names[joint]
            kind = model.joints[joint].shortname()
            if kind == "JointModelFreeFlyer" and description.floating is not None:
                base = [int(model.idx_vs[joint]) + k for k in range(6)]
                self.base_q = int(model.idx_qs[joint])
                continue
            if int(model.nvs[joint]) != 1 and kind != "JointModelSpherical":
                raise Refused(f"only 1-degree-of-freedom and spherical joints are compared; pinocchio's {name} has "
                              f"{int(model.nvs[joint])}")
            names.append(name)
            ids.append(joint)
        self.joint_ids = [ids[k] for k in index_map(description, names)]
        if description.floating is not None and not base:
            raise Refused("pinocchio's model has no free-flyer joint for the floating base")
        for moving, chosen in zip(description.moving_joints, self.joint_ids):
            if int(model.nvs[chosen]) != moving.nv:
                raise Refused(f"pinocchio's joint {moving.name} has {int(model.nvs[chosen])} degrees of freedom; "
                              f"the file's has {moving.nv}")
        #: Pinocchio's velocity index of each of xval's (the base's six first, when floating).
        self.dof = np.array(base + [int(model.idx_vs[j]) + k for j in self.joint_ids for k in range(int(model.nvs[j]))],
                            dtype=int)
        # Where each joint's configuration sits; continuous: (cos, sin), two numbers for one angle; ball: the
        # same quaternion x y z w.
        self.qslot = [int(model.idx_qs[j]) for j in self.joint_ids]
        self.circle = [model.nqs[j] == 2 and model.nvs[j] == 1 for j in self.joint_ids]

    def configuration(self, q) -> np.ndarray:
        """xval's configuration (nconfig,) as Pinocchio's (model.nq,): the base's pose and each ball joint's
        quaternion as they are (the same convention, normalised), each continuous joint's angle as (cos, sin)."""
        config = pin.neutral(self.model)
        q = np.asarray(q, dtype=float)
        if self.description.floating is not None:
            config[self.base_q:self.base_q + 7] = np.concatenate([q[:3], q[3:7] / np.linalg.norm(q[3:7])])
        slots = self.description.slots
        for joint, start, circle in zip(self.description.moving_joints, self.qslot, self.circle):
            values = q[slots[joint.name][0]]
            if joint.type == "ball":
                config[start:start + 4] = values / np.linalg.norm(values)
            elif circle:
                config[start:start + 2] = np.cos(values[0]), np.sin(values[0])
            else:
                config[start] = values[0]
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
            # A joint's body is its child link with every link welded to it, in the joint frame (a virtual
            # link between two joints of one MJCF body is massless and no engine's: left out).
            if joint not in names:
                continue
            inertia, pose = self.model.inertias[joint], self.data.oMi[joint]
            link = self.description.joint(names[joint]).child
            if self.description.body(link).virtual:
                continue
            found[link] = world_inertia(inertia.mass, inertia.lever, inertia.inertia, pose.rotation, pose.translation)
        return found
