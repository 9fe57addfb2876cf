"""Everything a third-party adapter needs, in one import, and helpers that keep it short.

A plugin imports from here only (docs/plugins.md walks through one)::

    from engines.external.plugin import Engine, Option, Recorder, Schedule, capabilities, scene_arrays

- :func:`capabilities` declares what the solver can express; scenes needing
  more are left out of its runs with the reason (never faked).
- :func:`scene_arrays` reads a Scene's particles and constraints as arrays,
  one row per constraint whatever its kind.
- :class:`Recorder` (engines.recorder, the loop every built-in adapter uses)
  stores the state at the scheduled sample steps, stops a run that runs away,
  times the stepping and builds the :class:`RawRun` that ``_run`` returns.
- :func:`refuse_constraint_kinds` refuses scenes with constraints the solver
  does not model, naming the constraint.
- :func:`planar_chain` converts between pendulum angles and particle
  positions / velocities (:mod:`engines.scene.pendulum`); :func:`force_array`
  builds per-constraint forces with NaN for "not reported".

What xval checks for every adapter, so a plugin need not (engines.adapter):
shapes and sample count of what ``_run`` returns, that sample 0 is the
scene's initial state (catches unit, frame and particle-order mistakes),
wall time in seconds, non-finite states (-> ``unstable``), exceptions
(-> ``failed``) and the declared ``api_version``.
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
