"""Metrics: pure functions of trajectories and reference samples, as defined in docs/metrics.md.

Every function takes arrays (or a Scene for its masses, lengths and
gravity) and returns plain numbers; nothing here runs an engine or touches
a file. Shapes: ``t (n,) s``, ``positions (n, P, 3) m``, ``velocities
(n, P, 3) m/s``, ``forces (n, C, 3) N`` (the force each constraint exerts on
its first particle). Engine and reference are compared at the same sample
times: the engine's own ``Trajectory.t``.

The bounds an ``ok`` run must stay within (:class:`Bounds`) are declared here; the status they
give is decided in :func:`compare.results.measure.decide_status`.
"""

from __future__ import annotations

import math
import statistics
from dataclasses import asdict, dataclass, fields
from typing import Any, Sequence

import numpy as np

from engines.scene.scene import Scene, SceneLike
from engines.scene.trajectory import (
    Trajectory, max_constraint_error, total_energy, trajectory_constraint_error, trajectory_energy,
)

#: Default divergence threshold δ: e(t) > δ·L counts as diverged.
DEFAULT_DELTA = 1e-2


def position_error(positions: np.ndarray, reference_positions: np.ndarray) -> np.ndarray:
    """e(t) (n,) m: max over particles of ‖pᵢ(t) − pᵢʳᵉᶠ(t)‖.

    positions : (n, P, 3) m; reference_positions : (≥ n, P, 3) m, the
    reference at the same times (only the first n rows are used, so a
    trajectory that stopped early is compared on the samples it has).
    """
    n = len(positions)
    if n == 0:
        return np.zeros(0)
    return np.linalg.norm(positions - reference_positions[:n], axis=2).max(axis=1)


@dataclass(frozen=True)
class ErrorSummary:
    """position error e(t) reduced: final (last sample), rms (root mean square over samples), linf (max), all m."""

    final: float
    rms: float
    linf: float


def summarize_error(e: np.ndarray) -> ErrorSummary:
    """Final, RMS and max of e (n,) m; NaN for an empty series."""
    if len(e) == 0:
        return ErrorSummary(math.nan, math.nan, math.nan)
    return ErrorSummary(float(e[-1]), float(np.sqrt(np.mean(e**2))), float(e.max()))


def divergence_time(t: np.ndarray, e: np.ndarray, threshold: float, end_of_data: float | None = None) -> float | None:
    """First t (s) with e(t) > threshold (m), or None when e stays at or below it.

    end_of_data : s, the time of the first sample the engine did not deliver
        (an unstable run is cut at its first non-finite state). Past it the
        error is unbounded, so a run that had not diverged before it diverges
        there. None when the trajectory is complete.
    """
    above = np.nonzero(e > threshold)[0]
    if len(above):
        return float(t[above[0]])
    return None if end_of_data is None else float(end_of_data)


def energy_drift(scene: Scene, positions: np.ndarray, velocities: np.ndarray) -> float:
    """max |E(t) − E(0)| / E* (dimensionless), E* = total mass · g · L; 0 for fewer than 2 samples."""
    return largest(energy_drift_series(scene, positions, velocities))


def largest(series: np.ndarray) -> float:
    """max |x| of a series (n,) (an :func:`energy_drift_series`, a :func:`max_constraint_error`): the
    scalar metric of it; 0 for no samples (a drift of one sample is 0 too)."""
    return float(np.abs(series).max()) if len(series) else 0.0


def energy_drift_series(scene: Scene, positions: np.ndarray, velocities: np.ndarray) -> np.ndarray:
    """(n,) (E(t) − E(0)) / E*, signed, for plots."""
    if len(positions) == 0:
        return np.zeros(0)
    return relative_drift(scene, total_energy(scene, positions, velocities))


def relative_drift(scene: Scene, energy: np.ndarray) -> np.ndarray:
    """(n,) (E(t) − E(0)) / E* of an energy series (n,) J."""
    return (energy - energy[0]) / scene.characteristic_energy if len(energy) else np.zeros(0)


def constraint_error(scene: Scene, positions: np.ndarray) -> float:
    """max over constraints and samples of |‖a − b‖ − l|, in m (0 for no samples or no constraints)."""
    return largest(max_constraint_error(scene, positions))


def constraint_force_error(forces: np.ndarray, reference_forces: np.ndarray) -> float:
    """max over samples and reported constraints of ‖F − Fʳᵉᶠ‖, in N.

    forces : (n, C, 3) N; reference_forces : (≥ n, C, 3) N at the same times.
    A constraint whose forces are NaN at every sample is not reported (a
    solver that exposes some constraints' forces only) and is left out; NaN
    when none is reported.
    """
    n = len(forces)
    if n == 0:
        return math.nan
    reported = ~np.isnan(forces).all(axis=(0, 2))
    if not reported.any():
        return math.nan
    return float(np.linalg.norm(forces[:, reported] - reference_forces[:n, reported], axis=2).max())


def characteristic_force(scene: Scene) -> float:
    """E*/L = total mass · g (N): the scale constraint-force errors are reported against."""
    return scene.characteristic_energy / scene.characteristic_length


@dataclass(frozen=True)
class Cost:
    """Stepping cost: wall_time (s, median over repeats), per simulated second (s/s), steps per second (1/s)."""

    wall_time: float
    per_simulated_second: float
    steps_per_second: float


def stepping_cost(wall_times: Sequence[float], simulated_time: float, steps: int) -> Cost:
    """Cost from the stepping-loop wall times (s) of repeated runs of ``steps`` steps over ``simulated_time`` s.

    The median, not the mean, so one run disturbed by the machine does not
    move it.
    """
    if not wall_times:
        return Cost(math.nan, math.nan, math.nan)
    median = float(statistics.median(wall_times))
    per_second = median / simulated_time if simulated_time > 0 else math.nan
    steps_per_second = steps / median if median > 0 else math.inf
    return Cost(median, per_second, steps_per_second)


@dataclass(frozen=True)
class CaseMetrics:
    """Every metric of one case (docs/metrics.md defines each).

    position_error_final / _rms / _linf : m (final is NaN for an incomplete run).
    divergence_time : s, or None when e(t) stays ≤ δ·L.
    energy_drift : max |E(t) − E(0)| / E*.
    constraint_error : m.
    constraint_force_error : N, None when the engine exposes no forces.
    constraint_force_error_relative : constraint_force_error / (total mass · g).
    wall_time : s (median of repeats); cost_per_simulated_second : s/s; steps_per_second : 1/s.
    n_samples : samples compared; complete : whether the run delivered every scheduled sample.
    """

    position_error_final: float
    position_error_rms: float
    position_error_linf: float
    divergence_time: float | None
    energy_drift: float
    constraint_error: float
    constraint_force_error: float | None
    constraint_force_error_relative: float | None
    wall_time: float
    cost_per_simulated_second: float
    steps_per_second: float
    n_samples: int
    complete: bool

    def to_dict(self) -> dict[str, Any]:
        # Its fields are numbers, flags and strings: no asdict (a deep copy) needed.
        return {f.name: _json_number(getattr(self, f.name)) for f in fields(self)}


def _json_number(value: Any) -> Any:
    """NaN and ±inf are not JSON; store them as None (the record's status says why)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


@dataclass(frozen=True)
class Series:
    """Per-sample series of one case for plots: t (n,) s, position error (n,) m,
    signed energy drift (n,) /E*, constraint error (n,) m."""

    t: np.ndarray
    position_error: np.ndarray
    energy_drift: np.ndarray
    constraint_error: np.ndarray


def case_metrics(
    scene: SceneLike,
    trajectory: Trajectory,
    reference_positions: np.ndarray,
    reference_forces: np.ndarray | None,
    *,
    scheduled_times: np.ndarray,
    wall_times: Sequence[float],
    delta: float = DEFAULT_DELTA,
) -> tuple[CaseMetrics, Series]:
    """All metrics of ``trajectory`` against the reference sampled at ``scheduled_times``.

    reference_positions : (N, P, 3) m and reference_forces : (N, C, 3) N at
    scheduled_times (N,) s, the times the engine was asked for; the
    trajectory holds the first n ≤ N of them. wall_times : s, one per repeat.
    """
    n = trajectory.n_samples
    complete = n == len(scheduled_times)
    e = position_error(trajectory.positions, reference_positions)
    summary = summarize_error(e)
    # Without a reference (NaN positions) e is NaN: no divergence time at all, not "diverged at the end of data".
    end_of_data = None if complete or not np.isfinite(e).any() else float(scheduled_times[n])
    threshold = delta * scene.characteristic_length
    force_error = None
    if trajectory.constraint_forces is not None and reference_forces is not None and n:
        force_error = constraint_force_error(trajectory.constraint_forces, reference_forces)
    cost = stepping_cost(wall_times, trajectory.info.steps * trajectory.info.dt, trajectory.info.steps)
    # Each series once; the scalar metrics are their maxima, as energy_drift and constraint_error give them.
    drift = relative_drift(scene, trajectory_energy(scene, trajectory))
    # The distance form of the scene's constraints, or the engine's own joints where it reports them.
    constraint_errors = trajectory_constraint_error(scene, trajectory)
    metrics = CaseMetrics(
        position_error_final=summary.final if complete else math.nan,
        position_error_rms=summary.rms,
        position_error_linf=summary.linf,
        divergence_time=divergence_time(trajectory.t, e, threshold, end_of_data),
        energy_drift=largest(drift),
        constraint_error=largest(constraint_errors),
        constraint_force_error=force_error,
        constraint_force_error_relative=None if force_error is None else force_error / characteristic_force(scene),
        wall_time=cost.wall_time,
        cost_per_simulated_second=cost.per_simulated_second,
        steps_per_second=cost.steps_per_second,
        n_samples=n,
        complete=complete,
    )
    series = Series(trajectory.t, e, drift, constraint_errors)
    return metrics, series


# -- status rules ------------------------------------------------------------------


@dataclass(frozen=True)
class Bounds:
    """When an ``ok`` run is called ``unstable`` although its state stayed finite.

    energy_drift : largest energy drift, in units of E* (a run that gains or
        loses more than this has blown up or been damped out).
    constraint_error : largest constraint error, in units of L (a particle
        that left its wire or rod by this much is no longer the same system).
    """

    energy_drift: float = 1.0
    constraint_error: float = 0.1


# -- across a dt sweep ---------------------------------------------------------------


#: Errors below this fraction of L are treated as round-off, reference error or an engine's own floor
#: (an engine's point-mass inertia sets one: MuJoCo's RK4 levels off near 2.6·ratio m on the bead, docs/engines.md;
#: points near a floor bend the fitted slope): the floor where the reference's own error is unknown.
ORDER_FLOOR = 1e-8
#: Where the reference's error is measured, the floor is this multiple of it: an error ten times the
#: reference's own is the engine's to within 10 % ...
ORDER_REFERENCE_MARGIN = 10.0
#: ... and never below this fraction of L, the round-off of a run of ~1e4 steps in double precision
#: (1e4 · 1.1e-16 ≈ 1e-12).
ORDER_ROUNDOFF = 1e-12
#: Below ORDER_FLOOR · L a point counts only while the error still falls at least like dt to it from the
#: next coarser dt (local order ≥ this; the coarsest dt: on to the next finer one): a level there is an
#: engine's own floor, not convergence.
ORDER_MIN_LOCAL = 1.0


def order_floor(length: float, reference_error: float | None = None) -> float:
    """The error (m) below which a sweep's points leave the asymptotic range: ORDER_REFERENCE_MARGIN times
    ``reference_error`` (m) and at least ORDER_ROUNDOFF · ``length``; ORDER_FLOOR · ``length`` when the
    reference's error is unknown (None, or not a positive finite number)."""
    if reference_error is None or not math.isfinite(reference_error) or reference_error <= 0:
        return ORDER_FLOOR * length
    return max(ORDER_REFERENCE_MARGIN * reference_error, ORDER_ROUNDOFF * length)
#: Errors above this fraction of L are treated as saturated (no longer asymptotic).
ORDER_CEILING = 1e-1
#: Fewest points an order is fitted to.
ORDER_MIN_POINTS = 3


@dataclass(frozen=True)
class OrderFit:
    """Observed order p from error ≈ C·dtᵖ.

    order : the least-squares slope of log error vs log dt, or None (reason says why).
    dt_min, dt_max : s, the range of dt used; n_points : how many.
    floor, ceiling : m, the error band that counts as asymptotic.
    """

    order: float | None
    dt_min: float | None
    dt_max: float | None
    n_points: int
    floor: float
    ceiling: float
    reason: str = ""

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)


def observed_order(
    dts: Sequence[float],
    errors: Sequence[float | None],
    *,
    length: float = 1.0,
    floor: float = ORDER_FLOOR,
    ceiling: float = ORDER_CEILING,
    min_points: int = ORDER_MIN_POINTS,
    reference_error: float | None = None,
) -> OrderFit:
    """Slope of log error vs log dt over the asymptotic range.

    dts : s; errors : m (None or non-finite for runs that are not ``ok``);
    length : L in m, scaling ``floor`` and ``ceiling`` (fractions of L).
    reference_error : m, the reference's own error bar; when given, the floor is
    :func:`order_floor` instead (a multiple of it, not ``floor`` · L).
    The asymptotic range is the longest run of consecutive dts (in sorted
    order) whose errors are finite and inside [floor, ceiling·L]: below the
    floor the error is round-off or the reference's own error, above the
    ceiling it has saturated (a chaotic or unstable run no longer shrinks
    with dt). A point below ``floor`` · L (possible only with a reference
    error) counts only while its error still falls with local order ≥
    ORDER_MIN_LOCAL from the next coarser dt's (the coarsest dt: to the next
    finer one). Fewer than ``min_points``
    points gives order None.
    """
    legacy = floor * length
    lo = legacy if reference_error is None else order_floor(length, reference_error)
    hi = ceiling * length
    pairs = sorted(
        (float(dt), (math.nan if err is None else float(err))) for dt, err in zip(dts, errors)
    )

    def inside(k: int) -> bool:
        err = pairs[k][1]
        if not (math.isfinite(err) and lo <= err <= hi):
            return False
        if err >= legacy:
            return True
        # Its local order with the next coarser dt (the coarsest: with the next finer one).
        (fine_dt, fine_err), (coarse_dt, coarse_err) = (pairs[k], pairs[k + 1]) if k + 1 < len(pairs) else (
            (pairs[k - 1], pairs[k]) if k else (pairs[k], pairs[k]))
        return (math.isfinite(fine_err) and math.isfinite(coarse_err) and coarse_err > fine_err > 0
                and coarse_dt > fine_dt
                and math.log(coarse_err / fine_err) / math.log(coarse_dt / fine_dt) >= ORDER_MIN_LOCAL)

    best: list[tuple[float, float]] = []
    current: list[tuple[float, float]] = []
    for k, (dt, err) in enumerate(pairs):
        if inside(k):
            current.append((dt, err))
            if len(current) > len(best):
                best = list(current)
        else:
            current = []
    if len(best) < min_points:
        return OrderFit(
            None, None, None, len(best), lo, hi,
            f"only {len(best)} consecutive dt with error in [{lo:.3g}, {hi:.3g}] m; need {min_points}",
        )
    x = np.log([dt for dt, _ in best])
    y = np.log([err for _, err in best])
    slope = float(np.polyfit(x, y, 1)[0])
    return OrderFit(slope, best[0][0], best[-1][0], len(best), lo, hi)
