"""Each engine's stepper for model scenes, built on its import of the file (``engines.model.<engine>.load``).

The imports already neutralise the file's joint damping, friction and
armature and leave out contacts; the steppers also make sure joint limits
are not enforced (MuJoCo: constraints disabled; DART: limit enforcement off
per joint; Drake's continuous plant and PyBullet's multibody without motors
enforce none), set the time step and the integrator, and put the scene's
initial state in place. Each engine library is imported only by its stepper.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from engines.model.stepping import file_values


def _common(scene: Any, loaded: Any) -> dict[str, Any]:
    """Settings every model run records: the import's options and notes, and what the file's joint
    damping and friction were (set to 0, or the damping kept; contacts and joint limits are off)."""
    return {
        "model": scene.model,
        "import_options": dict(loaded.options),
        "import_notes": list(loaded.notes),
        "file_damping_friction": file_values(scene),
        "file_dynamics": ("keep: the file's joint damping kept (no friction in the file)" if scene.file_dynamics == "keep"
                          else "neutral: joint damping, friction and armature set to 0"),
        "contacts": "off", "joint_limits": "off",
    }


def _kept_damping(scene: Any) -> np.ndarray:
    """(nq,) N·m·s/rad (N·s/m): the file's joint damping in the model's joint order when kept, else 0."""
    keep = scene.file_dynamics == "keep"
    return np.array([j.damping if keep else 0.0 for j in scene.description.moving_joints])


class MujocoStepper:
    """MuJoCo: the compiled file (engines.model.mujoco), ``mj_step`` with the variant's integrator."""

    def __init__(self, scene: Any, dt: float, integrator: str) -> None:
        import mujoco

        from engines.model import mujoco as importer

        self.mujoco = mujoco
        loaded = importer.load(scene.source, scene.description)
        self.model, self.data = loaded.model, loaded.data
        self.model.opt.timestep = dt
        self.model.opt.integrator = int(getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}"))
        self.qpos, self.dof = loaded.qpos, loaded.dof
        self.model.dof_damping[self.dof] = _kept_damping(scene)
        self.data.qpos[:] = 0.0
        self.data.qvel[:] = 0.0
        self.data.qpos[self.qpos] = scene.initial_q
        self.data.qvel[self.dof] = scene.initial_v
        mujoco.mj_forward(self.model, self.data)
        self.settings = {**_common(scene, loaded), "integrator": integrator,
                         "disableflags": int(self.model.opt.disableflags)}

    def advance(self, steps: int) -> None:
        self.mujoco.mj_step(self.model, self.data, nstep=steps)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return self.data.qpos[self.qpos].copy(), self.data.qvel[self.dof].copy()


class DartStepper:
    """DART: the file's Skeleton (engines.model.dart) in a World (``world``) or RK4 over its dynamics (``rk4``)."""

    def __init__(self, scene: Any, dt: float, integrator: str) -> None:
        import dartpy as dart

        from engines.adapters.dart import rk4_stepper as rk4_step
        from engines.model import dart as importer

        loaded = importer.load(scene.source, scene.description)
        skeleton = self.skeleton = loaded.skeleton
        for k in range(skeleton.getNumJoints()):
            skeleton.getJoint(k).setLimitEnforcement(False)
        self.dof = loaded.dof
        for dof, damping in zip(self.dof, _kept_damping(scene)):
            skeleton.getDof(int(dof)).setDampingCoefficient(float(damping))
        positions, velocities = np.zeros(skeleton.getNumDofs()), np.zeros(skeleton.getNumDofs())
        positions[self.dof], velocities[self.dof] = scene.initial_q, scene.initial_v
        skeleton.setPositions(positions)
        skeleton.setVelocities(velocities)
        skeleton.setForces(np.zeros(skeleton.getNumDofs()))
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
            self.step = rk4_step(skeleton, dt)
        self.settings = {**_common(scene, loaded), "integrator": integrator, "position_limits": "not enforced"}

    def advance(self, steps: int) -> None:
        for _ in range(steps):
            self.step()

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        return (np.asarray(self.skeleton.getPositions())[self.dof].copy(),
                np.asarray(self.skeleton.getVelocities())[self.dof].copy())


class DrakeStepper:
    """Drake: the file's continuous MultibodyPlant (engines.model.drake) under a Simulator with the variant's
    integrator (``scheme``: Drake's name), fixed step dt or error control at ``accuracy`` with dt the largest step."""

    def __init__(self, scene: Any, dt: float, scheme: str, fixed: bool, accuracy: float) -> None:
        from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator

        from engines.model import drake as importer

        loaded = importer.load(scene.source, scene.description)
        plant = self.plant = loaded.plant
        self.simulator = Simulator(plant)
        self.context = self.simulator.get_mutable_context()
        plant.get_applied_generalized_force_input_port().FixValue(self.context, np.zeros(plant.num_velocities()))
        positions, velocities = np.zeros(plant.num_positions()), np.zeros(plant.num_velocities())
        positions[loaded.qpos], velocities[loaded.dof] = scene.initial_q, scene.initial_v
        plant.SetPositionsAndVelocities(self.context, np.concatenate([positions, velocities]))
        self.qpos, self.dof, self.nq = loaded.qpos, loaded.dof, plant.num_positions()
        integrator = self.integrator = ResetIntegratorFromFlags(self.simulator, scheme, dt)
        integrator.set_fixed_step_mode(fixed)
        if not fixed:
            integrator.set_target_accuracy(accuracy)
        self.simulator.Initialize()
        self.dt, self.time = dt, 0.0
        self.settings = {**_common(scene, loaded), "drake_integrator": type(integrator).__name__,
                         "fixed_step_mode": fixed, "target_accuracy": None if fixed else accuracy}

    def advance(self, steps: int) -> None:
        for _ in range(steps):  # the integrator's own clock, t += dt, so no sliver steps (engines/adapters/drake.py)
            self.time += self.dt
        self.simulator.AdvanceTo(self.time)

    def steps_taken(self) -> int:
        return int(self.integrator.get_num_steps_taken())

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        x = self.plant.GetPositionsAndVelocities(self.context)
        return x[self.qpos].copy(), x[self.nq:][self.dof].copy()


class PyBulletStepper:
    """PyBullet: the file's multibody (engines.model.pybullet), ``stepSimulation`` at fixedTimeStep dt."""

    def __init__(self, scene: Any, dt: float) -> None:
        from engines.model import pybullet as importer
        from engines.adapters.pybullet import _pb as pb
        from engines.stdio import quiet_output

        self.pb, self.quiet = pb, quiet_output
        loaded = self.loaded = importer.load(_without_limits(scene.source), scene.description)
        self.kw = {"physicsClientId": loaded.client}
        pb.setPhysicsEngineParameter(fixedTimeStep=dt, numSubSteps=0, **self.kw)
        for joint, position, velocity in zip(loaded.joints, scene.initial_q, scene.initial_v):
            pb.resetJointState(loaded.body, joint, float(position), float(velocity), **self.kw)
        self.settings = {**_common(scene, loaded), "fixedTimeStep": dt, "numSubSteps": 0,
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
    import xml.etree.ElementTree as ET
    from dataclasses import replace

    if source.format != "urdf":
        return source
    root = ET.fromstring(source.text)
    for limit in root.iter("limit"):
        limit.set("lower", "1")
        limit.set("upper", "-1")
    return replace(source, text=ET.tostring(root, encoding="unicode"), keep_empty_ranges=True)


def stepper(engine: str, scene: Any, dt: float, settings: dict[str, Any]) -> Any:
    """The stepper of ``engine`` (an adapter's name) for ``scene`` at step ``dt`` (s), from the adapter's
    resolved ``settings`` (the variant's integrator)."""
    if engine == "mujoco":
        return MujocoStepper(scene, dt, settings["integrator"])
    if engine == "dart":
        return DartStepper(scene, dt, settings["integrator"])
    if engine == "drake":
        from engines.adapters.drake import SCHEMES  # the variant's integrator by Drake's own name

        return DrakeStepper(scene, dt, SCHEMES[settings["integrator"]], not settings["error_control"],
                            settings["accuracy"])
    if engine == "pybullet":
        return PyBulletStepper(scene, dt)
    if engine == "ours":  # ours' rigid bodies in maximal coordinates, from the description (engines/model/ours.py)
        from engines.model.ours import OursStepper

        return OursStepper(scene, dt, settings["method"], settings["integrator"], k_s=settings["k_s"],
                           k_d=settings["k_d"], tolerance=settings["tolerance"],
                           max_iterations=settings["max_iterations"])
    raise ValueError(f"no model stepper for engine {engine!r}")
