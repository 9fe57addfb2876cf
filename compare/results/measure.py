"""A case measured: everything that happens after its host answers, in one place.

:func:`measure` turns the host's answer (a :class:`CaseOutcome`) and the scene's reference into the
case's :class:`~compare.results.record.CaseRecord`: the metrics against the reference (and within the
reference's horizon), the suite's bounds, the status, and the stored series. The status a case ends
in is decided by :func:`decide_status` alone, from every fact that bears on it (skipped, what the
host saw, what the engine said, a non-finite state, the bounds); the runner schedules and writes,
and ``xval stability``'s trials are judged by the same function.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace
from typing import Any, NamedTuple, Protocol, Sequence

import numpy as np

from engines.adapter import join_messages, scheduled_times, warning_note
from engines.scene.scene import SceneLike
from engines.scene.trajectory import Status, Trajectory
from engines.stdio import EngineOutput

from compare.results.declared import MetricInputs, computed_extras
from compare.results.metrics import Bounds, CaseMetrics, case_metrics
from compare.results.record import CaseKey, CaseRecord, Characteristic, ReferenceFields
from compare.results.series import SeriesView, downsample_indices, round_each
from compare.results.store import jsonable, now


@dataclass
class CaseOutcome:
    """What came back from one case's host.

    trajectory : the first run's Trajectory (its RunInfo holds the engine's
        own status), or None when the case failed or timed out outside the engine.
    wall_times : s, the stepping-loop wall time of each repeat.
    cpu_times : s, the stepping-loop CPU time of each repeat (RunInfo.cpu_time).
    calibrations : s, CPU time of compare.run.isolation.calibration_cpu_time run just before each repeat.
    status, message : what the host saw: ``ok`` when the trajectory's own status applies; else
        ``failed`` (raised outside the engine, its process died) or ``timeout``.
    elapsed : s, wall time of the whole case (model building and all repeats).
    output : what the engine's library printed meanwhile (fds 1 and 2, warnings printed), captured in the host.
    """

    case_id: str
    trajectory: Trajectory | None
    wall_times: list[float] = field(default_factory=list)
    status: Status = Status.OK
    message: str = ""
    elapsed: float = 0.0
    cpu_times: list[float] = field(default_factory=list)
    calibrations: list[float] = field(default_factory=list)
    output: EngineOutput = field(default_factory=EngineOutput)
    #: The gradient metrics of a suite with [gradients] (compare.gradients.measure.gradient_metrics), or {}.
    gradients: dict[str, Any] = field(default_factory=dict)
    #: Their series for the report (compare.gradients.measure.gradient_series: name -> array), or {}.
    gradient_series: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self.status = Status(self.status)


class SampledReference:
    """A scene's reference: its dense solution, which carries its samples at this run's sample times
    (evaluated by the reference's host, ``ReferenceTask.sample_dts``), and its bound (or None)."""

    def __init__(self, solved: Any) -> None:
        # The reference host's (solution, bound); a bare solution (no bound) is accepted too.
        self.solution, self.bound = solved if isinstance(solved, tuple) else (solved, None)


class MeasureSettings(Protocol):
    """What a suite says about measuring a case (compare.suite.reader.Suite has these)."""

    sample_interval: float  # s between stored samples
    delta: float  # δ, the divergence threshold, fraction of L
    bounds: Bounds  # when an ok run is unstable


class CaseStatus(NamedTuple):
    """The status a case ends in, and why (the message; empty for a plain ok)."""

    status: Status
    message: str = ""


@dataclass(frozen=True)
class SceneFields:
    """The CaseRecord fields that depend on the scene alone (JSON-ready): the same for every case of it."""

    scene: dict[str, Any]
    scene_hash: str
    characteristic: Characteristic

    @classmethod
    def of(cls, scene: SceneLike) -> "SceneFields":
        return cls(jsonable(scene.to_dict()), scene.content_hash,
                   Characteristic(scene.characteristic_length, scene.characteristic_energy))


# -- the status -------------------------------------------------------------------------------

#: Why a trajectory the engine called ok is unstable anyway (engines.adapter.Engine.simulate cuts a run at
#: its first non-finite state; a plug-in that overrides simulate must not pass NaN off as ok).
NON_FINITE = "non-finite state in the returned trajectory"
#: Why a case whose host answered ok with no trajectory is failed (a host that breaks its own protocol).
NO_TRAJECTORY = "the case's host returned no trajectory"


def decide_status(
    *,
    skipped: str | None = None,
    host: CaseStatus = CaseStatus(Status.OK),
    run: CaseStatus | None = None,
    finite: bool = True,
    exceeded: Sequence[str] = (),
    notes: Sequence[str] = (),
) -> CaseStatus:
    """The status and message of a case, from every fact that bears on it; the rules, in order:

    1. ``skipped`` (why the engine cannot run the scene here): ``skipped``, with that reason.
    2. ``host``, what the host saw, when not ok (``timeout``; ``failed``: raised outside the engine,
       died, lost with its executor): kept with its message.
    3. no ``run`` (the engine's own status and message) although the host said ok: ``failed``.
    4. the engine's status when not ok (``unstable``: a non-finite state, stepping stopped early;
       ``failed``: it raised; a command engine's program may also answer ``timeout`` or ``skipped``):
       kept with its message.
    5. an ok run whose trajectory is not ``finite``: ``unstable``.
    6. an ok run past the suite's bounds (``exceeded``: one reason each, bounds_exceeded):
       ``unstable``, the reasons replacing the engine's message.
    7. otherwise ``ok`` with the engine's message.

    ``notes`` (the reference failed, warnings heard while measuring) are added to the message of
    a case that ran (rules 4 to 7); they never change its status.
    """
    if skipped is not None:
        return CaseStatus(Status.SKIPPED, skipped)
    if host.status is not Status.OK:
        return host
    if run is None:
        return CaseStatus(Status.FAILED, join_messages(host.message, NO_TRAJECTORY))
    status, message = run
    if status is Status.OK and not finite:
        status, message = Status.UNSTABLE, NON_FINITE
    elif status is Status.OK and exceeded:
        status, message = Status.UNSTABLE, "; ".join(exceeded)
    return CaseStatus(status, join_messages(message, *notes))


def bounds_exceeded(metrics: CaseMetrics, bounds: Bounds, scene: SceneLike) -> list[str]:
    """One reason per bound the run went past: energy drift over ``bounds.energy_drift`` (E*), constraint
    error over ``bounds.constraint_error`` · L. Equal to the bound is within it; a NaN metric is past it."""
    reasons = []
    if not metrics.energy_drift <= bounds.energy_drift:
        drift, bound = distinct(metrics.energy_drift, bounds.energy_drift)
        reasons.append(f"energy drift {drift} E* exceeds the bound {bound} E*")
    limit = bounds.constraint_error * scene.characteristic_length
    if not metrics.constraint_error <= limit:
        error, shown_limit = distinct(metrics.constraint_error, limit)
        reasons.append(f"constraint error {error} m exceeds the bound {bounds.constraint_error:g} L = {shown_limit} m")
    return reasons


def apply_bounds(status: str, message: str, metrics: CaseMetrics, bounds: Bounds, scene: SceneLike) -> CaseStatus:
    """The (status, message) of a finished run of ``status`` once the suite's bounds are applied
    (:func:`decide_status`, rules 4, 6 and 7): a status other than ``ok`` is kept; an ``ok`` run past a
    bound becomes ``unstable`` with a message naming the metric, its value and the bound."""
    return decide_status(run=CaseStatus(Status(status), message), exceeded=bounds_exceeded(metrics, bounds, scene))


def distinct(value: float, bound: float) -> tuple[str, str]:
    """``value`` and ``bound`` printed with 3 significant digits, or more until they differ (up to 17), so a
    value just past its bound never reads "1 exceeds the bound 1"."""
    for digits in range(3, 18):
        shown = f"{value:.{digits}g}", f"{bound:.{digits}g}"
        if shown[0] != shown[1]:
            return shown
    return shown


# -- the record -------------------------------------------------------------------------------


def measure(
    case: CaseKey,
    scene: SceneLike,
    outcome: CaseOutcome | None,
    reference: SampledReference | Exception | None,
    settings: MeasureSettings,
    *,
    skipped: str | None = None,
    scene_part: SceneFields | None = None,
) -> CaseRecord:
    """The record of one case: its metrics, status and message, and its series (a SeriesView of float
    arrays rounded to SERIES_DIGITS significant digits, which ResultsDir.write_case writes as lists).

    case : its key; scene : the scene it ran. outcome : the host's answer (None for a skipped case,
    ``skipped`` saying why). reference : the scene's SampledReference, or the exception that kept it
    from being solved (position metrics are then null and the message says why). scene_part :
    ``SceneFields.of(scene)``, kept by the caller for every case of the scene (shared, not copied).
    """
    part = scene_part or SceneFields.of(scene)
    record = CaseRecord(case=case, status=Status.SKIPPED, message="", metrics={}, run_info=None,
                        wall_times=(), elapsed=0.0, series=None, reference=None, finished=now(), scene=part.scene,
                        scene_hash=part.scene_hash, characteristic=part.characteristic)
    if outcome is None:
        return replace(record, **decide_status(skipped=skipped or "")._asdict())
    record = replace(record, **_timing(outcome))
    host = CaseStatus(outcome.status, outcome.message or "")
    if outcome.trajectory is None:
        return replace(record, **decide_status(host=host)._asdict())
    return _measured(record, scene, outcome, outcome.trajectory, host, reference, settings)


def _timing(outcome: CaseOutcome) -> dict[str, Any]:
    """The record's times of ``outcome``."""
    return {
        "elapsed": float(outcome.elapsed),
        "wall_times": tuple(float(w) for w in outcome.wall_times),
        "cpu_times": tuple(jsonable(outcome.cpu_times)),  # s of CPU per repeat: what the timing gate compares,
        "calibrations": tuple(jsonable(outcome.calibrations)),  # in units of this kernel's CPU time, beside each
        "engine_output": outcome.output.to_dict() if outcome.output else None,  # what its library printed
    }


def _measured(record: CaseRecord, scene: SceneLike, outcome: CaseOutcome, trajectory: Trajectory, host: CaseStatus,
              reference: SampledReference | Exception | None, settings: MeasureSettings) -> CaseRecord:
    """``record`` with what ``trajectory`` (``outcome``'s) gives: run info, reference, metrics, status, series."""
    info = trajectory.info
    finite = np.isfinite(trajectory.positions).all(axis=(1, 2)) & np.isfinite(trajectory.velocities).all(axis=(1, 2))
    if not finite.all():
        trajectory = truncate(trajectory, int(np.argmin(finite)))
    scheduled = scheduled_times(scene.duration, record.case.dt, settings.sample_interval)
    n = trajectory.n_samples
    reference_note = ""
    solved: ReferenceFields | None = None
    horizon = None
    if isinstance(reference, Exception) or reference is None:
        why = reference if reference is not None else "no reference"
        ref_positions = np.full((n, len(scene.particles), 3), math.nan)
        ref_forces = None
        # Every reference-based metric is null, and null here means "not measured", never "never diverged".
        reference_note = f"reference failed ({why}): no reference-based metric"
    else:
        solved, horizon = _reference_fields(reference, scene)
        # At the scheduled times (shared by every engine of this dt, their samples kept with the
        # solution), of which the trajectory holds the first n; else at an engine's own sample times.
        ref_times = scheduled if np.array_equal(trajectory.t, scheduled[:n]) else trajectory.t
        ref_positions, _, ref_forces = reference.solution.at(ref_times)
    # A state that ran away (finite, but 1e200 m/s) overflows numpy in the energy: a warning in the case's
    # message, not a line on the terminal.
    with warnings.catch_warnings(record=True) as heard:
        warnings.simplefilter("always")
        metrics, series = case_metrics(scene, trajectory, ref_positions, ref_forces, scheduled_times=scheduled,
                                       wall_times=outcome.wall_times, delta=settings.delta)
        n_ref = min(n, len(ref_positions))
        extras = computed_extras(MetricInputs(scene, trajectory, ref_positions[:n_ref], series.position_error))
    status = decide_status(host=host, run=CaseStatus(info.status, info.message), finite=bool(finite.all()),
                           exceeded=bounds_exceeded(metrics, settings.bounds, scene),
                           notes=(reference_note, warning_note(heard)))
    values = {**metrics.to_dict(), **extras, **outcome.gradients}
    if horizon is not None and n:
        # Past the horizon the reference is not trusted: judge the errors within it, keep the whole run's too.
        values.update(within_horizon(scene, trajectory, ref_positions, ref_forces, scheduled, horizon,
                                     outcome.wall_times, settings.delta, metrics.to_dict()))
    return replace(
        record, status=status.status, message=status.message, metrics=jsonable(values),
        run_info=jsonable(info.to_dict()), reference=jsonable(solved),
        reference_horizon=None if horizon is None else float(horizon),
        series=_series(series, trajectory, ref_positions, ref_forces, n, outcome.gradient_series),
    )


def _reference_fields(reference: SampledReference, scene: SceneLike) -> tuple[ReferenceFields, float | None]:
    """The record's ``reference`` fields, and the reference's horizon (s; None: it holds over the whole run)."""
    solution = reference.solution
    solved: ReferenceFields = {"rtol": solution.rtol, "atol": solution.atol, "steps": solution.n_steps,
                               "wall_time": solution.wall_time}
    if reference.bound is None:
        return solved, None
    bound = reference.bound
    # The reference's own error bar (m) and horizon (s; None: it holds over the whole run), the horizon's
    # interval and the Lyapunov estimate with its interval (a chaotic scene's; else None).
    rate, interval = bound.lyapunov, bound.horizon_interval
    solved["reference_error"] = bound.reference_error
    solved["tight_rtol"] = bound.tight_rtol
    solved["horizon_threshold"] = bound.threshold
    solved["reference_horizon_interval"] = None if interval is None else list(interval)
    solved["lyapunov_exponent"] = None if rate is None else rate.value
    solved["lyapunov_interval"] = None if rate is None else list(rate.interval)
    return solved, bound.reference_horizon


def _series(series: Any, trajectory: Trajectory, ref_positions: np.ndarray, ref_forces: np.ndarray | None,
            n: int, gradients: dict[str, Any] | None = None) -> SeriesView:
    """The record's stored series, downsampled and rounded (a SeriesView); ``gradients``: the gradient
    series ([gradients] suites), each downsampled on its own."""
    keep = downsample_indices(n)
    # Kept as rounded float arrays: ResultsDir.write_case writes them as lists, and making ~5,000 Python
    # floats a record here was most of the cost of writing it.
    arrays = {
        "t": series.t[keep],
        "position_error": series.position_error[keep],
        "energy_drift": series.energy_drift[keep],
        "constraint_error": series.constraint_error[keep],
        "positions": trajectory.positions[keep],
        # The reference at the same samples, so a report can overlay paths without re-solving.
        "reference_positions": ref_positions[:n][keep],
        # For the report's phase plot (angular velocity) and constraint-force plot.
        "velocities": trajectory.velocities[keep],
    }
    if trajectory.constraint_forces is not None:
        arrays["constraint_forces"] = trajectory.constraint_forces[keep]
        if ref_forces is not None and len(ref_forces) >= n:
            arrays["reference_constraint_forces"] = ref_forces[:n][keep]
    for name, values in (gradients or {}).items():
        values = np.asarray(values, dtype=float)
        arrays[name] = values[downsample_indices(len(values))]
    return SeriesView(round_each(arrays))


#: Metrics judged within the reference's horizon (when it ends inside the run); the whole run's values
#: stay in the record as ``<name>_whole_run``.
HORIZON_METRICS = (
    "position_error_final", "position_error_rms", "position_error_linf", "divergence_time",
    "constraint_force_error", "constraint_force_error_relative",
)


def within_horizon(scene: SceneLike, trajectory: Trajectory, ref_positions: np.ndarray, ref_forces: np.ndarray | None,
                   scheduled: np.ndarray, horizon: float, wall_times: Any, delta: float,
                   whole: dict[str, Any]) -> dict[str, Any]:
    """HORIZON_METRICS over the samples at t ≤ ``horizon`` (s), and the whole run's as ``<name>_whole_run``."""
    k = int(np.searchsorted(scheduled, horizon, side="right"))
    n = min(k, trajectory.n_samples, len(ref_positions))
    if n < 1:
        return {}
    inner, _ = case_metrics(
        scene, truncate(trajectory, n), ref_positions[:n], None if ref_forces is None else ref_forces[:n],
        scheduled_times=scheduled[:k], wall_times=wall_times, delta=delta,
    )
    values = inner.to_dict()
    out = {f"{name}_whole_run": whole.get(name) for name in HORIZON_METRICS}
    out.update({name: values.get(name) for name in HORIZON_METRICS})
    return out


def truncate(trajectory: Trajectory, n: int) -> Trajectory:
    """The first n samples of ``trajectory``."""
    forces = None if trajectory.constraint_forces is None else trajectory.constraint_forces[:n]
    joints = None if trajectory.joint_states is None else trajectory.joint_states[:n]
    violation = None if trajectory.constraint_violation is None else trajectory.constraint_violation[:n]
    return replace(trajectory, t=trajectory.t[:n], positions=trajectory.positions[:n],
                   velocities=trajectory.velocities[:n], constraint_forces=forces, joint_states=joints,
                   constraint_violation=violation)
