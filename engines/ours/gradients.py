"""ours' own derivatives: forward sensitivities by its tangent-linear step (ours.sensitivity), for every parameter.

Each parameter's direction in ours' state (the particles' positions and velocities on the scene's axes: ours'
state is the outputs themselves) comes from engines.gradients.initial_output_directions; g, masses and lengths
also move ours' model (the packed arrays 1/m, m·g, l², …), whose derivative is taken from the scene's own
builder (ours.sensitivity.ModelDirections.of: differences of the built System, no run). One tangent-linear run
carries every parameter to T, for every cure and integrator (the lagrangian method's in link angles): the
derivative of what ours computes, exact to round-off. Model files (ours' rigid bodies) are
engines/ours/rigid_gradients.py's (:func:`model_jacobian`).
"""

from __future__ import annotations

from typing import Any, Callable, Mapping, Sequence

import numpy as np

from engines.adapter import Schedule
from engines.gradients import SAMPLE_INTERVAL, initial_output_directions, is_initial_condition, parameter_step
from engines.scene.parameters import outputs_of, perturbed
from engines.scene.scene import Scene

#: The relative step of the differences of ours' model arrays along a physical parameter (they are 1/m, m·g
#: and l²: with one Richardson step, O(h⁴) ≈ 1e-16, and no run is differenced).
MODEL_STEP = 1e-4


def jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str], to_system: Any) -> tuple[np.ndarray, str, np.ndarray, np.ndarray] | None:
    """(J (m, k), method, times (n,) s, J at each (n, m, k)), or None where ours has no derivative of its own
    (then differences of rollouts answer). ``engine`` : ours' adapter; to_system : its map from a scene to
    (System, q0, v0, axes)."""
    if scene.is_model:
        return model_jacobian(engine, scene, variant, options, dt, wrt)
    return particle_jacobian(engine, scene, variant, options, dt, wrt, to_system)


def model_jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                   wrt: Sequence[str]) -> tuple[np.ndarray, str, np.ndarray, np.ndarray] | None:
    """A model file: ours' rigid bodies' own derivatives (engines/ours/rigid_gradients.py)."""
    from engines.ours import rigid_gradients

    return rigid_gradients.jacobian(engine, scene, variant, options, dt, wrt)


def particle_jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
                      wrt: Sequence[str], to_system: Any) -> tuple[np.ndarray, str, np.ndarray, np.ndarray] | None:
    """(J (6P, k), "analytic", times (n,) s, J at each (n, 6P, k)) by the tangent-linear step, sampled as
    differences of rollouts are (every SAMPLE_INTERVAL), for every cure and integrator, ``lagrangian`` too; None
    for a run that stops early (differences of rollouts then say what it does)."""
    from ours.sensitivity import forward_sensitivities

    settings = engine.resolve(variant, options)
    if not wrt:
        return None
    system, q0, v0, dq0, dv0, dmodel, axes = directions(scene, wrt, to_system)
    schedule = Schedule.make(scene.duration, dt, SAMPLE_INTERVAL)
    k, P = len(wrt), len(scene.particles)
    result = forward_sensitivities(
        system, q0, v0, dq0, dv0, dt, schedule.n_steps,
        dmodel=dmodel, method=settings["method"], integrator=settings["integrator"], k_s=settings["k_s"],
        k_d=settings["k_d"], tolerance=settings["tolerance"], max_iterations=settings["max_iterations"],
        sample_every=schedule.stride)
    if result.status != "ok":
        return None  # a run that stopped early has no derivative at T: differences of rollouts say what it does
    shape = (len(result.sample_steps), k, P, 3)
    positions, velocities = np.zeros(shape), np.zeros(shape)
    positions[..., axes], velocities[..., axes] = result.sample_dq, result.sample_dv
    series = np.swapaxes(outputs_of(positions, velocities), 1, 2)  # (n, m, k)
    return series[-1], "analytic", result.sample_steps * dt, series


def directions(scene: Scene, wrt: Sequence[str], to_system: Any) -> tuple:
    """(System, q0, v0, dq0, dv0 (k, P, dim), dmodel or None, axes): ours' run of ``scene`` and each parameter's
    direction in it: its state's from the scene's initial outputs, its model's (g, masses, lengths) from the
    System built at p ± h (``ours.sensitivity.ModelDirections.of``; None when no parameter moves the model)."""
    from ours.sensitivity import ModelDirections

    system, q0, v0, axes = to_system(scene)
    k, P = len(wrt), len(scene.particles)
    moved = initial_output_directions(scene, wrt).T.reshape(k, P, 6)
    moving = [not is_initial_condition(scene, name) for name in wrt]
    dmodel = None
    if any(moving):
        def system_at(name: str) -> Callable[[float], Any]:
            return lambda delta: to_system(perturbed(scene, name, delta))[0]

        dmodel = ModelDirections.stack([
            ModelDirections.of(system_at(name), parameter_step(scene, name, MODEL_STEP)) if moves
            else ModelDirections.zeros(system, 1) for name, moves in zip(wrt, moving)])
    return system, q0, v0, moved[:, :, axes], moved[:, :, [3 + a for a in axes]], dmodel, axes
