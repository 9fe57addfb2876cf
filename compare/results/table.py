"""Stored results as text: a short table per scene, or flat per-case rows as CSV or JSON.

The table has one row per engine variant: its statuses across the dt
sweep, and at its finest ``ok`` dt the max position error, energy drift,
constraint error and cost, then the observed order. CSV and JSON have one
row per case with every metric (for pandas: ``pd.read_csv`` /
``pd.read_json(orient="records")``).
"""

from __future__ import annotations

import csv
import io
import json
from dataclasses import fields
from typing import Any, Iterable

from compare.results.metrics import CaseMetrics
from compare.results.sweep import VariantSweep, sweeps

#: CaseMetrics fields left out of the export (bookkeeping of the comparison, not metrics).
NOT_EXPORTED = ("n_samples", "complete")
#: Columns of the CSV / JSON export, in order: every metric of a case, as CaseMetrics orders them.
ROW_FIELDS = (
    "scene",
    "engine",
    "dt",
    "status",
    "message",
    *(f.name for f in fields(CaseMetrics) if f.name not in NOT_EXPORTED),
    "observed_order",
    "order_dt_min",
    "order_dt_max",
    "engine_version",
    "scene_hash",
)


def case_rows(records: Iterable[dict[str, Any]]) -> list[dict[str, Any]]:
    """One flat dict per case (keys ``ROW_FIELDS``), in the suite's order; missing values are None."""
    rows = []
    for sweep in sweeps(records):
        order = sweep.order
        for record in sweep.records:
            metrics = record.get("metrics") or {}
            info = record.get("run_info") or {}
            row = {
                "scene": sweep.scene_id,
                "engine": sweep.engine,
                "dt": record["case"]["dt"],
                "status": record["status"],
                "message": record["message"],
                **{k: metrics.get(k) for k in ROW_FIELDS if k in metrics},
                "observed_order": order.order if order else None,
                "order_dt_min": order.dt_min if order else None,
                "order_dt_max": order.dt_max if order else None,
                "engine_version": info.get("engine_version"),
                "scene_hash": record["scene_hash"],
            }
            rows.append({k: row.get(k) for k in ROW_FIELDS})
    return rows


def to_csv(records: Iterable[dict[str, Any]]) -> str:
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=ROW_FIELDS, lineterminator="\n")
    writer.writeheader()
    for row in case_rows(records):
        writer.writerow({k: "" if v is None else v for k, v in row.items()})
    return buffer.getvalue()


def to_json(records: Iterable[dict[str, Any]]) -> str:
    return json.dumps(case_rows(records), indent=1) + "\n"


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
    messages = [r["message"] for r in sweep.records if r["status"] != "ok" and r["message"]]
    return messages[0][:70] if messages else ""


TABLE_COLUMNS = ("engine", "status", "dt", "error/m", "drift/E*", "c.err/m", "cost s/s", "order")


def scene_tables(records: Iterable[dict[str, Any]]) -> str:
    """A short text table per scene (columns ``TABLE_COLUMNS``), values at each variant's finest ok dt."""
    by_scene: dict[str, list[list[str]]] = {}
    notes: dict[str, list[str]] = {}
    for sweep in sweeps(records):
        finest = sweep.finest_ok
        metrics = (finest or {}).get("metrics") or {}
        order = sweep.order.order if sweep.order else None
        by_scene.setdefault(sweep.scene_id, []).append(
            [
                sweep.engine,
                _statuses(sweep),
                f"{finest['case']['dt']:.3g}" if finest else "-",
                _number(metrics.get("position_error_linf")),
                _number(metrics.get("energy_drift")),
                _number(metrics.get("constraint_error")),
                _number(metrics.get("cost_per_simulated_second")),
                "-" if order is None else f"{order:.2f}",
            ]
        )
        reason = _reason(sweep)
        if reason:
            notes.setdefault(sweep.scene_id, []).append(f"  {sweep.engine}: {reason}")
    blocks = []
    for scene_id, rows in by_scene.items():
        widths = [max(len(c), *(len(r[i]) for r in rows)) for i, c in enumerate(TABLE_COLUMNS)]
        lines = [f"scene {scene_id}"]
        lines.append("  ".join(c.ljust(w) if i < 2 else c.rjust(w) for i, (c, w) in enumerate(zip(TABLE_COLUMNS, widths))))
        for row in rows:
            lines.append("  ".join(v.ljust(w) if i < 2 else v.rjust(w) for i, (v, w) in enumerate(zip(row, widths))))
        lines.extend(notes.get(scene_id, []))
        blocks.append("\n".join(line.rstrip() for line in lines))
    return "\n\n".join(blocks) + "\n"
