"""Everything a third-party adapter needs, in one import, and helpers that keep it short.

A plugin imports from here only (docs/plugins.md walks through one)::

    from engines.plugin import Engine, Option, Recorder, Schedule, capabilities, scene_arrays

- :func:`capabilities` declares what the solver can express; scenes needing
  more are left out of its runs with the reason (never faked).
- :func:`scene_arrays` reads a Scene's particles and constraints as arrays,
  one row per constraint whatever its kind.
- :class:`Recorder` stores the state at the scheduled sample steps and
  builds the :class:`RawRun` that ``_run`` returns.
- :func:`refuse_constraint_kinds` refuses scenes with constraints the solver
  does not model, naming the constraint.
- :func:`planar_chain` converts between pendulum angles and particle
  positions / velocities (:mod:`engines.pendulum`); :func:`force_array`
  builds per-constraint forces with NaN for "not reported".

What xval checks for every adapter, so a plugin need not (engines.adapter):
shapes and sample count of what ``_run`` returns, that sample 0 is the
scene's initial state (catches unit, frame and particle-order mistakes),
wall time in seconds, non-finite states (-> ``unstable``), exceptions
(-> ``failed``) and the declared ``api_version``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, Iterable, Mapping

import numpy as np

from engines.adapter import API_VERSION, Engine, Option, RawRun, Schedule
from engines.errors import Unsupported, UserError
from engines.pendulum import PlanarChain, force_array, planar_chain
from engines.scene import Pin, Rod, Scene

__all__ = [
    "API_VERSION", "CONSTRAINT_FORCES", "THREE_D", "Engine", "Option", "PlanarChain", "RawRun", "Recorder",
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
    refuse_constraint_kinds(scene, (Pin, Rod), "engines.plugin.scene_arrays")
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


def refuse_constraint_kinds(scene: Scene, kinds: Iterable[type], engine: str) -> None:
    """Raise Unsupported naming the first constraint of ``scene`` not of one of ``kinds``."""
    kinds = tuple(kinds)
    for k, c in enumerate(scene.constraints):
        if not isinstance(c, kinds):
            names = ", ".join(getattr(t, "kind", t.__name__) for t in kinds)
            raise Unsupported(f"{engine} models only {names} constraints; constraints[{k}] is a {c.kind!r}")


class Recorder:
    """Stores the state at the scheduled sample steps and times the stepping loop.

    Use it as::

        rec = Recorder(scene, schedule, forces=True)
        rec.record(0, q, v, f)                  # the initial state (f: your t = 0 forces, or None)
        with rec.stepping():                    # only this is timed
            for step in range(1, schedule.n_steps + 1):
                q, v, f = my_step(q, v)
                if rec.wants(step):
                    with rec.paused():          # recording is not stepping
                        rec.record(step, q, v, f)
        return rec.raw_run()

    q, v : (P, 3) m, m/s; f : (C, 3) N on each constraint's first particle,
    or ``{k: (3,)}`` for the constraints reported; a constraint not reported
    (f None, absent from the dict, or NaN) stays NaN, "not reported", never
    zero. A loop that stops early (the state ran away) returns fewer
    samples; xval marks such a run ``unstable`` and keeps the samples recorded.
    """

    def __init__(self, scene: Scene, schedule: Schedule, *, forces: bool = False) -> None:
        self.schedule = schedule
        self._steps = schedule.sample_steps.tolist()
        self._index = {step: k for k, step in enumerate(self._steps)}
        n, p, c = len(self._steps), len(scene.particles), len(scene.constraints)
        self.positions = np.full((n, p, 3), np.nan)
        self.velocities = np.full((n, p, 3), np.nan)
        self.forces = np.full((n, c, 3), np.nan) if forces else None
        self._recorded = 0
        self._last_step = 0
        self.wall_time = 0.0  # s

    def wants(self, step: int) -> bool:
        """True when ``step`` is a sample step."""
        return step in self._index

    def record(self, step: int, q: np.ndarray, v: np.ndarray,
               f: np.ndarray | Mapping[int, np.ndarray] | None = None) -> None:
        """Store the state after ``step`` steps (a sample step; others are ignored).

        f : (C, 3) N, or {constraint index: (3,) N}; None or missing = not reported (NaN).
        """
        k = self._index.get(step)
        if k is None:
            return
        self.positions[k], self.velocities[k] = q, v
        if self.forces is not None and f is not None:
            self.forces[k] = force_array(self.forces.shape[1], f) if isinstance(f, Mapping) else f
        self._recorded = max(self._recorded, k + 1)
        self._last_step = max(self._last_step, step)

    def stepping(self) -> "_Clock":
        """A context that adds its wall time (s) to ``wall_time``."""
        return _Clock(self, sign=+1)

    def paused(self) -> "_Clock":
        """A context, inside ``stepping()``, whose wall time is not counted."""
        return _Clock(self, sign=-1)

    def raw_run(self, *, message: str = "", settings: dict[str, Any] | None = None) -> RawRun:
        """The RawRun of the samples recorded so far (steps taken = the last recorded step)."""
        n = self._recorded
        forces = None if self.forces is None else self.forces[:n]
        return RawRun(self.positions[:n], self.velocities[:n], forces, steps=self._last_step,
                      wall_time=self.wall_time, message=message, settings=dict(settings or {}))


class _Clock:
    def __init__(self, recorder: Recorder, sign: int) -> None:
        self.recorder, self.sign = recorder, sign

    def __enter__(self) -> None:
        self.started = time.perf_counter()

    def __exit__(self, *exc: Any) -> None:
        self.recorder.wall_time += self.sign * (time.perf_counter() - self.started)
