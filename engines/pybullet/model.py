"""PyBullet's import of a model file: ``loadURDF`` (or ``loadMJCF``) in a DIRECT client of its own.

Import options: useFixedBase (True unless the base floats), flags =
URDF_USE_INERTIA_FROM_FILE (else it recomputes inertia from collision
shapes), gravity (0, 0, −9.81), joint limits off (as in simulate). Linear,
angular and joint damping 0, every joint motor disabled. M is
``calculateMassMatrix``, the bias ``calculateInverseDynamics`` at zero
acceleration, the acceleration measured from one step of dt = 1e-3 (its
multibody step is semi-implicit Euler) on a fixed base, else M⁻¹(τ − b).
MJCF: of the bodies ``loadMJCF`` returns (one per static geom besides the
multibody) the one with joints; a root it floats though MuJoCo welds it is
welded back (:class:`PyBulletModel`); its links summed into the file's bodies for the diagnosis. Floating
base: engines/model/floating.py and :class:`PyBulletModel`; ball joints (``spherical``): :class:`BallJoints`.
Its prints (C-level stdout, stderr) are kept out of the caller's output.
"""

from __future__ import annotations

import xml.etree.ElementTree as ET
from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from engines.model.description import ModelDescription
from engines.model.floating import continuous, rotation, skew
from engines.model.inertia import LinkInertia, combine, world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.source import ModelSource
from engines.model.stepping import common_settings, Stepper
from engines.pybullet.library import pb
from engines.pybullet.library import version as _pybullet_version
from engines.stdio import quiet_output
from engines.model.scene import ModelScene

NAME = "pybullet"
#: The step that measures an acceleration (s).
STEP = 1e-3


def version() -> str:
    return _pybullet_version()


def load(source: ModelSource, description: ModelDescription) -> "PyBulletModel":
    if description.balls and source.format != "urdf":
        raise Refused("loadMJCF makes no joint of an MJCF ball joint (measured: a ball at the root leaves "
                      "one body without joints); ball joints are compared from a URDF's spherical joints")
    source = _without_limits(source)
    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    if source.format == "urdf":
        notes = (*notes, "joint limits off: every <limit> given lower 1 > upper -1, PyBullet's 'no limit' "
                         "(a range such as lower = upper = 0 would lock the joint)")
    with quiet_output():
        client = pb.connect(pb.DIRECT)
    try:
        with quiet_output():
            with source.engine_file(drop_mimic=description.mimic_independent) as path:
                if source.format == "urdf":
                    body = pb.loadURDF(path, useFixedBase=description.floating is None,
                                       flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
                else:
                    body = _multibody(pb.loadMJCF(path, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client),
                                      client)
    except (pb.error, Refused) as exc:
        pb.disconnect(client)
        raise Refused(str(exc)) from None
    options = {"useFixedBase": str(description.floating is None), "flags": "URDF_USE_INERTIA_FROM_FILE"}
    return PyBulletModel(client, body, description, options, notes)


def _multibody(bodies, client: int) -> int:
    """The one body of ``loadMJCF``'s answer that has joints (the others are static geoms); Refused otherwise."""
    jointed = [b for b in bodies if pb.getNumJoints(b, physicsClientId=client) > 0]
    if len(jointed) != 1:
        raise Refused(f"pybullet could not load the file: loadMJCF gave {len(bodies)} bodies, "
                      f"{len(jointed)} of them with joints (one multibody expected)")
    return jointed[0]


class PyBulletModel(LoadedModel):
    """PyBullet's multibody. A root that ``loadMJCF`` floats though the description welds it: M is the joints'
    block of its (6 + n)² matrix, the bias the joints' rows of its inverse dynamics at the base's pose with the
    base at rest, the acceleration M⁻¹(τ − b) (a step would let the base fall). A floating base: mapped to xval's
    convention with T (its base velocity: angular then linear of the base's inertial frame, in its axes)."""

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
        size = len(pb.calculateMassMatrix(body, [0.0] * len(self.movable), **kw))
        #: 6 when PyBullet's base is floating (a floating base, or an MJCF root PyBullet floats), else 0.
        self.base = size - sum(3 if infos[k][2] == pb.JOINT_SPHERICAL else 1 for k in self.movable)
        #: The ball joints' mapping (None without ball joints).
        self.balls = BallJoints(self) if description.balls else None
        self.floating = description.floating is not None
        if self.floating and not self.base:
            raise Refused("pybullet's body has a fixed base for the floating base")
        if self.base and not self.floating:
            self.notes = (*self.notes, "loadMJCF gave the root a floating base: M, bias and acceleration are "
                          "the fixed-base ones (joints' block and rows, base at rest)")
        if not self.base and not np.allclose(pb.getBasePositionAndOrientation(body, **kw)[1], (0, 0, 0, 1)):
            self.notes = (*self.notes, "the fixed base's inertial frame is turned: calculateInverseDynamics is "
                          "handed gravity in that frame's axes (it reads it there)")
        if self.floating:
            self.notes = (*self.notes, "floating base: acceleration M⁻¹(τ − b) from PyBullet's own M and bias; "
                          "calculateInverseDynamics given the base quaternion it reads as the pose (it takes "
                          "extrinsic x-y-z angles as intrinsic X-Y-Z)")
        #: PyBullet's velocity index of each of xval's (its base's six first).
        self.selected = np.concatenate([np.arange(6 if self.floating else 0), self.base + self.index]).astype(int)
        # PyBullet's base frame is the base link's inertial frame P (offset c, rotation Rc from the link frame B);
        # its base velocity (angular, linear of P's origin), both in P's axes (measured, tests/test_floating_base.py).
        info = pb.getDynamicsInfo(body, -1, **kw)
        self.offset = np.array(info[3])
        self.turn = np.array(pb.getMatrixFromQuaternion(info[4])).reshape(3, 3)
        self.T = np.eye(len(self.selected))
        if self.floating:
            a = self.turn.T
            self.T[:6, :6] = np.block([[np.zeros((3, 3)), a], [a, -a @ skew(self.offset)]])

    def _full(self, values) -> list[float]:
        full = np.zeros(len(self.movable))
        full[self.index] = values
        return full.tolist()

    def _joints_of(self, q) -> np.ndarray:
        return np.asarray(q, dtype=float)[7:] if self.floating else np.asarray(q, dtype=float)

    def _pose(self, q) -> list[float]:
        """PyBullet's base pose (P's position, quaternion x y z w) for xval's configuration q."""
        if not self.floating:
            position, orientation = pb.getBasePositionAndOrientation(self.body, physicsClientId=self.client)
            return [*position, *orientation]
        r = rotation(q[3:7])
        return [*(np.asarray(q[:3]) + r @ self.offset), *Rotation.from_matrix(r @ self.turn).as_quat()]

    def _engine_mass(self, q) -> np.ndarray:
        full = np.array(pb.calculateMassMatrix(self.body, self._full(self._joints_of(q)), physicsClientId=self.client))
        return full[np.ix_(self.selected, self.selected)]

    def mass_matrix(self, q):
        if self.balls is not None:
            return self.balls.mass_matrix(q)
        return self.T.T @ self._engine_mass(q) @ self.T

    def bias(self, q, v):
        if self.balls is not None:
            return self.balls.bias(q, v)
        size = self.base + len(self.movable)
        joints = self._full(self._joints_of(q))
        if not self.base:
            # A fixed base's calculateInverseDynamics reads gravity in the axes of the base's inertial frame P
            # (measured on tests/fixtures/urdf/quadruped.urdf, whose P is turned: its gravity torques 28 % off,
            # its stepping right): hand it gravity in P's axes, then restore the world's.
            kw = {"physicsClientId": self.client}
            turn = np.array(pb.getMatrixFromQuaternion(pb.getBasePositionAndOrientation(self.body, **kw)[1]))
            pb.setGravity(*(turn.reshape(3, 3).T @ np.array([0.0, 0.0, -GRAVITY])), **kw)
            try:
                tau = np.array(pb.calculateInverseDynamics(self.body, joints, self._full(v), [0.0] * size, **kw))
            finally:
                pb.setGravity(0.0, 0.0, -GRAVITY, **kw)
            return tau[self.index]
        velocity = np.zeros(size)
        rates = self.T @ np.asarray(v, dtype=float)
        velocity[self.selected] = rates
        pose = self._pose(q)
        # calculateInverseDynamics reads the base quaternion's extrinsic x-y-z angles as intrinsic X-Y-Z ones
        # (measured: gravity lands in the wrong base axes otherwise): hand it the quaternion it reads as the pose.
        pose[3:] = Rotation.from_euler("xyz", Rotation.from_quat(pose[3:]).as_euler("XYZ")).as_quat()
        raw = np.array(pb.calculateInverseDynamics(self.body, pose + joints, velocity.tolist(), [0.0] * size,
                                                   physicsClientId=self.client))
        raw[:6] = np.concatenate([raw[3:6], raw[:3]])  # its base rows are linear first, its velocities angular first
        if not self.floating:
            return raw[self.selected]
        # Its base's linear acceleration is P's classical one in P's axes, d/dt(v_P) + ω × v_P (measured).
        classical = np.zeros(len(self.selected))
        classical[3:6] = np.cross(rates[:3], rates[3:6])
        return self.T.T @ (raw[self.selected] + self._engine_mass(q) @ classical)

    def forward(self, q, v, tau):
        if self.balls is not None:
            return self.balls.forward(q, v, tau)
        if self.base:
            try:
                return np.linalg.solve(self.mass_matrix(q), np.asarray(tau) - self.bias(q, v))
            except np.linalg.LinAlgError:  # its M singular (links without inertia): no q̈; its M and links say why
                return np.full(len(self.selected), np.nan)
        kw = {"physicsClientId": self.client}
        for joint, position, velocity in zip(self.joints, q, v):
            pb.resetJointState(self.body, joint, position, velocity, **kw)
        pb.setJointMotorControlArray(self.body, self.joints, pb.TORQUE_CONTROL, forces=list(tau), **kw)
        with quiet_output():
            pb.stepSimulation(**kw)
        after = np.array([state[1] for state in pb.getJointStates(self.body, self.joints, **kw)])
        return (after - np.asarray(v)) / STEP

    def link_inertias(self) -> dict[str, LinkInertia]:
        kw = {"physicsClientId": self.client}
        if self.balls is not None:
            self.balls.reset(self.description.neutral(), np.zeros(self.description.nv))
        for joint in ([] if self.balls is not None else self.joints):
            pb.resetJointState(self.body, joint, 0.0, 0.0, **kw)
        parts: dict[str, list] = {}
        if self.floating:  # the base is a moving link: placed as the description's neutral pose has it
            pose = self._pose(self.description.neutral())
            pb.resetBasePositionAndOrientation(self.body, pose[:3], pose[3:], **kw)
            info = pb.getDynamicsInfo(self.body, -1, **kw)
            rotation = np.array(pb.getMatrixFromQuaternion(pose[3:])).reshape(3, 3)
            base = pb.getBodyInfo(self.body, **kw)[0].decode()
            parts[base] = [world_inertia(info[0], np.zeros(3), np.diag(info[2]), rotation, pose[:3])]
        for link, name in enumerate(self._file_names()):
            info = pb.getDynamicsInfo(self.body, link, **kw)
            state = pb.getLinkState(self.body, link, computeForwardKinematics=True, **kw)
            # state[0], state[1]: the inertial frame's world position and orientation; info[2]: its diagonal.
            rotation = np.array(pb.getMatrixFromQuaternion(state[1])).reshape(3, 3)
            parts.setdefault(name, []).append(world_inertia(info[0], np.zeros(3), np.diag(info[2]), rotation,
                                                            state[0]))
        return {name: combine(found) for name, found in parts.items()}

    def _file_names(self) -> list[str]:
        """The file's body each link belongs to. loadMJCF makes a body of one link per joint (named
        ``link1_N`` when the body is unnamed) and one more per geom, welded to it (the first named as the body):
        a link the file does not name is its moving joint's child body, or else part of its parent's."""
        bodies = {body.name for body in self.description.bodies}
        child = {joint.name: joint.child for joint in self.description.joints}
        base = pb.getBodyInfo(self.body, physicsClientId=self.client)[0].decode()
        names: list[str] = []
        for link, name in enumerate(self.link_names):
            if name not in bodies:
                info = pb.getJointInfo(self.body, link, physicsClientId=self.client)
                parent = info[16]
                joint = info[1].decode()
                if info[2] != pb.JOINT_FIXED and joint in child:
                    name = child[joint]
                else:
                    name = base if parent < 0 else names[parent]
            names.append(name)
        return names

    def __del__(self):
        try:
            pb.disconnect(self.client)
        except Exception:  # the interpreter is ending, or the client is gone
            pass


class BallJoints:
    """PyBullet's ball joints (JOINT_SPHERICAL) mapped to xval's convention, on a fixed base.

    Measured (tests/test_ball_joint.py): its quaternion (x y z w) and angular velocity live in the child's
    inertial frame, whose axes A (``getDynamicsInfo``'s local inertial orientation: the file's inertial rpy
    times the principal axes it finds) turn the link frame: q_pb = A⁻¹ q A, u_pb = A⁻¹ ω, τ_pb = A⁻¹ τ.
    ``calculateMassMatrix`` is a third off the reference with ball joints whatever the layout of its positions
    (x y z w, w x y z, rotation vectors; ball_chain.urdf), so M⁻¹ and the bias come from its forward dynamics,
    one 1e-3 s step per column (semi-implicit Euler: (v' − v)/dt is its acceleration at the state)."""

    def __init__(self, loaded: "PyBulletModel") -> None:
        if loaded.base:
            raise Refused("ball joints are compared on a fixed base only (its multibody's floating base "
                          "with spherical joints is not mapped here)")
        self.loaded, self.kw = loaded, {"physicsClientId": loaded.client}
        infos = [pb.getJointInfo(loaded.body, k, **self.kw) for k in loaded.joints]
        description = loaded.description
        self.turns = []  # per moving joint in description order: A (3, 3), or None for a 1-dof joint
        for joint, info in zip(description.moving_joints, infos):
            if (info[2] == pb.JOINT_SPHERICAL) != (joint.type == "ball"):
                raise Refused(f"pybullet's joint {joint.name} is {'' if info[2] == pb.JOINT_SPHERICAL else 'not '}"
                              f"spherical; the file's is {joint.type}")
            frame = pb.getDynamicsInfo(loaded.body, info[0], **self.kw)[4]
            self.turns.append(np.array(pb.getMatrixFromQuaternion(frame)).reshape(3, 3) if joint.type == "ball" else None)
        self.T = np.eye(description.nv)  # xval's v = T u_pb
        for joint, turn in zip(description.moving_joints, self.turns):
            if turn is not None:
                where = description.slots[joint.name][1]
                self.T[where, where] = turn
        for k, turn in zip(loaded.joints, self.turns):  # no motor: a spherical joint's takes force 0
            if turn is not None:
                pb.setJointMotorControlMultiDof(loaded.body, k, pb.POSITION_CONTROL, [0, 0, 0, 1],
                                                targetVelocity=[0, 0, 0], force=[0, 0, 0], **self.kw)

    def _entries(self, values, configuration: bool):
        """Per joint, PyBullet's entries of xval's q (configuration) or v, τ (turned by A⁻¹)."""
        description, out = self.loaded.description, []
        for joint, turn in zip(description.moving_joints, self.turns):
            where = description.slots[joint.name][0 if configuration else 1]
            part = np.asarray(values[where], dtype=float)
            if turn is not None and configuration:
                a = Rotation.from_matrix(turn)
                part = (a.inv() * Rotation.from_quat(part) * a).as_quat()
            elif turn is not None:
                part = turn.T @ part
            out.append([float(x) for x in part])
        return out

    def reset(self, q, v) -> None:
        for k, position, rate in zip(self.loaded.joints, self._entries(q, True), self._entries(v, False)):
            pb.resetJointStateMultiDof(self.loaded.body, k, position, rate, **self.kw)

    def read(self) -> tuple[np.ndarray, np.ndarray]:
        """xval's (q, v) of PyBullet's joint state."""
        states = pb.getJointStatesMultiDof(self.loaded.body, self.loaded.joints, **self.kw)
        q, u = [], []
        for state, turn in zip(states, self.turns):
            if turn is not None:
                a = Rotation.from_matrix(turn)
                q.extend((a * Rotation.from_quat(state[0]) * a.inv()).as_quat())
            else:
                q.extend(state[0])
            u.extend(state[1])
        return np.array(q), self.T @ np.array(u)

    def forward(self, q, v, tau) -> np.ndarray:
        self.reset(q, v)
        for k, force in zip(self.loaded.joints, self._entries(tau, False)):
            pb.setJointMotorControlMultiDof(self.loaded.body, k, pb.TORQUE_CONTROL, force=force, **self.kw)
        with quiet_output():
            pb.stepSimulation(**self.kw)
        after = np.array([x for s in pb.getJointStatesMultiDof(self.loaded.body, self.loaded.joints, **self.kw)
                          for x in s[1]])
        return self.T @ (after - np.linalg.solve(self.T, v)) / STEP

    def mass_matrix(self, q) -> np.ndarray:
        n = self.loaded.description.nv
        rest = np.zeros(n)
        free = self.forward(q, rest, rest)
        inverse = np.array([self.forward(q, rest, e) - free for e in np.eye(n)]).T
        try:
            return np.linalg.inv(inverse)
        except np.linalg.LinAlgError:  # its M singular (an inertia it dropped): compared as not finite, diagnosed
            return np.full((n, n), np.nan)

    def bias(self, q, v) -> np.ndarray:
        return -self.mass_matrix(q) @ self.forward(q, v, np.zeros(len(v)))


class PyBulletStepper(Stepper):
    """PyBullet: the file's multibody (engines.pybullet.model), ``stepSimulation`` at fixedTimeStep dt."""

    def __init__(self, scene: ModelScene, dt: float) -> None:
        self.pb, self.quiet = pb, quiet_output
        loaded = self.loaded = load(scene.source, scene.description)
        self.kw = {"physicsClientId": loaded.client}
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, **self.kw)
        pb.setGravity(*scene.gravity, **self.kw)
        q0, v0 = np.asarray(scene.initial_q, dtype=float), np.asarray(scene.initial_v, dtype=float)
        if loaded.floating:  # its base is the base link's inertial frame P: placed, and moving, as xval's base says
            pose, turn = loaded._pose(q0), rotation(q0[3:7])
            pb.resetBasePositionAndOrientation(loaded.body, pose[:3], pose[3:], **self.kw)
            pb.resetBaseVelocity(loaded.body, turn @ (v0[:3] + np.cross(v0[3:6], loaded.offset)), turn @ v0[3:6],
                                 **self.kw)
            q0, v0 = q0[7:], v0[6:]
        self._turn = np.asarray(scene.initial_q, dtype=float)[3:7]
        if loaded.balls is not None:
            loaded.balls.reset(q0, v0)
        for joint, position, velocity in zip([] if loaded.balls is not None else loaded.joints, q0, v0):
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
        loaded, kw = self.loaded, self.kw
        if loaded.balls is not None:
            return loaded.balls.read()
        states = self.pb.getJointStates(loaded.body, loaded.joints, **kw)
        q, v = np.array([s[0] for s in states]), np.array([s[1] for s in states])
        if not loaded.floating:
            return q, v
        # P's pose and velocity (its origin's, angular; both in the world) as the base link's, in its frame.
        position, orientation = self.pb.getBasePositionAndOrientation(loaded.body, **kw)
        linear, angular = (np.asarray(x, dtype=float) for x in self.pb.getBaseVelocity(loaded.body, **kw))
        turn = np.array(self.pb.getMatrixFromQuaternion(orientation)).reshape(3, 3) @ loaded.turn.T
        spin = turn.T @ angular
        quaternion = self._turn = continuous(Rotation.from_matrix(turn).as_quat(), self._turn)
        base = np.concatenate([np.asarray(position) - turn @ loaded.offset, quaternion])
        return np.concatenate([base, q]), np.concatenate([turn.T @ linear - np.cross(spin, loaded.offset), spin, v])


def _without_limits(source):
    """``source`` with every URDF ``<limit>``'s range emptied (lower 1 > upper -1): PyBullet then builds no
    joint-limit constraint, which it otherwise enforces whatever the caller asks (an MJCF is left as it is)."""
    if source.format != "urdf":
        return source
    root = ET.fromstring(source.text)
    for limit in root.iter("limit"):
        limit.set("lower", "1")
        limit.set("upper", "-1")
    return replace(source, text=ET.tostring(root, encoding="unicode"), keep_empty_ranges=True)
