"""ours' own derivatives: forward sensitivities by complex step through its compiled step (ours.sensitivity).

For initial-condition parameters (angles, rates) each parameter's direction in ours' state (the particles'
positions and velocities on the scene's axes: ours' state is the outputs themselves) comes from
engines.gradients.initial_output_directions, and one complex run per parameter carries it to T, exact to
round-off: the derivative of what ours computes. g, masses and lengths change ours' System rather than its
state: those columns are central differences of rollouts (engines.gradients.finite_difference_jacobian), as for
every engine. Model files (ours' rigid bodies) and the lagrangian method are left to differences of rollouts.
"""

from __future__ import annotations

from typing import Any, Mapping, Sequence

import numpy as np

from engines.gradients import finite_difference_jacobian, initial_output_directions, is_initial_condition
from engines.scene.parameters import outputs_of
from engines.scene.scene import Scene


def jacobian(engine: Any, scene: Scene, variant: str | None, options: Mapping[str, Any] | None, dt: float,
             wrt: Sequence[str], to_system: Any) -> tuple[np.ndarray, str] | None:
    """(J (6P, k), "autodiff") by complex step for the initial-condition columns, or None (a model scene, the
    lagrangian method, or no initial-condition parameter among ``wrt``). ``engine`` : ours' adapter;
    to_system : its map from a scene to (System, q0, v0, axes)."""
    from ours.sensitivity import forward_sensitivities

    settings = engine.resolve(variant, options)
    if scene.is_model or settings["method"] == "lagrangian":
        return None
    initial = [name for name in wrt if is_initial_condition(scene, name)]
    if not initial:
        return None
    system, q0, v0, axes = to_system(scene)
    directions = initial_output_directions(scene, initial).T.reshape(len(initial), len(scene.particles), 6)
    result = forward_sensitivities(
        system, q0, v0, directions[:, :, axes], directions[:, :, [3 + a for a in axes]], dt,
        max(1, round(scene.duration / dt)), method=settings["method"], integrator=settings["integrator"],
        k_s=settings["k_s"], k_d=settings["k_d"], tolerance=settings["tolerance"],
        max_iterations=settings["max_iterations"])
    if result.status != "ok":
        return None  # a run that stopped early has no derivative at T: differences of rollouts say what it does
    positions = np.zeros((len(initial), len(scene.particles), 3))
    velocities = np.zeros_like(positions)
    positions[:, :, axes], velocities[:, :, axes] = result.dq, result.dv
    columns = dict(zip(initial, outputs_of(positions, velocities)))
    physical = [name for name in wrt if name not in columns]
    if physical:
        differences = finite_difference_jacobian(engine, scene, variant, options, dt, physical).jacobian
        columns.update(zip(physical, differences.T))
    return np.array([columns[name] for name in wrt]).T, "autodiff"
