"""The tolerance axis: a suite's ``tolerance`` sweep, for engines whose error is set by a tolerance.

A suite may sweep ``tolerance = [1e-4, 1e-6]`` or ``tolerance = { from = 1e-4, to = 1e-10,
per_decade = 1 }`` beside its ``dt``. An engine variant takes part when its engine declares
the capability ``"tolerance"``, names the options a tolerance sets (``Engine.tolerance_options``,
e.g. Drake's ``("accuracy",)``), and says these settings are error-controlled
(``Engine.tolerance_capable(settings)``; a fixed-step variant of the same engine is not). Such a
variant gets one case per tolerance *instead of* one per dt: the tolerance is written into
each of its tolerance options, and dt is the suite's sample interval, which such an engine
takes as its largest step. Every other variant keeps its dt sweep. Both kinds of point land
on the same error-against-cost plane; an order is fitted only to a dt sweep, and consistency
is judged along the tolerance (does the error fall as it tightens).
"""

from __future__ import annotations

from typing import Any

from engines.adapter import Engine


#: The capability an engine declares to take part (engines.drake.adapter.DrakeEngine).
CAPABILITY = "tolerance"


def read_tolerances(reader: Any, value: Any) -> tuple[float, ...]:
    """The suite's tolerances, tightest last; ``reader`` is the suite reader (its ``sweep`` reads both forms)."""
    if value is None:
        return ()
    values = reader.sweep("tolerance", value, "tolerance", "[1e-4, 1e-6]", "{ from = 1e-4, to = 1e-10, per_decade = 1 }")
    return tuple(sorted(values, reverse=True))


def tolerance_options(engine: Engine | None, variant: str | None, options: Any) -> tuple[str, ...]:
    """The options a tolerance sets for this engine variant (Engine.tolerance_options, when
    Engine.tolerance_capable says its settings are error-controlled), or () when it takes no tolerance."""
    if engine is None or CAPABILITY not in engine.capabilities or not engine.tolerance_options:
        return ()
    return tuple(engine.tolerance_options) if engine.tolerance_capable(engine.resolve(variant, options)) else ()


def with_tolerance(options: Any, names: tuple[str, ...], tolerance: float) -> dict[str, Any]:
    """``options`` with each tolerance option set to ``tolerance``."""
    return {**dict(options), **{name: tolerance for name in names}}
