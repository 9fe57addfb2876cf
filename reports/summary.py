"""The per-scene summary tables: one per dt of the scene, one row per engine variant, best value per column marked.

The columns are the declared metrics (:mod:`compare.results.declared`)
with ``report = True``, the CPU cost of the case from its variant's cost
model (compare.results.cost: what the verdict ranks by, not the wall-clock
``cost_per_simulated_second``), then the per-variant observed order: a
metric declared for the report gets a column with no edit here.

Values are compared only between variants whose case at that dt is
``ok``: an unstable run's small cost or a failed run's missing drift is not
"best". The reference engine, when a suite runs it, is shown but not ranked.
A column where all ranked variants, or more than half (and more than two), share
the best gets no mark; ties (equal to the shown precision) are otherwise all marked. The observed order is a property of
the whole sweep, so it is ranked over every variant that has one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Callable

from compare.results import declared
from compare.results.cost import modelled
from compare.results.record import Status
from compare.results.sweep import VariantSweep

from reports.load import SceneResults
from reports.palette import Palette


def _exponent(value: float) -> str:
    return "0" if value == 0 else f"{value:.2e}"


@dataclass(frozen=True)
class Column:
    """A metric column: ``key`` in the record's metrics, heading, unit, which way is better, how to print.

    better : "low", "high", or None (not ranked).
    missing : text for a value the record does not have (None).
    """

    key: str
    heading: str
    unit: str
    better: str | None
    missing: str = "–"
    # One exponent format for the whole column, so magnitudes line up down the column (as in `xval show`).
    fmt: Callable[[float], str] = _exponent
    description: str = ""


def metric_columns() -> tuple[Column, ...]:
    """The metric columns, in order, from the declarations (compare.results.declared: ``report = True``);
    status, consistency and the order are added around them."""
    columns = []
    for metric in declared.reported():
        better = "high" if metric.higher_is_better else "low"
        # A time in seconds reads better without an exponent (divergence time: "never" when null).
        fmt = (lambda v: f"{v:.3g}") if metric.unit == "s" else _exponent
        columns.append(Column(metric.name, metric.title or metric.name, metric.unit, better, metric.missing, fmt,
                              metric.description))
    return tuple(columns)


#: Key of the CPU-cost column in a row's values (no declared metric: it comes from the variant's cost model).
CPU_COST = "cpu_cost"


def cost_column() -> Column:
    return Column(CPU_COST, "CPU cost", "s/s", "low", "–", _exponent,
                  "CPU time of the stepping loop per simulated second from the variant's cost model: per-step cost "
                  "× steps per simulated second (hover a value for its interval)")


def order_column() -> Column:
    metric = declared.METRICS["observed_order"]
    return Column(metric.name, metric.title or "observed order", metric.unit, "high", "–", lambda v: f"{v:.2f}",
                  metric.description)


#: The columns at import time (a metric registered later appears in the next table built).
METRIC_COLUMNS = metric_columns()
ORDER_COLUMN = order_column()


@dataclass(frozen=True)
class Cell:
    """One table cell: the text shown, whether it is its column's best, a tooltip, and the value to sort on."""

    text: str
    best: bool = False
    title: str = ""
    sort: str = ""


@dataclass(frozen=True)
class Row:
    """One engine variant: name, status at the table's dt, statuses over the sweep, consistency, metric cells, order."""

    engine: str
    status: str
    message: str
    sweep_statuses: str
    cells: list[Cell]
    order: Cell
    colour: str = "#888"
    consistent: bool | None = None
    consistency: str = ""


@dataclass(frozen=True)
class SummaryTable:
    columns: tuple[Column, ...]
    rows: list[Row]
    dt: float | None


def _sweep_statuses(sweep: VariantSweep) -> str:
    counts = sweep.statuses
    total = sum(counts.values())
    return ", ".join(f"{status} {n}/{total}" for status, n in counts.items())


def _rank_value(column: Column, value: Any) -> float | None:
    """A number to rank on (higher is better after the sign flip), or None when the value cannot rank."""
    if value is None:
        # A divergence time of None means "never diverged": better than any time.
        metric = declared.METRICS.get(column.key)
        return math.inf if metric is not None and metric.none_means == "infinite" else None
    if not isinstance(value, (int, float)) or not math.isfinite(value):
        return None
    return float(value) if column.better == "high" else -float(value)


def _best_flags(column: Column, values: list[Any], eligible: list[bool],
                uncertainty: list[float] | None = None) -> list[bool]:
    """Which of ``values`` are the column's best among the ``eligible`` ones (ties to the shown precision).

    uncertainty : per value, its error bar (same unit; the reference's for errors). The best is marked only
    when it beats every other eligible value by more than both their bars: a difference inside them is noise.
    """
    ranks = [_rank_value(column, v) if ok else None for v, ok in zip(values, eligible)]
    candidates = [r for r in ranks if r is not None]
    if column.better is None or not candidates:
        return [False] * len(values)
    top = max(candidates)
    if len(candidates) > 1 and min(candidates) == top:
        # Everyone ties (e.g. no variant diverges): a star on every row would say nothing.
        return [False] * len(values)
    bars = uncertainty or [0.0] * len(values)
    best = next(k for k, r in enumerate(ranks) if r == top)
    if any(r is not None and r != top and math.isfinite(r) and math.isfinite(top) and top - r <= bars[best] + bars[k]
           for k, r in enumerate(ranks)):
        return [False] * len(values)  # the runner-up is within the error bars: no one value is best
    shown = lambda v: column.missing if v is None else column.fmt(v)  # noqa: E731
    top_text = next(shown(v) for v, r in zip(values, ranks) if r == top)
    flags = [r is not None and (r == top or shown(v) == top_text) for v, r in zip(values, ranks)]
    if sum(flags) > max(2, len(candidates) / 2):
        return [False] * len(values)  # most rows share the best ("never" diverged): a star on each says nothing
    return flags


#: Metrics whose error bar is the reference's own (``reference_error``, m).
REFERENCE_BARRED = ("position_error_final", "position_error_rms", "position_error_linf")
#: A constraint error under this many ε·L is the round-off of a constraint the formulation holds exactly.
ROUND_OFF = 64 * 2.220446049250313e-16
BY_CONSTRUCTION = "0 (by construction)"


def _sort_key(column: Column, value: Any) -> str:
    """What a sortable table sorts the cell on when its text will not do ("Infinity" for never), else ""
    (the page then sorts on the text, which for a number is the number: "1.2e-04")."""
    metric = declared.METRICS.get(column.key)
    if value is None and metric is not None and metric.none_means == "infinite":
        return "Infinity"
    return ""


def _title(column: Column, cost: tuple[float, float, float] | None) -> str:
    """The tooltip of a CPU-cost cell: its interval."""
    return f"interval [{cost[1]:.2e}, {cost[2]:.2e}] s/s" if column.key == CPU_COST and cost is not None else ""


def summary_table(scene: SceneResults, dt: float | None = None, palette: Palette | None = None) -> SummaryTable:
    """The summary table of ``scene`` at ``dt`` (s; default its chosen dt)."""
    dt = scene.chosen_dt if dt is None else dt
    palette = palette or Palette(s.engine for s in scene.sweeps)
    columns = metric_columns() + (cost_column(),)
    order_col = order_column()
    cases = [scene.case_at(sweep, dt) for sweep in scene.sweeps]
    costs = [modelled(sweep.cost, case) if case is not None and case.has_metrics else None
             for sweep, case in zip(scene.sweeps, cases)]
    metrics = [{**(case.metrics if case is not None else {}), CPU_COST: None if cost is None else cost[0]}
               for case, cost in zip(cases, costs)]
    # The reference is the yardstick, not a competitor: its zero error would always be "best".
    ok = [case is not None and case.status is Status.OK and not sweep.is_reference
          for case, sweep in zip(cases, scene.sweeps)]
    # Without a reference there is no position error, so a divergence time of
    # None would falsely read "never": such cells are unknown, not best.
    no_reference = [m.get("position_error_linf") is None for m in metrics]
    columns_cells: list[list[Cell]] = []
    for col in columns:
        values = [m.get(col.key) for m in metrics]
        infinite = getattr(declared.METRICS.get(col.key), "none_means", "") == "infinite"
        unknown = [infinite and nr for nr in no_reference]
        zero = [col.key == "constraint_error" and isinstance(v, (int, float)) and abs(v) <= ROUND_OFF * scene.length
                for v in values]
        bars = [float((case.reference or {}).get("reference_error") or 0.0) if case is not None
                and col.key in REFERENCE_BARRED else 0.0 for case in cases]
        if col.key == CPU_COST:  # a cost is best only beyond its interval (what a rerun may give)
            bars = [0.0 if c is None else max(c[2] - c[0], c[0] - c[1]) for c in costs]
        flags = _best_flags(col, values, [o and not u and not z for o, u, z in zip(ok, unknown, zero)], bars)
        cells = []
        for value, best, case, cost, unknown_here, zero_here in zip(values, flags, cases, costs, unknown, zero):
            if case is None or not case.metrics or not case.metrics.get("n_samples"):
                # A run with no samples (it raised at once) has drift and constraint error 0 by
                # definition; printing those zeros would read as a perfect result.
                cells.append(Cell("–", title="no samples at this dt"))
            elif unknown_here:
                cells.append(Cell("–", title="no position error (no reference solution)"))
            elif zero_here:
                cells.append(Cell(BY_CONSTRUCTION, title=f"{value:.2g} m: round-off (under 64 ε·L); not ranked",
                                  sort="0"))
            else:
                cells.append(Cell(col.missing if value is None else col.fmt(value), best, _title(col, cost),
                                  sort=_sort_key(col, value)))
        columns_cells.append(cells)
    orders = [s.order.order if s.order is not None else None for s in scene.sweeps]
    order_flags = _best_flags(order_col, orders, [o is not None and not s.is_reference for o, s in zip(orders, scene.sweeps)])
    rows = []
    for k, (sweep, case) in enumerate(zip(scene.sweeps, cases)):
        fit = sweep.order
        if orders[k] is None:
            order = Cell("–", title=(fit.reason if fit is not None else ""))
        else:
            order = Cell(order_col.fmt(orders[k]), order_flags[k],
                         f"fitted over dt {fit.dt_min:.3g}–{fit.dt_max:.3g} s ({fit.n_points} points)")
        verdict = sweep.consistency
        rows.append(Row(
            engine=sweep.engine,
            status=case.status.value if case is not None else "not run",
            message=case.message if case is not None else "",
            sweep_statuses=_sweep_statuses(sweep),
            cells=[cells[k] for cells in columns_cells],
            order=order,
            colour=palette.colour(sweep.engine),
            consistent=None if verdict is None else verdict.consistent,
            consistency="" if verdict is None else verdict.reason,
        ))
    return SummaryTable(columns + (order_col,), rows, dt)


def summary_tables(scene: SceneResults, palette: Palette | None = None) -> list[SummaryTable]:
    """One summary table per dt of ``scene``, largest dt first (the dt selector switches between them)."""
    return [summary_table(scene, dt, palette) for dt in scene.dts]
