"""A trajectory as a table: one row per sample, the columns ``xval simulate`` writes."""

from __future__ import annotations

import csv
import io

import numpy as np

from engines.scene import Scene
from engines.trajectory import Trajectory, max_constraint_error, total_energy


def trajectory_columns(scene: Scene) -> list[str]:
    """``t``, then ``p{i}_x p{i}_y p{i}_z v{i}_x v{i}_y v{i}_z`` per particle, then ``energy``, ``constraint_error``."""
    columns = ["t"]
    for i in range(len(scene.particles)):
        columns += [f"p{i}_{a}" for a in "xyz"] + [f"v{i}_{a}" for a in "xyz"]
    return columns + ["energy", "constraint_error"]


def trajectory_table(scene: Scene, trajectory: Trajectory) -> np.ndarray:
    """(n_samples, n_columns) float64 in the order of :func:`trajectory_columns`.

    energy : J; constraint_error : m, the largest over constraints at that sample.
    """
    n = trajectory.n_samples
    state = np.concatenate([trajectory.positions, trajectory.velocities], axis=2).reshape(n, -1)
    energy = total_energy(scene, trajectory.positions, trajectory.velocities)
    error = max_constraint_error(scene, trajectory.positions)
    return np.column_stack([trajectory.t, state, energy, error])


def trajectory_csv(scene: Scene, trajectory: Trajectory) -> str:
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(trajectory_columns(scene))
    writer.writerows([repr(float(x)) for x in row] for row in trajectory_table(scene, trajectory))
    return buffer.getvalue()
