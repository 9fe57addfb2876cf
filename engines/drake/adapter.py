"""Drake adapter: a MultibodyPlant per scene, stepped by Drake's own integrators or its discrete plant.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/drake/adapter.py``.
"""

from __future__ import annotations

import time
from typing import Any, Mapping, cast

import numpy as np

from engines.adapter import Engine, ModelImport, Option, RawRun, Schedule, refuse_constraint_kinds
from engines.drake import library as drake
from engines.drake import model
from engines.errors import Unsupported, UserError
from engines.model.stepping import run_model
from engines.scene.scene import Pin, Rod, Scene, ModelSceneLike
from engines.scene.tree import Tree, read_tree

#: Drake's scheme names (``ResetIntegratorFromFlags``) by this adapter's integrator option value.
SCHEMES = {
    "rk3": "runge_kutta3",
    "rk5": "runge_kutta5",
    "bs3": "bogacki_shampine3",
    "radau3": "radau3",
    "rk2": "runge_kutta2",
    "semi-explicit-euler": "semi_explicit_euler",
}
#: Integrators Drake runs with error control; the others only in fixed-step mode.
ERROR_CONTROLLED = ("rk3", "rk5", "bs3", "radau3")

#: Drake's Simulator defaults (RK3 at accuracy 1e-4, largest step 0.1 s), read from a bare plant's Simulator.
DRAKE_DEFAULT_ACCURACY = 1e-4

#: A 3-D (ball-joint) body needs rotational inertia; this ratio (of m·L²) when inertia_ratio = 0 is asked for.
BALL_INERTIA_RATIO = 1e-9

#: The option an error-controlled variant's tolerance sets (see the tolerance capability).
TOLERANCE_OPTION = "accuracy"


class DrakeEngine(Engine):
    """Drake: MultibodyPlant in joint coordinates; continuous with Drake's integrators, or discrete (SAP)."""

    name = "drake"
    capabilities = frozenset({"3d", "constraint-forces", "tolerance", "model"})
    #: Option that a tolerance case sets to its tolerance, for variants with error control.
    tolerance_options = (TOLERANCE_OPTION,)
    options = {
        "plant": Option(
            "plant", "continuous",
            "continuous: MultibodyPlant(time_step=0) stepped by the Simulator's integrator; "
            "discrete: MultibodyPlant(time_step=dt), SAP, Drake's own time stepping",
            kind="str", choices=("continuous", "discrete"),
        ),
        "integrator": Option(
            "integrator", "rk3", "Drake integrator of the continuous plant (rk3 is the Simulator's default)",
            kind="str", choices=tuple(SCHEMES),
        ),
        "error_control": Option(
            "error_control", True,
            "true: Drake picks the step to meet accuracy, dt is the largest step; false: fixed step dt",
            kind="bool",
        ),
        TOLERANCE_OPTION: Option(
            TOLERANCE_OPTION, DRAKE_DEFAULT_ACCURACY,
            "target accuracy of an error-controlled integrator (Drake's set_target_accuracy; default 1e-4)",
        ),
        "inertia_ratio": Option(
            "inertia_ratio", 0.0,
            "rotational inertia of each point-mass body about its centre of mass, as a fraction of m·L² "
            f"(0: none; a ball joint then uses {BALL_INERTIA_RATIO:g})",
        ),
    }
    variants = {
        "rk3": {"integrator": "rk3"},
        "rk5": {"integrator": "rk5"},
        "bs3": {"integrator": "bs3"},
        "radau3": {"integrator": "radau3"},
        "rk2": {"integrator": "rk2", "error_control": False},
        "semi-explicit-euler": {"integrator": "semi-explicit-euler", "error_control": False},
        "discrete": {"plant": "discrete", "error_control": False},
    }
    variant_docs = {
        "rk3": "continuous plant, Runge–Kutta 3 with error control at accuracy (Drake's default integrator)",
        "rk5": "continuous plant, Runge–Kutta 5 (Dormand–Prince) with error control at accuracy",
        "bs3": "continuous plant, Bogacki–Shampine 3 with error control at accuracy",
        "radau3": "continuous plant, implicit 3rd-order Radau IIA with error control at accuracy",
        "rk2": "continuous plant, explicit midpoint (2nd order), fixed step dt",
        "semi-explicit-euler": "continuous plant, symplectic Euler (1st order), fixed step dt",
        "discrete": "discrete plant (time_step = dt, SAP): symplectic Euler without contact",
    }
    overrides = {
        "MultibodyPlant.time_step": "0 (continuous) or dt (discrete); MultibodyPlantConfig's default is 0.001",
        "Simulator.integrator": "the variant's (the Simulator's default is RK3 at accuracy 1e-4, largest step 0.1 s)",
        "discrete_contact_approximation": "kSap (a bare plant's default is kLagged); there is no contact",
        "use_sampled_output_ports": "false, so reaction forces are computed from the sampled state",
    }

    def version(self) -> str:
        return drake.version()

    def preload(self, scenes) -> None:
        """Import pydrake's plant, frames and simulator in this process, so that case hosts forked from it
        (a run whose suite uses Drake) inherit them instead of each importing them again."""
        drake.preload()

    def tolerance_capable(self, settings: Mapping[str, Any]) -> bool:
        """Whether these settings run with error control, so that ``accuracy`` (not dt) sets the error."""
        return settings["plant"] == "continuous" and settings["error_control"]

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        refuse_constraint_kinds(scene, (Pin, Rod), "drake")  # it builds them as revolute (or ball) joints
        tree = read_tree(scene)
        if tree.loose:
            raise Unsupported(
                f"drake: particles {tree.loose} are not hung from a Pin; the adapter builds chains of joints "
                "from fixed anchors (no free-floating bodies)"
            )
        if tree.closures:
            raise Unsupported(
                f"drake: constraint {tree.closures[0]} closes a loop; the adapter builds a tree of joints, and a "
                f"continuous MultibodyPlant has no constraint to close it"
            )
        if not scene.is_planar and len(scene.particles) != 1:
            raise Unsupported(
                "drake: a 3-D scene is built with a ball joint per particle, and only one-particle 3-D scenes "
                "keep the roll-pitch-yaw ball joint away from its singular pitch"
            )

    def _run_model(self, scene: ModelSceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        return run_model(scene, schedule, model.DrakeStepper(
            scene, schedule.dt, SCHEMES[settings["integrator"]], not settings["error_control"], settings["accuracy"]))

    def model_import(self) -> ModelImport:
        return ModelImport(model.version, model.load)

    def _check_model(self, scene: ModelSceneLike, settings: Mapping[str, Any]) -> None:
        if settings["plant"] == "discrete":
            raise Unsupported("drake/discrete: a model file is loaded into a continuous plant; use the "
                              "integrator variants (rk3, rk5, bs3, radau3, rk2, semi-explicit-euler)")
        scene.refuse_kept_dynamics(self.name)

    def _check_options(self, settings: Mapping[str, Any]) -> None:
        if settings[TOLERANCE_OPTION] <= 0:
            raise UserError(f"drake: option accuracy must be positive, got {settings[TOLERANCE_OPTION]}")
        if settings["inertia_ratio"] < 0:
            raise UserError(f"drake: option inertia_ratio must be ≥ 0, got {settings['inertia_ratio']}")
        if (settings["plant"] == "continuous" and settings["error_control"]
                and settings["integrator"] not in ERROR_CONTROLLED):
            raise UserError(
                f"drake: integrator {settings['integrator']} has no error estimate; set error_control = false "
                f"or choose one of {', '.join(ERROR_CONTROLLED)}"
            )

    # -- building ----------------------------------------------------------------------

    def inertia(self, scene: Scene, settings: Mapping[str, Any]) -> np.ndarray:
        """(n,) kg·m²: each particle body's rotational inertia about its centre of mass (isotropic)."""
        ratio = settings["inertia_ratio"]
        if ratio == 0 and not scene.is_planar:
            ratio = BALL_INERTIA_RATIO
        return ratio * scene.masses * scene.characteristic_length**2

    def build(self, scene: Scene, time_step: float, settings: Mapping[str, Any]) -> "DrakeModel":
        """The finalized plant for ``scene`` (time_step s: 0 continuous, dt discrete) and its joints."""
        RigidTransform = drake.RigidTransform
        DiscreteContactApproximation, MultibodyPlant = drake.DiscreteContactApproximation, drake.MultibodyPlant
        BallRpyJoint, RevoluteJoint, RotationalInertia, SpatialInertia = drake.BallRpyJoint, drake.RevoluteJoint, drake.RotationalInertia, drake.SpatialInertia

        tree = read_tree(scene)
        q = scene.initial_positions
        inertia = self.inertia(scene, settings)
        plant = MultibodyPlant(time_step)
        if time_step > 0:
            plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
        plant.mutable_gravity_field().set_gravity_vector(np.asarray(scene.gravity, dtype=float))
        bodies: dict[int, Any] = {}
        joints: dict[int, Any] = {}
        for i in tree.order:
            arm = q[i] - tree.pivot[i]
            spatial = SpatialInertia.MakeFromCentralInertia(
                scene.particles[i].mass, arm, RotationalInertia(inertia[i], inertia[i], inertia[i])
            )
            body = plant.AddRigidBody(f"p{i}", spatial)
            parent = plant.world_body() if tree.parent[i] == -1 else bodies[tree.parent[i]]
            # The parent's frame sits at its own pivot: this body's pivot is at (pivot − parent's pivot).
            offset = tree.pivot[i] - (0.0 if tree.parent[i] == -1 else tree.pivot[tree.parent[i]])
            joint: Any
            if scene.is_planar:
                on_parent = plant.AddFrame(_fixed_frame(f"pivot{i}", parent.body_frame(), RigidTransform(offset)))
                joint = RevoluteJoint(f"j{i}", on_parent, body.body_frame(), np.array([0.0, 1.0, 0.0]), damping=0.0)
            else:
                # x of the child's joint frame along the arm, so pitch ±90° is the arm vertical
                # (docs/engines.md, "Adapter notes").
                R_BM = _frame_with_x_along(arm)
                on_parent = plant.AddFrame(_fixed_frame(f"pivot{i}", parent.body_frame(), RigidTransform(offset)))
                on_child = plant.AddFrame(_fixed_frame(f"arm{i}", body.body_frame(), RigidTransform(R_BM, np.zeros(3))))
                joint = BallRpyJoint(f"j{i}", on_parent, on_child, damping=0.0)
            joints[i] = plant.AddJoint(joint)
            bodies[i] = body
        plant.SetUseSampledOutputPorts(False)
        plant.Finalize()
        return DrakeModel(scene, plant, tree, bodies, joints, inertia)

    def jacobian(self, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                 wrt: list[str]) -> tuple[np.ndarray, str] | None:
        """AutoDiffXd through the plant and its fixed-step integrator (engines/drake/gradients.py); None for
        error-controlled and discrete variants."""
        from engines.drake import gradients

        return gradients.jacobian(self, scene, variant, options, dt, wrt, SCHEMES)

    # -- running -----------------------------------------------------------------------

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        ResetIntegratorFromFlags, Simulator = drake.ResetIntegratorFromFlags, drake.Simulator

        discrete = settings["plant"] == "discrete"
        model = self.build(scene, schedule.dt if discrete else 0.0, settings)
        plant = model.plant
        simulator = Simulator(plant)
        context = simulator.get_mutable_context()
        model.set_initial_state(context)
        record: dict[str, Any] = {
            "point_mass_inertia": [float(x) for x in model.inertia],
            "time_step": float(plant.time_step()),
        }
        integrator = None
        fixed = discrete or not settings["error_control"]
        if not discrete:
            integrator = ResetIntegratorFromFlags(simulator, SCHEMES[settings["integrator"]], schedule.dt)
            integrator.set_fixed_step_mode(fixed)
            if not fixed:
                integrator.set_target_accuracy(settings[TOLERANCE_OPTION])
            record.update({
                "drake_integrator": type(integrator).__name__,
                "fixed_step_mode": bool(integrator.get_fixed_step_mode()),
                "maximum_step_size": float(integrator.get_maximum_step_size()),
                "target_accuracy": None if fixed else float(integrator.get_target_accuracy()),
            })
        else:
            record["discrete_contact_approximation"] = plant.get_discrete_contact_approximation().name
            record["discrete_contact_solver"] = plant.get_discrete_contact_solver().name
        simulator.Initialize()

        targets = _sample_targets(schedule, running_sum=fixed and not discrete)
        nq_nv = plant.num_positions() + plant.num_velocities()
        states = np.empty((len(targets), nq_nv))
        states[0] = plant.GetPositionsAndVelocities(context)
        wall, recorded, message = 0.0, 1, ""
        try:
            for k in range(1, len(targets)):
                t0 = time.perf_counter()
                simulator.AdvanceTo(targets[k])
                wall += time.perf_counter() - t0
                state = plant.GetPositionsAndVelocities(context)
                if not np.isfinite(state).all():
                    # Blown up: keep the finite samples (model.read would trip Drake's AllFinite(q_v) check,
                    # which pydrake raises as SystemExit); the run ends unstable with this message.
                    message = f"non-finite state at t = {targets[k]:.6g} s"
                    break
                states[k] = state
                recorded += 1
        except RuntimeError as exc:  # e.g. the error-controlled step fell below its minimum
            message = f"Drake stopped at t = {context.get_time():.6g} s: {str(exc).splitlines()[0]}"
        if discrete:
            steps = int(simulator.get_num_discrete_updates() + simulator.get_num_unrestricted_updates())
        else:
            steps = int(integrator.get_num_steps_taken())
            record["derivative_evaluations"] = int(integrator.get_num_derivative_evaluations())
            if not fixed:
                record["smallest_step"] = float(integrator.get_smallest_adapted_step_size_taken())
                record["largest_step"] = float(integrator.get_largest_step_size_taken())
        positions, velocities, forces = model.read(states[:recorded])
        return RawRun(positions, velocities, forces, steps=steps, wall_time=wall, message=message, settings=record)


def _fixed_frame(name: str, parent_frame, X):
    FixedOffsetFrame = drake.FixedOffsetFrame

    return FixedOffsetFrame(name, parent_frame, X)


def _frame_with_x_along(direction: np.ndarray) -> Any:
    """A rotation whose first column is ``direction`` (normalized); the others complete a right-handed frame."""
    RotationMatrix = drake.RotationMatrix

    x = np.asarray(direction, dtype=float) / np.linalg.norm(direction)
    helper = np.array([0.0, 0.0, 1.0]) if abs(x[2]) < 0.9 else np.array([1.0, 0.0, 0.0])
    y = np.cross(helper, x)
    y /= np.linalg.norm(y)
    z = np.cross(x, y)
    return RotationMatrix(np.column_stack([x, y, z]))


def _sample_targets(schedule: Schedule, running_sum: bool) -> list[float]:
    """(n_samples,) s: the times at which the state is sampled.

    running_sum (a fixed-step integrator): the sum ``t += dt`` that is the
    integrator's clock, read at each sample step, so it reaches every target in
    whole steps. Otherwise k·dt at the sample steps k: an error-controlled
    integrator lands on any target, and the discrete plant's updates are
    scheduled at k·dt (a running-sum target falls short of k·dt by a rounding
    error and leaves that update undone, one step behind).
    """
    steps = schedule.sample_steps
    if not running_sum:
        return [float(s) * schedule.dt for s in steps]
    targets, t, done = [0.0], 0.0, 0
    for s in steps[1:]:
        for _ in range(int(s) - done):
            t += schedule.dt
        done = int(s)
        targets.append(t)
    return targets


class DrakeModel:
    """A built plant and what is needed to set and read its state in the scene's terms."""

    def __init__(self, scene: Scene, plant: Any, tree: Tree, bodies: dict, joints: dict,
                 inertia: np.ndarray) -> None:
        self.scene, self.plant, self.tree, self.bodies, self.joints, self.inertia = (
            scene, plant, tree, bodies, joints, inertia
        )
        q = scene.initial_positions
        self.arms = {i: q[i] - tree.pivot[i] for i in tree.order}

    def set_initial_state(self, context) -> None:
        """Angles at the initial configuration (0 for hinges) and joint rates from the particle velocities.

        Each link's absolute angular velocity ω solves ω × r = Δv with ω ⊥ r:
        ω = r × Δv / |r|² (r the arm, Δv the particle's velocity relative to its
        pivot); a revolute joint's rate is (ω − ω_parent)·ŷ.
        """
        RollPitchYaw = drake.RollPitchYaw

        scene, tree = self.scene, self.tree
        plant_context = context
        v = scene.initial_velocities
        omega = {}
        for i in tree.order:
            parent = tree.parent[i]
            r = self.arms[i]
            dv = v[i] - (v[parent] if parent >= 0 else 0.0)
            omega[i] = np.cross(r, dv) / float(r @ r)
            relative = omega[i] - (omega[parent] if parent >= 0 else 0.0)
            joint = self.joints[i]
            if scene.is_planar:
                joint.set_angle(plant_context, 0.0)
                joint.set_angular_rate(plant_context, float(relative[1]))
            else:
                # Joint frame M on the child is R_BM; at the start the body is aligned with the world (F).
                R_FM = _frame_with_x_along(r)
                joint.set_angles(plant_context, RollPitchYaw(R_FM).vector())
                joint.set_angular_velocity(plant_context, relative)

    def read(self, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions (n, P, 3) m, velocities (n, P, 3) m/s and constraint forces (n, C, 3) N at each state.

        states : (n, nq + nv), joint positions then velocities as the plant orders them.
        The force on each particle from its link is the reaction force on its body at the
        joint (Drake's F_CJc_Jc, rotated into the world); it is stored on the constraint's
        first particle (negated when that is the parent).
        """
        scene, plant, tree = self.scene, self.plant, self.tree
        n, n_p, n_c = len(states), len(scene.particles), len(scene.constraints)
        positions, velocities, forces = np.empty((n, n_p, 3)), np.empty((n, n_p, 3)), np.empty((n, n_c, 3))
        context = plant.CreateDefaultContext()
        port = plant.get_reaction_forces_output_port()
        for s, x in enumerate(states):
            plant.SetPositionsAndVelocities(context, x)
            reactions = cast("list[Any]", port.Eval(context))  # Eval is typed object: here a SpatialForce per joint
            for i in tree.order:
                body = self.bodies[i]
                X_WB = body.EvalPoseInWorld(context)
                r_W = X_WB.rotation().multiply(self.arms[i])
                positions[s, i] = X_WB.translation() + r_W
                V = body.EvalSpatialVelocityInWorld(context)
                velocities[s, i] = V.translational() + np.cross(V.rotational(), r_W)
                joint = self.joints[i]
                R_WJc = joint.frame_on_child().CalcPoseInWorld(context).rotation()
                on_child = R_WJc.multiply(reactions[int(joint.index())].translational())
                k = tree.constraint_of[i]
                c = scene.constraints[k]
                forces[s, k] = on_child if isinstance(c, Pin) or c.a == i else -on_child
        return positions, velocities, forces


ENGINE = DrakeEngine()
