"""What every engine returns: sampled states in the scene frame, SI units.

Derived quantities (energy, constraint error in the distance form, rod
tension) are pure functions of a Scene and arrays, so metrics and reports
compute them the same way for every engine.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from engines.scene import Pin, Scene

STATUSES = ("ok", "unstable", "failed", "skipped", "timeout")


@dataclass(frozen=True)
class RunInfo:
    """How a trajectory was produced.

    engine : engine name (``mujoco``); variant : full id (``mujoco/hinge-rk4``).
    engine_version : the engine library's version string.
    dt : s, the time step; steps : steps actually taken.
    wall_time : s, wall time of the stepping loop alone (model building excluded).
    status : one of ``STATUSES``; message : why, when not ok.
    settings : every option used, and every engine default overridden.
    """

    engine: str
    variant: str
    engine_version: str
    dt: float
    steps: int = 0
    wall_time: float = 0.0
    status: str = "ok"
    message: str = ""
    settings: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "engine": self.engine,
            "variant": self.variant,
            "engine_version": self.engine_version,
            "dt": self.dt,
            "steps": self.steps,
            "wall_time": self.wall_time,
            "status": self.status,
            "message": self.message,
            "settings": dict(self.settings),
        }


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Samples of one run.

    t : (n_samples,) s.
    positions : (n_samples, n_particles, 3) m.
    velocities : (n_samples, n_particles, 3) m/s.
    constraint_forces : (n_samples, n_constraints, 3) N, the force each
        constraint exerts on its first particle (``Pin.particle``, ``Rod.a``),
        or None when the engine does not expose constraint forces.
    info : RunInfo.
    """

    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    info: RunInfo
    constraint_forces: np.ndarray | None = None

    def __post_init__(self) -> None:
        n = len(self.t)
        for name in ("positions", "velocities", "constraint_forces"):
            array = getattr(self, name)
            if array is None:
                continue
            array = np.asarray(array, dtype=np.float64)
            if array.ndim != 3 or array.shape[0] != n or array.shape[2] != 3:
                raise ValueError(f"Trajectory.{name}: expected shape ({n}, k, 3), got {array.shape}")
            object.__setattr__(self, name, array)
        object.__setattr__(self, "t", np.asarray(self.t, dtype=np.float64))
        if self.positions.shape != self.velocities.shape:
            raise ValueError("Trajectory: positions and velocities must have the same shape")

    @property
    def n_samples(self) -> int:
        return len(self.t)

def kinetic_energy(scene: Scene, velocities: np.ndarray) -> np.ndarray:
    """(n_samples,) J from velocities (n_samples, n_particles, 3) m/s."""
    return 0.5 * np.einsum("p,spi,spi->s", scene.masses, velocities, velocities)


def potential_energy(scene: Scene, positions: np.ndarray) -> np.ndarray:
    """(n_samples,) J: −Σ mᵢ g·pᵢ (zero at the origin's height)."""
    return -np.einsum("p,spi,i->s", scene.masses, positions, np.asarray(scene.gravity))


def total_energy(scene: Scene, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """(n_samples,) J, kinetic plus gravitational potential."""
    return kinetic_energy(scene, velocities) + potential_energy(scene, positions)


def constraint_vectors(scene: Scene, positions: np.ndarray) -> np.ndarray:
    """(n_samples, n_constraints, 3) m: first particle minus the other end (anchor or particle b)."""
    out = np.empty((positions.shape[0], len(scene.constraints), 3))
    for k, c in enumerate(scene.constraints):
        if isinstance(c, Pin):
            out[:, k] = positions[:, c.particle] - np.asarray(c.anchor)
        else:
            out[:, k] = positions[:, c.a] - positions[:, c.b]
    return out


def constraint_errors(scene: Scene, positions: np.ndarray) -> np.ndarray:
    """(n_samples, n_constraints) m: |‖a − b‖ − l|, the distance form whatever a solver uses inside."""
    lengths = np.array([c.length for c in scene.constraints])
    return np.abs(np.linalg.norm(constraint_vectors(scene, positions), axis=2) - lengths)


def max_constraint_error(scene: Scene, positions: np.ndarray) -> np.ndarray:
    """(n_samples,) m: the largest constraint error at each sample (0 with no constraints)."""
    if not scene.constraints:
        return np.zeros(positions.shape[0])
    return constraint_errors(scene, positions).max(axis=1)


def tensions(scene: Scene, positions: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """(n_samples, n_constraints) N: the pull of each constraint (positive when it pulls the ends together).

    forces : (n_samples, n_constraints, 3), the force on each constraint's first particle.
    """
    d = constraint_vectors(scene, positions)
    unit = d / np.linalg.norm(d, axis=2, keepdims=True)
    return -np.einsum("ski,ski->sk", forces, unit)
