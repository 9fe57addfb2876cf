"""MuJoCo's hinge model for an engine that steps it with an integrator of its own (MJX): the public face of
MuJoCo's home, so that engine uses none of the adapter's helpers.

``hinge_model`` builds what ``mujoco/hinge`` builds (its MJCF, compiled), with the caller's integrator and
point-mass inertia; ``read_hinge_samples`` reads positions, velocities and constraint forces from full
physics states as ``mujoco/hinge`` does.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np

from engines.mujoco.adapter import ENGINE, constraint_tree, hinge_velocities, read_samples, without_timestep
from engines.mujoco.gradients import hinge_readout
from engines.mujoco.library import mujoco
from engines.mujoco.options import HINGE_INERTIA_RATIO
from engines.scene.scene import Scene

__all__ = ["HINGE_INERTIA_RATIO", "HingeModel", "check_hinge", "hinge_model", "hinge_readout", "read_hinge_samples",
           "tree_depth"]


@dataclass(frozen=True)
class HingeModel:
    """model : the compiled MjModel (the caller's). structure : its MJCF without the timestep, equal for
    models that compile alike whatever dt. inertia : (n,) kg·m² of each particle body (MuJoCo's floor
    included). qvel : (nv,) rad/s the joint velocities of the scene's initial state."""

    model: Any
    structure: str
    inertia: np.ndarray
    qvel: np.ndarray


def _options(integrator: str, inertia_ratio: float) -> dict[str, Any]:
    return {"integrator": integrator, "inertia_ratio": inertia_ratio}


def check_hinge(scene: Scene, integrator: str, inertia_ratio: float) -> None:
    """Unsupported when ``mujoco/hinge`` with this integrator and inertia cannot express ``scene``."""
    ENGINE.check(scene, "hinge", _options(integrator, inertia_ratio))


def hinge_settings(integrator: str, inertia_ratio: float) -> dict[str, Any]:
    """``mujoco/hinge``'s resolved settings with this integrator and point-mass inertia."""
    return ENGINE.resolve("hinge", _options(integrator, inertia_ratio))


def hinge_model(scene: Scene, dt: float, integrator: str, inertia_ratio: float) -> HingeModel:
    """``mujoco/hinge``'s model of ``scene`` at timestep ``dt`` s with this integrator and inertia."""
    model, xml, inertia = ENGINE.build(scene, dt, hinge_settings(integrator, inertia_ratio))
    return HingeModel(model, without_timestep(xml), inertia, hinge_velocities(scene, model))


def read_hinge_samples(scene: Scene, model: Any, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Positions (n, P, 3) m, velocities (n, P, 3) m/s and constraint forces (n, C, 3) N at each full physics
    state (n, nstate) of the hinge ``model``."""
    return read_samples(scene, model, mujoco.MjData(model), states, hinge=True)


def tree_depth(scene: Scene) -> int:
    """Bodies from the world down to the deepest particle of ``mujoco/hinge``'s body tree (1: hung from a Pin)."""
    parent = constraint_tree(scene).parent
    deepest = 0
    for i in range(len(parent)):
        depth, k = 1, i
        while parent[k] >= 0:
            k, depth = parent[k], depth + 1
        deepest = max(deepest, depth)
    return deepest
