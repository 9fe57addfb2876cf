"""DART's import of a model file: ``DartLoader`` (URDF) or ``MjcfParser.readWorld`` (MJCF, the self-contained text in a temporary file) into a Skeleton.

Import options: ``DartLoader.Options`` with mDefaultRootJointType = FIXED
(DART gives a URDF a floating root otherwise) and its default
mDefaultInertia (1 kg, identity inertia: what a link without ``<inertial>``
gets); the text is parsed with ``parseSkeletonString`` (so unresolvable
``package://`` meshes, already stripped, cannot stop it). Gravity (0, 0,
−9.81); every degree of freedom's damping, Coulomb friction and spring
stiffness set to 0. M is ``getMassMatrix``, the bias
``getCoriolisAndGravityForces``, the forward dynamics
``computeForwardDynamics`` (no constraint solver: limits are not enforced).
MJCF: readWorld's skeleton with degrees of freedom (the others are static
geoms), ``<freejoint>`` spelled ``<joint type="free">``, its FreeJoint's frames
made the body's; its parser's inertias (it ignores <inertial>) left as parsed.
"""

from __future__ import annotations


import re
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from engines.dart import library
from engines.dart.rk4 import floating_rk4_stepper, rk4_stepper
from engines.model.description import ModelDescription
from engines.model.floating import Mapping, angular_linear_world, continuous
from engines.model.inertia import world_inertia
from engines.model.loaded import GRAVITY, LoadedModel, Refused, index_map
from engines.model.source import ModelSource
from engines.model.stepping import common_settings, kept_damping, Stepper
from engines.stdio import quiet_output
from engines.model.scene import ModelScene

NAME = "dart"
#: The key of the floating base's quaternion among the balls' last reads (a joint name is never empty).
BASE_KEY = ""


def version() -> str:
    return library.version()


def load(source: ModelSource, description: ModelDescription) -> "DartModel":
    dartpy = library.dartpy()

    text, notes = source.engine_text(drop_mimic=description.mimic_independent)
    if source.format == "mjcf":
        text, freed = _free_joints_spelled_out(text)
        try:
            with quiet_output(), source.engine_file(text=text) as path:
                world = dartpy.utils.MjcfParser.readWorld(dartpy.common.Uri(Path(path).as_uri()))
        except RuntimeError as exc:
            raise Refused(" ".join(str(exc).split())) from None
        if world is None:
            raise Refused("MjcfParser.readWorld gave no world (DART printed the reason)")
        skeletons = [world.getSkeleton(k) for k in range(world.getNumSkeletons())]
        # Its parser makes each geom of the world body a skeleton of its own (no joint: a static geom, never a
        # body); the model is the one skeleton with degrees of freedom.
        jointed = [s for s in skeletons if s.getNumDofs() > 0]
        if len(jointed) != 1:
            raise Refused(f"MjcfParser.readWorld gave {len(skeletons)} skeletons, {len(jointed)} of them with "
                          f"degrees of freedom (one expected)")
        if len(skeletons) > 1:
            notes = (*notes, f"{len(skeletons) - 1} skeleton{'s' if len(skeletons) > 2 else ''} of the world "
                             f"body's static geoms left out (MjcfParser.readWorld makes one per geom)")
        if freed:
            notes = (*notes, "<freejoint> given to DART as <joint type=\"free\"> (its parser welds the body of a "
                             "<freejoint>)")
        stated = {"loader": "MjcfParser.readWorld"}
        return DartModel(jointed[0], description, stated, notes, _file_names(jointed[0], description))
    if description.balls:
        raise Refused("DART's URDF reader (urdfdom) has no spherical joint; DART compares ball joints from an MJCF")
    loader = dartpy.utils.DartLoader()
    options = dartpy.utils.DartLoader.Options()
    floating = description.floating is not None
    root_type = "FLOATING" if floating else "FIXED"
    options.mDefaultRootJointType = getattr(dartpy.utils.DartLoader.RootJointType, root_type)
    loader.setOptions(options)
    with quiet_output():  # DART prints a warning per massless link to stdout
        skeleton = loader.parseSkeletonString(text, source.path.resolve().as_uri())
    if skeleton is None:
        raise Refused("DartLoader.parseSkeletonString returned no skeleton (DART printed the reason)")
    stated = {"loader": "DartLoader.parseSkeletonString", "mDefaultRootJointType": root_type,
              "mDefaultInertia": "1 kg, identity (DART's default)"}
    return DartModel(skeleton, description, stated, notes)


def _free_joints_spelled_out(text: str) -> tuple[str, int]:
    """The MJCF text with each ``<freejoint …/>`` written ``<joint type="free" …/>`` (DART 6.20's parser
    welds a <freejoint>'s body to the world, and reads the long form), and how many there were."""
    return re.subn(r"<freejoint\b", '<joint type="free"', text)


def _file_names(skeleton, description: ModelDescription) -> dict[str, str]:
    """DART's name of each unnamed MJCF body ("Nonamed (k)") -> the description's ("body<id>"), where DART's tree
    is the file's body for body (both list the bodies in the file's order); {} otherwise."""
    bodies = [b.name for b in description.bodies if not b.virtual and b.parent_joint is not None]
    nodes = [skeleton.getBodyNode(k).getName() for k in range(skeleton.getNumBodyNodes())]
    if len(nodes) != len(bodies):
        return {}
    return {dart: file for dart, file in zip(nodes, bodies) if dart != file and dart.startswith("Nonamed")}


def ball_positions(description: ModelDescription, q: np.ndarray) -> np.ndarray:
    """xval's configuration with each ball joint's quaternion (4 entries) replaced by its rotation vector (3)."""
    parts = [q[:description.nconfig - description.nq]]
    for joint in description.moving_joints:
        where = description.slots[joint.name][0]
        values = q[where]
        parts.append(Rotation.from_quat(values / np.linalg.norm(values)).as_rotvec() if joint.type == "ball" else values)
    return np.concatenate(parts)


class DartModel(LoadedModel):
    engine = NAME

    def __init__(self, skeleton, description: ModelDescription, options, notes=(), named=None):
        super().__init__(description, options, (*notes, "damping, Coulomb friction and spring stiffness set to 0"))
        self.skeleton = skeleton
        #: DART's name of a body -> the file's, where they differ (an unnamed MJCF body).
        self.named = named or {}
        skeleton.setGravity([0.0, 0.0, -GRAVITY])
        names, dofs = [], []
        base: list[int] = []
        for k in range(skeleton.getNumJoints()):
            joint = skeleton.getJoint(k)
            if joint.getNumDofs() == 0:
                continue
            if joint.getType() == "FreeJoint" and description.floating is not None and not base:
                base = [joint.getIndexInSkeleton(i) for i in range(6)]
                # Its MJCF parser puts the body's pose in the joint's parent transform (q = 0 is the file's
                # pose); xval's q is the base frame's pose in the world: the joint's frames made the body's.
                identity = library.dartpy().math.Isometry3()  # the identity
                joint.setTransformFromParentBodyNode(identity)
                joint.setTransformFromChildBodyNode(identity)
                continue
            if joint.getNumDofs() != 1 and joint.getType() != "BallJoint":
                raise Refused(f"only 1-degree-of-freedom and ball joints are compared; DART's {joint.getName()} is "
                              f"a {joint.getType()}")
            for i in range(joint.getNumDofs()):
                joint.setDampingCoefficient(i, 0.0)
                joint.setCoulombFriction(i, 0.0)
                joint.setSpringStiffness(i, 0.0)
            names.append(joint.getName())
            dofs.append([joint.getIndexInSkeleton(i) for i in range(joint.getNumDofs())])
        # A BallJoint (its MJCF parser's ball): positions the rotation vector, velocities the child's angular
        # velocity in the child frame, xval's (measured, tests/test_ball_joint.py).
        self.dof = np.array([i for k in index_map(description, names) for i in dofs[k]], dtype=int)
        self._quaternions: dict[str, np.ndarray] = {}  # each ball's (and the base's) quaternion as last read
        if bool(base) != (description.floating is not None):
            raise Refused("DART's skeleton has no FreeJoint for the floating base (its MJCF parser welds a free "
                          "joint's body to the world)")
        #: DART's index of each of xval's velocities (the base's six first: its FreeJoint, angular then linear,
        #: both in the world frame as measured (engines/model/floating.py); its positions are the rotation
        #: vector, then the position).
        self.selected = np.array(base + list(self.dof), dtype=int)
        self.n = skeleton.getNumDofs()

    def _set(self, q, v=None, tau=None) -> Mapping | None:
        q = np.asarray(q, dtype=float)
        rates = None if v is None else np.asarray(v, dtype=float)
        mapping = Mapping(angular_linear_world, q, rates, self.description.nv) if len(self.selected) > len(self.dof) else None
        if self.description.balls:  # each ball's quaternion as DART's rotation vector
            q = ball_positions(self.description, q)
        if mapping is not None:
            rotvec = Rotation.from_quat(q[3:7] / np.linalg.norm(q[3:7])).as_rotvec()
            q = np.concatenate([rotvec, q[:3], q[7:]])
        for values, setter in ((q, self.skeleton.setPositions), (v, self.skeleton.setVelocities),
                               (tau, self.skeleton.setForces)):
            full = np.zeros(self.n)
            if values is not None:
                if mapping is not None and values is v:
                    values = mapping.velocity(values)
                elif mapping is not None and values is tau:
                    values = mapping.force(values)
                full[self.selected] = values
            setter(full)
        return mapping

    def xval_state(self) -> tuple[np.ndarray, np.ndarray]:
        """xval's (q (nconfig,), v (nv,)) of the skeleton's state: the inverse of :meth:`_set`."""
        positions, velocities = np.asarray(self.skeleton.getPositions()), np.asarray(self.skeleton.getVelocities())
        q, rates = self._joint_configuration(positions[self.dof]), velocities[self.selected]
        if len(self.selected) == len(self.dof):
            return q, rates.copy()
        base = self.selected[:6]  # the FreeJoint's (rotation vector, position)
        # DART's rotation vector wraps at π: kept continuous like each ball's (BASE_KEY: no joint has that name).
        quaternion = continuous(Rotation.from_rotvec(positions[base[:3]]).as_quat(), self._quaternions.get(BASE_KEY))
        self._quaternions[BASE_KEY] = quaternion
        config = np.concatenate([positions[base[3:]], quaternion, q])
        return config, np.linalg.solve(Mapping(angular_linear_world, config, nv=len(rates)).T, rates)

    def _joint_configuration(self, values: np.ndarray) -> np.ndarray:
        """xval's joint configuration of DART's joint positions (description order): each BallJoint's rotation
        vector as a quaternion x y z w, kept continuous between reads (q and −q are one turn)."""
        if not self.description.balls:
            return values.copy()
        parts, at = [], 0
        for joint in self.description.moving_joints:
            part = values[at:at + joint.nv]
            at += joint.nv
            if joint.type == "ball":
                part = continuous(Rotation.from_rotvec(part).as_quat(), self._quaternions.get(joint.name))
                self._quaternions[joint.name] = part
            parts.append(part)
        return np.concatenate(parts)

    def _mass(self) -> np.ndarray:
        return np.array(self.skeleton.getMassMatrix())[np.ix_(self.selected, self.selected)]

    def mass_matrix(self, q):
        mapping = self._set(q)
        return self._mass() if mapping is None else mapping.mass_matrix(self._mass())

    def bias(self, q, v):
        mapping = self._set(q, v)
        bias = np.array(self.skeleton.getCoriolisAndGravityForces())[self.selected]
        return bias if mapping is None else mapping.bias(self._mass(), bias)

    def forward(self, q, v, tau):
        mapping = self._set(q, v, tau)
        self.skeleton.computeForwardDynamics()
        acceleration = np.array(self.skeleton.getAccelerations())[self.selected]
        return acceleration if mapping is None else mapping.acceleration(acceleration)

    def link_inertias(self):
        self._set(self.description.neutral())
        found = {}
        for k in range(self.skeleton.getNumBodyNodes()):
            node = self.skeleton.getBodyNode(k)
            inertia = node.getInertia()  # moment about the COM, in the body frame
            pose = node.getWorldTransform()
            name = self.named.get(node.getName(), node.getName())
            found[name] = world_inertia(node.getMass(), inertia.getLocalCOM(), inertia.getMoment(), pose.rotation(),
                                        pose.translation())
        return found


class DartStepper(Stepper):
    """DART: the file's Skeleton (engines.dart.model) in a World (``world``) or RK4 over its dynamics (``rk4``; with
    a floating base in xval's coordinates, engines.dart.rk4); the state read in xval's convention (DartModel)."""

    def __init__(self, scene: ModelScene, dt: float, integrator: str) -> None:
        dart = library.dartpy()
        loaded = load(scene.source, scene.description)
        skeleton = self.skeleton = loaded.skeleton
        for k in range(skeleton.getNumJoints()):
            skeleton.getJoint(k).setLimitEnforcement(False)
        self.loaded = loaded
        for dof, damping in zip(loaded.dof, kept_damping(scene)):
            skeleton.getDof(int(dof)).setDampingCoefficient(float(damping))
        loaded._set(scene.initial_q, scene.initial_v)  # a floating base mapped from xval's convention; no forces
        skeleton.setGravity(np.asarray(scene.gravity, dtype=float))
        if integrator == "world":
            self.world = dart.simulation.World()
            self.world.setGravity(np.asarray(scene.gravity, dtype=float))
            self.world.addSkeleton(skeleton)
            self.world.setTimeStep(dt)
            self.step = self.world.step
        else:
            # DART's forward dynamics treats joint damping implicitly over the skeleton's time step
            # (a dt·d term in the articulated inertia); RK4 needs the acceleration itself: step 0.
            skeleton.setTimeStep(0.0)
            # A rotation vector's rate is not the angular velocity: a floating base or a ball joint is integrated
            # in xval's coordinates (quaternions), the others in DART's own.
            quaternions = scene.description.floating is not None or bool(scene.description.balls)
            self.step = floating_rk4_stepper(loaded, dt) if quaternions else rk4_stepper(skeleton, dt)
        self.settings = {**common_settings(scene, loaded), "integrator": integrator, "position_limits": "not enforced"}

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            self.step()

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.loaded.xval_state()
