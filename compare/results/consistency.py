"""Consistency: does a variant's error keep falling towards the reference as dt shrinks, or converge to something else?

Per scene × variant over its ``ok`` runs, finest dt first: the error has plateaued when the local
order log(e₂/e₁)/log(dt₂/dt₁) between the two finest points is below MIN_LOCAL_ORDER (0.5).
consistent: no plateau, or one explained (the reference's error bar, a declared precision floor,
the tolerance); inconsistent: a plateau above all of these; None with fewer than two ok points.

Details: docs/report.md, "Module notes", ``compare/results/consistency.py``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

#: The verdict's default tolerance, a fraction of L (``[verdict] tolerance``): a plateau under it is right.
DEFAULT_TOLERANCE = 1e-6
#: Local order below which the error counts as no longer falling.
MIN_LOCAL_ORDER = 0.5
#: A plateau within this multiple of the reference's error bar is the reference's floor, not the engine's.
REFERENCE_MARGIN = 10.0


@dataclass(frozen=True)
class Consistency:
    """consistent : True, False or None (docs/report.md, "Module notes"); reason : one line saying why.

    plateau : m, the error the variant stopped at (None: still falling, or not judged).
    """

    consistent: bool | None
    reason: str
    plateau: float | None = None


def _fmt(value: float) -> str:
    return f"{value:.2g}"


def judge(dts: Sequence[float], errors: Sequence[float | None], *, tolerance: float,
          reference_error: float | None = None, floor: float | None = None,
          horizon_limited: bool = False, axis: str = "dt") -> Consistency:
    """The verdict for one variant.

    dts : s, of its ok runs (or tolerances on the tolerance axis); errors : m, their max position error
    (None or non-finite: no value). tolerance : m. reference_error : m, the reference's error bar.
    floor : m, the engine's declared precision floor. horizon_limited : the reference's two solves part
    inside the run. axis : "dt" or "tolerance" (for the messages).
    """
    points = sorted((float(dt), float(e)) for dt, e in zip(dts, errors) if e is not None and math.isfinite(e))
    if len(points) < 2:
        return Consistency(None, f"{len(points)} ok {axis} with an error; need 2 to judge")
    orders = [_local_order(points[k], points[k + 1]) for k in range(len(points) - 1)]
    if orders[0] >= MIN_LOCAL_ORDER:
        return Consistency(True, f"error still falls (local order {orders[0]:.2f} from "
                                 f"{_span(axis, points[1][0], points[0][0])})")
    extent = 1
    while extent < len(orders) and not orders[extent] >= MIN_LOCAL_ORDER:
        extent += 1
    level = points[0][1]
    stopped = (f"error stops falling at {_fmt(level)} m from {_span(axis, points[extent][0], points[0][0])} "
               f"(local order {_order_text(orders[0])})")
    if reference_error is not None and level <= REFERENCE_MARGIN * reference_error:
        return Consistency(True, f"{stopped}: the reference's own floor ({_fmt(reference_error)} m)", level)
    if floor is not None and level <= floor:
        return Consistency(True, f"{stopped}: within the engine's declared precision floor ({_fmt(floor)} m)", level)
    if level <= tolerance:
        return Consistency(True, f"{stopped}: within the tolerance {_fmt(tolerance)} m", level)
    if horizon_limited:
        return Consistency(None, f"{stopped}, but the reference is chaotic within the run; not judged", level)
    bars = [f"the tolerance {_fmt(tolerance)} m"]
    if reference_error is not None:
        bars.append(f"the reference's error bar {_fmt(reference_error)} m")
    if floor is not None:
        bars.append(f"its declared floor {_fmt(floor)} m")
    return Consistency(False, f"converges to something {_fmt(level)} m from the reference: {stopped}, "
                              f"above {', '.join(bars)}", level)


def _local_order(fine: tuple[float, float], coarse: tuple[float, float]) -> float:
    """log(e_coarse/e_fine)/log(dt_coarse/dt_fine); nan for a zero error or equal dts."""
    (dt1, e1), (dt2, e2) = fine, coarse
    if e1 > 0 and e2 > 0 and dt2 > dt1:
        return math.log(e2 / e1) / math.log(dt2 / dt1)
    return math.nan


def _order_text(order: float) -> str:
    """The order at 2 decimals; a plateau's tiny negative order reads "0.00", not "-0.00"."""
    text = "nan" if math.isnan(order) else f"{order:.2f}"
    return "0.00" if text == "-0.00" else text


def _span(axis: str, coarse: float, fine: float) -> str:
    """``dt 0.001 to 0.0001 s`` or ``tolerance 1e-06 to 1e-08``."""
    return f"dt {coarse:.3g} to {fine:.3g} s" if axis == "dt" else f"{axis} {coarse:.3g} to {fine:.3g}"
