"""What every engine returns: sampled states in the scene frame, SI units.

Derived quantities (energy, constraint error in the distance form, rod
tension) are pure functions of a Scene and arrays, so metrics and reports
compute them the same way for every engine.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np

from engines.scene.scene import Ellipse, Line, Pin, Rod, Scene, SceneLike



class Status(str, enum.Enum):
    """How a run, and the case around it, ended (the JSON spelling is the value): one enum from an
    engine's RunInfo up to the case record (compare.results.record).

    ok : ran to the end inside the bounds (did not blow up; see the record's ``consistent`` for "is right").
    unstable : a non-finite state, or energy drift / constraint error past the suite's bounds.
    failed : the engine raised or its process died.
    timeout : ran past the case timeout and was killed.
    skipped : left out (the engine cannot express the scene, or is not installed); message says why.
    """

    OK = "ok"
    UNSTABLE = "unstable"
    FAILED = "failed"
    TIMEOUT = "timeout"
    SKIPPED = "skipped"

    def __str__(self) -> str:  # f"{status}" gives "ok", as the JSON does
        return self.value



@dataclass(frozen=True)
class RunInfo:
    """How a trajectory was produced.

    engine : engine name (``mujoco``); variant : full id (``mujoco/hinge-rk4``).
    engine_version : the engine library's version string.
    dt : s, the time step; steps : steps actually taken.
    wall_time : s, wall time of the stepping loop alone (model building excluded).
    cpu_time : s, this thread's CPU time of the run (the adapter's stepping loop's when it measures it),
        see engines.adapter.loop_cpu_time;
        what the timing gate compares, since a busy neighbour stretches wall time, not CPU time.
    status : how the run ended (a string given is read as its :class:`Status`); message : why, when not ok.
    settings : every option used, and every engine default overridden.
    """

    engine: str
    variant: str
    engine_version: str
    dt: float
    steps: int = 0
    wall_time: float = 0.0
    status: Status = Status.OK
    message: str = ""
    #: Free-form: every engine's own option names and values.
    settings: Mapping[str, Any] = field(default_factory=dict)
    cpu_time: float = 0.0

    def __post_init__(self) -> None:
        object.__setattr__(self, "status", Status(self.status))

    def to_dict(self) -> dict[str, Any]:
        return {
            "engine": self.engine,
            "variant": self.variant,
            "engine_version": self.engine_version,
            "dt": self.dt,
            "steps": self.steps,
            "wall_time": self.wall_time,
            "status": self.status.value,
            "message": self.message,
            "settings": dict(self.settings),
            "cpu_time": self.cpu_time,
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
    joint_states : (n_samples, 2·nq), q then v (rad or m, rad/s or m/s) of a model scene's moving
        joints (engines.model.scene), whose "particles" are its link frames; None for catalog scenes.
    constraint_violation : (n_samples,) m, the largest violation of the engine's own constraints at
        each sample as the engine reports it (a maximal-coordinate solver's joints, which the link
        frames cannot show: they are computed from the joint coordinates), or None: nothing beyond
        what the positions show (reduced coordinates hold their joints by construction).
    """

    t: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    info: RunInfo
    constraint_forces: np.ndarray | None = None
    joint_states: np.ndarray | None = None
    constraint_violation: np.ndarray | None = None

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
        if self.joint_states is not None:
            states = np.asarray(self.joint_states, dtype=np.float64)
            if states.ndim != 2 or states.shape[0] != n:
                raise ValueError(f"Trajectory.joint_states: expected shape ({n}, 2·nq), got {states.shape}")
            object.__setattr__(self, "joint_states", states)
        if self.constraint_violation is not None:
            violation = np.asarray(self.constraint_violation, dtype=np.float64)
            if violation.shape != (n,):
                raise ValueError(f"Trajectory.constraint_violation: expected shape ({n},), got {violation.shape}")
            object.__setattr__(self, "constraint_violation", violation)
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


def trajectory_energy(scene: SceneLike, trajectory: Trajectory) -> np.ndarray:
    """(n_samples,) J: a catalog scene's point-mass energy (:func:`total_energy`), or a model scene's from its
    joint states (``scene.energy``: rotational kinetic energy included; NaN without joint states)."""
    if isinstance(scene, Scene):
        return total_energy(scene, trajectory.positions, trajectory.velocities)
    model: Any = scene  # an engines.model.scene.ModelScene (a layer above this one)
    states = trajectory.joint_states
    if states is None:
        return np.full(trajectory.n_samples, np.nan)
    nq = states.shape[1] // 2
    return model.energy(states[:, :nq], states[:, nq:]) if len(states) else np.zeros(0)


def constraint_vectors(scene: SceneLike, positions: np.ndarray) -> np.ndarray:
    """(n_samples, n_constraints, 3) m: first particle minus the other end (anchor or particle b).

    Distance kinds (Pin, Rod) only; a Line or Ellipse has no other end, so its rows are NaN.
    """
    out = np.full((positions.shape[0], len(scene.constraints), 3), np.nan)
    for k, c in enumerate(scene.constraints):
        if isinstance(c, Pin):
            out[:, k] = positions[:, c.particle] - np.asarray(c.anchor)
        elif isinstance(c, Rod):
            out[:, k] = positions[:, c.a] - positions[:, c.b]
    return out


def constraint_errors(scene: SceneLike, positions: np.ndarray) -> np.ndarray:
    """(n_samples, n_constraints) m: the distance form whatever a solver uses inside.

    |‖a − b‖ − l| for a Pin or Rod; the particle's Euclidean distance from
    the line (Line) or from the wire (Ellipse).
    """
    lengths = np.array([getattr(c, "length", 0.0) for c in scene.constraints])
    with np.errstate(invalid="ignore"):
        out = np.abs(np.linalg.norm(constraint_vectors(scene, positions), axis=2) - lengths)
    for k, c in enumerate(scene.constraints):
        if isinstance(c, (Line, Ellipse)):
            out[:, k] = c.distances(positions[:, c.particle])
    return out


def max_constraint_error(scene: SceneLike, positions: np.ndarray) -> np.ndarray:
    """(n_samples,) m: the largest constraint error at each sample (0 with no constraints)."""
    if not scene.constraints:
        return np.zeros(positions.shape[0])
    return constraint_errors(scene, positions).max(axis=1)


def trajectory_constraint_error(scene: SceneLike, trajectory: Trajectory) -> np.ndarray:
    """(n_samples,) m: the largest constraint error at each sample: the distance form of the scene's
    constraints (:func:`max_constraint_error`) or the engine's reported ``constraint_violation``,
    whichever is larger (a NaN in either stays NaN)."""
    errors = max_constraint_error(scene, trajectory.positions)
    reported = trajectory.constraint_violation
    return errors if reported is None else np.maximum(errors, reported)


def linear_momentum(scene: Scene, velocities: np.ndarray) -> np.ndarray:
    """(n_samples, 3) kg·m/s: Σ mᵢ vᵢ from velocities (n_samples, n_particles, 3) m/s."""
    return np.einsum("p,spi->si", scene.masses, velocities)


def free_direction(scene: Scene) -> np.ndarray | None:
    """(3,) the unit direction along which no external force acts, so linear momentum along it is conserved.

    That is the case when gravity is perpendicular to it and every constraint
    is either internal (a Rod) or a Line along it (whose force is
    perpendicular to the line). Pins and Ellipses pull in every direction of
    the plane over a swing, so a scene with one has None; so has a scene
    whose Lines disagree, or with no Line at all.
    """
    lines = [c for c in scene.constraints if isinstance(c, Line)]
    if not lines or any(not isinstance(c, (Line, Rod)) for c in scene.constraints):
        return None
    u = lines[0].unit
    if any(abs(abs(float(c.unit @ u)) - 1.0) > 1e-12 for c in lines[1:]):
        return None
    g = np.asarray(scene.gravity)
    if abs(float(g @ u)) > 1e-12 * max(float(np.linalg.norm(g)), 1.0):
        return None
    return u


def linear_momentum_drift(scene: Scene, velocities: np.ndarray) -> float | None:
    """max_t |P(t)·u − P(0)·u| / (M √(g L)) along the scene's :func:`free_direction` u, or None without one.

    Dimensionless: the momentum change relative to the total mass M moving at
    the characteristic speed √(|g| L) (√L m/s when g = 0). Exactly zero for the
    true motion of a slider-pendulum; a solver that leaks momentum along the
    rail shows it here.
    """
    u = free_direction(scene)
    if u is None or len(velocities) == 0:
        return None
    along = linear_momentum(scene, velocities) @ u
    scale = float(scene.masses.sum()) * scene.characteristic_speed
    return float(np.abs(along - along[0]).max() / scale)


def tensions(scene: Scene, positions: np.ndarray, forces: np.ndarray) -> np.ndarray:
    """(n_samples, n_constraints) N: the pull of each constraint (positive when it pulls the ends together).

    forces : (n_samples, n_constraints, 3), the force on each constraint's first particle.
    Pins and Rods only (a Line or Ellipse gives NaN: see :func:`constraint_vectors`).
    """
    d = constraint_vectors(scene, positions)
    unit = d / np.linalg.norm(d, axis=2, keepdims=True)
    return -np.einsum("ski,ski->sk", forces, unit)


# -- angular momentum about the vertical -------------------------------------------------------


def vertical_axis(scene: Scene) -> np.ndarray | None:
    """(2,) m: the (x, y) of the vertical line about which the scene conserves angular momentum, or None.

    L_z about a vertical line is conserved when gravity is vertical and every external
    constraint force passes through that line: Rods are internal (equal and opposite along
    the rod, no torque), and a Pin pulls along the line to its anchor, so every Pin's anchor
    must lie on the one line. None when gravity is not vertical, the anchors are not on one
    vertical line, there are no Pins (any line would do; none is singled out), or the scene
    is planar (L_z is then zero by symmetry, which tests nothing).
    """
    gx, gy, _gz = scene.gravity
    if gx != 0.0 or gy != 0.0 or scene.is_planar:
        return None
    anchors = np.array([c.anchor[:2] for c in scene.constraints if isinstance(c, Pin)], dtype=float)
    if len(anchors) == 0:
        return None
    scale = scene.characteristic_length
    if np.abs(anchors - anchors[0]).max() > 1e-12 * scale:
        return None
    return anchors[0]


def angular_momentum_z(scene: Scene, positions: np.ndarray, velocities: np.ndarray, axis: np.ndarray) -> np.ndarray:
    """(n_samples,) kg·m²/s: Σ mᵢ (xᵢ v_yᵢ − yᵢ v_xᵢ) about the vertical line through ``axis`` (2,) m."""
    x = positions[..., 0] - axis[0]
    y = positions[..., 1] - axis[1]
    return np.einsum("p,sp->s", scene.masses, x * velocities[..., 1] - y * velocities[..., 0])


def momentum_drift(scene: Scene, positions: np.ndarray, velocities: np.ndarray) -> float | None:
    """max |L_z(t) − L_z(0)| / L* (dimensionless), or None when the scene does not conserve L_z.

    L_z is the angular momentum about the vertical line of :func:`vertical_axis`;
    L* = M·L·√(g·L) (total mass, characteristic length, |g|), the momentum of the whole
    mass moving at the characteristic speed at arm L (``Scene.characteristic_speed``). 0 for fewer
    than 2 samples.
    """
    axis = vertical_axis(scene)
    if axis is None:
        return None
    if len(positions) < 2:
        return 0.0
    lz = angular_momentum_z(scene, positions, velocities, axis)
    scale = float(scene.masses.sum()) * scene.characteristic_length * scene.characteristic_speed
    return float(np.abs(lz - lz[0]).max() / scale)
