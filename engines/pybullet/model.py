"""PyBullet's import of a model file: ``loadURDF`` (or ``loadMJCF``) in a DIRECT client of its own.

Import options: useFixedBase = True, flags = URDF_USE_INERTIA_FROM_FILE
(otherwise PyBullet recomputes inertia from collision shapes), gravity
(0, 0, −9.81). Linear, angular and joint damping set to 0 and every joint
motor disabled. M is ``calculateMassMatrix``, the bias
``calculateInverseDynamics`` at zero acceleration. PyBullet has no
forward-dynamics call: the acceleration is measured from one step of
dt = 1e-3 (its multibody step is semi-implicit Euler, v₁ = v₀ + dt·a(q₀, v₀)).
Its prints (C-level stdout, stderr) are kept out of the caller's output.
"""

from __future__ import annotations

import contextlib
import os
import tempfile
import xml.etree.ElementTree as ET
from dataclasses import replace
from typing import Any, Iterator

import numpy as np

from engines.model.description import ModelDescription
from engines.model.inertia import world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.source import ModelSource
from engines.model.stepping import common_settings
from engines.pybullet.library import pb
from engines.pybullet.library import version as _pybullet_version
from engines.stdio import quiet_output

NAME = "pybullet"
#: The step that measures an acceleration (s).
STEP = 1e-3


def version() -> str:
    return _pybullet_version()


def load(source: ModelSource, description: ModelDescription) -> "PyBulletModel":
    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    with quiet_output():
        client = pb.connect(pb.DIRECT)
    try:
        with quiet_output():
            if source.format == "urdf":
                with _as_file(text) as path:
                    body = pb.loadURDF(path, useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE,
                                       physicsClientId=client)
            else:  # an MJCF file is loaded as it is (its includes resolve from its own folder)
                bodies = pb.loadMJCF(str(source.path), flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
                body = bodies[0] if len(bodies) == 1 else -1
        if body < 0:
            raise Refused("pybullet could not load the file (loadMJCF gave no single multibody)")
    except (pb.error, Refused) as exc:
        pb.disconnect(client)
        raise Refused(str(exc)) from None
    options = {"useFixedBase": "True", "flags": "URDF_USE_INERTIA_FROM_FILE"}
    return PyBulletModel(client, body, description, options, notes)


@contextlib.contextmanager
def _as_file(text: str) -> Iterator[str]:
    """loadURDF reads a file: the stripped text (no meshes left to resolve) in a temporary one, removed after."""
    handle, name = tempfile.mkstemp(suffix=".urdf", prefix="xval-model-")
    try:
        with os.fdopen(handle, "w") as stream:
            stream.write(text)
        yield name
    finally:
        os.unlink(name)


class PyBulletModel(LoadedModel):
    engine = NAME

    def __init__(self, client: int, body: int, description: ModelDescription, options, notes=()):
        super().__init__(description, options, (*notes, "linear, angular and joint damping set to 0; joint "
                                                "motors off; acceleration measured from one 1e-3 s step"))
        self.client, self.body = client, body
        kw = {"physicsClientId": client}
        pb.setGravity(0, 0, -GRAVITY, **kw)
        pb.setPhysicsEngineParameter(fixedTimeStep=STEP, numSubSteps=0, **kw)
        self.n_joints = pb.getNumJoints(body, **kw)
        infos = [pb.getJointInfo(body, k, **kw) for k in range(self.n_joints)]
        self.link_names = [info[12].decode() for info in infos]
        self.movable = [k for k, info in enumerate(infos) if info[2] != pb.JOINT_FIXED]
        names = [infos[k][1].decode() for k in self.movable]
        self.index = index_map(description, names)  # description order -> position among movable joints
        self.joints = [self.movable[k] for k in self.index]
        for link in range(-1, self.n_joints):
            pb.changeDynamics(body, link, linearDamping=0, angularDamping=0, jointDamping=0, **kw)
        pb.setJointMotorControlArray(body, self.movable, pb.VELOCITY_CONTROL, forces=[0.0] * len(self.movable), **kw)

    def _full(self, values) -> list[float]:
        full = np.zeros(len(self.movable))
        full[self.index] = values
        return full.tolist()

    def mass_matrix(self, q):
        full = np.array(pb.calculateMassMatrix(self.body, self._full(q), physicsClientId=self.client))
        return full[np.ix_(self.index, self.index)]

    def bias(self, q, v):
        zeros = [0.0] * len(self.movable)
        tau = pb.calculateInverseDynamics(self.body, self._full(q), self._full(v), zeros, physicsClientId=self.client)
        return np.array(tau)[self.index]

    def forward(self, q, v, tau):
        kw = {"physicsClientId": self.client}
        for joint, position, velocity in zip(self.joints, q, v):
            pb.resetJointState(self.body, joint, position, velocity, **kw)
        pb.setJointMotorControlArray(self.body, self.joints, pb.TORQUE_CONTROL, forces=list(tau), **kw)
        with quiet_output():
            pb.stepSimulation(**kw)
        after = np.array([state[1] for state in pb.getJointStates(self.body, self.joints, **kw)])
        return (after - np.asarray(v)) / STEP

    def link_inertias(self):
        kw = {"physicsClientId": self.client}
        for joint in self.joints:
            pb.resetJointState(self.body, joint, 0.0, 0.0, **kw)
        found = {}
        for link, name in enumerate(self.link_names):
            info = pb.getDynamicsInfo(self.body, link, **kw)
            state = pb.getLinkState(self.body, link, computeForwardKinematics=True, **kw)
            # state[0], state[1]: the inertial frame's world position and orientation; info[2]: its diagonal.
            rotation = np.array(pb.getMatrixFromQuaternion(state[1])).reshape(3, 3)
            found[name] = world_inertia(info[0], np.zeros(3), np.diag(info[2]), rotation, state[0])
        return found

    def __del__(self):
        try:
            pb.disconnect(self.client)
        except Exception:  # the interpreter is ending, or the client is gone
            pass


class PyBulletStepper:
    """PyBullet: the file's multibody (engines.pybullet.model), ``stepSimulation`` at fixedTimeStep dt."""

    def __init__(self, scene: Any, dt: float) -> None:
        self.pb, self.quiet = pb, quiet_output
        loaded = self.loaded = load(_without_limits(scene.source), scene.description)
        self.kw = {"physicsClientId": loaded.client}
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, **self.kw)
        for joint, position, velocity in zip(loaded.joints, scene.initial_q, scene.initial_v):
            pb.resetJointState(loaded.body, joint, float(position), float(velocity), **self.kw)
        self.settings = {**common_settings(scene, loaded), "fixedTimeStep": dt, "numSubSteps": 0,
                         "motors": "velocity motors disabled (force 0)",
                         "joint_limits": "off: every URDF <limit> given lower 1 > upper -1, so loadURDF makes no "
                                         "limit constraint (changeDynamics cannot remove one)"}

    def advance(self, steps: int) -> None:
        step = self.pb.stepSimulation
        with self.quiet():
            for _ in range(steps):
                step(**self.kw)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        states = self.pb.getJointStates(self.loaded.body, self.loaded.joints, **self.kw)
        return np.array([s[0] for s in states]), np.array([s[1] for s in states])


def _without_limits(source):
    """``source`` with every URDF ``<limit>``'s range emptied (lower 1 > upper -1): PyBullet then builds no
    joint-limit constraint, which it otherwise enforces whatever the caller asks (an MJCF is left as it is)."""
    if source.format != "urdf":
        return source
    root = ET.fromstring(source.text)
    for limit in root.iter("limit"):
        limit.set("lower", "1")
        limit.set("upper", "-1")
    return replace(source, text=ET.tostring(root, encoding="unicode"))
