"""A model run as a table: ``t``, q and v of every moving joint, then each link frame's origin, in SI.

Columns: ``t`` (s); ``q_<joint>`` (rad or m) and ``v_<joint>`` (rad/s or
m/s) for each moving joint in the model's order, after a floating base's
``q_BASE.x`` … ``q_BASE.qw`` and ``v_BASE.vx`` … ``v_BASE.wz``
(ModelScene.config_names, velocity_names); ``<link>_x``, ``_y``, ``_z``
(m, world frame) for each moving link; then ``energy`` (J, rotational
kinetic energy included). ``xval score --model`` reads the joint columns
back and recomputes the link frames from them (the frame columns may be left
out of a file written by another program).
"""

from __future__ import annotations

import numpy as np

from engines.external import protocol
from engines.errors import UserError
from engines.model.scene import ModelScene
from engines.scene.trajectory import Trajectory, trajectory_energy

_AXES = ("x", "y", "z")


def model_columns(scene: ModelScene) -> list[str]:
    return (["t", *(f"q_{j}" for j in scene.config_names), *(f"v_{j}" for j in scene.velocity_names),
             *(f"{link}_{a}" for link in scene.frames for a in _AXES), "energy"])


def model_table(scene: ModelScene, trajectory: Trajectory) -> np.ndarray:
    """(n, columns) float64 in the order of :func:`model_columns`."""
    n = trajectory.n_samples
    joints = trajectory.joint_states
    if joints is None:
        joints = np.full((n, len(scene.config_names) + len(scene.velocity_names)), np.nan)
    return np.column_stack([trajectory.t, joints, trajectory.positions.reshape(n, -1),
                            trajectory_energy(scene, trajectory)])


def joint_states(table: protocol.Table, scene: ModelScene, where: str) -> np.ndarray:
    """(n, nconfig + nv): q then v from ``table``'s ``q_<name>``, ``v_<name>`` columns; UserError naming a missing one."""
    wanted = [f"q_{j}" for j in scene.config_names] + [f"v_{j}" for j in scene.velocity_names]
    missing = [name for name in wanted if name not in table.header]
    if missing:
        raise UserError(f"{where}: header (line {table.header_line}), missing column {missing[0]!r}; a run of "
                        f"model {scene.model} has t, then q_<joint> and v_<joint> for its moving joints "
                        f"{', '.join(scene.joint_names)}")
    index = {name: k for k, name in enumerate(table.header)}
    return table.values[:, [index[name] for name in wanted]]
