"""PyBullet adapter: point-mass scenes as one multibody, or as separate bodies joined by point-to-point constraints.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/pybullet/adapter.py``.
"""

from __future__ import annotations

import contextlib
import os
import threading
from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, ModelImport, RawRun, Schedule, refuse_ellipse
from engines.errors import Unsupported, UserError
from engines.model.stepping import run_model
from engines.pybullet import model
from engines.pybullet.library import pb as _pb
from engines.pybullet.library import version as pybullet_version
from engines.pybullet import options as tables
from engines.pybullet.options import KEEPABLE, SOLVERS
from engines.recorder import Recorder
from engines.scene.scene import Line, Pin, Scene, ModelSceneLike
from engines.scene.tree import ROOT, read_tree
from engines.stdio import quiet_output

#: A loop-closing arm body's mass, as a fraction of the mean particle mass (its central inertia is
#: that mass · L²). On the four-bar (p2p-dantzig, dt = 1e-3 s, particle inertia_ratio 1e-6) any value
#: from 1e-3 to 1e-9 gave errors of 5.6e-4 to 7.1e-4 m; 1e-6 keeps the mass it adds negligible.
#: (The particles' own inertia_ratio matters more: 1e-4 leaves a floor of ~3e-3 m there, and
#: 1e-9 broke the solve, 0.75 m.)
ARM_MASS_RATIO = 1e-6

# -- the scene as a forest: which constraint ties each particle to its parent -------------


@dataclass(frozen=True)
class Link:
    """One particle and the constraint that ties it to its parent.

    particle : index in the scene; constraint : index in scene.constraints.
    parent : the parent particle's index, or None when the parent is the Pin's anchor.
    joint : (3,) m, where the joint sits at the initial state (anchor or parent particle; a particle
        on a Line is its own joint).
    first_is_self : whether the constraint's first particle (Pin.particle, Rod.a) is ``particle``.
    slide : (3,) the unit direction of a Line the particle slides on (a prismatic joint), or None.
    """

    particle: int
    constraint: int
    parent: int | None
    joint: np.ndarray
    first_is_self: bool
    slide: np.ndarray | None = None


#: Links PyBullet 3.2.7 builds into one multibody correctly. Measured on a chain
#: (tests/test_engine_pybullet.py): 122 links start in the scene's pose, 123 start
#: with one link's pose missing — consistent with a fixed 128-DoF buffer upstream
#: (bullet3 issues #3116 "createMultiBody limited to 127 object", #4621).
MAX_MULTIBODY_LINKS = 122


def _tree_sizes(links: list[Link]) -> dict[int, int]:
    """Links per multibody: {pinned root particle: number of particles hung from it}."""
    parent = {link.particle: link.parent for link in links}
    sizes: dict[int, int] = {}
    for particle in parent:
        root = particle
        while (up := parent[root]) is not None:
            root = up
        sizes[root] = sizes.get(root, 0) + 1
    return sizes


def forest(scene: Scene) -> list[Link]:
    """The links of the scene, parents before children, grown breadth-first from each Pin or Line.

    Raises Unsupported when the constraints form a loop (two paths to one
    particle) or a particle is not tied to any Pin: a multibody (a tree of
    joints) cannot express those; ``p2p`` reads the loops with :func:`grow`.
    """
    links, closures = grow(scene)
    if closures:
        raise Unsupported(closures[0][1])
    return links


def grow(scene: Scene) -> tuple[list[Link], list[tuple[int, str]]]:
    """(links of a spanning forest, loop closures): each closure is (constraint index, why a tree lacks it).

    Raises Unsupported for an Ellipse, for a Line that would close a loop, and
    for particles not tied to any Pin or Line.
    """
    refuse_ellipse(scene, "pybullet: no joint or constraint of PyBullet holds a body on an ellipse (revolute "
                          "joints move a point on a circle, prismatic ones on a line)")
    tree = read_tree(scene)
    closures: list[tuple[int, str]] = []
    for k in tree.found:
        c = scene.constraints[k]
        if isinstance(c, Line):
            raise Unsupported(
                f"pybullet: constraints[{k}] holds particle {c.particle} on a line as well as "
                f"constraints[{tree.constraint_of[c.particle]}]: a loop through a rail, which this adapter "
                "cannot close"
            )
        if isinstance(c, Pin):
            closures.append((k, (
                f"pybullet: particle {c.particle} is fixed twice (constraints {tree.constraint_of[c.particle]} "
                f"and {k}): a closed loop, which a multibody (a tree of joints) cannot express; "
                "pybullet/p2p closes it with a light arm body"
            )))
        else:  # met from the end the walk reached first: the loop closes through the other
            child = max((c.a, c.b), key=tree.order.index)
            closures.append((k, (
                f"pybullet: constraint {k} closes a loop through particle {child}; a multibody is a tree "
                "of joints and cannot express it; pybullet/p2p closes it with a light arm body"
            )))
    if tree.loose:
        raise Unsupported(
            f"pybullet: particles {tree.loose} are not tied to any Pin; this adapter builds only scenes "
            "hung from fixed anchors (no floating bodies)"
        )
    links = []
    for i in tree.order:
        c = scene.constraints[tree.constraint_of[i]]
        parent = tree.parent[i]
        if parent == ROOT:
            links.append(Link(i, tree.constraint_of[i], None, tree.pivot[i].copy(), True,
                              c.unit if isinstance(c, Line) else None))
        else:
            links.append(Link(i, tree.constraint_of[i], parent, tree.pivot[i].copy(), c.a == i))
    return links, closures


def _kept(settings: Mapping[str, Any]) -> list[str]:
    """The PyBullet defaults the ``keep_defaults`` option leaves in place."""
    return [name.strip() for name in str(settings["keep_defaults"]).split(",") if name.strip()]


def _slider_axes(unit: np.ndarray) -> np.ndarray:
    """(2, 3): the directions of a multibody slider constraint's two linear rows (world frame, body at rest).

    As ``btMultiBodySliderConstraint::createConstraintRows``: the first frame axis eᵢ with
    eᵢ × u ≠ 0 gives a₀ = unit(eᵢ × u), then a₁ = unit(u × a₀); each row's impulse acts on
    the slider (body A) along its axis.
    """
    for e in np.eye(3):
        a0 = np.cross(e, unit)
        if np.linalg.norm(a0) > 1e-6:
            a0 = a0 / np.linalg.norm(a0)
            a1 = np.cross(unit, a0)
            return np.array([a0, a1 / np.linalg.norm(a1)])
    raise ValueError("a slider axis must be nonzero")  # pragma: no cover - Line refuses a zero direction


def _angular_velocity(r: np.ndarray, u: np.ndarray) -> np.ndarray:
    """(3,) rad/s: the rotation rate of an arm r (m) whose tip moves at u (m/s) relative to its root (no spin about r)."""
    return np.cross(r, u) / float(r @ r)


# -- the adapter --------------------------------------------------------------------------------


class PyBulletEngine(Engine):
    """PyBullet, as a multibody (reduced coordinates) or as separate bodies with point-to-point constraints."""

    name = "pybullet"
    capabilities = frozenset({"3d", "constraint-forces", "model"})
    # The option tables (engines/pybullet/options.py).
    options, variants, variant_docs, overrides = tables.OPTIONS, tables.VARIANTS, tables.VARIANT_DOCS, tables.OVERRIDES

    def version(self) -> str:
        return pybullet_version()

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        if settings["formulation"] != "multibody":
            grow(scene)  # p2p: Unsupported for an ellipse, a Line closing a loop, a particle tied to nothing
            return
        largest = max(_tree_sizes(forest(scene)).values(), default=0)
        if largest > MAX_MULTIBODY_LINKS:
            raise Unsupported(
                f"pybullet/multibody: PyBullet {self.version()} builds at most {MAX_MULTIBODY_LINKS} links into "
                f"one multibody correctly (from the next one on, a link's initial pose is not applied; "
                f"bullet3 issues #3116 and #4621) and this scene needs {largest}; use pybullet/p2p"
            )

    def _run_model(self, scene: ModelSceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        return run_model(scene, schedule, model.PyBulletStepper(scene, schedule.dt))

    def model_import(self) -> ModelImport:
        return ModelImport(model.version, model.load)

    def _check_model(self, scene: ModelSceneLike, settings: Mapping[str, Any]) -> None:
        if settings["formulation"] != "multibody":
            raise Unsupported("pybullet: a model file is loaded as one multibody (loadURDF); the p2p variants "
                              "build particle scenes from separate bodies, use pybullet/multibody")
        if scene.ball_joints and (scene.floating_base or scene.file_format != "urdf"):
            raise Unsupported(f"pybullet: ball joints ({', '.join(scene.ball_joints)}) are stepped from a URDF's "
                              f"spherical joints on a fixed base only (its loadMJCF makes no ball; a floating base "
                              f"with spherical joints is not mapped here)")
        scene.refuse_kept_dynamics(self.name)

    def _check_options(self, settings: Mapping[str, Any]) -> None:
        # A bad option value is the user's mistake (UserError), not a scene PyBullet cannot express
        # (Unsupported): a suite would record the latter as a skipped case and run on.
        if not 0.0 <= settings["erp"] <= 1.0:
            raise UserError(f"pybullet: option erp must be in [0, 1], got {settings['erp']}")
        if settings["iterations"] < 1:
            raise UserError(f"pybullet: option iterations must be at least 1, got {settings['iterations']}")
        if settings["inertia_ratio"] <= 0:
            raise UserError(
                f"pybullet: option inertia_ratio must be positive, got {settings['inertia_ratio']}; try 1e-9"
            )
        unknown = set(_kept(settings)) - set(KEEPABLE)
        if unknown:
            raise UserError(
                f"pybullet: option keep_defaults names {', '.join(sorted(unknown))}; "
                f"use a comma-separated subset of {', '.join(KEEPABLE)}"
            )

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        with quiet_output():
            client = _clients.take()
            try:
                raw = _Run(client, scene, schedule, settings).execute()
            except BaseException:
                _clients.drop(client)  # a world left half-built or broken is not reused
                raise
            _clients.give_back(client)
            return raw


def _empty(client: int) -> None:
    """Remove every constraint and body from ``client``'s world (constraints first: they hold bodies).

    What a run leaves in its client is its bodies and constraints, and the
    parameters its ``_Run._world`` set, which the next run sets anew (every
    run sets the same ones). Removing them costs a small fraction of
    ``resetSimulation``, which rebuilds the whole world.
    """
    for i in reversed(range(_pb.getNumConstraints(physicsClientId=client))):
        _pb.removeConstraint(_pb.getConstraintUniqueId(i, physicsClientId=client), physicsClientId=client)
    for i in reversed(range(_pb.getNumBodies(physicsClientId=client))):
        _pb.removeBody(_pb.getBodyUniqueId(i, physicsClientId=client), physicsClientId=client)


class _Clients:
    """One PyBullet DIRECT client per thread of a process, emptied (:func:`_empty`) between runs.

    Connecting starts a new physics server, which costs far more CPU than
    stepping a short case. Emptied of the last run's bodies and constraints,
    with every run setting its parameters anew (``_Run._world``), a client
    gives a run the trajectory a fresh one would, bit for bit: a run does not
    depend on what ran in the client before it (``tests/test_engine_pybullet.py``
    checks every variant on four scenes, the multibody chains and closed loops
    included). The client is owned by the process that connected it: a forked
    child connects its own rather than drive its parent's copy.
    """

    def __init__(self) -> None:
        self._idle: dict[tuple[int, int], int] = {}  # (pid, thread id) -> client id

    @staticmethod
    def _key() -> tuple[int, int]:
        return os.getpid(), threading.get_ident()

    def take(self) -> int:
        """This thread's idle client, emptied; a new one when it has none (or it was disconnected)."""
        client = self._idle.pop(self._key(), None)
        if client is not None and _pb.isConnected(physicsClientId=client):
            _empty(client)
            return client
        return _pb.connect(_pb.DIRECT)

    def give_back(self, client: int) -> None:
        """Keep ``client`` for this thread's next run (take() left its slot empty)."""
        self._idle[self._key()] = client

    def drop(self, client: int) -> None:
        with contextlib.suppress(Exception):
            _pb.disconnect(physicsClientId=client)

    def drop_all(self) -> None:
        """Disconnect this process's idle clients (the next run connects a new one)."""
        pid = os.getpid()
        for key in [k for k in self._idle if k[0] == pid]:
            self.drop(self._idle.pop(key))


_clients = _Clients()


class _Run:
    """One simulation in one private PyBullet client."""

    def __init__(self, client: int, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]):
        self.client = client
        self.scene = scene
        self.schedule = schedule
        self.settings = settings
        self.links, closures = grow(scene)
        if closures and settings["formulation"] == "multibody":
            raise Unsupported(closures[0][1])
        self.closures = [k for k, _ in closures]
        self.inertia = float(settings["inertia_ratio"]) * scene.characteristic_length**2
        self.n_particles = len(scene.particles)
        self.n_constraints = len(scene.constraints)
        kept = _kept(settings)
        self.keep_motors = "motors" in kept
        # changeDynamics keywords: zero damping for every body and link, no sleeping for every body
        # (base), unless kept. activationState goes on bases only: given for a multibody link it
        # broke the multibody in 3.2.7 (the bead stopped swinging: energy drift 5e-2 of E*).
        self.damping: dict[str, Any] = {}
        self.activation: dict[str, Any] = {}
        if "damping" not in kept:
            self.damping.update(linearDamping=0.0, angularDamping=0.0)
        if "sleeping" not in kept:
            self.activation.update(activationState=_pb.ACTIVATION_STATE_DISABLE_SLEEPING)

    # -- building --

    def _world(self) -> None:
        pb, c, s = _pb, self.client, self.settings
        pb.setGravity(*self.scene.gravity, physicsClientId=c)
        pb.setPhysicsEngineParameter(
            fixedTimeStep=self.schedule.dt,
            numSubSteps=0,
            numSolverIterations=int(s["iterations"]),
            erp=float(s["erp"]),
            constraintSolverType=SOLVERS[s["solver"]],
            physicsClientId=c,
        )

    def _point_mass(self, body: int, link: int, particle: int, **dynamics: Any) -> None:
        """Give ``link`` of ``body`` the mass m of ``particle`` and the central inertia ``self.inertia`` · m per axis."""
        m = float(self.scene.masses[particle])
        # The mass goes with the inertia: localInertiaDiagonal alone zeroed a rigid body's mass.
        _pb.changeDynamics(body, link, mass=m, localInertiaDiagonal=[self.inertia * m] * 3, physicsClientId=self.client,
                           **dynamics)

    def _build_multibody(self) -> None:
        """One multibody per Pin; every particle a link with its joint at its parent."""
        pb, c = _pb, self.client
        q = self.scene.initial_positions
        v = self.scene.initial_velocities
        masses = self.scene.masses
        joint_type = pb.JOINT_REVOLUTE if self.scene.is_planar else pb.JOINT_SPHERICAL
        # Link handle per particle: (body id, link index); absolute angular velocity per particle.
        self.handles: list[tuple[int, int]] = [(-1, -1)] * self.n_particles
        omega = {}
        roots = [link for link in self.links if link.parent is None]
        for root in roots:
            members = [root]
            index_of = {root.particle: 0}
            for link in self.links:
                if link.parent is not None and link.parent in index_of:
                    index_of[link.particle] = len(members)
                    members.append(link)
            # Link frames sit at the joint, aligned with the scene frame at the initial state;
            # a link's joint is placed at its parent's particle (the parent link's centre of mass).
            positions, parents = [], []
            for link in members:
                if link.parent is None:
                    positions.append([0.0, 0.0, 0.0])  # the base frame is at the anchor
                    parents.append(0)  # 0 = the base; k = link k − 1
                else:
                    parent = self.links_by_particle[link.parent]
                    positions.append(list(q[link.parent] - parent.joint))
                    parents.append(index_of[link.parent] + 1)
            count = len(members)
            body = pb.createMultiBody(
                baseMass=0.0,
                baseCollisionShapeIndex=-1,
                baseVisualShapeIndex=-1,
                basePosition=list(root.joint),
                linkMasses=[float(masses[l.particle]) for l in members],
                linkCollisionShapeIndices=[-1] * count,
                linkVisualShapeIndices=[-1] * count,
                linkPositions=positions,
                linkOrientations=[[0.0, 0.0, 0.0, 1.0]] * count,
                linkInertialFramePositions=[list(q[l.particle] - l.joint) for l in members],
                linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * count,
                linkParentIndices=parents,
                linkJointTypes=[joint_type if l.slide is None else pb.JOINT_PRISMATIC for l in members],
                linkJointAxis=[[0.0, 1.0, 0.0] if l.slide is None else list(map(float, l.slide)) for l in members],
                physicsClientId=c,
            )
            pb.changeDynamics(body, -1, **self.damping, **self.activation, physicsClientId=c)
            for j, link in enumerate(members):
                i = link.particle
                self.handles[i] = (body, j)
                self._point_mass(body, j, i, jointDamping=0.0, **self.damping)
                if link.slide is not None:  # a prismatic joint: the speed along the line; no turning
                    omega[i] = np.zeros(3)
                    if not self.keep_motors:
                        pb.setJointMotorControl2(
                            body, j, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0, physicsClientId=c
                        )
                    pb.resetJointState(body, j, 0.0, targetVelocity=float(v[i] @ link.slide), physicsClientId=c)
                    continue
                v_parent = np.zeros(3) if link.parent is None else v[link.parent]
                omega[i] = _angular_velocity(q[i] - link.joint, v[i] - v_parent)
                relative = omega[i] - (np.zeros(3) if link.parent is None else omega[link.parent])
                if joint_type == pb.JOINT_REVOLUTE:
                    if not self.keep_motors:
                        # Disable PyBullet's default velocity motor: it holds the joint at rest.
                        pb.setJointMotorControl2(
                            body, j, pb.VELOCITY_CONTROL, targetVelocity=0.0, force=0.0, physicsClientId=c
                        )
                    pb.resetJointState(body, j, 0.0, targetVelocity=float(relative[1]), physicsClientId=c)
                else:
                    if not self.keep_motors:
                        pb.setJointMotorControlMultiDof(
                            body, j, pb.POSITION_CONTROL, targetPosition=[0.0, 0.0, 0.0, 1.0],
                            targetVelocity=[0.0, 0.0, 0.0], force=[0.0, 0.0, 0.0], physicsClientId=c,
                        )
                    # At the initial state every frame is aligned with the scene frame, so the
                    # joint's angular velocity (child frame) is the scene-frame relative rate.
                    pb.resetJointStateMultiDof(
                        body, j, targetValue=[0.0, 0.0, 0.0, 1.0], targetVelocity=list(map(float, relative)),
                        physicsClientId=c,
                    )

    def _build_p2p(self) -> None:
        """A body per particle carrying the arm to its parent; a point-to-point constraint at the arm's tip."""
        pb, c = _pb, self.client
        q = self.scene.initial_positions
        v = self.scene.initial_velocities
        self.bodies = [-1] * self.n_particles
        for i in range(self.n_particles):
            body = pb.createMultiBody(
                baseMass=float(self.scene.masses[i]), baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                basePosition=list(q[i]), physicsClientId=c,
            )
            self._point_mass(body, -1, i, **self.damping, **self.activation)
            self.bodies[i] = body
        omega = {}
        self.constraint_ids = [-1] * self.n_constraints
        # getConstraintState gives the impulse/dt on the constraint's child side (world frame): the
        # force on the particle carrying the arm is its negative (checked on a hanging bead: +m·g·z).
        self.force_sign = np.zeros(self.n_constraints)
        #: A rail's (JOINT_PRISMATIC) first two rows are impulses along two axes ⊥ the line, on the slider.
        self.slider_axes: dict[int, np.ndarray] = {}
        anchors: dict[tuple[float, ...], int] = {}
        for link in self.links:
            i = link.particle
            arm = link.joint - q[i]  # from the particle to its pivot, scene frame = body frame at rest
            if link.parent is None:
                key = tuple(link.joint)
                if key not in anchors:
                    anchors[key] = pb.createMultiBody(
                        baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                        basePosition=list(link.joint), physicsClientId=c,
                    )
                other = anchors[key]
                v_parent = np.zeros(3)
            else:
                other = self.bodies[link.parent]
                v_parent = v[link.parent]
            if link.slide is not None:  # a rail: a prismatic constraint to the anchor body, along the line
                omega[i] = np.zeros(3)
                cid = pb.createConstraint(
                    self.bodies[i], -1, other, -1, pb.JOINT_PRISMATIC, list(map(float, link.slide)),
                    parentFramePosition=[0.0, 0.0, 0.0], childFramePosition=[0.0, 0.0, 0.0], physicsClientId=c,
                )
                self.constraint_ids[link.constraint] = cid
                self.force_sign[link.constraint] = 1.0
                self.slider_axes[link.constraint] = _slider_axes(link.slide)
                continue
            omega[i] = _angular_velocity(-arm, v[i] - v_parent)
            cid = pb.createConstraint(
                self.bodies[i], -1, other, -1, pb.JOINT_POINT2POINT, [0.0, 0.0, 0.0],
                parentFramePosition=list(arm), childFramePosition=[0.0, 0.0, 0.0], physicsClientId=c,
            )
            self.constraint_ids[link.constraint] = cid
            self.force_sign[link.constraint] = -1.0 if link.first_is_self else 1.0
        for i, body in enumerate(self.bodies):
            pb.resetBaseVelocity(body, list(map(float, v[i])), list(map(float, omega[i])), physicsClientId=c)
        for k in self.closures:
            self._closure_arm(k, anchors)

    def _closure_arm(self, k: int, anchors: dict[tuple[float, ...], int]) -> None:
        """Close loop constraint k with a light rigid arm body between two ball joints.

        The arm's origin (and its mass, ``ARM_MASS_RATIO`` · the mean particle mass, with a
        central inertia of that mass times L²) sits at the constraint's far end: particle b of a
        Rod, or a Pin's anchor; a point-to-point constraint there, and one at the arm's other
        end to the first particle. That second one's force is the constraint's force on its first
        particle (getConstraintState gives it on the child side, the particle).
        """
        pb, c = _pb, self.client
        q, v = self.scene.initial_positions, self.scene.initial_velocities
        con = self.scene.constraints[k]
        mass = ARM_MASS_RATIO * float(self.scene.masses.mean())
        if isinstance(con, Pin):
            first, origin, origin_velocity = con.particle, np.asarray(con.anchor, float), np.zeros(3)
            key = tuple(origin)
            if key not in anchors:
                anchors[key] = pb.createMultiBody(
                    baseMass=0.0, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                    basePosition=list(origin), physicsClientId=c,
                )
            far_body = anchors[key]
        else:
            first, origin, origin_velocity = con.a, q[con.b], v[con.b]
            far_body = self.bodies[con.b]
        arm = pb.createMultiBody(baseMass=mass, baseCollisionShapeIndex=-1, baseVisualShapeIndex=-1,
                                 basePosition=list(origin), physicsClientId=c)
        length = self.scene.characteristic_length
        pb.changeDynamics(arm, -1, mass=mass, localInertiaDiagonal=[mass * length**2] * 3,
                          **self.damping, **self.activation, physicsClientId=c)
        r = q[first] - origin
        pb.resetBaseVelocity(arm, list(map(float, origin_velocity)),
                             list(map(float, _angular_velocity(r, v[first] - origin_velocity))), physicsClientId=c)
        pb.createConstraint(arm, -1, far_body, -1, pb.JOINT_POINT2POINT, [0.0, 0.0, 0.0],
                            parentFramePosition=[0.0, 0.0, 0.0], childFramePosition=[0.0, 0.0, 0.0],
                            physicsClientId=c)
        self.constraint_ids[k] = pb.createConstraint(
            arm, -1, self.bodies[first], -1, pb.JOINT_POINT2POINT, [0.0, 0.0, 0.0],
            parentFramePosition=list(map(float, r)), childFramePosition=[0.0, 0.0, 0.0], physicsClientId=c,
        )
        self.force_sign[k] = 1.0

    # -- reading --

    # The readers give what PyBullet gives, made arrays after the loop: the particles' positions (m)
    # and velocities (m/s) now, a list of P (x, y, z) tuples each; the constraints' states, one tuple each.

    def _state_multibody(self) -> tuple[list, list]:
        pb, c = _pb, self.client
        x, u = [], []
        for body, j in self.handles:
            # [0]: the link's centre of mass (the particle), [6]: its linear velocity, world frame.
            s = pb.getLinkState(body, j, computeLinkVelocity=1, computeForwardKinematics=1, physicsClientId=c)
            x.append(s[0])
            u.append(s[6])
        return x, u

    def _state_p2p(self) -> tuple[list, list]:
        pb, c = _pb, self.client
        return ([pb.getBasePositionAndOrientation(body, physicsClientId=c)[0] for body in self.bodies],
                [pb.getBaseVelocity(body, physicsClientId=c)[0] for body in self.bodies])

    def _forces_p2p(self) -> list:
        """Each constraint's getConstraintState now (impulse/dt rows, N), as PyBullet gives them."""
        pb, c = _pb, self.client
        return [pb.getConstraintState(cid, physicsClientId=c) for cid in self.constraint_ids]

    def _force_array(self, rows: list) -> np.ndarray:
        """(n, C, 3) N: each constraint's force on its first particle, from n samples of _forces_p2p."""
        f = np.empty((len(rows), self.n_constraints, 3))
        for k in range(self.n_constraints):
            raw = np.array([sample[k] for sample in rows], dtype=float)
            if k in self.slider_axes:
                for s, row in enumerate(raw):  # sample by sample: the same product as before, bit for bit
                    f[s, k] = row[:2] @ self.slider_axes[k]
            else:
                f[:, k] = self.force_sign[k] * raw[:, :3]
        return f

    # -- stepping --

    def execute(self) -> RawRun:
        pb, c = _pb, self.client
        self.links_by_particle = {link.particle: link for link in self.links}
        self._world()
        if self.settings["formulation"] == "multibody":
            self._build_multibody()
            state, forces = self._state_multibody, None
        else:
            self._build_p2p()
            state, forces = self._state_p2p, self._forces_p2p
        rec = Recorder(self.scene, self.schedule)
        x0, u0 = state()
        taken = 0
        f_rows: list = []  # samples 0, 1, ...: each the force reader's list, made an array after the loop

        def advance(n: int) -> None:
            for _ in range(n):
                pb.stepSimulation(physicsClientId=c)

        def read() -> tuple[list, list]:
            x, u = state()
            if forces:
                f_rows.append(forces())
            return x, u

        if forces:  # no step precedes t = 0: the first step's force stands in
            with rec.stepping():
                advance(1)
            taken = 1
            f_rows.append(forces())
        rec.record(0, x0, u0)
        rec.run(advance, read, taken=taken)
        return rec.raw_run(
            forces=self._force_array(f_rows) if forces else None,
            settings={
                "point_mass_inertia": f"{self.inertia:.6g}·m kg·m² about each axis (inertia_ratio · L²)",
                "joint": ("revolute about y" if self.scene.is_planar else "spherical")
                if self.settings["formulation"] == "multibody"
                else "JOINT_POINT2POINT",
            },
        )

ENGINE = PyBulletEngine()
