"""What the gate compares, and how much change it forgives: metric rules, defaults, and the suite's ``[gate]`` table.

Accuracy metrics are deterministic: the same code on the same machine gives
the same bits, so their tolerances only have to absorb round-off that
differs across machines (BLAS, CPU instruction sets, numpy / scipy builds),
amplified a little by sensitive scenes. Timing is noisy everywhere, so it is
judged by a factor *and* the spread of the repeats (see :mod:`compare.gate.gate`).

Details: docs/gate.md, "Module notes", ``compare/suite/gate_rules.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any, Callable, Iterator, Mapping

from compare.results import declared
from compare.results.declared import TIMING_METRIC, Metric, Tolerance


class _Rules(Mapping[str, Metric]):
    """The gated accuracy metrics by name, read live from compare.results.declared (so a metric
    registered later is gated too), in table order."""

    def __getitem__(self, name: str) -> Metric:
        metric = declared.METRICS[name]
        if not metric.gated:
            raise KeyError(name)
        return metric

    def __iter__(self) -> Iterator[str]:
        return iter([m.name for m in declared.gated()])

    def __len__(self) -> int:
        return len(declared.gated())


#: Gated accuracy metrics by name (live view of the declarations).
RULES: Mapping[str, Metric] = _Rules()

#: A slowdown must exceed this factor (and the repeats' spread) to be worse.
#: 1.5: shared CI machines move single timings by 10-40 %; a real
#: regression worth a red build (an extra solve per step, a lost
#: vectorisation) costs ×2 or more.
DEFAULT_TIMING_FACTOR = 1.5


@dataclass(frozen=True)
class GateSettings:
    """Tolerances per accuracy metric (every name in RULES) and the timing factor (> 1)."""

    tolerances: Mapping[str, Tolerance] = field(default_factory=lambda: {r.name: r.tolerance for r in declared.gated()})
    timing_factor: float = DEFAULT_TIMING_FACTOR

    def tolerance(self, metric: str) -> Tolerance:
        return self.tolerances.get(metric, RULES[metric].tolerance)


def gate_keys() -> tuple[str, ...]:
    """Keys a [gate] table may hold."""
    return ("timing_factor", *RULES)

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
    chosen = {r.name: r.tolerance for r in declared.gated()}
    factor = DEFAULT_TIMING_FACTOR
    if tolerances is not None:
        if not isinstance(tolerances, dict):
            raise make_error("tolerances", f"must be a table of metric = rtol, got {tolerances!r}")
        for name, value in tolerances.items():
            name = declared.current_name(name)  # a suite written before a rename still reads
            if name == TIMING_METRIC:
                # A relative tolerance on cost is the slowdown it forgives: the factor 1 + value, which must
                # be > 1 as [gate] timing_factor must (timing is noisy; 0 would fail every rerun).
                if isinstance(value, bool) or not isinstance(value, (int, float)) or not 0 < value < math.inf:
                    raise make_error(f"tolerances.{name}", f"must be a number > 0 (the slowdown forgiven: 0.5 is a "
                                                           f"factor 1.5), got {value!r}; or write [gate] timing_factor = 1.5")
                factor = 1.0 + float(value)
                continue
            if name not in RULES:
                raise make_error(f"tolerances.{name}", f"unknown key; valid keys are: {', '.join((*RULES, TIMING_METRIC))}")
            chosen[name] = replace(chosen[name], rtol=_non_negative(make_error, f"tolerances.{name}", value))
    if gate is None:
        return GateSettings(chosen, factor)
    if not isinstance(gate, dict):
        raise make_error("gate", "must be a table, e.g. [gate] with timing_factor = 1.5")
    for name, value in gate.items():
        key = f"gate.{name}"
        name = declared.current_name(name)  # a suite written before a rename still reads
        if name == "timing_factor":
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not value > 1 or not math.isfinite(value):
                raise make_error(key, f"must be a number > 1 (a slowdown factor), got {value!r}; write e.g. timing_factor = 1.5")
            factor = float(value)
        elif name not in RULES:
            raise make_error(key, f"unknown key; valid keys are: {', '.join(gate_keys())}")
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
