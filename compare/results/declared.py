"""Every metric of a case, declared once: name, unit, which way is better, whether the gate judges it.

show (``xval show``), the CSV/JSON export, the HTML report, the baseline and
the gate all take their metric lists from :data:`METRICS`, so a metric
declared here — with a ``compute`` function for a metric the runner does
not already produce — appears everywhere without further edits::

    from compare.results.declared import Metric, register
    register(Metric("peak_speed", "m/s", "lower", gated=True,
                    compute=lambda inputs: float(abs(inputs.trajectory.velocities).max())))

Metrics with ``per = "variant"`` (the observed order) are computed across a
variant's dt sweep, not per case; they are declared here for their unit,
direction and gate tolerance, and stored in the baseline per variant.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any, Callable, Mapping

import numpy as np

from engines.scene.scene import SceneLike
from engines.scene.trajectory import momentum_drift

from compare.results.metrics import CaseMetrics

#: Relative tolerance shared by the accuracy metrics. 10 %: far above the
#: cross-machine round-off of a deterministic run (~1e-12 relative on these
#: short scenes, up to ~1e-6 where a chaotic scene amplifies it), far below
#: the regressions worth catching (a doubled error, a lost order of
#: accuracy, a drift cure switched off: factors of 2 to 1000).
DEFAULT_RTOL = 0.1


@dataclass(frozen=True)
class Tolerance:
    """rtol (fraction of the baseline) and atol (the metric's unit) forgiven before a change counts."""

    rtol: float
    atol: float


@dataclass(frozen=True)
class MetricInputs:
    """What a metric's ``compute`` receives for one case (all in the scene frame, SI units).

    scene : engines.scene.scene.Scene; trajectory : engines.scene.trajectory.Trajectory (first n samples);
    reference_positions : (n, P, 3) m at the trajectory's times; position_error : (n,) m.
    """

    scene: SceneLike
    trajectory: Any
    reference_positions: np.ndarray
    position_error: np.ndarray


@dataclass(frozen=True)
class Metric:
    """One metric.

    name : the key in a case record's ``metrics`` and in every export.
    unit : shown beside values ("m", "E*", "s/s", "" for a pure number).
    better : ``"lower"`` (errors, drifts, cost) or ``"higher"`` (divergence time, order).
    gated : whether ``xval gate`` compares it (accuracy); timing is gated by its own rule.
    tolerance : the gate's default tolerance (gated metrics only).
    none_means : how a null value ranks: ``"infinite"`` (divergence time: never diverged, the best)
        or ``"absent"`` (nothing to compare).
    per : ``"case"`` (a value per case) or ``"variant"`` (one value per dt sweep).
    shown : whether ``xval show``'s short table has a column for it; label : its short heading.
    report : whether the report's per-scene summary has a column for it; title : its heading there;
    missing : the text the report shows for a null value ("never" for divergence time).
    compute : for a metric the runner does not produce itself, f(MetricInputs) -> float | None.
    description : one line for docs and the report's tooltips.
    """

    name: str
    unit: str
    better: str
    gated: bool = False
    tolerance: Tolerance = Tolerance(DEFAULT_RTOL, 0.0)
    none_means: str = "absent"
    per: str = "case"
    shown: bool = False
    label: str = ""
    report: bool = False
    title: str = ""
    missing: str = "–"
    compute: Callable[[MetricInputs], float | None] | None = None
    description: str = ""

    def __post_init__(self) -> None:
        if self.better not in ("lower", "higher"):
            raise ValueError(f"metric {self.name}: better must be 'lower' or 'higher', not {self.better!r}")
        if self.per not in ("case", "variant"):
            raise ValueError(f"metric {self.name}: per must be 'case' or 'variant', not {self.per!r}")

    @property
    def higher_is_better(self) -> bool:
        return self.better == "higher"

    @property
    def heading(self) -> str:
        return self.label or self.name


#: The atols sit at the level below which a value is noise, not accuracy:
#: 1e-9 m is where compare.results.metrics.ORDER_FLOOR puts the reference's
#: own error (rtol = atol = 1e-12 over a few seconds) for ~1 m scenes;
#: constraint error is pure round-off near 1e-13 m for a projecting solver,
#: so 1e-10 m; forces come from differentiated states and are good to ~1e-6
#: N; divergence time is quantized by the sample interval, so two default
#: samples (0.02 s); an observed order is a fitted slope whose asymptotic
#: range may gain or lose a point, which moves it by up to ~0.2, while a lost
#: order moves it by ≥ 1.
_BUILT_IN = (
    Metric("position_error_linf", "m", "lower", True, Tolerance(DEFAULT_RTOL, 1e-9), shown=True, label="error/m",
           report=True, title="position error",
           description="max over samples of e(t) = max over particles ‖p − p_ref‖"),
    Metric("position_error_rms", "m", "lower", True, Tolerance(DEFAULT_RTOL, 1e-9),
           description="RMS over samples of e(t)"),
    Metric("position_error_final", "m", "lower", True, Tolerance(DEFAULT_RTOL, 1e-9),
           description="e(t) at the last sample (null for an incomplete run)"),
    Metric("divergence_time", "s", "higher", True, Tolerance(DEFAULT_RTOL, 0.02), none_means="infinite",
           report=True, title="divergence time", missing="never",
           description="first t with e(t) > δ·L (null: never)"),
    Metric("energy_drift", "E*", "lower", True, Tolerance(DEFAULT_RTOL, 1e-9), shown=True, label="drift/E*",
           report=True, title="energy drift",
           description="max |E(t) − E(0)| / E*"),
    Metric("constraint_error", "m", "lower", True, Tolerance(DEFAULT_RTOL, 1e-10), shown=True, label="c.err/m",
           report=True, title="constraint error",
           description="max over constraints and samples of the distance-form violation"),
    Metric("constraint_force_error", "N", "lower", True, Tolerance(DEFAULT_RTOL, 1e-6),
           report=True, title="constraint-force error", missing="not exposed",
           description="max over samples and constraints of ‖F − F_ref‖ (null: engine reports no forces)"),
    Metric("constraint_force_error_relative", "", "lower",
           description="constraint_force_error / (total mass · g)"),
    Metric("wall_time", "s", "lower", description="stepping loop wall time, median of repeats"),
    # Wall clock, as baselines and the history store keep it; the verdict and the report's "CPU cost" column
    # use the CPU cost model (compare.results.cost) instead, which a busy neighbour does not stretch.
    Metric("cost_per_simulated_second", "s/s", "lower", shown=True, label="wall s/s", title="wall-clock cost",
           description="wall_time per simulated second (wall clock; the verdict uses the CPU cost model)"),
    Metric("steps_per_second", "1/s", "higher", description="steps per second of wall time"),
    Metric("observed_order", "", "higher", True, Tolerance(0.0, 0.25), per="variant", shown=True, label="order",
           description="slope of log error against log dt over the asymptotic range"),
    # A conserved quantity beside energy: atol at the round-off of a reduced-coordinate run (~1e-13).
    Metric("momentum_drift", "L*", "lower", True, Tolerance(DEFAULT_RTOL, 1e-9),
           title="angular-momentum drift", missing="not conserved",
           compute=lambda inputs: _momentum_drift(inputs),
           description="max |L_z(t) − L_z(0)| / L*, L_z about the Pins' vertical line, L* = M·L·√(g·L) "
                       "(null where L_z is not conserved or is zero by symmetry: planar scenes)"),
    # A suite's [gradients] wrt (compare/gradients/measure.py, docs/gradients.md): null without it.
    Metric("gradient_error", "", "lower", True, Tolerance(DEFAULT_RTOL, 1e-9), title="gradient error",
           description="‖J − J_ref‖_F / ‖J_ref‖_F of d outputs(T) / d [gradients] wrt against the reference's"),
    Metric("gradient_self_consistency", "", "lower",
           description="the engine's own derivatives against differences of its own rollouts (null when the "
                       "Jacobian is those differences)"),
    Metric("gradient_wrong", "", "lower", True, Tolerance(0.0, 0.5),
           description="1 when the gradient's class is wrong or nan (it does not converge to the reference as dt "
                       "halves), 0 when correct or chaotic"),
)


def _momentum_drift(inputs: "MetricInputs") -> float | None:
    trajectory, scene = inputs.trajectory, inputs.scene
    drift = getattr(scene, "momentum_drift", None)
    if getattr(scene, "is_model", False) and drift is not None:  # its root joints' momenta (docs/metrics.md)
        states = trajectory.joint_states
        if states is None or not np.isfinite(states).all():
            return None
        n = states.shape[1] // 2
        return drift(states[:, :n], states[:, n:])
    return momentum_drift(scene, trajectory.positions, trajectory.velocities)

#: Every declared metric by name, in table order.
METRICS: dict[str, Metric] = {m.name: m for m in _BUILT_IN}

#: The timing metric (s of wall time per simulated s, median of repeats); gated by its own rule.
TIMING_METRIC = "cost_per_simulated_second"

#: Metric names earlier releases wrote, by the name that replaced them (the same quantity; a horizon
#: metric's whole-run value is stored as ``<name>_whole_run``, compare.run.runner.HORIZON_METRICS).
RENAMED = {
    "position_error_l2": "position_error_rms",
    "position_error_l2_whole_run": "position_error_rms_whole_run",
}


def current_name(name: str) -> str:
    """The metric name that replaced ``name`` (:data:`RENAMED`), else ``name``."""
    return RENAMED.get(name, name)


def current_names(metrics: Mapping[str, Any]) -> dict[str, Any]:
    """``metrics`` with every name of :data:`RENAMED` under its current name.

    The readers of stored metrics (a case record, a baseline entry, a history row) call it, so results,
    baselines and histories written before a rename still compare with new runs.
    """
    return {current_name(name): value for name, value in metrics.items()}


def register(metric: Metric) -> Metric:
    """Declare a new metric (a plug-in's, or a test's); refuses a name already declared."""
    if metric.name in METRICS:
        raise ValueError(f"metric {metric.name!r} is already declared")
    METRICS[metric.name] = metric
    return metric


def unregister(name: str) -> None:
    """Remove a metric declared with :func:`register` (tests clean up with it)."""
    if name in (m.name for m in _BUILT_IN):
        raise ValueError(f"metric {name!r} is built in")
    METRICS.pop(name, None)


def gated() -> list[Metric]:
    """The metrics the gate judges for accuracy, in table order."""
    return [m for m in METRICS.values() if m.gated]


def case_metrics() -> list[Metric]:
    """The per-case metrics in export order (exports have a column for each): the ones the runner computes
    itself in compare.results.metrics.CaseMetrics' field order (which CSV readers of earlier releases rely
    on), then the others in declaration order."""
    # CaseMetrics, the dataclass, is the order; no copy of it here.
    per_case = [m for m in METRICS.values() if m.per == "case"]
    rank = {f.name: k for k, f in enumerate(fields(CaseMetrics))}
    return sorted(per_case, key=lambda m: rank.get(m.name, len(rank)))


def shown() -> list[Metric]:
    """The metrics of ``xval show``'s short table and the report's summary, in order."""
    return [m for m in METRICS.values() if m.shown]


def reported() -> list[Metric]:
    """The per-case metrics of the report's summary table, in order."""
    return [m for m in METRICS.values() if m.report and m.per == "case"]


def computed_extras(inputs: MetricInputs) -> dict[str, float | None]:
    """Values of the declared metrics that have a ``compute`` function (non-finite as None)."""
    values: dict[str, float | None] = {}
    for metric in METRICS.values():
        if metric.compute is None:
            continue
        value = metric.compute(inputs)
        values[metric.name] = None if value is None or not math.isfinite(value) else float(value)
    return values
