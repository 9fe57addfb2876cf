"""Across a dt sweep: per (scene, engine variant), its records in order, the observed order and the consistency.

On the tolerance axis (compare/suite/tolerance_axis.py) a variant sweeps a tolerance instead:
no order is fitted, and consistency is judged with the tolerance in dt's place.

Works on typed case records (:class:`compare.results.record.CaseRecord`),
so ``xval show``, the report, the baseline and the gate compute the same
numbers from a results directory.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Iterable

from compare.results.consistency import DEFAULT_TOLERANCE, Consistency, judge
from compare.results.cost import CostModel, fit
from compare.results.metrics import OrderFit, observed_order
from compare.results.record import CaseRecord, Status

#: The error an order is fitted to and work-precision points plot: max position error, m.
ORDER_METRIC = "position_error_linf"


@dataclass(frozen=True)
class VariantSweep:
    """One engine variant on one scene across the suite's time steps.

    records : that variant's case records, largest dt first.
    order : the observed order fitted to ``ORDER_METRIC`` over ``ok`` cases.
    consistency : whether the error falls towards the reference (compare.results.consistency).
    cost : the variant's stepping-cost model over its sweep (compare.results.cost), None when untimed.
    """

    scene_id: str
    engine: str
    records: list[CaseRecord] = field(default_factory=list)
    order: OrderFit | None = None
    consistency: Consistency | None = None
    cost: CostModel | None = None

    @property
    def statuses(self) -> dict[str, int]:
        counts: dict[str, int] = {}
        for record in self.records:
            counts[record.status.value] = counts.get(record.status.value, 0) + 1
        return counts

    @property
    def ok_records(self) -> list[CaseRecord]:
        return [r for r in self.records if r.status is Status.OK and r.has_metrics]

    @property
    def finest_ok(self) -> CaseRecord | None:
        """The ``ok`` case with the smallest dt (the tightest tolerance on the tolerance axis), or None."""
        ok = self.ok_records
        return min(ok, key=_step) if ok else None

    @property
    def is_reference(self) -> bool:
        """Whether this is the reference engine run as a suite engine (the yardstick, not a competitor)."""
        return bool(self.records) and self.records[0].case.engine_id.startswith("reference/")

    @property
    def all_skipped(self) -> bool:
        return all(r.status is Status.SKIPPED for r in self.records)


def _step(record: CaseRecord) -> float:
    """What a sweep runs along: the tolerance on the tolerance axis, else dt (s)."""
    return record.case.dt if record.case.tolerance is None else record.case.tolerance


def sweeps(records: Iterable[CaseRecord], tolerance: float | None = None) -> list[VariantSweep]:
    """Group records by (scene, engine variant) in the suite's order; fit each variant's order and judge it.

    tolerance : the verdict's tolerance as a fraction of L (None: DEFAULT_TOLERANCE).
    """
    groups: dict[tuple[str, str], list[CaseRecord]] = {}
    for record in sorted(records, key=lambda r: r.case.position):
        groups.setdefault((record.case.scene_id, record.case.engine), []).append(record)
    result = []
    for (scene_id, engine), members in groups.items():
        sweep = VariantSweep(scene_id, engine, members)
        ok = sweep.ok_records
        length = members[0].characteristic.length
        # A tolerance sweep has no order in dt; its consistency is judged along the tolerance.
        on_tolerance_axis = any(r.case.tolerance is not None for r in members)
        order = None if sweep.all_skipped or on_tolerance_axis else observed_order(
            [r.case.dt for r in ok], [r.metric(ORDER_METRIC) for r in ok], length=length,
            reference_error=_largest(_order_bar(r) for r in ok),
        )
        verdict = judge(
            [_step(r) for r in ok], [r.metric(ORDER_METRIC) for r in ok],
            tolerance=(DEFAULT_TOLERANCE if tolerance is None else tolerance) * length,
            reference_error=_largest(r.reference.get("reference_error") for r in ok if r.reference),
            floor=_largest((r.run_info.get("settings") or {}).get("precision_floor") for r in ok if r.run_info),
            horizon_limited=any(r.reference_horizon is not None for r in ok),
            axis="tolerance" if on_tolerance_axis else "dt",
        )
        result.append(VariantSweep(scene_id, engine, members, order, verdict, fit(engine, members)))
    return result


def _order_bar(record: CaseRecord) -> object:
    """The reference's error bar (m) over the samples a case's errors are judged on: its ``reference_error``,
    or within a horizon (which ends inside the run) the threshold the horizon is defined by."""
    reference = record.reference or {}
    if record.reference_horizon is not None:
        return reference.get("horizon_threshold")
    return reference.get("reference_error")


def _largest(values: Iterable[object]) -> float | None:
    """The largest positive finite number among ``values`` (None when there is none)."""
    found = [float(v) for v in values
             if isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v) and v > 0]
    return max(found) if found else None
