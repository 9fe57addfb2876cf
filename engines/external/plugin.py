"""Everything a third-party adapter needs, in one import, and helpers that keep it short.

A plugin imports from here only (docs/plugins.md walks through one)::

    from engines.external.plugin import Engine, Option, Recorder, Schedule, capabilities, scene_arrays

Details: docs/engines.md, "Adapter notes", ``engines/external/plugin.py``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from engines.adapter import API_VERSION, Engine, Option, RawRun, Schedule, refuse_constraint_kinds
from engines.errors import Unsupported, UserError
from engines.scene.pendulum import PlanarChain, force_array, planar_chain
from engines.recorder import RUNAWAY_LENGTHS, Recorder
from engines.scene.scene import Pin, Rod, Scene

__all__ = [
    "API_VERSION", "CONSTRAINT_FORCES", "RUNAWAY_LENGTHS", "THREE_D", "Engine", "Option", "PlanarChain", "RawRun", "Recorder",
    "Schedule", "SceneArrays", "Unsupported", "UserError", "capabilities", "force_array", "planar_chain",
    "refuse_constraint_kinds", "scene_arrays",
]

#: The engine can move particles out of the x–z plane (3-D scenes).
THREE_D = "3d"
#: The engine reports the force each constraint exerts (RawRun.forces).
CONSTRAINT_FORCES = "constraint-forces"


def capabilities(*, three_d: bool = False, constraint_forces: bool = False) -> frozenset[str]:
    """The ``Engine.capabilities`` set. Without ``three_d`` only planar (x–z) scenes are run."""
    return frozenset(name for name, on in ((THREE_D, three_d), (CONSTRAINT_FORCES, constraint_forces)) if on)


@dataclass(frozen=True)
class SceneArrays:
    """A Scene as arrays (float64, SI units, scene frame: z up, gravity along −z).

    masses : (P,) kg; inverse_masses : (P,) 1/kg.
    positions, velocities : (P, 3) m, m/s: the initial state.
    gravity : (3,) m/s².
    first : (C,) int, the constraint's first particle (``Pin.particle``, ``Rod.a``);
        constraint forces are reported on it.
    second : (C,) int, ``Rod.b``, or -1 for a Pin (the other end is fixed).
    anchors : (C, 3) m, a Pin's fixed point (zeros for a Rod).
    lengths : (C,) m.
    """

    masses: np.ndarray
    inverse_masses: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    gravity: np.ndarray
    first: np.ndarray
    second: np.ndarray
    anchors: np.ndarray
    lengths: np.ndarray

    @property
    def n_particles(self) -> int:
        return len(self.masses)

    @property
    def n_constraints(self) -> int:
        return len(self.lengths)


def scene_arrays(scene: Scene) -> SceneArrays:
    """The particles and constraints of ``scene`` as arrays (see :class:`SceneArrays`)."""
    refuse_constraint_kinds(scene, (Pin, Rod), "engines.external.plugin.scene_arrays")
    n = len(scene.constraints)
    first, second = np.empty(n, dtype=np.int64), np.full(n, -1, dtype=np.int64)
    anchors, lengths = np.zeros((n, 3)), np.empty(n)
    for k, c in enumerate(scene.constraints):
        lengths[k] = c.length
        if isinstance(c, Pin):
            first[k], anchors[k] = c.particle, c.anchor
        else:
            first[k], second[k] = c.a, c.b
    masses = scene.masses
    return SceneArrays(masses, 1.0 / masses, scene.initial_positions, scene.initial_velocities,
                       np.asarray(scene.gravity, dtype=np.float64), first, second, anchors, lengths)
