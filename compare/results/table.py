"""Stored results as text: a short table per scene, or flat per-case rows as CSV or JSON.

The table has one row per engine variant: its statuses across the dt
sweep, and at its finest ``ok`` dt the max position error, energy drift,
constraint error and cost, then the observed order and the variant's per-step
CPU cost with its interval (compare.results.cost). CSV and JSON have one
row per case with every metric (for pandas: ``pd.read_csv`` /
``pd.read_json(orient="records")``).
"""

from __future__ import annotations

import csv
import io
import json
import textwrap
from typing import Any, Iterable

from compare.results import declared
from compare.results.record import CaseRecord, Status
from compare.results.sweep import VariantSweep, sweeps


def row_fields() -> tuple[str, ...]:
    """Columns of the CSV / JSON export, in order: every declared metric (compare.results.declared)."""
    return (
        "scene",
        "engine",
        "dt",
        "status",
        "message",
        *(m.name for m in declared.case_metrics()),
        "observed_order",
        "order_dt_min",
        "order_dt_max",
        "consistent",
        "consistency",
        "engine_version",
        "scene_hash",
        "tolerance",
        *REFERENCE_FIELDS,
    )


#: The reference's own error bar (m), horizon (s) with its interval ([low, high] s) and the scene's
#: Lyapunov estimate (1/s) with its interval, per case row (docs/metrics.md, "The reference's own
#: error"); null when not measured (the intervals: for a scene with a horizon, a chaotic one).
REFERENCE_FIELDS = ("reference_error", "reference_horizon", "reference_horizon_interval", "lyapunov_exponent",
                    "lyapunov_interval")


def reference_values(record: CaseRecord) -> dict[str, Any]:
    """:data:`REFERENCE_FIELDS` of one case (None where the record has no reference)."""
    reference = record.reference or {}
    return {"reference_horizon": record.reference_horizon,
            **{name: reference.get(name) for name in REFERENCE_FIELDS if name != "reference_horizon"}}


def estimate_text(value: float | None, interval: Any, unit: str, digits: int = 2) -> str:
    """``0.95 [0.55, 1.1] /s``: an estimate with its interval (``-`` for none; no interval: the value alone)."""
    if value is None:
        return "-"
    if not (isinstance(interval, (list, tuple)) and len(interval) == 2):
        return f"{value:.{digits}g} {unit}"
    return f"{value:.{digits}g} [{interval[0]:.{digits}g}, {interval[1]:.{digits}g}] {unit}"


def case_rows(records: Iterable[CaseRecord], tolerance: float | None = None) -> list[dict[str, Any]]:
    """One flat dict per case (keys :func:`row_fields`), in the suite's order; missing values are None."""
    fields_now = row_fields()
    rows = []
    for sweep in sweeps(records, tolerance):
        order = sweep.order
        verdict = sweep.consistency
        for record in sweep.records:
            row = {
                "scene": sweep.scene_id,
                "engine": sweep.engine,
                "dt": record.case.dt,
                "status": record.status.value,
                "message": record.message,
                **{m.name: record.metrics.get(m.name) for m in declared.case_metrics()},
                "observed_order": order.order if order else None,
                "order_dt_min": order.dt_min if order else None,
                "order_dt_max": order.dt_max if order else None,
                "consistent": verdict.consistent if verdict else None,
                "consistency": verdict.reason if verdict else "",
                "engine_version": record.engine_version,
                "scene_hash": record.scene_hash,
                "tolerance": record.case.tolerance,  # the tolerance axis's (compare/suite/tolerance_axis.py)
                **reference_values(record),
            }
            rows.append({k: row.get(k) for k in fields_now})
    return rows


def to_csv(records: Iterable[CaseRecord], tolerance: float | None = None) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=row_fields(), lineterminator="\n")
    writer.writeheader()
    for row in case_rows(records, tolerance):
        writer.writerow({k: "" if v is None else v for k, v in row.items()})
    return buffer.getvalue()


def to_json(records: Iterable[CaseRecord], tolerance: float | None = None) -> str:
    return json.dumps(case_rows(records, tolerance), indent=1) + "\n"


def _number(value: float | None, unit: str = "") -> str:
    return "-" if value is None else f"{value:.2e}{unit}"


def _statuses(sweep: VariantSweep) -> str:
    counts = sweep.statuses
    total = sum(counts.values())
    if counts.get("ok") == total:
        return f"ok {total}/{total}"
    return ", ".join(f"{status} {n}" for status, n in counts.items())


def _reason(sweep: VariantSweep) -> str:
    """The message shared by a variant's non-ok cases, shortened (e.g. why it was skipped)."""
    messages = [r.message for r in sweep.records if r.status is not Status.OK and r.message]
    return textwrap.shorten(messages[0], 70, placeholder=" …") if messages else ""  # cut between words


def table_columns() -> tuple[str, ...]:
    """Headings of the short table: engine, statuses, finest ok dt, the shown metrics, the per-step CPU cost
    with its interval (compare.results.cost), the verdict."""
    return ("engine", "status", "dt", *(m.heading for m in declared.shown()), "s/step [interval]", "consistent")


def _verdict(sweep: VariantSweep) -> str:
    if sweep.consistency is None or sweep.consistency.consistent is None:
        return "-"
    return "yes" if sweep.consistency.consistent else "NO"


def scene_tables(variant_sweeps: Iterable[VariantSweep]) -> str:
    """A short text table per scene (columns :func:`table_columns`), values at each variant's finest ok dt.

    variant_sweeps : compare.results.sweep.sweeps(records, tolerance), which the caller's verdict uses too.
    """
    columns = table_columns()
    by_scene: dict[str, list[list[str]]] = {}
    notes: dict[str, list[str]] = {}
    references: dict[str, str] = {}
    for sweep in variant_sweeps:
        finest = sweep.finest_ok
        if not references.get(sweep.scene_id):  # a sweep skipped throughout has no reference
            references[sweep.scene_id] = _reference_line(sweep.records)
        values = []
        for metric in declared.shown():
            if metric.per == "variant":
                value = sweep.order.order if (metric.name == "observed_order" and sweep.order) else None
                values.append("-" if value is None else f"{value:.2f}")
            else:
                values.append(_number(finest.metrics.get(metric.name) if finest else None))
        by_scene.setdefault(sweep.scene_id, []).append(
            [sweep.engine, _statuses(sweep), _step(finest), *values,
             sweep.cost.describe().replace(" s/step", "") if sweep.cost else "-", _verdict(sweep)]
        )
        reason = _reason(sweep)
        if reason:
            notes.setdefault(sweep.scene_id, []).append(f"  {sweep.engine}: {reason}")
        if sweep.consistency is not None and sweep.consistency.consistent is False:
            notes.setdefault(sweep.scene_id, []).append(f"  {sweep.engine}: {sweep.consistency.reason}")
    blocks = []
    for scene_id, rows in by_scene.items():
        widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(columns)]
        lines = [f"scene {scene_id}" + references.get(scene_id, "")]
        lines.append("  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(columns, widths))))
        for row in rows:
            lines.append("  ".join(v.ljust(w) if i < 2 else v.rjust(w) for i, (v, w) in enumerate(zip(row, widths))))
        lines.extend(notes.get(scene_id, []))
        blocks.append("\n".join(line.rstrip() for line in lines))
    return "\n\n".join(blocks) + "\n"


def scene_reference(records: Iterable[CaseRecord]) -> dict[str, Any] | None:
    """:data:`REFERENCE_FIELDS` of a scene: those of its first record that has a reference (None: none has)."""
    for record in records:
        values = reference_values(record)
        if values["reference_error"] is not None:
            return values
    return None


def _reference_line(records: Iterable[CaseRecord]) -> str:
    """`` (reference error 3e-12 m, horizon none, Lyapunov -)`` from the first record that has a reference."""
    values = scene_reference(records)
    if values is not None:
        horizon = values["reference_horizon"]
        return (f" (reference error {values['reference_error']:.2g} m, horizon "
                f"{'none' if horizon is None else estimate_text(horizon, values['reference_horizon_interval'], 's', 3)}"
                f", Lyapunov exponent {estimate_text(values['lyapunov_exponent'], values['lyapunov_interval'], '/s')})")
    return ""


def _step(finest: CaseRecord | None) -> str:
    """The short table's dt column: the finest ok dt, or ``tol 1e-08`` on the tolerance axis."""
    if finest is None:
        return "-"
    return f"{finest.case.dt:.3g}" if finest.case.tolerance is None else f"tol {finest.case.tolerance:.3g}"
