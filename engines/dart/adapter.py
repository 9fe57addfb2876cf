"""DART adapter (pip ``dartpy``): a Skeleton per scene in joint coordinates, stepped by DART's World or by RK4.

One body per particle, nested along the constraint tree hung from the Pins:
a revolute joint about +y per link of a planar scene, a prismatic joint along
a Line, a ball joint for a one-particle 3-D scene; every constraint holds by
construction. Each body's frame sits at its pivot with the world's
orientation in the scene's initial configuration (joint positions 0), its
point mass at the end of the arm. ``dart/world`` steps DART's own
``World.step`` (semi-implicit Euler, DART 6's only scheme); ``dart/rk4``
integrates DART's forward dynamics (``Skeleton.computeForwardDynamics``,
Featherstone's articulated-body algorithm) with the classic RK4 tableau in
this module, which isolates DART's dynamics from its integrator.
docs/engines.md ("DART") lists every default changed and what is refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Mapping

import numpy as np

from engines.adapter import Engine, ModelImport, Option, RawRun, Schedule, refuse_constraint_kinds, refuse_ellipse
from engines.dart import library
from engines.dart.rk4 import rk4_stepper
from engines.dart import model
from engines.errors import Unsupported
from engines.model.stepping import run_model
from engines.recorder import Recorder
from engines.scene.scene import Line, Pin, Rod, Scene, ModelSceneLike
from engines.scene.tree import Tree, read_tree

#: A ball joint's body needs rotational inertia (with none the spin about the arm has no mass and the
#: mass matrix is singular): this ratio of m·L² when inertia_ratio = 0 is asked for (MuJoCo's and Drake's too).
BALL_INERTIA_RATIO = 1e-9
#: Rotational inertia (fraction of m·L²) given about an axis a body never turns about, where it would be 0.
UNTURNED_INERTIA_RATIO = 1e-12


def point_mass_inertia(mass: float, arm: np.ndarray, inertia: float, fill: float) -> np.ndarray:
    """(6, 6) DART spatial inertia, in the body frame, of a mass (kg) at ``arm`` (m) with isotropic
    rotational inertia ``inertia`` (kg·m²) about it: [[I_c + m[c][c]ᵀ, m[c]], [m[c]ᵀ, m·1]].

    DART warns on stderr for a rotational inertia with a zero diagonal entry; such an entry is about an
    axis the body never turns about (x or z of a planar arm, any axis of a slider: the adapter's joints
    leave no other case), so it gets ``fill`` (kg·m²), which changes no motion.
    """
    c = np.asarray(arm, dtype=float)
    skew = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    moment = inertia * np.eye(3) + mass * skew @ skew.T
    moment[np.diag_indices(3)] = np.where(np.diag(moment) > 0, np.diag(moment), fill)
    tensor = np.zeros((6, 6))
    tensor[:3, :3] = moment
    tensor[:3, 3:] = mass * skew
    tensor[3:, :3] = mass * skew.T
    tensor[3:, 3:] = mass * np.eye(3)
    return tensor


class DartEngine(Engine):
    """DART: a Skeleton in joint coordinates; World.step (semi-implicit Euler) or RK4 over its forward dynamics."""

    name = "dart"
    capabilities = frozenset({"3d", "model"})
    options = {
        "integrator": Option(
            "integrator", "world",
            "world: DART's World.step (semi-implicit Euler); rk4: classic RK4 over DART's forward dynamics",
            kind="str", choices=("world", "rk4"),
        ),
        "inertia_ratio": Option(
            "inertia_ratio", 0.0,
            "rotational inertia of each point-mass body about its centre of mass, as a fraction of m·L² "
            f"(0: none; a ball joint then uses {BALL_INERTIA_RATIO:g})",
            low=0.0,
        ),
    }
    variants = {
        "world": {"integrator": "world"},
        "rk4": {"integrator": "rk4"},
    }
    variant_docs = {
        "world": "DART's World.step: semi-implicit Euler in joint coordinates (1st order), MuJoCo hinge's scheme",
        "rk4": "DART's forward dynamics (articulated-body algorithm) integrated by classic RK4 (4th order)",
    }
    overrides = {
        "World.gravity": "the scene's (DART's default is (0, 0, -9.81))",
        "BodyNode inertia": "a point mass at the end of each arm, set as a spatial tensor (see inertia_ratio)",
    }

    def version(self) -> str:
        return library.version()

    def preload(self, scenes) -> None:
        """Import dartpy in this process, so that case hosts forked from it inherit it."""
        library.dartpy()

    def _check_model(self, scene: ModelSceneLike, settings: Mapping[str, Any]) -> None:
        if scene.ball_joints and scene.file_format == "urdf":
            raise Unsupported(f"dart: its URDF reader (urdfdom) has no spherical joint ({', '.join(scene.ball_joints)}); "
                              f"DART steps ball joints from an MJCF")

    def _run_model(self, scene: ModelSceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        return run_model(scene, schedule, model.DartStepper(scene, schedule.dt, settings["integrator"]))

    def model_import(self) -> ModelImport:
        return ModelImport(model.version, model.load)

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        refuse_ellipse(scene, "dart: no DART joint moves a point on an ellipse (a revolute joint moves it on "
                              "a circle, a prismatic joint on a line)")
        refuse_constraint_kinds(scene, (Pin, Rod, Line), "dart")
        tree = read_tree(scene)
        if tree.loose:
            raise Unsupported(
                f"dart: particles {tree.loose} are not hung from a Pin or Line; the adapter builds chains of "
                "joints from fixed anchors (no free-floating bodies)"
            )
        if tree.closures:
            raise Unsupported(
                f"dart: constraint {tree.closures[0]} closes a loop; the adapter builds a tree of joints and "
                f"does not close loops with DART's joint constraints"
            )
        if not scene.is_planar:
            if len(scene.particles) != 1:
                raise Unsupported("dart: a 3-D scene is built with a ball joint, for one-particle scenes only")
            if settings["integrator"] == "rk4":
                raise Unsupported(
                    "dart/rk4: a ball joint's positions are a rotation vector whose rate is not its angular "
                    "velocity, so RK4 over (q, v) does not apply; use dart/world"
                )

    # -- building ----------------------------------------------------------------------

    def inertia(self, scene: Scene, settings: Mapping[str, Any]) -> np.ndarray:
        """(n,) kg·m²: each particle body's rotational inertia about its centre of mass (isotropic)."""
        ratio = settings["inertia_ratio"] or (0.0 if scene.is_planar else BALL_INERTIA_RATIO)
        return ratio * scene.masses * scene.characteristic_length**2

    def build(self, scene: Scene, settings: Mapping[str, Any]) -> "DartModel":
        """The skeleton of ``scene`` in a World with the scene's gravity, at its initial state."""
        dart = library.dartpy()

        tree = read_tree(scene)
        q = scene.initial_positions
        inertia = self.inertia(scene, settings)
        skeleton = dart.dynamics.Skeleton(scene.name)
        bodies: dict[int, Any] = {}
        for i in tree.order:
            parent = tree.parent[i]
            link = scene.constraints[tree.constraint_of[i]]
            # The parent's frame sits at its own pivot: this body's pivot is at (pivot − parent's pivot).
            offset = dart.math.Isometry3()
            offset.set_translation(tree.pivot[i] - (tree.pivot[parent] if parent >= 0 else 0.0))
            if isinstance(link, Line):
                properties = dart.dynamics.PrismaticJointProperties()
                properties.mAxis = np.asarray(link.unit, dtype=float)
                create = skeleton.createPrismaticJointAndBodyNodePair
            elif scene.is_planar:
                properties = dart.dynamics.RevoluteJointProperties()
                properties.mAxis = np.array([0.0, 1.0, 0.0])
                create = skeleton.createRevoluteJointAndBodyNodePair
            else:
                properties = dart.dynamics.BallJointProperties()
                create = skeleton.createBallJointAndBodyNodePair
            properties.mName = f"j{i}"
            properties.mT_ParentBodyToJoint = offset
            joint, body = create(bodies.get(parent), properties)
            body.setName(f"p{i}")
            mass = scene.particles[i].mass
            body.setInertia(dart.dynamics.Inertia(point_mass_inertia(
                mass, q[i] - tree.pivot[i], inertia[i], UNTURNED_INERTIA_RATIO * mass * scene.characteristic_length**2)))
            bodies[i] = body
        world = dart.simulation.World()
        world.setGravity(np.asarray(scene.gravity, dtype=float))
        world.addSkeleton(skeleton)
        model = DartModel(scene, tree, world, skeleton, [bodies[i] for i in range(len(scene.particles))], inertia)
        model.set_initial_state()
        return model

    # -- running -----------------------------------------------------------------------

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        model = self.build(scene, settings)
        dt = schedule.dt
        if settings["integrator"] == "world":
            model.world.setTimeStep(dt)
            step = model.world.step
        else:
            step = rk4_stepper(model.skeleton, dt)
        record = {
            "point_mass_inertia": [float(x) for x in model.inertia],
            "joints": model.joint_types(),
            "stepping": "World.step" if settings["integrator"] == "world" else
                        "RK4 over Skeleton.computeForwardDynamics",
        }
        recorder = Recorder(scene, schedule)
        recorder.record(0, *model.particles())

        def advance(steps: int) -> None:
            for _ in range(steps):
                step()

        recorder.run(advance, model.particles)
        return recorder.raw_run(settings=record)


@dataclass
class DartModel:
    """A built skeleton in its World, and what is needed to set and read its state in the scene's terms."""

    scene: Scene
    tree: Tree
    world: Any
    skeleton: Any
    bodies: list  # BodyNode of each particle, in scene order
    inertia: np.ndarray

    def set_initial_state(self) -> None:
        """Joint positions 0 (the build is the initial configuration) and joint rates from the particle velocities.

        Each link's absolute angular velocity ω solves ω × r = Δv with ω ⊥ r:
        ω = r × Δv / |r|² (r the arm, Δv the particle's velocity relative to its
        pivot); a joint's rate is relative to its parent's (a revolute's about
        +y; a ball joint's in its child frame, the world's at the start). A
        slider's rate is its speed along the line.
        """
        scene, tree = self.scene, self.tree
        q, v = scene.initial_positions, scene.initial_velocities
        omega: dict[int, np.ndarray] = {}
        rates = np.zeros(self.skeleton.getNumDofs())
        for i in tree.order:
            parent = tree.parent[i]
            joint = self.bodies[i].getParentJoint()
            dof = joint.getIndexInSkeleton(0)
            link = scene.constraints[tree.constraint_of[i]]
            if isinstance(link, Line):
                omega[i] = omega.get(parent, np.zeros(3))
                rates[dof] = float(v[i] @ link.unit)
                continue
            r = q[i] - tree.pivot[i]
            dv = v[i] - (v[parent] if parent >= 0 else 0.0)
            omega[i] = np.cross(r, dv) / float(r @ r)
            relative = omega[i] - omega.get(parent, np.zeros(3))
            if scene.is_planar:
                rates[dof] = relative[1]
            else:
                rates[dof : dof + 3] = relative
        self.skeleton.setPositions(np.zeros(self.skeleton.getNumDofs()))
        self.skeleton.setVelocities(rates)

    def particles(self) -> tuple[np.ndarray, np.ndarray]:
        """(P, 3) m positions and (P, 3) m/s velocities of the particles (the bodies' centres of mass)."""
        positions = np.array([body.getCOM() for body in self.bodies])
        velocities = np.array([body.getCOMLinearVelocity() for body in self.bodies])
        return positions, velocities

    def joint_types(self) -> list[str]:
        return [body.getParentJoint().getType() for body in self.bodies]


ENGINE = DartEngine()
