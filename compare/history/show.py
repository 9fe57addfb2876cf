"""``xval history show``'s rows: one per stored run × case, with the metrics, as a text table or JSON.

JSON rows are flat objects (``pd.DataFrame(json.load(f))`` reads them):
``run`` (id), ``commit``, ``dirty``, ``commit_date``, ``date`` (run start),
``machine`` (fingerprint), ``machine_name``, ``suite``, ``scene``, ``engine``,
``dt`` (s), ``status``, then one key per metric (compare.results.declared;
``observed_order`` is the variant's, repeated on each of its dts).
"""

from __future__ import annotations

import fnmatch
import json
from dataclasses import dataclass
from typing import Any, Sequence

from engines.errors import UserError

from compare.history.store import History
from compare.results import declared
from compare.results.declared import Metric


@dataclass(frozen=True)
class Filters:
    """scene / engine : exact ids or shell patterns (``ours/*``); suite : a suite name; last : the last N runs."""

    scene: str | None = None
    engine: str | None = None
    suite: str | None = None
    last: int | None = None


def metric_named(name: str) -> Metric:
    """The declared metric ``name`` (or its name before a rename); UserError listing the declared ones otherwise."""
    name = declared.current_name(name)
    if name not in declared.METRICS:
        raise UserError(f"--metric: unknown metric {name!r}; declared metrics are: {', '.join(declared.METRICS)}")
    return declared.METRICS[name]


def _match(pattern: str | None, value: str) -> bool:
    return pattern is None or fnmatch.fnmatchcase(value, pattern)


def rows(history: History, filters: Filters, metrics: Sequence[Metric]) -> list[dict[str, Any]]:
    """One flat dict per stored run × case matching ``filters``, runs in history order, cases in suite order."""
    runs = history.runs(suite=filters.suite)
    by_run: dict[int, list] = {}
    for case in history.cases([r.id for r in runs]):
        if _match(filters.scene, case.scene_id) and _match(filters.engine, case.engine):
            by_run.setdefault(case.run_id, []).append(case)
    runs = [r for r in runs if r.id in by_run]
    if filters.last is not None:
        runs = runs[-filters.last:] if filters.last > 0 else []
    out = []
    for run in runs:
        for case in sorted(by_run[run.id], key=lambda c: (c.entry.position, -c.dt)):
            out.append({
                "run": run.id, "commit": run.origin.commit, "dirty": run.origin.dirty, "commit_date": run.origin.date,
                "date": run.started, "machine": run.machine.fingerprint, "machine_name": run.machine.name,
                "suite": run.suite_name, "scene": case.scene_id, "engine": case.engine, "dt": case.dt,
                "status": case.status, **{m.name: case.metrics.get(m.name) for m in metrics},
            })
    return out


def to_json(table: list[dict[str, Any]]) -> str:
    return json.dumps(table, indent=1) + "\n"


def _cell(value: Any) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3g}" if 1e-2 <= abs(value) < 1e4 or value == 0 else f"{value:.2e}"
    return str(value)


def format_table(table: list[dict[str, Any]], metrics: Sequence[Metric], location: str) -> str:
    """Aligned text: run, commit (``*`` = dirty), date, machine, scene, engine, dt, status, the metrics."""
    if not table:
        return f"history {location}: no stored case matches\n"
    columns = ["run", "commit", "date", "machine", "scene", "engine", "dt", "status",
               *(f"{m.heading}" + (f" ({m.unit})" if m.unit and m.unit not in m.heading else "") for m in metrics)]
    body = []
    for row in table:
        commit = "?" if row["commit"] is None else row["commit"][:10] + ("*" if row["dirty"] else "")
        body.append([str(row["run"]), commit, (row["date"] or "")[:16].replace("T", " "), row["machine"][:8],
                     row["scene"], row["engine"], f"{row['dt']:.3g}", row["status"],
                     *(_cell(row[m.name]) for m in metrics)])
    widths = [max(len(c), *(len(r[i]) for r in body)) for i, c in enumerate(columns)]
    left = 6  # run … engine are text; dt, status and the metrics right-aligned
    lines = ["  ".join(c.ljust(w) if i < left else c.rjust(w) for i, (c, w) in enumerate(zip(columns, widths)))]
    for cells in body:
        lines.append("  ".join(v.ljust(w) if i < left else v.rjust(w) for i, (v, w) in enumerate(zip(cells, widths))))
    machines = sorted({(r["machine"][:8], r["machine_name"]) for r in table})
    runs = len({r["run"] for r in table})
    lines.append("")
    lines.append(f"{len(table)} cases of {runs} runs from {location}; * = uncommitted changes")
    lines.extend(f"machine {short}: {name}" for short, name in machines)
    return "\n".join(line.rstrip() for line in lines) + "\n"
