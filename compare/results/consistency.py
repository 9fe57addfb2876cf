"""Consistency: does a variant's error fall towards the reference as dt shrinks, or converge to something else?

``ok`` only says a run did not blow up; a solver with a wrong mass matrix
converges cleanly, at its full order, to the wrong trajectory. The rule, per
scene × engine variant over its ``ok`` runs ordered by dt (e = max position
error, m; tol = the suite's ``[verdict] tolerance`` · L):

- **true** when e at the finest dt is ≤ tol (right within the tolerance; an
  engine's own error floor well under it does not count against it), or when
  e still falls: the local order log(e₂/e₁)/log(dt₂/dt₁) between the two
  finest dts is ≥ ``MIN_LOCAL_ORDER`` (0.5);
- **false** when e has stopped falling while above tol: the solver
  converges, but not to the reference;
- **null** with fewer than two ok dts, or when the reference itself is only
  trustworthy up to a horizon inside the run (a chaotic scene) and e is not
  falling: chaos, not the engine, may have stopped it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

#: Local order between the two finest dts at or above which the error counts as still falling.
MIN_LOCAL_ORDER = 0.5


@dataclass(frozen=True)
class Consistency:
    """consistent : True, False or None (see the module docstring); reason : one line saying why."""

    consistent: bool | None
    reason: str


def judge(dts: Sequence[float], errors: Sequence[float | None], *, tolerance: float,
          horizon_limited: bool = False, axis: str = "dt") -> Consistency:
    """The verdict for one variant.

    dts : s, of its ok runs; errors : m, their max position error (None or non-finite: no value);
    tolerance : m; horizon_limited : the reference's two solves part inside the run.
    axis : "dt", or "tolerance" when ``dts`` are a tolerance sweep's tolerances (the messages say so).
    """
    points = sorted((float(dt), float(e)) for dt, e in zip(dts, errors) if e is not None and math.isfinite(e))
    if len(points) < 2:
        return Consistency(None, f"{len(points)} ok {axis} with an error; need 2 to judge")
    (dt1, e1), (dt2, e2) = points[0], points[1]
    if e1 <= tolerance:
        return Consistency(True, f"error {e1:.2g} m at {_at(axis, dt1)} is within the tolerance {tolerance:.2g} m")
    if e1 > 0 and e2 > 0 and dt2 > dt1:
        local = math.log(e2 / e1) / math.log(dt2 / dt1)
    else:
        local = math.nan
    if local >= MIN_LOCAL_ORDER:
        between = f"dt {dt2:g} and {dt1:g} s" if axis == "dt" else f"{axis} {dt2:g} and {dt1:g}"
        return Consistency(True, f"error still falls (local order {local:.2f} between {between})")
    if horizon_limited:
        return Consistency(None, f"error {e1:.2g} m stopped falling, but the reference is chaotic within the run; "
                                 f"not judged")
    order = "nan" if math.isnan(local) else f"{local:.2f}"
    return Consistency(False, f"converges to something else: error {e1:.2g} m at {_at(axis, dt1)} stopped falling "
                              f"(local order {order}) above the tolerance {tolerance:.2g} m")


def _at(axis: str, value: float) -> str:
    """``dt 0.001 s`` or ``tolerance 1e-08``."""
    return f"dt {value:g} s" if axis == "dt" else f"{axis} {value:g}"
