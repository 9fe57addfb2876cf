"""The ground truth: reduced-coordinate equations integrated at tight tolerances.

Details (what is built, which defaults are overridden and why): docs/engines.md, "Adapter notes",
``engines/reference/reference.py``.
"""

from __future__ import annotations

import contextlib
import functools
import hashlib
import math
import pickle
import sys
import time
from dataclasses import dataclass, field, replace
from functools import cached_property
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Mapping

import numpy as np
import scipy

from engines.adapter import Engine, Option, RawRun, Schedule
from engines.errors import Unsupported
from engines.reference.ensemble import Estimate, members
from engines.reference.mechanisms import Mechanism, empty_samples, mechanism_model
from engines.scene.scene import Pin, Rod, Scene, SceneLike
from engines.scene.tree import read_tree

if TYPE_CHECKING:  # imported on use: only model-file scenes need Pinocchio
    from engines.model.dynamics import ModelDynamics

DEFAULT_RTOL = 1e-12
DEFAULT_ATOL = 1e-12


# -- planar chain ----------------------------------------------------------------


@dataclass(frozen=True)
class ChainModel:
    """A scene read as a serial chain hung from ``anchor``.

    order : (n,) particle indices from the anchor down.
    lengths, masses : (n,) m, kg; link k joins order[k−1] (or the anchor) to order[k].
    constraint_of_link : (n,) index into scene.constraints of link k.
    first_is_lower : (n,) whether that constraint's first particle is order[k].
    gravity : (2,) m/s², (g_x, g_z).
    """

    anchor: np.ndarray
    order: np.ndarray
    lengths: np.ndarray
    masses: np.ndarray
    constraint_of_link: np.ndarray
    first_is_lower: np.ndarray
    gravity: np.ndarray

    @property
    def tail_mass(self) -> np.ndarray:
        """(n,) kg: μ_i = Σ_{k ≥ i} m_k, the mass a link carries."""
        return np.cumsum(self.masses[::-1])[::-1]

    def initial_state(self, scene: Scene) -> np.ndarray:
        """(2n,) [θ, θ̇] in rad, rad/s from the scene's particles."""
        q = scene.initial_positions[self.order][:, [0, 2]]
        v = scene.initial_velocities[self.order][:, [0, 2]]
        upper_q = np.vstack([self.anchor[[0, 2]], q[:-1]])
        upper_v = np.vstack([np.zeros(2), v[:-1]])
        d, dv = q - upper_q, v - upper_v
        theta = np.arctan2(d[:, 0], -d[:, 1])
        theta_dot = (d[:, 0] * dv[:, 1] - d[:, 1] * dv[:, 0]) / self.lengths**2
        return np.concatenate([theta, theta_dot])

    @cached_property
    def _inertia(self) -> np.ndarray:
        """(n, n) kg·m²: μ_ij l_i l_j, constant, so built once (the right-hand side is called ~10⁵ times)."""
        n = len(self.lengths)
        mu = self.tail_mass[np.maximum.outer(np.arange(n), np.arange(n))]
        return np.outer(self.lengths, self.lengths) * mu

    @cached_property
    def _weight(self) -> np.ndarray:
        """(n,) kg·m: μ_i l_i, the gravity moment arm of each link per unit g."""
        return self.tail_mass * self.lengths

    def accelerations(self, theta: np.ndarray, theta_dot: np.ndarray) -> np.ndarray:
        """(n,) rad/s²: θ̈ from Lagrange's equations."""
        gx, gz = self.gravity
        from engines.reference.kernels import chain_accelerations

        return chain_accelerations(theta, theta_dot, self._inertia, self._weight, gx, gz)

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        gx, gz = self.gravity
        from engines.reference.kernels import chain_rhs

        return chain_rhs(y, self._inertia, self._weight, gx, gz)

    def evaluate(self, scene: Scene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities (n_samples, P, 3) and constraint forces (n_samples, C, 3) from states (n_samples, 2n)."""
        n = len(self.lengths)
        theta, theta_dot = states[:, :n], states[:, n:]
        theta_ddot = np.array([self.accelerations(a, b) for a, b in zip(theta, theta_dot)])
        sin, cos = np.sin(theta), np.cos(theta)
        # Per-link offsets in (x, z), then cumulative sums down the chain.
        dq = self.lengths * np.stack([sin, -cos], axis=-1).transpose(2, 0, 1)
        dv = self.lengths * theta_dot * np.stack([cos, sin], axis=-1).transpose(2, 0, 1)
        da = self.lengths * np.stack(
            [theta_ddot * cos - theta_dot**2 * sin, theta_ddot * sin + theta_dot**2 * cos], axis=-1
        ).transpose(2, 0, 1)
        q, v, a = (np.cumsum(x, axis=2).transpose(1, 2, 0) for x in (dq, dv, da))  # (s, n, 2)
        q = q + self.anchor[[0, 2]]
        # f_k = m_k (a_k − g) + f_{k+1}: accumulate from the free end.
        own = self.masses[None, :, None] * (a - self.gravity)
        f = np.cumsum(own[:, ::-1], axis=1)[:, ::-1]

        positions, velocities, forces = empty_samples(scene, len(states))
        for k, p in enumerate(self.order):
            positions[:, p, 0], positions[:, p, 2] = q[:, k, 0], q[:, k, 1]
            velocities[:, p, 0], velocities[:, p, 2] = v[:, k, 0], v[:, k, 1]
            sign = 1.0 if self.first_is_lower[k] else -1.0
            c = self.constraint_of_link[k]
            forces[:, c, 0], forces[:, c, 2] = sign * f[:, k, 0], sign * f[:, k, 1]
        return positions, velocities, forces


def chain_model(scene: Scene) -> ChainModel:
    """Read ``scene`` as a planar serial chain, or raise Unsupported saying why it is not one."""
    if not scene.is_planar:
        raise Unsupported(f"{scene.name!r} is not planar, so it is not a planar chain")
    pins = [k for k, c in enumerate(scene.constraints) if isinstance(c, Pin)]
    if len(pins) != 1:
        raise Unsupported(f"the reference's chain form needs exactly one Pin, {scene.name!r} has {len(pins)}")
    if len(scene.constraints) != len(scene.particles):
        raise Unsupported(
            f"the reference's chain form needs one constraint per particle "
            f"({len(scene.constraints)} constraints, {len(scene.particles)} particles)"
        )
    tree = read_tree(scene)
    order = tree.path()
    if order is None or any(not isinstance(scene.constraints[tree.constraint_of[i]], (Pin, Rod)) for i in order):
        why = "form a loop" if tree.closures else "do not form a single path from the pinned particle"
        raise Unsupported(f"the rods of {scene.name!r} {why}")
    pin = scene.constraints[pins[0]]
    links = [tree.constraint_of[i] for i in order]
    first_is_lower = [k == pins[0] or scene.constraints[k].a == i for i, k in zip(order, links)]
    return ChainModel(
        anchor=np.asarray(pin.anchor, dtype=float),
        order=np.array(order),
        lengths=np.array([scene.constraints[k].length for k in links]),
        masses=scene.masses[order],
        constraint_of_link=np.array(links),
        first_is_lower=np.array(first_is_lower),
        gravity=np.array([scene.gravity[0], scene.gravity[2]]),
    )


# -- spherical pendulum -----------------------------------------------------------


@dataclass(frozen=True)
class SphericalPin:
    """One particle of ``mass`` (kg) at ``radius`` (m) from ``anchor``, gravity ``g`` (m/s²) along −z.

    State [θ, φ, θ̇, φ̇]: θ polar angle from −z, φ azimuth from +x toward +y.
    """

    anchor: np.ndarray
    radius: float
    mass: float
    g: float

    def initial_state(self, scene: Scene) -> np.ndarray:
        d = scene.initial_positions[0] - self.anchor
        v = scene.initial_velocities[0]
        theta = math.atan2(math.hypot(d[0], d[1]), -d[2])
        phi = math.atan2(d[1], d[0])
        e_theta = np.array([math.cos(theta) * math.cos(phi), math.cos(theta) * math.sin(phi), math.sin(theta)])
        e_phi = np.array([-math.sin(phi), math.cos(phi), 0.0])
        return np.array([theta, phi, v @ e_theta / self.radius, v @ e_phi / (self.radius * math.sin(theta))])

    def rhs(self, _t: float, y: np.ndarray) -> np.ndarray:
        theta, _phi, theta_dot, phi_dot = y
        s, c = math.sin(theta), math.cos(theta)
        theta_ddot = s * c * phi_dot**2 - (self.g / self.radius) * s
        phi_ddot = -2.0 * c / s * theta_dot * phi_dot
        return np.array([theta_dot, phi_dot, theta_ddot, phi_ddot])

    def evaluate(self, scene: Scene, states: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        theta, phi, theta_dot, phi_dot = states.T
        st, ct, sp, cp = np.sin(theta), np.cos(theta), np.sin(phi), np.cos(phi)
        r = self.radius
        d = r * np.stack([st * cp, st * sp, -ct], axis=-1)
        v = r * np.stack(
            [ct * cp * theta_dot - st * sp * phi_dot, ct * sp * theta_dot + st * cp * phi_dot, st * theta_dot], axis=-1
        )
        unit = d / r
        # Radial balance: −m v²/r = m g·r̂ − T, so T = m v²/r + m g·r̂ and the force is −T r̂.
        gravity = np.array([0.0, 0.0, -self.g])
        tension = self.mass * (np.einsum("si,si->s", v, v) / r + unit @ gravity)
        forces = -tension[:, None] * unit
        return (d + self.anchor)[:, None, :], v[:, None, :], forces[:, None, :]


def spherical_pin(scene: Scene) -> SphericalPin:
    """Read a one-particle 3-D pinned scene, or raise Unsupported saying why not."""
    if len(scene.particles) != 1 or len(scene.constraints) != 1 or not isinstance(scene.constraints[0], Pin):
        raise Unsupported(
            f"the reference handles 3-D scenes of one pinned particle only; {scene.name!r} is not one"
        )
    gx, gy, gz = scene.gravity
    if gx != 0.0 or gy != 0.0:
        raise Unsupported("the reference's spherical form needs gravity along −z")
    pin = scene.constraints[0]
    model = SphericalPin(np.asarray(pin.anchor, dtype=float), pin.length, scene.particles[0].mass, -gz)
    d = scene.initial_positions[0] - model.anchor
    lz = d[0] * scene.initial_velocities[0][1] - d[1] * scene.initial_velocities[0][0]
    if abs(lz) < 1e-12 * max(pin.length, 1.0):
        raise Unsupported(
            "this 3-D pin has no angular momentum about the vertical, so it swings through the pole of "
            "the reference's spherical coordinates; rotate it into the x–z plane (a planar scene)"
        )
    return model


# -- solving -------------------------------------------------------------------


def model_for(scene: Scene) -> ChainModel | SphericalPin | Mechanism | ModelDynamics:
    """The reduced-coordinate model of ``scene``; Unsupported when the reference cannot express it.

    Mechanisms (slider-pendulum, four-bar, bead on an ellipse) are read by
    :mod:`engines.reference.mechanisms`; everything else is a chain or a spherical pin.
    """
    if scene.is_model:  # a model file: Pinocchio's ABA (engines/model/dynamics.py)
        from engines.model.dynamics import ModelDynamics

        return ModelDynamics(scene)
    mechanism = mechanism_model(scene)
    if mechanism is not None:
        return mechanism
    return chain_model(scene) if scene.is_planar else spherical_pin(scene)


def _solve_ivp():
    """scipy's solve_ivp, imported on first use: `xval engines`, and a run whose references are all
    kept, need not load scipy.integrate."""
    from scipy.integrate import solve_ivp

    return solve_ivp


class DenseOutput:
    """scipy's dense solution (an ``OdeSolution``), evaluated as ``dense(times)`` -> (n_state, n).

    Once pickled, it stays a pickle until first evaluated: unpickling it
    imports scipy.integrate (and scipy.linalg, scipy.optimize: a visible part
    of a run's own CPU, bench/bench_harness.py), which a run that finds every
    sample it needs already kept (ReferenceSolution.samples) never has to.
    """

    __slots__ = ("_ode", "_pickled")
    _ode: Any  # scipy's OdeSolution, or None while only its pickle is held
    _pickled: bytes | None

    def __init__(self, ode: Any) -> None:
        self._ode, self._pickled = ode, None

    def __call__(self, times: np.ndarray) -> np.ndarray:
        if self._ode is None:
            self._ode = pickle.loads(self._pickled)
        return self._ode(times)

    def __getstate__(self) -> bytes:
        if self._pickled is None:
            self._pickled = pickle.dumps(self._ode, protocol=pickle.HIGHEST_PROTOCOL)
        return self._pickled

    def __setstate__(self, pickled: bytes) -> None:
        self._ode, self._pickled = None, pickled


#: At most this many sample-time sets are kept with a solution (the oldest goes first): a run keeps
#: one per dt of the suite, and users' suites with other dts or sample intervals add their own.
MOST_SAMPLE_SETS = 64


@dataclass(frozen=True)
class ReferenceSolution:
    """A dense solution: evaluate at any times in [0, scene.duration].

    wall_time : s spent integrating; n_steps : accepted DOP853 steps; nfev : right-hand-side calls.
    samples : what :meth:`at` gives for the sets of times :meth:`sample` was asked for, by the
        times' bytes (kept with the solution, so a run that finds them needs no scipy).
    """

    scene: Scene
    model: ChainModel | SphericalPin | Mechanism
    ode: DenseOutput
    rtol: float
    atol: float
    n_steps: int
    nfev: int
    wall_time: float
    samples: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray]] = field(
        default_factory=dict, compare=False, repr=False)

    def at(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """positions (n, P, 3) m, velocities (n, P, 3) m/s, constraint forces (n, C, 3) N at ``times`` (n,) s."""
        times = np.asarray(times, dtype=float)
        kept = self.samples.get(times.tobytes())
        if kept is not None:
            return kept
        states = self.ode(times).T.reshape(len(times), -1)
        return self.model.evaluate(self.scene, states)

    def sample(self, sets: Iterable[np.ndarray]) -> bool:
        """Evaluate and keep :meth:`at` for each set of times (each (n,) s) not kept yet; whether any was."""
        added = False
        for times in sets:
            times = np.asarray(times, dtype=float)
            key = times.tobytes()
            if key in self.samples:
                continue
            self.samples[key] = self.at(times)
            added = True
            while len(self.samples) > MOST_SAMPLE_SETS:
                del self.samples[next(iter(self.samples))]
        return added


def solve(scene: Scene, rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL) -> ReferenceSolution:
    """Integrate ``scene`` over its duration with DOP853; Unsupported when it has no reduced form here."""
    model = model_for(scene)
    y0 = model.initial_state(scene)
    solve_ivp = _solve_ivp()
    start = time.perf_counter()
    result = solve_ivp(
        model.rhs, (0.0, scene.duration), y0, method="DOP853", rtol=rtol, atol=atol, dense_output=True
    )
    wall_time = time.perf_counter() - start
    if not result.success:
        raise RuntimeError(f"reference integration failed: {result.message}")
    return ReferenceSolution(scene, model, DenseOutput(result.sol), rtol, atol, len(result.t) - 1, result.nfev, wall_time)


# -- the reference's own error bar, horizon and Lyapunov exponent ------------------------------

#: How much tighter the second solve is: rtol and atol divided by this, but never below what
#: DOP853 accepts (scipy raises any rtol < 100·ε ≈ 2.2e-14 to that floor, with a warning).
TIGHTER = 100.0
#: scipy's smallest accepted rtol for DOP853 (a hair above 100·ε, so it never warns).
MIN_RTOL = 100 * np.finfo(float).eps * (1 + 1e-9)
#: The reference is trusted to this fraction of L: the gate's position tolerance (1e-9 m for
#: L = 1 m, "the reference's own accuracy", README) ...
REFERENCE_ACCURACY = 1e-9
#: ... and its horizon is the first time the two solves differ by more than this fraction of it
#: (1e-10 L): by then an error measured against the reference is no longer the engine's alone.
HORIZON_FRACTION = 0.1


@dataclass(frozen=True)
class ReferenceBound:
    """The reference solved twice, and what the difference says about it.

    rtol, atol : the suite's tolerances; tight_rtol, tight_atol : the second solve's.
    t : (n,) s sample times; difference : (n,) m, max over particles of the position difference.
    threshold : m, HORIZON_FRACTION · REFERENCE_ACCURACY · L unless given.
    reference_error : m, the largest difference over the whole run.
    reference_horizon : s, the first sample time where the difference exceeds ``threshold``,
        None when it never does (the reference holds over the whole run).
    horizon_interval : (low, high) s, where the horizon falls when the loose solve's tolerance is
        scaled by each of HORIZON_FACTORS (a reference error halved or doubled); None without a horizon.
    lyapunov : the largest Lyapunov exponent (1/s) from Benettin's ensemble (engines.reference.ensemble),
        for a scene whose two solves part exponentially (growth_rate); None otherwise or when not asked.
    """

    rtol: float
    atol: float
    tight_rtol: float
    tight_atol: float
    t: np.ndarray
    difference: np.ndarray
    threshold: float
    reference_error: float
    reference_horizon: float | None
    horizon_interval: tuple[float, float] | None = None
    lyapunov: Estimate | None = None


#: The factors the loose solve's tolerance is scaled by for the horizon's interval: a reference half or
#: twice as accurate parts from the truth earlier or later by about ln 2 / λ.
HORIZON_FACTORS = (0.5, 2.0)


def reference_horizon(t: np.ndarray, difference: np.ndarray, threshold: float) -> float | None:
    """First t (s) with difference (n,) m above threshold (m), or None when it never is."""
    above = np.nonzero(np.asarray(difference) > threshold)[0]
    return float(t[above[0]]) if len(above) else None


#: The cheap Lyapunov estimate (growth_rate; it decides whether a scene is chaotic, and so gets the
#: ensemble's estimate, lyapunov_ensemble) fits ln d(t) between these fractions of L: above the
#: round-off of two solves at rtol ~1e-12 and below where the difference saturates ...
GROWTH_BAND = (1e-13, 1e-3)
#: ... and only when d grows by at least this factor over the fit: a regular scene's two solves drift apart
#: in phase, linearly in t (by a factor 25-50 over the catalog's 10 s runs), a chaotic one's exponentially.
GROWTH_FACTOR = 1e3
#: Fewest samples in the band for a fit.
GROWTH_MIN_SAMPLES = 10


def growth_rate(t: np.ndarray, difference: np.ndarray, length: float) -> float | None:
    """A cheap estimate of the largest Lyapunov exponent (1/s) from the reference's two solves, or None.

    t : (n,) s; difference : (n,) m, the two solves' position difference (ReferenceBound.difference);
    length : L, m. The least-squares slope of ln d against t over the samples from the first one
    with d above GROWTH_BAND[0]·L up to the last below GROWTH_BAND[1]·L; None (regular over this
    run) when fewer than GROWTH_MIN_SAMPLES lie there, d grows by less than GROWTH_FACTOR across
    them, or the slope is not positive.
    """
    t, d = np.asarray(t, dtype=float), np.asarray(difference, dtype=float) / length
    lo, hi = GROWTH_BAND
    above = np.nonzero(d > lo)[0]
    if not len(above):
        return None
    window = np.arange(above[0], len(d))
    window = window[(d[window] > lo) & (d[window] < hi)]
    if len(window) < GROWTH_MIN_SAMPLES or d[window].max() < GROWTH_FACTOR * d[window].min():
        return None
    slope = float(np.polyfit(t[window], np.log(d[window]), 1)[0])
    return slope if slope > 0 else None


def bound(
    scene: Scene,
    rtol: float = DEFAULT_RTOL,
    atol: float = DEFAULT_ATOL,
    times: np.ndarray | None = None,
    threshold: float | None = None,
    solution: ReferenceSolution | None = None,
) -> ReferenceBound:
    """Solve ``scene`` at (rtol, atol) and TIGHTER times tighter; compare positions at ``times``.

    times : (n,) s, default every 0.01 s over the scene's duration. threshold : m, default
    HORIZON_FRACTION · REFERENCE_ACCURACY · L. solution : the scene's solve at (rtol, atol)
    when the caller has it already (the runner does), so only the tighter one is solved here.
    Unsupported when the reference cannot express the scene.
    """
    if times is None:
        times = np.linspace(0.0, scene.duration, max(2, round(scene.duration / 0.01) + 1))
    times = np.asarray(times, dtype=float)
    tight_rtol, tight_atol = max(rtol / TIGHTER, MIN_RTOL), atol / TIGHTER
    if solution is None or (solution.rtol, solution.atol) != (rtol, atol):
        solution = solve(scene, rtol, atol)
    loose = solution.at(times)[0]
    tight = solve(scene, tight_rtol, tight_atol).at(times)[0]
    difference = np.linalg.norm(loose - tight, axis=2).max(axis=1)
    if threshold is None:
        threshold = HORIZON_FRACTION * REFERENCE_ACCURACY * scene.characteristic_length
    horizon = reference_horizon(times, difference, threshold)
    interval = None
    if horizon is not None:
        # Each member's horizon; one that holds over the whole run counts as its last sample time.
        members = [horizon]
        for factor in HORIZON_FACTORS:
            other = solve(scene, max(rtol * factor, MIN_RTOL), atol * factor).at(times)[0]
            found = reference_horizon(times, np.linalg.norm(other - tight, axis=2).max(axis=1), threshold)
            members.append(float(times[-1]) if found is None else found)
        interval = (min(members), max(members))
    return ReferenceBound(
        rtol, atol, tight_rtol, tight_atol, times, difference, float(threshold),
        float(difference.max()), horizon, interval,
    )


#: Samples solve_and_bound compares the two solves on (at most; evenly over the scene's duration).
BOUND_SAMPLES = 2001


def solve_and_bound(scene: Scene, rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL
                    ) -> tuple[ReferenceSolution, ReferenceBound]:
    """The reference at (rtol, atol) and its :func:`bound`, compared on up to BOUND_SAMPLES times."""
    solution = solve(scene, rtol, atol)
    n = min(BOUND_SAMPLES, max(2, round(scene.duration / 0.01) + 1))
    found = bound(scene, rtol, atol, times=np.linspace(0.0, scene.duration, n), solution=solution)
    if growth_rate(found.t, found.difference, scene.characteristic_length) is not None:
        # A chaotic scene: its exponent as an ensemble's estimate (a second or two, kept with the bound).
        found = replace(found, lyapunov=lyapunov_ensemble(scene, solution))
    return solution, found


#: The reference's own source (paths under engines/): part of the key of a kept solution, so an edit to it
#: solves again.
_SOURCES = ("reference/reference.py", "reference/ensemble.py", "reference/mechanisms.py", "reference/kernels.py", "scene/scene.py",
            "model/dynamics.py", "model/scene.py")
#: A solution whose pickle is larger is solved again each run rather than kept (bytes).
_LARGEST_KEPT = 64 * 2**20


def solve_and_bound_kept(scene: Scene, rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL,
                         sample_times: Iterable[np.ndarray] = ()) -> tuple[ReferenceSolution, ReferenceBound]:
    """:func:`solve_and_bound`, kept across runs in the user cache directory (``<cache>/reference``,
    ``$XVAL_CACHE_DIR`` or ``~/.cache/xval``), with the solution sampled at each set of
    ``sample_times`` (each (n,) s; ReferenceSolution.sample).

    A run solves each scene's reference twice (at the suite's tolerance and a
    tighter one, for the bound) before its cases can be judged, and evaluates
    it at each dt's sample times; the same scene at the same tolerances gives
    the same answer every time, so the answer and its samples are kept, as a
    pickle, under a key of everything they depend on: the scene's physics
    (``Scene.content_hash``, duration included), rtol and atol, the reference's
    own source text, and the versions of Python, numpy and scipy. A kept file
    that cannot be read is solved again and replaced; one that lacks some of the
    sample times is sampled and written again. The solution returned holds the
    samples at ``sample_times`` only.
    """
    path = _kept_path(scene, rtol, atol)
    solved = None
    try:
        with open(path, "rb") as handle:
            solved = pickle.load(handle)
    except FileNotFoundError:
        pass
    except MemoryError:  # the file is fine; this process (a case host under its limit) is not
        raise
    except Exception:  # noqa: BLE001 - damaged or from an incompatible build: solve again
        path.unlink(missing_ok=True)
    sample_times = [np.asarray(times, dtype=float) for times in sample_times]
    if solved is None:
        solved = solve_and_bound(scene, rtol, atol)
        solved[0].sample(sample_times)
        _keep(path, solved)
    elif solved[0].sample(sample_times):
        _keep(path, solved)
    # The answer carries only the samples asked for (the file may hold other suites' too).
    solution, bound = solved
    wanted = {times.tobytes() for times in sample_times}
    return replace(solution, samples={k: v for k, v in solution.samples.items() if k in wanted}), bound


def _keep(path: Path, solved: tuple[ReferenceSolution, ReferenceBound]) -> None:
    """Write ``solved`` to ``path`` whole or not at all (a concurrent reader sees the old file or the new)."""
    data = pickle.dumps(solved, protocol=pickle.HIGHEST_PROTOCOL)
    if len(data) > _LARGEST_KEPT:
        return
    from ours.files import atomic_write

    with contextlib.suppress(OSError):  # a cache that cannot be written only costs the next run the solve
        path.parent.mkdir(parents=True, exist_ok=True)
        atomic_write(path, data, durable=False)


def is_kept(scene: Scene, rtol: float = DEFAULT_RTOL, atol: float = DEFAULT_ATOL) -> bool:
    """Whether :func:`solve_and_bound_kept` has ``scene``'s reference at these tolerances kept."""
    return _kept_path(scene, rtol, atol).is_file()


def _kept_path(scene: Scene, rtol: float, atol: float) -> Path:
    from ours.files import cache_dir  # the one user cache directory of xval

    key = hashlib.sha256()
    for part in (scene.content_hash, repr(float(rtol)), repr(float(atol)), _code_digest()):
        key.update(part.encode())
        key.update(b"\0")
    return cache_dir() / "reference" / f"{key.hexdigest()[:32]}.pickle"


@functools.cache
def _code_digest() -> str:
    """A hash of what a kept solution's code depends on: the reference's source files and the versions
    of Python, numpy and scipy (read once per process: a run asks for every scene, in parent and host)."""
    here = Path(__file__).parents[1]
    key = hashlib.sha256()
    for part in (sys.version, np.__version__, scipy.__version__,
                 *((here / name).read_text(encoding="utf-8") for name in _SOURCES)):
        key.update(part.encode())
        key.update(b"\0")
    return key.hexdigest()


def lyapunov_exponent(
    scene: Scene, duration: float | None = None, interval: float = 0.1, separation: float = 1e-8,
    rtol: float = 1e-11, start: np.ndarray | None = None, direction: np.ndarray | None = None,
) -> float:
    """Largest Lyapunov exponent estimate (1/s) of ``scene`` over ``duration`` s (default its own):
    one orbit's, which moves by ±15 % with round-off (engines.reference.ensemble has the estimate
    with its interval).

    Benettin's method on the reference's reduced state y (angles and rates), from ``start`` (default
    the scene's initial state): a copy started ``separation`` away (relative to |y0|, along
    ``direction``, a unit vector, default all components equal) is integrated beside y, and
    every ``interval`` s the log of its growth is added up and the copy pulled back to
    ``separation``. The estimate is that sum over the time. A regular scene (the bead, a
    spherical pendulum) gives a value that falls towards 0 like ln(growth)/time; a chaotic one
    converges to a positive rate (about 1 per second for the default double pendulum).
    """
    solve_ivp = _solve_ivp()
    model = model_for(scene)
    duration = scene.duration if duration is None else float(duration)
    if not duration > 0 or not interval > 0:
        raise ValueError("lyapunov_exponent: duration and interval must be positive")
    y = model.initial_state(scene) if start is None else np.asarray(start, dtype=float)
    n = len(y)
    direction = np.ones(n) / math.sqrt(n) if direction is None else np.asarray(direction, dtype=float)
    d0 = separation * max(1.0, float(np.linalg.norm(y)))
    z = y + d0 * direction

    def pair(_t, w):
        return np.concatenate([model.rhs(_t, w[:n]), model.rhs(_t, w[n:])])

    total, elapsed = 0.0, 0.0
    while elapsed < duration - 1e-12:
        step = min(interval, duration - elapsed)
        out = solve_ivp(pair, (0.0, step), np.concatenate([y, z]), method="DOP853", rtol=rtol, atol=rtol * 1e-2)
        if not out.success:
            raise RuntimeError(f"lyapunov_exponent: integration failed: {out.message}")
        y, z = out.y[:n, -1], out.y[n:, -1]
        gap = float(np.linalg.norm(z - y))
        total += math.log(gap / d0)
        z = y + (z - y) * (d0 / gap)
        elapsed += step
    return total / elapsed


def lyapunov_ensemble(scene: Scene, solution: ReferenceSolution | None = None,
                      duration: float | None = None) -> Estimate:
    """The largest Lyapunov exponent (1/s) of ``scene`` from the ensemble of :func:`members`.

    Each member is Benettin's estimate (:func:`lyapunov_exponent`) over ``duration``
    s (default the scene's) from the state the reference ``solution`` (solved here when None) reaches at
    its start time, along a direction drawn from its seed.
    """
    duration = scene.duration if duration is None else float(duration)
    if solution is None:
        solution = solve(scene)
    out = []
    for separation, interval, start, seed in members():
        y0 = np.asarray(solution.ode(np.array([start * scene.duration])), dtype=float).reshape(-1)
        direction = np.random.default_rng(seed).standard_normal(len(y0))
        out.append(lyapunov_exponent(scene, duration, interval, separation, start=y0,
                                     direction=direction / np.linalg.norm(direction)))
    return Estimate.of(out)


class ReferenceEngine(Engine):
    """The reference as an engine, so it can be simulated, listed and compared like any other."""

    name = "reference"
    capabilities = frozenset({"3d", "constraint-forces", "tolerance", "model"})
    #: A suite's tolerance axis (compare/suite/tolerance_axis.py) sets both DOP853 tolerances.
    tolerance_options = ("rtol", "atol")
    options = {
        # scipy raises rtol below 100 eps to 100 eps with a warning: refuse it instead.
        "rtol": Option("rtol", DEFAULT_RTOL, "relative tolerance of DOP853", low=1e-14, high=0.1),
        "atol": Option("atol", DEFAULT_ATOL, "absolute tolerance of DOP853 (rad, rad/s)", low=0.0, high=1.0,
                       low_open=True),
    }
    variants = {"dop853": {}}
    variant_docs = {"dop853": "reduced coordinates, scipy DOP853 at rtol = atol = 1e-12, dense output"}

    def version(self) -> str:
        return f"scipy {scipy.__version__}"

    def tolerance_capable(self, settings: Mapping[str, Any]) -> bool:
        """DOP853 is always error-controlled: on a tolerance axis it sweeps rtol = atol."""
        return True

    def preload(self, scenes) -> None:
        """Import scipy's integrators and load the compiled right-hand side (numba's cache) in this
        process, so that workers forked from it do not each do it again."""
        _solve_ivp()

        from engines.reference.kernels import chain_rhs

        chain_rhs(np.zeros(4), np.eye(2), np.ones(2), 0.0, -9.81)

    def _check(self, scene: Scene, settings: Mapping[str, Any]) -> None:
        model_for(scene)

    def _check_model(self, scene: SceneLike, settings: Mapping[str, Any]) -> None:
        model_for(scene)

    def _run(self, scene: Scene, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        return self._solved(scene, schedule, settings, model=False)

    def _run_model(self, scene: SceneLike, schedule: Schedule, settings: Mapping[str, Any]) -> RawRun:
        """A model file: Pinocchio's ABA (model_for) solved the same way; its joint states, no constraint forces."""
        return self._solved(scene, schedule, settings, model=True)

    def _solved(self, scene: SceneLike, schedule: Schedule, settings: Mapping[str, Any], model: bool) -> RawRun:
        solution = solve(scene, settings["rtol"], settings["atol"])
        positions, velocities, forces = solution.at(schedule.times)
        return RawRun(
            positions,
            velocities,
            None if model else forces,
            steps=solution.n_steps,
            wall_time=solution.wall_time,
            settings={"method": "DOP853", "nfev": solution.nfev, "formulation": type(solution.model).__name__},
            joint_states=solution.ode(np.asarray(schedule.times, dtype=float)).T if model else None,
        )


ENGINE = ReferenceEngine()
