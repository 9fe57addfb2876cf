"""One gradient case: an engine's Jacobian of its outputs at T against the reference's, and its class.

error : ‖J − J_ref‖_F / ‖J_ref‖_F at T; the engine runs at dt and dt/2. Classes (docs/gradients.md):

- ``nan``: the Jacobian holds a NaN or an infinity;
- ``chaotic``: T lies past the reference's horizon (its two solves' Jacobians part by more than
  JACOBIAN_HORIZON), where neither side resolves the sensitivity;
- ``correct``: the error is under the floor (1e-6, 1e-3 for float32, or ten times the reference's own
  error), or under SMALL (100 %) and falling with dt at an observed order of at least MIN_ORDER;
- ``wrong``: it does not fall (a bias, such as a parameter the solver ignores), or is off by its own size.

Self-consistency, for an engine with derivatives of its own: its Jacobian against central differences
of its own rollouts at the same dt ("is the derivative of what it computes right?", not "is it accurate?").
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Mapping, Sequence

import numpy as np

from engines.adapter import Engine
from engines.gradients import EngineJacobian, engine_jacobian, finite_difference_jacobian, single_precision
from engines.reference.sensitivity import SensitivityBound, bound_sensitivity, relative_error
from engines.scene.parameters import output_columns, real_parameters
from engines.scene.scene import Scene

CLASSES = ("correct", "chaotic", "wrong", "nan")
#: Observed order (log2 of the error's fall from dt to dt/2) below which a Jacobian is not converging.
MIN_ORDER = 0.5
#: A Jacobian off by its own size is not small, converging or not: wrong at this dt.
SMALL = 1.0
#: Relative error under which a float64 Jacobian is correct whatever its trend: the tolerance the verdict
#: grants a plateau by default (1e-6·L for trajectories). A plateau under it is a model's own small difference
#: (MJX's default point-mass inertia, 1e-9·m·L², holds its Jacobian 8e-9 off on the double pendulum) ...
FLOAT64_FLOOR = 1e-6
#: ... and for a float32 engine, a multiple of its ε (1.2e-7): its rollouts and their derivatives are
#: rounded to that at each step.
FLOAT32_FLOOR = 1e-3


@dataclass(frozen=True)
class GradientCase:
    """What ``xval grad`` reports; see the module docstring for error, class and self_consistency.

    jacobian, reference_jacobian : (m, k) per SI unit; error_half : the error at dt/2 (None for the
    reference); column_errors, column_classes : (k,) per parameter; horizon : s or None;
    reference_error : the reference's own relative error at T; growth : ‖J_ref(T)‖_F / ‖J_ref(0)‖_F (None when
    J_ref(0) = 0), whose log over T is a finite-time Lyapunov estimate (1/s); first_nonfinite : (s, parameter) of
    the first sample whose Jacobian holds a NaN or an infinity, at dt, else at dt/2 (a finite Jacobian at dt can
    sit beside a NaN at dt/2), or None; times (n,) s, error_over_time (n,) : the
    error at every sample, when the engine's Jacobian is known there (differences of rollouts).
    """

    scene: str
    engine: str
    dt: float
    duration: float
    wrt: list[str]
    outputs: list[str]
    jacobian: np.ndarray
    reference_jacobian: np.ndarray
    error: float
    method: str
    self_consistency: float | None
    klass: str
    horizon: float | None
    error_half: float | None
    column_errors: list[float]
    column_classes: list[str]
    reference_error: float
    growth: float | None
    first_nonfinite: tuple[float, str] | None = None
    times: np.ndarray | None = None
    error_over_time: np.ndarray | None = None

    def to_json(self) -> dict[str, Any]:
        """The JSON object of ``xval grad --format json`` (NaN and infinities as null)."""
        return {
            "scene": self.scene, "engine": self.engine, "dt": self.dt, "duration": self.duration,
            "wrt": list(self.wrt), "outputs": list(self.outputs),
            "jacobian": _rows(self.jacobian), "reference_jacobian": _rows(self.reference_jacobian),
            "error": _number(self.error), "method": self.method, "self_consistency": _number(self.self_consistency),
            "class": self.klass, "horizon": self.horizon,
        }


def _number(x: float | None) -> float | None:
    return None if x is None or not math.isfinite(x) else float(x)


def _rows(matrix: np.ndarray) -> list[list[float | None]]:
    return [[_number(float(x)) for x in row] for row in np.asarray(matrix)]


#: A column whose reference norm is under this fraction of ‖J_ref‖_F is measured against ‖J_ref‖_F: it is zero
#: to the accuracy asked of any Jacobian (FLOAT64_FLOOR), and against its own norm round-off would read as 100 %.
ZERO_COLUMN = FLOAT64_FLOOR


def column_errors(jacobian: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """(k,) ‖ΔJ_col‖ / ‖J_ref,col‖ per parameter; a column the reference calls zero (under ZERO_COLUMN of
    ‖J_ref‖_F: a uniform chain's common mass moves nothing, the reference says 3e-14) is measured against
    ‖J_ref‖_F instead."""
    norms = np.linalg.norm(reference, axis=0)
    whole = np.linalg.norm(reference)
    scale = np.where(norms < ZERO_COLUMN * whole, whole, norms)
    with np.errstate(over="ignore", invalid="ignore"):
        return np.linalg.norm(jacobian - reference, axis=0) / scale


def classify(error: float, error_half: float | None, floor: float, horizon: float | None, time: float) -> str:
    """The class of a Jacobian whose relative error is ``error`` at dt and ``error_half`` at dt/2."""
    if not math.isfinite(error) or (error_half is not None and not math.isfinite(error_half)):
        return "nan"
    if horizon is not None and horizon < time:
        return "chaotic"
    if error <= floor:
        return "correct"
    if error < SMALL and error_half is not None and error_half > 0 and math.log2(error / error_half) >= MIN_ORDER:
        return "correct"
    return "wrong"


def worst(classes: Sequence[str]) -> str:
    """The most serious class of several: nan, then wrong, then chaotic, then correct."""
    return max(classes, key=lambda c: ("correct", "chaotic", "wrong", "nan").index(c))


def reference_case(scene: Scene, dt: float, wrt: Sequence[str], bound: SensitivityBound | None = None) -> GradientCase:
    """The reference's own answer (``xval grad`` without --engine): its Jacobian at its tolerance, against its
    tighter solve."""
    bound = bound or bound_sensitivity(scene, wrt)
    time = _end_time(scene, dt)
    loose, tight = _reference_at(bound, time)
    errors = column_errors(loose, tight)
    error = float(relative_error(loose, tight))
    klass = "chaotic" if bound.horizon is not None and bound.horizon < time else "correct"
    return GradientCase(scene.name, "reference/dop853", dt, scene.duration, list(wrt), output_columns(scene), loose,
                        tight, error, "reference", None, klass, bound.horizon, None, [float(e) for e in errors],
                        [klass] * len(wrt), error, _growth(bound, time))


def engine_case(engine: Engine, variant: str | None, options: Mapping[str, Any] | None, scene: Scene, dt: float,
                wrt: Sequence[str], bound: SensitivityBound | None = None) -> GradientCase:
    """``engine``'s Jacobian at dt (its own derivatives, or differences of its rollouts) against the reference's,
    classed with its error at dt/2."""
    variant = variant or engine.default_variant
    bound = bound or bound_sensitivity(scene, wrt)
    answer = engine_jacobian(engine, scene, variant, options, dt, wrt)
    half = engine_jacobian(engine, scene, variant, options, dt / 2, wrt)
    _, reference = _reference_at(bound, answer.time)
    _, reference_half = _reference_at(bound, half.time)
    floor = max(_floor(engine, variant, options), 10 * _reference_error(bound, answer.time))
    error, error_half = _error(answer, reference), _error(half, reference_half)
    per, per_half = column_errors(answer.jacobian, reference), column_errors(half.jacobian, reference_half)
    classes = [classify(float(a), float(b), floor, bound.horizon, answer.time) for a, b in zip(per, per_half)]
    klass = worst([classify(error, error_half, floor, bound.horizon, answer.time), *classes])
    consistency = None
    if answer.own:
        own = finite_difference_jacobian(engine, scene, variant, options, dt, wrt).jacobian
        consistency = _error(answer, own)
    over_time = None
    if answer.over_time is not None and answer.times is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            over_time = relative_error(answer.over_time, bound.sensitivity.jacobian(answer.times))
    return GradientCase(scene.name, f"{engine.name}/{variant}", dt, scene.duration, list(wrt), output_columns(scene),
                        answer.jacobian, reference, error, answer.method, consistency, klass, bound.horizon, error_half,
                        [float(e) for e in per], classes, _reference_error(bound, answer.time),
                        _growth(bound, answer.time),
                        first_nonfinite(answer, list(wrt)) or first_nonfinite(half, list(wrt)), answer.times,
                        over_time)


def first_nonfinite(answer: EngineJacobian, wrt: list[str]) -> tuple[float, str] | None:
    """(s, parameter): the first sample, and its first parameter, whose Jacobian holds a NaN or an infinity."""
    series = answer.over_time if answer.over_time is not None else answer.jacobian[None]
    times = answer.times if answer.times is not None else np.array([answer.time])
    bad = ~np.isfinite(series).all(axis=1)  # (n, k)
    if not bad.any():
        return None
    sample = int(np.argmax(bad.any(axis=1)))
    return float(times[sample]), wrt[int(np.argmax(bad[sample]))]


def _end_time(scene: Scene, dt: float) -> float:
    return float(max(1, round(scene.duration / dt)) * dt)


def _reference_at(bound: SensitivityBound, time: float) -> tuple[np.ndarray, np.ndarray]:
    """(loose, tight) reference Jacobians (m, k) at ``time`` s."""
    times = np.array([min(time, bound.sensitivity.scene.duration)])
    return bound.loose.jacobian(times)[0], bound.sensitivity.jacobian(times)[0]


def _reference_error(bound: SensitivityBound, time: float) -> float:
    loose, tight = _reference_at(bound, time)
    return float(relative_error(loose, tight))


def _growth(bound: SensitivityBound, time: float) -> float | None:
    """‖J_ref(T)‖_F / ‖J_ref(0)‖_F, or None when J_ref(0) = 0 (only physical parameters: they move nothing at 0)."""
    at = np.linalg.norm(_reference_at(bound, time)[1])
    return float(at / bound.growth[0]) if bound.growth[0] > 0 else None


def _error(answer: EngineJacobian, reference: np.ndarray) -> float:
    with np.errstate(invalid="ignore"):
        return float(relative_error(answer.jacobian, reference))


def _floor(engine: Engine, variant: str, options: Mapping[str, Any] | None) -> float:
    """The relative error a Jacobian of this variant is correct under, whatever its trend."""
    return FLOAT32_FLOOR if single_precision(engine, variant, options) else FLOAT64_FLOOR


def gradient_metrics(engine: Engine, variant: str | None, options: Mapping[str, Any] | None, scene: Scene, dt: float,
                     wrt: Sequence[str]) -> dict[str, Any]:
    """A suite case's gradient metrics (compare/results/declared.py): gradient_error, gradient_self_consistency,
    gradient_wrong (1 for wrong or nan), with respect to the parameters of ``wrt`` this scene has; {} (null
    metrics) when it has none of them, the reference's sensitivities do not cover it, or the differentiation
    raised: the case's own run and metrics stand."""
    return gradient_measurement(engine, variant, options, scene, dt, wrt)[0]


def gradient_measurement(engine: Engine, variant: str | None, options: Mapping[str, Any] | None, scene: Scene,
                         dt: float, wrt: Sequence[str]) -> tuple[dict[str, Any], dict[str, np.ndarray]]:
    """(:func:`gradient_metrics`, :func:`gradient_series`): the metrics and the series the report draws; both {}
    when the metrics are null."""
    names = [name for name in wrt if name in real_parameters(scene)]
    if not names:
        return {}, {}
    try:
        bound = bound_sensitivity(scene, names)
        case = engine_case(engine, variant, options, scene, dt, names, bound)
    except Exception:  # noqa: BLE001 - a UserError (the reference's sensitivities do not cover this scene) or the
        return {}, {}  # gradient's own trouble leaves its metrics null, not the case failed
    metrics = {"gradient_error": _number(case.error), "gradient_self_consistency": _number(case.self_consistency),
               "gradient_wrong": float(case.klass in ("wrong", "nan"))}
    return metrics, gradient_series(case, bound)


def gradient_series(case: GradientCase, bound: SensitivityBound) -> dict[str, np.ndarray]:
    """What the report's gradient section draws (reports/gradients.py), as a case record's series:

    gradient_t (n,) s, the reference's samples; gradient_reference_norm (n,) ‖J_ref(t)‖_F (its growth);
    gradient_reference_difference (n,) its two solves' relative difference (its own error, whose crossing of
    JACOBIAN_HORIZON is the horizon); gradient_horizon (1,) s, only when there is one; gradient_error_t (p,) s and
    gradient_error_over_time (p,), the engine's error at its samples when known there, else at T alone.
    """
    series = {"gradient_t": bound.t, "gradient_reference_norm": bound.growth,
              "gradient_reference_difference": bound.difference}
    if case.horizon is not None:
        series["gradient_horizon"] = np.array([case.horizon])
    if case.times is not None and case.error_over_time is not None:
        series["gradient_error_t"], series["gradient_error_over_time"] = case.times, case.error_over_time
    else:
        series["gradient_error_t"] = np.array([round(case.duration / case.dt) * case.dt])
        series["gradient_error_over_time"] = np.array([case.error])
    return series
