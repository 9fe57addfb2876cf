"""What the gate compares, and how much change it forgives: metric rules, defaults, and the suite's ``[gate]`` table.

Accuracy metrics are deterministic: the same code on the same machine gives
the same bits, so their tolerances only have to absorb round-off that
differs across machines (BLAS, CPU instruction sets, numpy / scipy builds),
amplified a little by sensitive scenes. Timing is noisy everywhere, so it is
judged by a factor *and* the spread of the repeats (see :mod:`compare.gate.gate`).

A suite overrides any default in its ``[gate]`` table::

    [gate]
    timing_factor = 2.0                                  # slowdown that may fail a gate
    position_error_linf = { rtol = 0.2, atol = 1e-8 }    # either key may be left out
    energy_drift = 0.5                                   # a bare number is rtol

The older ``[tolerances]`` table (``metric = number``) is read as rtol
overrides, so suites written for it keep working; ``[gate]`` wins where both
name a metric.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Mapping


@dataclass(frozen=True)
class Tolerance:
    """rtol (fraction of the baseline) and atol (the metric's unit) forgiven before a change counts."""

    rtol: float
    atol: float


@dataclass(frozen=True)
class MetricRule:
    """One gated accuracy metric: its record key, unit, which way is better, and the default tolerance.

    higher_is_better : False for errors and drifts (worse = larger), True for
        divergence time and observed order (worse = smaller).
    none_means : how a null value ranks: ``"infinite"`` for divergence time
        (null = never diverged, the best), ``"absent"`` otherwise (nothing to
        compare).
    """

    name: str
    unit: str
    higher_is_better: bool
    default: Tolerance
    none_means: str = "absent"


#: Relative tolerance shared by the accuracy metrics. 10 %: far above the
#: cross-machine round-off of a deterministic run (~1e-12 relative on these
#: short scenes, up to ~1e-6 where a chaotic scene amplifies it), far below
#: the regressions worth catching (a doubled error, a lost order of
#: accuracy, a drift cure switched off: factors of 2 to 1000).
DEFAULT_RTOL = 0.1

#: Accuracy metrics the gate compares, in table order. The atols sit at the
#: level below which a value is noise, not accuracy: 1e-9 m is where
#: compare.results.metrics.ORDER_FLOOR puts the reference's own error (rtol = atol =
#: 1e-12 over a few seconds) for ~1 m scenes; constraint error is pure
#: round-off near 1e-13 m for a projecting solver, so 1e-10 m; forces come
#: from differentiated states and are good to ~1e-6 N; divergence time is
#: quantized by the sample interval, so two default samples (0.02 s); an
#: observed order is a fitted slope whose asymptotic range may gain or lose
#: a point, which moves it by up to ~0.2, while a lost order moves it by ≥ 1.
ACCURACY_METRICS: tuple[MetricRule, ...] = (
    MetricRule("position_error_linf", "m", False, Tolerance(DEFAULT_RTOL, 1e-9)),
    MetricRule("position_error_l2", "m", False, Tolerance(DEFAULT_RTOL, 1e-9)),
    MetricRule("position_error_final", "m", False, Tolerance(DEFAULT_RTOL, 1e-9)),
    MetricRule("divergence_time", "s", True, Tolerance(DEFAULT_RTOL, 0.02), none_means="infinite"),
    MetricRule("energy_drift", "E*", False, Tolerance(DEFAULT_RTOL, 1e-9)),
    MetricRule("constraint_error", "m", False, Tolerance(DEFAULT_RTOL, 1e-10)),
    MetricRule("constraint_force_error", "N", False, Tolerance(DEFAULT_RTOL, 1e-6)),
    MetricRule("observed_order", "", True, Tolerance(0.0, 0.25)),
)
RULES = {rule.name: rule for rule in ACCURACY_METRICS}

#: The timing metric (s of wall time per simulated s, median of repeats).
TIMING_METRIC = "cost_per_simulated_second"
#: A slowdown must exceed this factor (and the repeats' spread) to be worse.
#: 1.5: shared CI machines move single timings by 10-40 %; a real
#: regression worth a red build (an extra solve per step, a lost
#: vectorisation) costs ×2 or more.
DEFAULT_TIMING_FACTOR = 1.5


@dataclass(frozen=True)
class GateSettings:
    """Tolerances per accuracy metric (every name in RULES) and the timing factor (> 1)."""

    tolerances: Mapping[str, Tolerance] = field(default_factory=lambda: {r.name: r.default for r in ACCURACY_METRICS})
    timing_factor: float = DEFAULT_TIMING_FACTOR

    def tolerance(self, metric: str) -> Tolerance:
        return self.tolerances.get(metric, RULES[metric].default)


#: Keys a [gate] table may hold.
GATE_KEYS = ("timing_factor", *RULES)

ErrorMaker = Callable[[str, str], Exception]


def _non_negative(make_error: ErrorMaker, key: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise make_error(key, f"must be a number ≥ 0, got {value!r}; write e.g. {key.split('.')[-1]} = 0.1")
    return float(value)


def gate_settings(gate: Any, tolerances: Any, make_error: ErrorMaker) -> GateSettings:
    """GateSettings from a suite's ``[gate]`` table and legacy ``[tolerances]`` table (either may be None).

    make_error(key, message) builds the exception to raise (the suite reader
    passes one that adds the file and line), so every mistake names the key.
    """
    chosen = {r.name: r.default for r in ACCURACY_METRICS}
    factor = DEFAULT_TIMING_FACTOR
    if tolerances is not None:
        if not isinstance(tolerances, dict):
            raise make_error("tolerances", f"must be a table of metric = rtol, got {tolerances!r}")
        for name, value in tolerances.items():
            if name == TIMING_METRIC:
                # A relative tolerance on cost is the slowdown it forgives.
                factor = 1.0 + _non_negative(make_error, f"tolerances.{name}", value)
                continue
            if name not in RULES:
                raise make_error(f"tolerances.{name}", f"unknown metric; gated metrics are: {', '.join(RULES)}")
            chosen[name] = replace(chosen[name], rtol=_non_negative(make_error, f"tolerances.{name}", value))
    if gate is None:
        return GateSettings(chosen, factor)
    if not isinstance(gate, dict):
        raise make_error("gate", "must be a table, e.g. [gate] with timing_factor = 1.5")
    for name, value in gate.items():
        key = f"gate.{name}"
        if name == "timing_factor":
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 1 or not math.isfinite(value):
                raise make_error(key, f"must be a number > 1 (a slowdown factor), got {value!r}; write e.g. timing_factor = 1.5")
            factor = float(value)
        elif name not in RULES:
            raise make_error(key, f"unknown key; valid keys are: {', '.join(GATE_KEYS)}")
        elif isinstance(value, dict):
            for part in value:
                if part not in ("rtol", "atol"):
                    raise make_error(f"{key}.{part}", f"unknown key; write {name} = {{ rtol = 0.1, atol = 1e-9 }}")
            chosen[name] = Tolerance(
                _non_negative(make_error, f"{key}.rtol", value.get("rtol", chosen[name].rtol)),
                _non_negative(make_error, f"{key}.atol", value.get("atol", chosen[name].atol)),
            )
        else:
            chosen[name] = replace(chosen[name], rtol=_non_negative(make_error, key, value))
    return GateSettings(chosen, factor)
