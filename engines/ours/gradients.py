"""ours' own derivatives: forward sensitivities by complex step through its compiled step (ours.sensitivity).

For initial-condition parameters (angles, rates) each parameter's direction in ours' state (the particles'
positions and velocities on the scene's axes: ours' state is the outputs themselves) comes from
engines.gradients.initial_output_directions, and one complex run per parameter carries it to T, exact to
round-off: the derivative of what ours computes. g, masses and lengths change ours' System rather than its
state: those columns are central differences of rollouts (engines.gradients.finite_difference_jacobian), as for
every engine. Model files (ours' rigid bodies) are engines/ours/rigid_gradients.py's; the lagrangian method is left
to differences of rollouts.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from engines.adapter import Schedule
from engines.gradients import SAMPLE_INTERVAL, finite_difference_jacobian, initial_output_directions, \
    is_initial_condition
from engines.scene.parameters import outputs_of
from engines.scene.scene import Scene


def jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str], to_system: Any) -> tuple[np.ndarray, str, np.ndarray, np.ndarray] | None:
    """(J (6P, k), "autodiff", times (n,) s, J at each (n, 6P, k)) by complex step for the initial-condition
    columns, sampled as differences of rollouts are (every SAMPLE_INTERVAL); a model scene's from
    engines/ours/rigid_gradients.py; None for the lagrangian method, a run that stops early, or no initial-condition
    parameter among ``wrt``. ``engine`` : ours' adapter; to_system : its map from a scene to (System, q0, v0, axes)."""
    from ours.sensitivity import forward_sensitivities

    if scene.is_model:  # ours' rigid bodies
        from engines.ours import rigid_gradients

        return rigid_gradients.jacobian(engine, scene, variant, options, dt, wrt)
    settings = engine.resolve(variant, options)
    if settings["method"] == "lagrangian":
        return None
    initial = [name for name in wrt if is_initial_condition(scene, name)]
    if not initial:
        return None
    system, q0, v0, axes = to_system(scene)
    schedule = Schedule.make(scene.duration, dt, SAMPLE_INTERVAL)
    directions = initial_output_directions(scene, initial).T.reshape(len(initial), len(scene.particles), 6)
    result = forward_sensitivities(
        system, q0, v0, directions[:, :, axes], directions[:, :, [3 + a for a in axes]], dt, schedule.n_steps,
        method=settings["method"], integrator=settings["integrator"], k_s=settings["k_s"], k_d=settings["k_d"],
        tolerance=settings["tolerance"], max_iterations=settings["max_iterations"], sample_every=schedule.stride)
    if result.status != "ok":
        return None  # a run that stopped early has no derivative at T: differences of rollouts say what it does
    shape = (len(result.sample_steps), len(initial), len(scene.particles), 3)
    positions, velocities = np.zeros(shape), np.zeros(shape)
    positions[..., axes], velocities[..., axes] = result.sample_dq, result.sample_dv
    over_time = np.swapaxes(outputs_of(positions, velocities), 1, 2)  # (n, m, k)
    columns = {name: over_time[:, :, j] for j, name in enumerate(initial)}
    physical = [name for name in wrt if name not in columns]
    if physical:
        differences = finite_difference_jacobian(engine, scene, variant, options, dt, physical)
        assert differences.over_time is not None  # differences of rollouts always come at every sample
        columns.update(zip(physical, np.moveaxis(differences.over_time, -1, 0)))
    series = np.stack([columns[name] for name in wrt], axis=-1)
    return series[-1], "autodiff", result.sample_steps * dt, series
