"""Drake's import of a model file: ``Parser`` into a continuous ``MultibodyPlant``.

Import options: ``Parser(plant).AddModelsFromString(text, "urdf")`` (or
"xml" for MJCF) into a plant with time_step = 0 (continuous: no discrete
solver, joint limits not enforced), the root link welded to the world
before ``Finalize()``, gravity (0, 0, −9.81), every joint's default damping
set to 0. M is ``CalcMassMatrix``, the bias ``CalcBiasTerm −
CalcGravityGeneralizedForces``, the forward dynamics ``EvalTimeDerivatives``
with the torques on the applied-generalized-force port. The parser's
warnings go to Python's ``drake`` logger: they are kept in the notes
(an inertia Drake finds physically invalid is replaced, and it says so).
"""

from __future__ import annotations

import logging


import numpy as np

from engines.drake import library as drake
from engines.model.description import ModelDescription
from engines.model.floating import Mapping, angular_linear_world, continuous, rotation, with_balls
from engines.model.kinematics import matrix_rpy, rpy_matrix
from engines.model.inertia import world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.source import ModelSource
from engines.model.stepping import common_settings, Stepper
from engines.model.scene import ModelScene

NAME = "drake"


def version() -> str:
    return drake.version()


def load(source: ModelSource, description: ModelDescription, gravity: float = GRAVITY) -> "DrakeModel":
    """``gravity`` : m/s² along −z (set before ``Finalize()``, the only time Drake takes it)."""
    Parser = drake.Parser
    MultibodyPlant = drake.MultibodyPlant

    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    if source.format == "mjcf":
        text, notes = _named(text, description.name, notes)
    elif description.balls:
        text, notes = _drake_balls(text, notes)
    plant = MultibodyPlant(0.0)
    logger, warnings = logging.getLogger("drake"), _Collect()
    level, propagate = logger.level, logger.propagate
    logger.setLevel(logging.WARNING)
    logger.propagate = False
    logger.addHandler(warnings)
    try:
        Parser(plant).AddModelsFromString(text, "urdf" if source.format == "urdf" else "xml")
        # A body's frame (a joint may share its name); none with a floating base.
        root = plant.GetBodyByName(description.root).body_frame() if description.floating is None else None
        if root is not None and root.body().index() != plant.world_body().index():  # "world" is the world
            plant.WeldFrames(plant.world_frame(), root)
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            if joint.num_velocities() == 1 and hasattr(joint, "set_default_damping"):
                joint.set_default_damping(0.0)
        # Drake's MJCF parser turns a joint's armature into its actuator's reflected inertia (rotor inertia ×
        # gear ratio²): zeroed like every engine's armature.
        reflected = 0
        for index in plant.GetJointActuatorIndices():
            actuator = plant.get_mutable_joint_actuator(index)
            if actuator.default_rotor_inertia() != 0.0:
                actuator.set_default_rotor_inertia(0.0)
                reflected += 1
        plant.mutable_gravity_field().set_gravity_vector([0.0, 0.0, -gravity])
        plant.Finalize()
    except RuntimeError as exc:
        raise Refused(" ".join(str(exc).split())) from None
    finally:
        logger.removeHandler(warnings)
        logger.setLevel(level)
        logger.propagate = propagate
    notes = (*notes, *(f"drake warned: {line}" for line in warnings.lines),
             *((f"reflected inertia (the MJCF's armature) of {reflected} actuators set to 0",) if reflected else ()))
    options = {"parser": "Parser.AddModelsFromString", "time_step": "0 (continuous plant)",
               "root": f"{description.root} welded to the world"}
    return DrakeModel(plant, description, options, notes)


class _Collect(logging.Handler):
    """Keeps the parser's warnings (one line each, the file name dropped) for the notes."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = " ".join(record.getMessage().split())
        if "safety_controller" not in text:  # ROS tags Drake ignores: no bearing on dynamics
            self.lines.append(text.split(": warning: ", 1)[-1][:300])


#: The namespace of Drake's URDF extensions (``<drake:joint type="ball">``).
DRAKE_NS = "http://drake.mit.edu"


def _drake_balls(text: str, notes: tuple[str, ...]) -> tuple[str, tuple[str, ...]]:
    """A URDF text whose spherical joints (PyBullet's extension, which Drake's parser refuses) are Drake's own
    ball joints, ``<drake:joint type="ball">`` (a BallRpyJoint), said in a note."""
    import xml.etree.ElementTree as ET

    ET.register_namespace("drake", DRAKE_NS)
    root = ET.fromstring(text)
    names: list[str] = []
    for joint in root.findall("joint"):
        if joint.get("type") == "spherical":
            joint.tag = f"{{{DRAKE_NS}}}joint"
            names.append(joint.get("name", "?"))
            joint.set("type", "ball")
            for extra in joint.findall("axis") + joint.findall("limit"):
                joint.remove(extra)
    return ET.tostring(root, encoding="unicode"), (*notes, f"spherical joint{'s' if len(names) > 1 else ''} "
                                                          f"{', '.join(names)} given to Drake as <drake:joint "
                                                          f"type=\"ball\"> (its parser has no spherical type)")


def _named(text: str, name: str, notes: tuple[str, ...]) -> tuple[str, tuple[str, ...]]:
    """An MJCF text whose <mujoco> has a model name (Drake's parser refuses one without: "must have a name
    attribute"), the description's name given when the file has none, said in a note."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(text)
    if root.get("model"):
        return text, notes
    root.set("model", name or "model")
    return ET.tostring(root, encoding="unicode"), (*notes, f"<mujoco> has no model name; Drake's parser needs one: "
                                                          f"given model=\"{name or 'model'}\"")


class DrakeModel(LoadedModel):
    engine = NAME

    def __init__(self, plant, description: ModelDescription, options, notes=()):
        balls = ("ball joints are Drake's BallRpyJoint: roll, pitch, yaw of the child frame in the joint frame (singular "
                 "at pitch ±90°) and, as measured, the angular velocity in the joint frame; mapped to xval's "
                 "quaternion and child-frame angular velocity",) if description.balls else ()
        super().__init__(description, options, (*notes, "joint damping set to 0", *balls))
        self.plant, self.context = plant, plant.CreateDefaultContext()
        names: list[str] = []
        positions: list[list[int]] = []
        rates: list[list[int]] = []
        #: The floating joint's first position and velocity (quaternion w x y z, position; angular, linear).
        self.base_q, self.base_v = -1, -1
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            if joint.num_velocities() == 0:
                continue
            if joint.num_velocities() == 6 and description.floating is not None and self.base_q < 0:
                self.base_q, self.base_v = joint.position_start(), joint.velocity_start()
                continue
            ball = joint.type_name() == "ball_rpy"
            if not ball and (joint.num_velocities() != 1 or joint.num_positions() != 1):
                raise Refused(f"only 1-degree-of-freedom and ball joints are compared; drake's {joint.name()} is "
                              f"{joint.type_name()}")
            names.append(joint.name())
            positions.append([joint.position_start() + k for k in range(joint.num_positions())])
            rates.append([joint.velocity_start() + k for k in range(joint.num_velocities())])
        index = index_map(description, names)
        for joint, k in zip(description.moving_joints, index):
            if (joint.type == "ball") != (len(rates[k]) == 3):
                raise Refused(f"drake's joint {joint.name} has {len(rates[k])} degrees of freedom; the file's "
                              f"has {joint.nv}")
        #: Per moving joint, Drake's position entries (a ball's roll, pitch, yaw); Drake's velocity index of each of
        #: xval's joint velocity entries (a ball's: the angular velocity in the joint's parent frame, measured).
        self.joint_q = [positions[k] for k in index]
        self.qpos = np.array([i for k in index for i in positions[k]], dtype=int)
        self.dof = np.array([i for k in index for i in rates[k]], dtype=int)
        self._last: dict[str, np.ndarray] = {}  # each ball's quaternion as last read (kept continuous)
        if (self.base_q >= 0) != (description.floating is not None):
            raise Refused("drake's plant has no floating joint for the floating base")
        base = np.arange(self.base_v, self.base_v + 6) if self.base_q >= 0 else np.zeros(0, int)
        #: Drake's velocity index of each of xval's (the base's six first).
        self.selected = np.concatenate([base, self.dof]).astype(int)
        self.forces = plant.get_applied_generalized_force_input_port().FixValue(self.context, np.zeros(plant.num_velocities()))

    def plant_state(self, q, v=None) -> tuple[np.ndarray, Mapping | None]:
        """Drake's (positions, velocities) for xval's q (nconfig,) and v (nv,) (zero when None), and the
        floating base's mapping (None with a fixed base)."""
        q = np.asarray(q, dtype=float)
        mapping = Mapping(angular_linear_world, q, None if v is None else np.asarray(v, dtype=float),
                          self.description.nv) if self.base_q >= 0 else None
        mapping = with_balls(self.description, q, mapping)
        positions = np.zeros(self.plant.num_positions())
        if self.base_q >= 0:
            quaternion = q[3:7] / np.linalg.norm(q[3:7])
            positions[self.base_q:self.base_q + 7] = quaternion[3], *quaternion[:3], *q[:3]
        for joint, where in zip(self.description.moving_joints, self.joint_q):
            values = q[self.description.slots[joint.name][0]]
            positions[where] = matrix_rpy(rotation(values)) if joint.type == "ball" else values
        velocities = np.zeros(self.plant.num_velocities())
        if v is not None:
            velocities[self.selected] = v if mapping is None else mapping.velocity(v)
        return np.concatenate([positions, velocities]), mapping

    def xval_state(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """xval's (q, v) of Drake's state x (positions then velocities): the inverse of :meth:`plant_state`."""
        from scipy.spatial.transform import Rotation

        positions, velocities = x[:self.plant.num_positions()], x[self.plant.num_positions():]
        parts, v = [], velocities[self.selected]
        for joint, where in zip(self.description.moving_joints, self.joint_q):
            if joint.type != "ball":
                parts.append(positions[where])
                continue
            quaternion = continuous(Rotation.from_matrix(rpy_matrix(positions[where])).as_quat(),
                                    self._last.get(joint.name))
            self._last[joint.name] = quaternion
            parts.append(quaternion)
        q = np.concatenate(parts) if parts else np.zeros(0)
        if self.base_q >= 0:
            pose = positions[self.base_q:self.base_q + 7]  # (w x y z, p)
            q = np.concatenate([pose[4:7], pose[1:4], pose[:1], q])
        mapping = with_balls(self.description, q, Mapping(angular_linear_world, q, nv=self.description.nv)
                             if self.base_q >= 0 else None)
        return q, v.copy() if mapping is None else np.linalg.solve(mapping.T, v)

    def _set(self, q, v=None, tau=None) -> Mapping | None:
        x, mapping = self.plant_state(q, v)
        self.plant.SetPositionsAndVelocities(self.context, x)
        forces = np.zeros(self.plant.num_velocities())
        if tau is not None:
            forces[self.selected] = tau if mapping is None else mapping.force(tau)
        self.forces.GetMutableData().set_value(forces)
        return mapping

    def _mass(self) -> np.ndarray:
        return self.plant.CalcMassMatrix(self.context)[np.ix_(self.selected, self.selected)]

    def mass_matrix(self, q):
        mapping = self._set(q)
        return self._mass() if mapping is None else mapping.mass_matrix(self._mass())

    def bias(self, q, v):
        mapping = self._set(q, v)
        bias = (self.plant.CalcBiasTerm(self.context) - self.plant.CalcGravityGeneralizedForces(self.context))[self.selected]
        return bias if mapping is None else mapping.bias(self._mass(), bias)

    def forward(self, q, v, tau):
        mapping = self._set(q, v, tau)
        derivatives = self.plant.EvalTimeDerivatives(self.context).get_vector().CopyToVector()
        acceleration = derivatives[self.plant.num_positions():][self.selected]
        return acceleration if mapping is None else mapping.acceleration(acceleration)

    def joint_origins(self) -> dict[str, np.ndarray]:
        self._set(self.description.neutral())
        return {j.name: np.asarray(self.plant.GetJointByName(j.name).frame_on_child()
                                   .CalcPoseInWorld(self.context).translation())
                for j in self.description.moving_joints if j.type != "prismatic"}

    def link_inertias(self):
        BodyIndex = drake.BodyIndex

        self._set(self.description.neutral())
        found = {}
        for k in range(1, self.plant.num_bodies()):  # body 0 is the world
            body = self.plant.get_body(BodyIndex(k))
            pose = self.plant.EvalBodyPoseInWorld(self.context, body)
            mass, com = body.default_mass(), np.asarray(body.default_com())
            # Drake keeps the inertia about the body origin Bo: shift it to the centre of mass.
            about_origin = body.default_rotational_inertia().CopyToFullMatrix3()
            about_com = about_origin - mass * (com @ com * np.eye(3) - np.outer(com, com))
            found[body.name()] = world_inertia(mass, com, about_com, pose.rotation().matrix(), pose.translation())
        return found


class DrakeStepper(Stepper):
    """Drake: the file's continuous MultibodyPlant (engines.drake.model) under a Simulator with the variant's
    integrator (``scheme``: Drake's name), fixed step dt or error control at ``accuracy`` with dt the largest step."""

    def __init__(self, scene: ModelScene, dt: float, scheme: str, fixed: bool, accuracy: float) -> None:
        ResetIntegratorFromFlags, Simulator = drake.ResetIntegratorFromFlags, drake.Simulator
        loaded = load(scene.source, scene.description, gravity=scene.g)
        plant = self.plant = loaded.plant
        self.simulator = Simulator(plant)
        self.context = self.simulator.get_mutable_context()
        plant.get_applied_generalized_force_input_port().FixValue(self.context, np.zeros(plant.num_velocities()))
        plant.SetPositionsAndVelocities(self.context, loaded.plant_state(scene.initial_q, scene.initial_v)[0])
        self.loaded = loaded
        integrator = self.integrator = ResetIntegratorFromFlags(self.simulator, scheme, dt)
        integrator.set_fixed_step_mode(fixed)
        if not fixed:
            integrator.set_target_accuracy(accuracy)
        self.simulator.Initialize()
        self.dt, self.time = dt, 0.0
        self.settings = {**common_settings(scene, loaded), "drake_integrator": type(integrator).__name__,
                         "fixed_step_mode": fixed, "target_accuracy": None if fixed else accuracy}

    def advance(self, steps: int) -> None:
        for _ in range(steps):  # the integrator's own clock, t += dt, so no sliver steps (engines/drake/adapter.py)
            self.time += self.dt
        self.simulator.AdvanceTo(self.time)

    def steps_taken(self) -> int:
        return int(self.integrator.get_num_steps_taken())

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.loaded.xval_state(self.plant.GetPositionsAndVelocities(self.context))
