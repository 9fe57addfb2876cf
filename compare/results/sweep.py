"""Across a dt sweep: per (scene, engine variant), its records in order and the observed order.

Works on stored case records (dicts as written by the runner), so ``xval
show`` and reports compute the same numbers from a results directory.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable

from compare.results.metrics import OrderFit, observed_order

#: The error an order is fitted to and work-precision points plot: max position error, m.
ORDER_METRIC = "position_error_linf"


@dataclass(frozen=True)
class VariantSweep:
    """One engine variant on one scene across the suite's time steps.

    records : that variant's case records, largest dt first.
    order : the observed order fitted to ``ORDER_METRIC`` over ``ok`` cases.
    """

    scene_id: str
    engine: str
    records: list[dict[str, Any]] = field(default_factory=list)
    order: OrderFit | None = None

    @property
    def statuses(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for record in self.records:
            counts[record["status"]] = counts.get(record["status"], 0) + 1
        return counts

    @property
    def finest_ok(self) -> dict[str, Any] | None:
        """The ``ok`` case with the smallest dt, or None."""
        ok = [r for r in self.records if r["status"] == "ok" and r.get("metrics")]
        return min(ok, key=lambda r: r["case"]["dt"]) if ok else None


def _position(record: dict[str, Any]) -> tuple:
    return tuple(record["case"].get("position", (0, 0, 0)))


def sweeps(records: Iterable[dict[str, Any]]) -> list[VariantSweep]:
    """Group records by (scene, engine variant) in the suite's order and fit each variant's order."""
    groups: dict[tuple[str, str], VariantSweep] = {}
    for record in sorted(records, key=_position):
        case = record["case"]
        key = (case["scene_id"], case["engine"])
        groups.setdefault(key, VariantSweep(case["scene_id"], case["engine"])).records.append(record)
    result = []
    for sweep in groups.values():
        ok = [r for r in sweep.records if r["status"] == "ok" and r.get("metrics")]
        length = sweep.records[0].get("characteristic", {}).get("length", 1.0)
        order = observed_order(
            [r["case"]["dt"] for r in ok], [r["metrics"].get(ORDER_METRIC) for r in ok], length=length
        ) if sweep.statuses.get("skipped", 0) < len(sweep.records) else None
        result.append(VariantSweep(sweep.scene_id, sweep.engine, sweep.records, order))
    return result
