"""A trajectory as a table: one row per sample, the columns ``xval simulate`` writes.

The columns are the process protocol's (engines.external.protocol, docs/protocol.md),
so what ``xval simulate`` writes is what ``xval score`` and a ``command/``
engine's reader accept: ``t``, the state of every particle, optionally the
constraint forces ``f{k}_x..z``, then the derived ``energy`` and
``constraint_error``.
"""

from __future__ import annotations

import numpy as np

from engines.external import protocol
from engines.scene.scene import Scene
from engines.scene.trajectory import Trajectory, max_constraint_error, total_energy


def trajectory_columns(scene: Scene, forces: bool = False) -> list[str]:
    """``t``, then ``p{i}_x p{i}_y p{i}_z v{i}_x v{i}_y v{i}_z`` per particle, [``f{k}_x..z`` per constraint],
    then ``energy``, ``constraint_error``; a model scene's are compare.results.model_csv's."""
    if scene.is_model:
        from compare.results.model_csv import model_columns

        return model_columns(scene)
    return protocol.columns(scene, forces=forces, derived=True)


def trajectory_table(scene: Scene, trajectory: Trajectory, forces: bool = False) -> np.ndarray:
    """(n_samples, n_columns) float64 in the order of :func:`trajectory_columns`.

    forces : N, the force on each constraint's first particle (NaN when the
    trajectory has none); energy : J; constraint_error : m, the largest over
    constraints at that sample.
    """
    if scene.is_model:
        from compare.results.model_csv import model_table

        return model_table(scene, trajectory)
    n = trajectory.n_samples
    state = np.concatenate([trajectory.positions, trajectory.velocities], axis=2).reshape(n, 6 * len(scene.particles))
    parts = [trajectory.t[:, None], state]
    if forces:
        f = trajectory.constraint_forces
        parts.append(np.full((n, 3 * len(scene.constraints)), np.nan) if f is None else f.reshape(n, 3 * len(scene.constraints)))
    energy = total_energy(scene, trajectory.positions, trajectory.velocities)
    error = max_constraint_error(scene, trajectory.positions)
    return np.column_stack([*parts, energy, error])


def trajectory_csv(scene: Scene, trajectory: Trajectory, forces: bool = False) -> str:
    """The CSV text (every number written with repr, so it reads back exactly)."""
    return protocol.write_csv(trajectory_columns(scene, forces), trajectory_table(scene, trajectory, forces))
