"""Mass properties in the world frame: one record per link (or group of links fused together).

:class:`LinkInertia` is what an engine holds for a link after import, at
q = 0: mass (kg), centre of mass (3,) m and rotational inertia (3, 3) kg·m²
about that centre, both in the world frame. Engines that fuse links welded
together report the group under the name of the link that survives.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engines.model.description import ModelDescription
from engines.model.kinematics import link_poses


@dataclass(frozen=True)
class LinkInertia:
    """mass : kg. com : (3,) m, world. inertia : (3, 3) kg·m² about com, world axes."""

    mass: float
    com: np.ndarray
    inertia: np.ndarray


def world_inertia(mass: float, com_local, inertia_local, rotation, origin) -> LinkInertia:
    """A body's inertia given in its own frame (com, inertia about com in body axes) moved to the world."""
    r = np.asarray(rotation, dtype=float)
    return LinkInertia(float(mass), np.asarray(origin, dtype=float) + r @ np.asarray(com_local, dtype=float),
                       r @ np.asarray(inertia_local, dtype=float) @ r.T)


def combine(parts: list[LinkInertia]) -> LinkInertia:
    """One rigid body made of ``parts`` (parallel-axis theorem about the combined centre of mass)."""
    mass = sum(p.mass for p in parts)
    if mass > 0:
        com = sum(p.mass * p.com for p in parts) / mass
    else:
        com = np.mean([p.com for p in parts], axis=0) if parts else np.zeros(3)
    inertia = np.zeros((3, 3))
    for p in parts:
        d = p.com - com
        inertia += p.inertia + p.mass * (d @ d * np.eye(3) - np.outer(d, d))
    return LinkInertia(mass, com, inertia)


def description_inertias(model: ModelDescription) -> dict[str, LinkInertia]:
    """Each link's mass properties as the file says them, in the world frame at q = 0."""
    poses = link_poses(model)
    return {b.name: world_inertia(b.inertial.mass, b.inertial.com, b.inertial.inertia_matrix, *poses[b.name])
            for b in model.bodies}
